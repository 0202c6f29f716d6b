"""1,000 cassette tests under pytest: wiretape's plugin against
pytest-reserial on the same suite (issue 42, cassette_suite_vs_reserial_time_ratio).

Each test writes one request and reads its echo. wiretape's cassettes are
recorded once by the plugin itself (`--wiretape-record=once` on a
`type=loopback` device, which echoes); pytest-reserial's one cassette file
is written as that plugin reads it (one entry a test). Then the two suites
run in alternating order, each as a whole `pytest -q` run, and the figure
is the median of the per-pair ratios of their wall times.

Prints one JSON line: {"ratio": median, "ratios": [...], "wiretape_s":
median, "reserial_s": median, "tests": N}.

Usage: python cassette_suite_bench.py WORKDIR TESTS ROUNDS
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

WIRETAPE_TEST = '''
def test_{index:05d}(wiretape_port):
    wiretape_port.write(b"REQ{index:05d}\\n")
    assert wiretape_port.read_exactly(9) == b"REQ{index:05d}\\n"
'''
RESERIAL_HEAD = '''import serial


def exchange(expected):
    port = serial.Serial("/dev/reserial-bench", 115200, timeout=1)
    port.write(expected)
    assert port.read(len(expected)) == expected
    port.close()
'''
RESERIAL_TEST = '''

def test_{index:05d}(reserial):
    exchange(b"REQ{index:05d}\\n")
'''


def pytest_run(python: str, where: Path, *args: str) -> float:
    env = {key: value for key, value in os.environ.items() if key != "PYTEST_ADDOPTS"}
    start = time.perf_counter()
    proc = subprocess.run([python, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "-p", "no:xdist", *args], cwd=where, env=env,
                          capture_output=True, text=True, timeout=1800)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"pytest {' '.join(args)} in {where} failed: "
                         + " | ".join(proc.stdout.strip().splitlines()[-3:]))
    return seconds


def make_suites(work: Path, tests: int, python: str) -> tuple[Path, Path]:
    ours, theirs = work / "wiretape_suite", work / "reserial_suite"
    for folder in (ours, theirs):
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
    (ours / "test_suite.py").write_text(
        "".join(WIRETAPE_TEST.format(index=i) for i in range(tests)))
    pytest_run(python, ours, "-p", "no:reserial", "--wiretape-record=once",
               "--wiretape-device=type=loopback", "test_suite.py")
    (theirs / "test_suite.py").write_text(
        RESERIAL_HEAD + "".join(RESERIAL_TEST.format(index=i) for i in range(tests)))
    cassette = {f"test_{i:05d}": {"rx_encoding": "utf-8", "tx_encoding": "utf-8",
                                  "rx": f"REQ{i:05d}\n", "tx": f"REQ{i:05d}\n"}
                for i in range(tests)}
    (theirs / "test_suite.jsonl").write_text(json.dumps(cassette) + "\n")
    return ours, theirs


def main() -> int:
    work, tests, rounds = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
    python = sys.executable
    ours, theirs = make_suites(work, tests, python)
    times: dict[str, list[float]] = {"wiretape": [], "reserial": []}
    runs = {"wiretape": (ours, ("-p", "no:reserial", "test_suite.py")),
            "reserial": (theirs, ("test_suite.py",))}
    for index in range(rounds):
        order = ("wiretape", "reserial") if index % 2 == 0 else ("reserial", "wiretape")
        for kind in order:
            where, args = runs[kind]
            times[kind].append(pytest_run(python, where, *args))
    ratios = [w / r for w, r in zip(times["wiretape"], times["reserial"])]
    print(json.dumps({"ratio": statistics.median(ratios), "ratios": ratios,
                      "wiretape_s": statistics.median(times["wiretape"]),
                      "reserial_s": statistics.median(times["reserial"]), "tests": tests}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
