"""A campaign split into shards (`wiretape faults --shard K/N`) and merged
(`wiretape faults merge`) equals the campaign run whole (DESIGN §22,
docs/faults.md, "Campaigns over several machines"); bad shards and bad
merges are usage errors naming the flag or file."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from campaign_driver import write_campaign_files

from wiretape import faults

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
pytest_plugins = ["pytester"]

KINDS = "drop,corrupt,duplicate"



def run_cli(*args, timeout=300):
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def campaign_files(tmp_path_factory):
    """The session, the driver, and the campaign run whole and in 3 shards."""
    folder = tmp_path_factory.mktemp("shards")
    session, driver = write_campaign_files(folder, 3)
    command = ["--kinds", KINDS, "--options", "timing=none", "--timeout", "2", "--jobs", "2"]
    argv = ["--", sys.executable, str(driver), "{port}"]
    whole = run_cli("faults", str(session), *command, "--json", str(folder / "whole.json"), *argv)
    shards = [run_cli("faults", str(session), *command, "--shard", f"{k}/3",
                      "--json", str(folder / f"shard{k}.json"), *argv) for k in (1, 2, 3)]
    return {"folder": folder, "session": session, "driver": driver, "whole": whole,
            "shards": shards, "command": command, "argv": argv}


def runs_of(path: Path):
    return [(run["case"], run["kind"], run["where"], run["outcome"])
            for run in json.loads(path.read_text())["runs"]]


def test_the_shards_split_the_cases_by_index_modulo_n(campaign_files):
    folder = campaign_files["folder"]
    whole = runs_of(folder / "whole.json")
    assert len(whole) == 9
    assert {"crash", "hang"} <= {outcome for *_, outcome in whole}
    for k in (1, 2, 3):
        document = json.loads((folder / f"shard{k}.json").read_text())
        assert document["shard"] == f"{k}/3"
        assert document["cases"] == 9
        assert [run[0] for run in runs_of(folder / f"shard{k}.json")] == list(range(k - 1, 9, 3))
    # Each shard's exit says whether it found a crash or hang of its own.
    for k, result in zip((1, 2, 3), campaign_files["shards"]):
        own = {run[3] for run in runs_of(folder / f"shard{k}.json")}
        assert result.returncode == (1 if own & {"crash", "hang"} else 0), result.stderr


def test_merged_shards_equal_the_whole_campaign(campaign_files):
    folder = campaign_files["folder"]
    merged = run_cli("faults", "merge", *(str(folder / f"shard{k}.json") for k in (3, 1, 2)),
                     "--json", str(folder / "merged.json"))
    assert merged.returncode == campaign_files["whole"].returncode == 1, merged.stderr
    assert runs_of(folder / "merged.json") == runs_of(folder / "whole.json")
    whole_doc = json.loads((folder / "whole.json").read_text())
    merged_doc = json.loads((folder / "merged.json").read_text())
    assert merged_doc["summary"] == whole_doc["summary"]
    assert merged_doc["shard"] is None and merged_doc["interrupted"] is False
    # The table printed is the whole campaign's, reproduction lines included.
    table = lambda out: [line for line in out.splitlines() if not line.startswith("  |")]
    assert table(merged.stdout) == table(campaign_files["whole"].stdout)


def test_python_cases_take_a_shard(campaign_files):
    session = str(campaign_files["session"])
    everything = faults.cases(session, kinds=KINDS.split(","))
    parts = [faults.cases(session, kinds=KINDS.split(","), shard=faults.Shard(k, 3))
             for k in (1, 2, 3)]
    assert sorted(sum(parts, []), key=everything.index) == everything
    assert parts[1] == everything[1::3]


@pytest.mark.parametrize("shard", ["0/3", "4/3", "-1/3", "1/0", "3", "a/b", "1/3/3", ""])
def test_a_bad_shard_is_a_usage_error_naming_the_flag(campaign_files, shard):
    result = run_cli("faults", str(campaign_files["session"]), "--shard", shard,
                     *campaign_files["argv"], timeout=60)
    assert result.returncode == 2, result.stderr
    assert "--shard" in result.stderr
    assert "Traceback" not in result.stderr


def _rewrite(source: Path, target: Path, change) -> Path:
    document = json.loads(source.read_text())
    change(document)
    target.write_text(json.dumps(document))
    return target


def _bad_merge(campaign_files, change, name="bad.json", replace=2):
    folder = campaign_files["folder"]
    files = [folder / f"shard{k}.json" for k in (1, 2, 3)]
    files[replace - 1] = _rewrite(files[replace - 1], folder / name, change)
    return run_cli("faults", "merge", *map(str, files), timeout=60)


@pytest.mark.parametrize("change, words", [
    (lambda d: d.update(seed=7), "--seed"),
    (lambda d: d.update(session_sha256="0" * 64), "SESSION"),
    (lambda d: d.update(kinds=["drop"]), "--kinds"),
    (lambda d: d.update(budget=4), "--budget"),
    (lambda d: d.update(options="timing=session"), "--options"),
    (lambda d: d.update(shard="2/4"), "share N"),
    (lambda d: d.update(shard="1/3"), "also"),
    (lambda d: d.update(interrupted=True), "interrupted"),
    (lambda d: d["runs"].pop(), "not the cases of shard"),
    (lambda d: d.pop("session_sha256"), "session_sha256"),
    (lambda d: d["runs"][0].update(outcome="fine"), "runs[0]"),
    (lambda d: d.update(seed=True), "'seed'"),
])
def test_merging_runs_that_do_not_belong_together_is_refused(campaign_files, change, words):
    result = _bad_merge(campaign_files, change)
    assert result.returncode == 2, result.stderr
    assert words in result.stderr and "bad.json" in result.stderr
    assert "Traceback" not in result.stderr


def test_a_missing_shard_and_a_whole_campaign_are_refused(campaign_files):
    folder = campaign_files["folder"]
    missing = run_cli("faults", "merge", str(folder / "shard1.json"), str(folder / "shard3.json"))
    assert missing.returncode == 2 and "missing shard 2/3" in missing.stderr
    whole = run_cli("faults", "merge", str(folder / "whole.json"))
    assert whole.returncode == 2 and "without --shard" in whole.stderr
    garbage = folder / "garbage.json"
    garbage.write_text("{not json")
    broken = run_cli("faults", "merge", str(garbage))
    assert broken.returncode == 2 and "garbage.json" in broken.stderr
    absent = run_cli("faults", "merge", str(folder / "absent.json"))
    assert absent.returncode == 3 and "absent.json" in absent.stderr


def test_pytest_xdist_splits_the_cases_over_its_workers(campaign_files, pytester):
    pytest.importorskip("xdist", reason="pytest-xdist is not installed (pip install .[test])")
    session, driver = campaign_files["session"], campaign_files["driver"]
    # The oracle: whether each case crashed in the whole campaign's run.
    outcomes = {f"{run['kind']}@{run['where']}": run["outcome"] for run in
                json.loads((campaign_files["folder"] / "whole.json").read_text())["runs"]}
    pytester.makepyfile(test_campaign=f"""
        import os, subprocess, sys
        import pytest
        from wiretape import faults

        CASES = faults.cases({str(session)!r}, kinds=["corrupt", "duplicate"])

        @pytest.mark.parametrize("case", CASES, ids=lambda case: case.id)
        def test_driver_survives(case):
            with faults.faulty_device({str(session)!r}, case, "timing=none") as path:
                try:
                    status = subprocess.run([sys.executable, {str(driver)!r}, path],
                                            timeout=2).returncode
                    outcome = "crash" if status < 0 else "ok" if status == 0 else "error"
                except subprocess.TimeoutExpired:
                    outcome = "hang"
            with open(os.environ["PYTEST_XDIST_WORKER"] + ".ran", "a") as note:
                note.write(case.id + "\\n")
            # The same outcome as the campaign's (its --timeout was 2 s too).
            assert outcome == {outcomes!r}[case.id]
    """)
    result = pytester.runpytest_subprocess("-n", "2", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=6)
    ran = {path.stem: path.read_text().split() for path in pytester.path.glob("gw*.ran")}
    assert len(ran) == 2, ran  # both workers ran cases
    assert sorted(sum(ran.values(), [])) == sorted(
        case.id for case in faults.cases(str(session), kinds=["corrupt", "duplicate"]))
