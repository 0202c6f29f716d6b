"""A campaign as CI engines run it (DESIGN §28): `--shard auto` from the
engine's variables, written into the JSON as `shard` and `shard_from`, and
`--junit FILE` for campaigns and `faults merge`, read back by junitparser,
the parser CI systems' JUnit readers follow."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from campaign_driver import write_campaign_files


junitparser = pytest.importorskip("junitparser", reason="junitparser is in the test extra "
                                  "(make installs it into .venv)")

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
KINDS = "drop,corrupt"


ENGINE_VARIABLES = ("TEST_SHARD_INDEX", "TEST_TOTAL_SHARDS", "TEST_SHARD_STATUS_FILE",
                    "JOB_COMPLETION_INDEX", "CI_NODE_INDEX", "CI_NODE_TOTAL")


def run_cli(*args, environ=None, timeout=300):
    env = {name: value for name, value in os.environ.items() if name not in ENGINE_VARIABLES}
    env.update(environ or {})
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True, timeout=timeout,
                          env=env)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ci")
    session, driver = write_campaign_files(folder, 2)
    command = ["--kinds", KINDS, "--options", "timing=none", "--timeout", "2", "--jobs", "2"]
    argv = ["--", sys.executable, str(driver), "{port}"]
    return folder, session, command, argv


def campaign(setup, name, *extra, environ=None):
    folder, session, command, argv = setup
    json_path, junit_path = folder / f"{name}.json", folder / f"{name}.xml"
    result = run_cli("faults", str(session), *command, *extra, "--json", str(json_path),
                     "--junit", str(junit_path), *argv, environ=environ)
    return result, json_path, junit_path


def test_shard_auto_takes_gitlabs_shard_and_says_so(setup):
    auto, auto_json, _ = campaign(setup, "auto2", "--shard", "auto",
                                  environ={"CI_NODE_INDEX": "2", "CI_NODE_TOTAL": "2"})
    given, given_json, _ = campaign(setup, "given2", "--shard", "2/2")
    assert auto.returncode == given.returncode, auto.stderr
    auto_doc, given_doc = json.loads(auto_json.read_text()), json.loads(given_json.read_text())
    assert auto_doc["shard"] == "2/2" and auto_doc["shard_from"] == "gitlab"
    assert given_doc["shard_from"] is None
    runs = lambda doc: [(r["case"], r["kind"], r["where"], r["outcome"]) for r in doc["runs"]]
    assert runs(auto_doc) == runs(given_doc)


def test_shard_auto_for_a_kubernetes_job_needs_its_total(setup):
    folder, session, command, argv = setup
    refused = run_cli("faults", str(session), *command, "--shard", "auto", *argv,
                      environ={"JOB_COMPLETION_INDEX": "0"})
    assert refused.returncode == 2
    assert "JOB_COMPLETION_INDEX" in refused.stderr and "--shards N" in refused.stderr
    none = run_cli("faults", str(session), *command, "--shard", "auto", *argv)
    assert none.returncode == 2 and "no CI engine" in none.stderr
    disagree = run_cli("faults", str(session), *command, "--shard", "auto", *argv,
                       environ={"CI_NODE_INDEX": "1", "CI_NODE_TOTAL": "2",
                                "TEST_SHARD_INDEX": "1", "TEST_TOTAL_SHARDS": "2"})
    assert disagree.returncode == 2 and "bazel says shard 2/2" in disagree.stderr
    assert not (folder / "never.json").exists()


def _cases(path):
    document = junitparser.JUnitXml.fromfile(str(path))
    suites = list(document) if isinstance(document, junitparser.JUnitXml) else [document]
    return [case for suite in suites for case in suite]


def test_junit_has_a_case_per_run_and_failures_with_the_reproduction(setup):
    result, json_path, junit_path = campaign(setup, "whole")
    assert result.returncode == 1, result.stderr  # something crashed or hung
    runs = json.loads(json_path.read_text())["runs"]
    cases = _cases(junit_path)
    assert [case.name for case in cases] == [f"{r['kind']}@{r['where']}" for r in runs]
    for case, run in zip(cases, runs):
        failures = [item for item in case.result if isinstance(item, junitparser.Failure)]
        if run["outcome"] in ("crash", "hang"):
            assert len(failures) == 1 and failures[0].type == run["outcome"]
            assert failures[0].text.splitlines()[0] == f"reproduce: {run['repro']}"
        else:
            assert failures == [] and case.is_passed
    assert {run["outcome"] for run in runs} >= {"crash"}
    # The driver's own words (with characters XML must escape) reach the report.
    assert any("unexpected answer <&>" in (failure.text or "") for case in cases
               for failure in case.result if isinstance(failure, junitparser.Failure))


def test_merged_shards_write_the_whole_campaigns_junit(setup):
    folder = setup[0]
    whole, _, whole_xml = campaign(setup, "whole_for_merge")
    parts = []
    for k in (1, 2):
        shard, part_json, _ = campaign(setup, f"part{k}", "--shard", "auto",
                                       environ={"TEST_SHARD_INDEX": str(k - 1),
                                                "TEST_TOTAL_SHARDS": "2"})
        assert json.loads(part_json.read_text())["shard_from"] == "bazel"
        parts.append(str(part_json))
    merged_xml = folder / "merged.xml"
    merged = run_cli("faults", "merge", *parts, "--junit", str(merged_xml))
    assert merged.returncode == whole.returncode, merged.stderr
    outcome = lambda case: [item.type for item in case.result if isinstance(
        item, junitparser.Failure)]
    assert [(c.name, outcome(c)) for c in _cases(merged_xml)] == \
        [(c.name, outcome(c)) for c in _cases(whole_xml)]


def test_junit_and_json_cannot_be_one_file(setup):
    folder, session, command, argv = setup
    same = folder / "same.out"
    result = run_cli("faults", str(session), *command, "--json", str(same), "--junit",
                     str(same), *argv)
    assert result.returncode == 2 and "give two files" in result.stderr
    assert not same.exists()
