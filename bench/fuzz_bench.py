#!/usr/bin/env python3
"""The fuzzing figures (DESIGN §27, docs/fuzzing.md "Figures so far"):
prints one JSON line. Usage: fuzz_bench.py BUILD_DIR [RUNS [WORKDIR]]
(make bench: bench/run.py group `fuzz`; the scratch files go under WORKDIR)

- in_process_runs_per_cpu_s: BUILD_DIR/bin/hokuyo_scan_fuzz (built with gcc:
  the corpus-replay program) over RUNS plans, half the recording unchanged,
  half random plans of 1 to 4 steps (wiretape.fuzz.random_plan, seed 0),
  each plan once; CPU seconds of the child (user + system);
- processes_runs_per_s_speed10: `wiretape fuzz` of urg04lx_md.wtape with the
  scip profile to BUILD_DIR/bin/hokuyo-scan at --speed 10, RUNS / 100 runs
  (at least 10)
  (and the clean run), wall-clock seconds.

Not yet here: the bench copy of the driver with eight planted bugs, the
bugs found and the CPU time to each, and `wiretape fuzz` against `wiretape
faults` with the same budget (issue 40).
"""

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from wiretape import fuzz

ROOT = Path(__file__).resolve().parent.parent
RECORDING = ROOT / "examples" / "hokuyo" / "recordings" / "urg04lx_md.wtape"
SCAN_ARGS = ["--mode", "md", "--scans", "3", "--cluster", "3"]


def child_cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def in_process(build: Path, runs: int, scratch: Path) -> dict:
    program = build / "bin" / "hokuyo_scan_fuzz"
    files = []
    for index in range(runs):
        path = scratch / f"plan-{index}"
        path.write_bytes(b"" if index % 2 == 0 else fuzz.random_plan(0, index, 8))
        files.append(str(path))
    before = child_cpu_seconds()
    started = time.monotonic()
    subprocess.run([str(program), *files], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    cpu = child_cpu_seconds() - before
    return {"in_process_runs": runs, "in_process_cpu_s": round(cpu, 3),
            "in_process_wall_s": round(time.monotonic() - started, 3),
            "in_process_runs_per_cpu_s": round(runs / cpu, 1)}


def as_processes(build: Path, runs: int, scratch: Path) -> dict:
    target = fuzz.Target([str(build / "bin" / "hokuyo-scan"), "--port", "{port}", *SCAN_ARGS],
                         timeout=20.0, speed=10.0)
    started = time.monotonic()
    result = fuzz.search(str(RECORDING), target, str(scratch / "findings"), profile="scip",
                         runs=runs)
    seconds = time.monotonic() - started
    return {"processes_runs": runs, "processes_s": round(seconds, 2),
            "processes_runs_per_s_speed10": round(runs / seconds, 2),
            "processes_outcomes": ", ".join(f"{outcome} {count}" for outcome, count in
                                            sorted(Counter(run.outcome for run in result.runs).items())),
            "processes_findings": len(result.findings)}


def main() -> int:
    build = Path(sys.argv[1])
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 2000
    workdir = sys.argv[3] if len(sys.argv) > 3 else None
    if workdir:
        os.makedirs(workdir, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="wiretape-fuzz-bench-", dir=workdir) as scratch:
        figures = in_process(build, runs, Path(scratch))
        figures.update(as_processes(build, max(runs // 100, 10), Path(scratch)))
    figures["cpus"] = os.cpu_count()
    figures["load_average"] = round(os.getloadavg()[0], 1)
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
