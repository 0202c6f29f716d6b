"""`wiretape faults merge` reads shard files anyone may have written: what
no campaign writes is exit 2 naming the file and the member, escaped for a
terminal, before anything is written (docs/faults.md, "Campaigns over
several machines")."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

import wiretape
from wiretape import faults

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
KINDS = ["drop", "corrupt"]
OPTIONS = "timing=none"


def run_cli(*args):
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True, timeout=120)


@pytest.fixture
def shards(tmp_path):
    """Two shard files as `faults --shard K/2 --json` writes them (every run
    ok), over a session of three exchanges, without running a campaign."""
    session = tmp_path / "lines.wtape"
    with wiretape.SessionWriter(str(session), port_type="serial") as writer:
        for n in range(3):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}\n".encode())
    cases = faults.cases(str(session), kinds=KINDS, options=OPTIONS)
    assert len(cases) == 6
    files = []
    for k in (1, 2):
        runs = [{"case": index, "kind": case.kind, "where": case.where, "outcome": "ok",
                 "exit": 0, "seconds": 0.25, "repro": ""}
                for index, case in enumerate(cases) if index % 2 == k - 1]
        document = {"session": str(session), "session_sha256": faults.session_digest(str(session)),
                    "seed": 0, "kinds": KINDS, "budget": None, "options": OPTIONS,
                    "cases": len(cases), "shard": f"{k}/2", "speed": 1.0, "runs": runs,
                    "summary": {"ok": len(runs), "error": 0, "crash": 0, "hang": 0},
                    "interrupted": False}
        path = tmp_path / f"shard{k}.json"
        path.write_text(json.dumps(document))
        files.append(path)
    return {"folder": tmp_path, "session": session, "files": files}


def merge_changed(shards, change=None, text=None):
    """Merges shard 1 and a copy of shard 2 changed by `change` (or replaced
    by `text`) named bad.json, asking for --json OUT."""
    bad = shards["folder"] / "bad.json"
    if text is None:
        document = json.loads(shards["files"][1].read_text())
        change(document)
        text = json.dumps(document)
    bad.write_text(text)
    out = shards["folder"] / "merged.json"
    return run_cli("faults", "merge", str(shards["files"][0]), str(bad), "--json", str(out)), out


def test_shards_as_a_campaign_writes_them_merge(shards):
    out = shards["folder"] / "merged.json"
    result = run_cli("faults", "merge", *map(str, shards["files"]), "--json", str(out))
    assert result.returncode == 0, result.stderr
    assert len(json.loads(out.read_text())["runs"]) == 6
    assert "not checked" not in result.stderr


def run_of(number):
    return lambda document: document["runs"][number]


@pytest.mark.parametrize("change, member", [
    (lambda d: d["runs"][0].update(kind="\x1b[2J\x1b]0;pwned\x07drop"), "'kind'"),
    (lambda d: d["runs"][0].update(kind="bogus"), "'kind'"),
    (lambda d: d["runs"][0].update(kind="garbage"), "'kind'"),  # a kind, not the campaign's
    (lambda d: d["runs"][0].update(where="exchange:99"), "'where'"),
    (lambda d: d["runs"][0].update(where="exchange:1;drop@exchange:2"), "'where'"),
    (lambda d: d["runs"][0].update(where="rx:1\x1b[31m"), "'where'"),
    (lambda d: d["runs"][1].update(kind=d["runs"][0]["kind"], where=d["runs"][0]["where"]),
     "run twice"),
    (lambda d: d["runs"][0].update(outcome="ok", exit=3), "'exit'"),
    (lambda d: d["runs"][0].update(outcome="error", exit=0), "'exit'"),
    (lambda d: d["runs"][0].update(outcome="hang", exit=0), "'exit'"),
    (lambda d: d["runs"][0].update(outcome="crash", exit=None), "'exit'"),
    (lambda d: d["runs"][0].update(outcome="ok\x1b[0m"), "'outcome'"),
    (lambda d: d["runs"][0].update(seconds=float("nan")), "'seconds'"),
    (lambda d: d["runs"][0].update(seconds=float("inf")), "'seconds'"),
    (lambda d: d["runs"][0].update(seconds=-1), "'seconds'"),
    (lambda d: d["runs"][0].update(repro="\x1b[2Jrm -rf ~"), "'repro'"),
    (lambda d: d.update(cases=0), "'cases'"),
    (lambda d: d.update(cases=-6), "'cases'"),
    (lambda d: d.update(kinds=["drop", "\x1b[31m"]), "'kinds[1]'"),
    (lambda d: d.update(options="timing=\x1b[31m"), "'options'"),
    (lambda d: d.update(budget=0), "'budget'"),
    (lambda d: d.update(seed=-1), "'seed'"),
])
def test_what_no_campaign_writes_is_refused_naming_file_and_member(shards, change, member):
    result, out = merge_changed(shards, change)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "bad.json" in result.stderr and member in result.stderr, result.stderr
    assert "\x1b" not in result.stderr + result.stdout and "\x07" not in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists(), "written before the refusal"


def test_a_deeply_nested_file_is_refused_naming_it(shards):
    result, out = merge_changed(shards, text="[" * 100_000 + "]" * 100_000)
    assert result.returncode == 2, result.stderr
    assert "bad.json" in result.stderr and "nested too deeply" in result.stderr
    assert "recursion" not in result.stderr
    assert not out.exists()


def test_non_json_numbers_are_refused_by_the_member_holding_them(shards):
    text = shards["files"][1].read_text().replace('"seconds": 0.25', '"seconds": NaN', 1)
    result, out = merge_changed(shards, text=text)
    assert result.returncode == 2 and "'seconds' is NaN" in result.stderr, result.stderr
    assert not out.exists()


def test_without_the_session_the_places_are_not_checked_and_it_says_so(shards):
    shards["session"].rename(shards["folder"] / "elsewhere.wtape")
    out = shards["folder"] / "merged.json"
    result = run_cli("faults", "merge", *map(str, shards["files"]), "--json", str(out))
    assert result.returncode == 0, result.stderr
    assert "places are not checked" in result.stderr
    # What the file alone shows is still checked.
    result, out = merge_changed(shards, lambda d: d["runs"][0].update(kind="bogus"))
    assert result.returncode == 2 and "'kind'" in result.stderr


CORPUS = Path(__file__).resolve().parents[3] / "fuzz" / "corpus" / "faults_merge_fuzz"


def _load_fuzz_target():
    spec = importlib.util.spec_from_file_location(
        "faults_merge_fuzz", CORPUS.parents[1] / "faults_merge_fuzz.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("seed", sorted(path.name for path in CORPUS.iterdir()))
def test_the_fuzz_corpus_merges_or_is_refused_cleanly(tmp_path, seed):
    """What ctest's corpus replay is for the C++ fuzz targets."""
    _load_fuzz_target().check_input((CORPUS / seed).read_bytes(), str(tmp_path))
