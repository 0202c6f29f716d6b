"""`wiretape fuzz -- CMD` guided by AFL++'s coverage (DESIGN §27,
docs/fuzzing.md "Coverage from AFL++"): a program built with afl-clang-fast
is seen as instrumented, its map read after each run, and a plan that lit
new edges mutated further; a crash behind two conditions one after the
other is found, and the corpus grows past the seed."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import wiretape
from wiretape import fuzz
from wiretape.fuzz import coverage

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
DRIVER = Path(__file__).parent / "programs" / "two_step_driver.c"
#: A seed whose coverage-guided search reaches the crash within RUNS runs
#: (at run 25), where blind plans of the same seed do not in 100
#: (bench/fuzz_coverage_bench.py compares with blind plans over many seeds).
SEED = 0
RUNS = 40


@pytest.fixture(scope="module")
def driver(tmp_path_factory) -> Path:
    compiler = shutil.which("afl-clang-fast")
    if compiler is None:
        pytest.skip("SKIPPED LOUDLY: afl-clang-fast is not installed (Debian package afl++; "
                    ".ci/run installs it): AFL++ coverage guidance is not tested")
    program = tmp_path_factory.mktemp("afl") / "two_step_driver"
    subprocess.run([compiler, "-O1", "-o", str(program), str(DRIVER)], check=True,
                   capture_output=True)
    return program


@pytest.fixture()
def session(tmp_path) -> Path:
    path = tmp_path / "reply.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        writer.write("tx", 0, b"Q\n")
        writer.write("rx", 1_000_000, b"ABC")
    return path


def test_hit_counts_are_bucketed_and_only_new_buckets_count():
    def bucketed(counts):
        return bytes(counts).translate(coverage._BUCKETS)

    assert list(bucketed([0, 1, 2, 3, 4, 7, 8, 200])) == [0, 1, 2, 4, 8, 8, 16, 128]
    seen = coverage.Coverage()
    assert seen.add(bucketed([0, 1, 2, 3, 4, 7, 8, 200])) == 7
    assert seen.add(bucketed([0, 1, 2, 3, 5, 6, 9, 130])) == 0  # the same buckets again
    assert seen.add(bucketed([0, 2, 0, 0, 0, 0, 0, 0])) == 1  # edge 1 hit twice: new
    assert seen.edges == 7


def test_mutated_plans_come_from_the_seed_the_index_and_the_corpus():
    # The recording alone: the random plan a search without coverage makes.
    assert fuzz.mutated_plan(3, 7, [b""], 2) == fuzz.random_plan(3, 7, 2)
    corpus = [b"", bytes.fromhex("01000005"), bytes.fromhex("0100000507000102")]
    plans = [fuzz.mutated_plan(3, index, corpus, 2) for index in range(200)]
    assert plans == [fuzz.mutated_plan(3, index, corpus, 2) for index in range(200)]
    assert all(plan and len(plan) % 4 == 0 for plan in plans)
    # Some are mutations of the corpus plans: they keep a step of theirs.
    assert sum(b"\x01\x00\x00\x05" in plan for plan in plans) > 50


def test_a_program_built_with_afl_clang_fast_is_seen_as_instrumented(driver):
    assert coverage.instrumented([str(driver), "{port}"])
    assert not coverage.instrumented([sys.executable, "-c", "pass", "{port}"])
    assert not coverage.instrumented(["no-such-program-here", "{port}"])
    assert coverage.map_size([str(driver)]) >= 64


def test_coverage_guides_the_search_to_a_crash_behind_two_conditions(tmp_path, driver, session):
    findings = tmp_path / "findings"
    done = subprocess.run(WIRETAPE + ["fuzz", str(session), "--seed", str(SEED), "--runs",
                                      str(RUNS), "--speed", "10", "--findings", str(findings),
                                      "--", str(driver), "{port}"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "coverage from AFL++" in done.stdout
    index = json.loads((findings / "index.json").read_text())
    assert [finding["kind"] for finding in index["findings"]] == ["crash"]
    changed = index["findings"][0]["changed"]
    assert any("byte 0" in line for line in changed) and any("byte 2" in line for line in changed)
    corpus = sorted((findings / "corpus").iterdir())
    assert len(corpus) > 1  # the recording unchanged, and plans that lit new edges
    assert (findings / "corpus" / "plan-0.hex").read_text() == "\n"


def test_coverage_none_leaves_an_instrumented_program_unguided(tmp_path, driver, session):
    findings = tmp_path / "findings"
    done = subprocess.run(WIRETAPE + ["fuzz", str(session), "--runs", "2", "--speed", "10",
                                      "--coverage", "none", "--findings", str(findings),
                                      "--", str(driver), "{port}"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode in (0, 1), done.stdout + done.stderr
    assert "coverage" not in done.stdout
    assert not (findings / "corpus").exists()


def test_coverage_afl_refuses_a_program_that_writes_no_map(tmp_path, session):
    true = shutil.which("true")
    assert true is not None
    done = subprocess.run(WIRETAPE + ["fuzz", str(session), "--runs", "1", "--coverage", "afl",
                                      "--findings", str(tmp_path / "findings"),
                                      "--", true, "{port}"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "wrote nothing into AFL++'s coverage map" in done.stderr
