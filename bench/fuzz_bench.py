#!/usr/bin/env python3
"""The fuzzing figures (DESIGN §27, docs/fuzzing.md "Figures"): prints one
JSON line. Usage: fuzz_bench.py BUILD_DIR [RUNS [SECONDS [WORKDIR]]]
(make bench: bench/run.py group `fuzz`; the scratch files go under WORKDIR)

BUILD_DIR needs WIRETAPE_BENCH (bench/planted/: planted-scan and
planted_scan_fuzz, the Hokuyo driver's decoding with eight planted bugs,
over bench/planted/urg04lx_md15.wtape: 20 device answers).

- in_process_runs_per_cpu_s: BUILD_DIR/bin/hokuyo_scan_fuzz (the example's
  target, gcc: corpus replay; 8 frames) over RUNS plans, half the recording
  unchanged, half random plans of 1 to 4 steps (wiretape.fuzz.random_plan,
  seed 0); CPU seconds of the child (user + system);
- in_process_20_runs_per_cpu_s: the same RUNS plans (over 20 answers)
  through hokuyo_scan20_fuzz, the example driver's decoding over
  bench/planted/urg04lx_md15.wtape (20 answers): the figure of a
  20-exchange session, DESIGN §27;
- in_process_20_planted_runs_per_cpu_s: the same plans through
  planted_scan_fuzz (the same recording, the planted driver); a plan that
  hits a planted bug aborts the program, which is started again after it
  (the restarts are counted in: in_process_20_planted_restarts);
- processes_runs_per_s_speed10: `wiretape fuzz` of urg04lx_md.wtape with the
  scip profile to hokuyo-scan at --speed 10, RUNS / 100 runs (at least 10)
  and the clean run, wall-clock seconds;
- planted bugs: `wiretape fuzz` (--seed 0, --speed 10, --timeout 5, one
  job) to planted-scan for SECONDS, against `wiretape faults`' fixed
  campaign (every fault kind at every exchange, seed 0, the same runner and
  settings), cut at the CPU seconds the search used (user + system, this
  process and its children). A bug counts when a run hit it (its abort
  message, SIGFPE for cluster-division, a hang for missing-terminator); the
  CPU to it is what was spent from the start to that run's end.
"""

import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Dict, Optional

from wiretape import fuzz
from wiretape.faults.cases import all_cases
from wiretape.faults.run import _quiet_stderr, run_case

ROOT = Path(__file__).resolve().parent.parent
RECORDING = ROOT / "examples" / "hokuyo" / "recordings" / "urg04lx_md.wtape"
SCAN_ARGS = ["--mode", "md", "--scans", "3", "--cluster", "3"]
PLANTED = ROOT / "bench" / "planted"
PLANTED_RECORDING = PLANTED / "urg04lx_md15.wtape"
PLANTED_SCANS = 15
SPEED = 10.0
TIMEOUT = 5.0  # on CMD's clock: 0.5 s at --speed 10

_PLANTED_NAMES = re.search(r"planted_bugs\[\] = \{(.*?)\};",
                           (PLANTED / "planted_scip.hpp").read_text(), re.S).group(1)
BUGS = re.findall(r'"([a-z-]+)"', _PLANTED_NAMES)
_PLANTED_MESSAGE = re.compile(r"planted bug ([a-z-]+):")


def cpu_seconds() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def child_cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def plan_files(runs: int, scratch: Path, units: int) -> list:
    files = []
    for index in range(runs):
        path = scratch / f"plan-{units}-{index}"
        path.write_bytes(b"" if index % 2 == 0 else fuzz.random_plan(0, index, units))
        files.append(str(path))
    return files


def corpus_replay(program: Path, files: list) -> dict:
    """Runs every file through a corpus-replay program, started again after
    each file that crashes it; CPU seconds of the children."""
    before = child_cpu_seconds()
    started = time.monotonic()
    crashed = 0
    at = 0
    while at < len(files):
        proc = subprocess.run([str(program), *files[at:]], stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
        if proc.returncode == 0:
            break
        ran = re.findall(r"^running (\S+) ", proc.stderr, re.M)
        if not ran:
            raise RuntimeError(f"{program}: failed before any input: {proc.stderr[-300:]}")
        crashed += 1
        at = files.index(ran[-1], at) + 1
    return {"cpu_s": child_cpu_seconds() - before, "wall_s": time.monotonic() - started,
            "crashed": crashed}


def in_process(build: Path, runs: int, scratch: Path) -> dict:
    figures = {}
    example = corpus_replay(build / "bin" / "hokuyo_scan_fuzz", plan_files(runs, scratch, 8))
    figures.update({"in_process_runs": runs, "in_process_cpu_s": round(example["cpu_s"], 3),
                    "in_process_wall_s": round(example["wall_s"], 3),
                    "in_process_runs_per_cpu_s": round(runs / example["cpu_s"], 1)})
    plans_20 = plan_files(runs, scratch, 20)
    clean = corpus_replay(build / "bin" / "hokuyo_scan20_fuzz", plans_20)
    if clean["crashed"]:
        raise RuntimeError(f"hokuyo_scan20_fuzz crashed on {clean['crashed']} plans: "
                           "the example driver has a bug a plan reaches (a finding)")
    figures.update({"in_process_20_cpu_s": round(clean["cpu_s"], 3),
                    "in_process_20_runs_per_cpu_s": round(runs / clean["cpu_s"], 1)})
    planted = corpus_replay(build / "bin" / "planted_scan_fuzz", plans_20)
    figures.update({"in_process_20_planted_cpu_s": round(planted["cpu_s"], 3),
                    "in_process_20_planted_restarts": planted["crashed"],
                    "in_process_20_planted_runs_per_cpu_s": round(runs / planted["cpu_s"], 1)})
    return figures


def as_processes(build: Path, runs: int, scratch: Path) -> dict:
    target = fuzz.Target([str(build / "bin" / "hokuyo-scan"), "--port", "{port}", *SCAN_ARGS],
                         timeout=20.0, speed=SPEED)
    started = time.monotonic()
    result = fuzz.search(str(RECORDING), target, str(scratch / "findings"), profile="scip",
                         runs=runs)
    seconds = time.monotonic() - started
    return {"processes_runs": runs, "processes_s": round(seconds, 2),
            "processes_runs_per_s_speed10": round(runs / seconds, 2),
            "processes_outcomes": ", ".join(f"{outcome} {count}" for outcome, count in
                                            sorted(Counter(run.outcome for run in result.runs).items())),
            "processes_findings": len(result.findings)}


def planted_bug(outcome: str, exit_status: Optional[int], text: str) -> Optional[str]:
    """Which planted bug a run (or a finding's signature) shows, if any."""
    named = _PLANTED_MESSAGE.search(text)
    if named and named.group(1) in BUGS:
        return named.group(1)
    if outcome == "hang" or text == "hang":
        return "missing-terminator"
    if exit_status == -8 or text.startswith("signal SIGFPE"):
        return "cluster-division"
    return None


def planted_argv(build: Path) -> list:
    return [str(build / "bin" / "planted-scan"), "--port", "{port}", "--scans", str(PLANTED_SCANS)]


def fuzz_planted(build: Path, seconds: float, scratch: Path) -> dict:
    target = fuzz.Target(planted_argv(build), timeout=TIMEOUT, speed=SPEED)
    found: Dict[str, float] = {}
    start = cpu_seconds()

    def progress(line: str) -> None:
        signature = line.split("(", 1)[1].rsplit(")", 1)[0] if "(" in line else line
        bug = planted_bug("", None, signature)
        if bug and bug not in found:
            found[bug] = cpu_seconds() - start

    result = fuzz.search(str(PLANTED_RECORDING), target, str(scratch / "planted-findings"),
                         profile="scip", seed=0, seconds=seconds, progress=progress)
    budget = cpu_seconds() - start
    kept = {planted_bug(f.kind, None, f.signature) for f in result.findings} - {None}
    return {"budget_cpu_s": budget, "runs": len(result.runs), "found": found,
            "findings": len(result.findings), "findings_bugs": len(kept),
            "findings_other": sum(1 for f in result.findings
                                  if planted_bug(f.kind, None, f.signature) is None)}


def faults_planted(build: Path, budget_cpu_s: float) -> dict:
    """The fixed campaign's cases in order, one run each as `wiretape
    faults --jobs 1` makes them, until the cases or the CPU budget end."""
    session = str(PLANTED_RECORDING)
    argv = planted_argv(build)
    found: Dict[str, float] = {}
    start = cpu_seconds()
    runs = 0
    with _quiet_stderr(True):
        clean = run_case(session, None, argv, TIMEOUT, speed=SPEED)
        if clean.outcome != "ok":
            raise RuntimeError(f"planted-scan fails on its recording: {clean.output[-300:]}")
        for case in all_cases(session, None, None, 0, None, None, ""):
            if cpu_seconds() - start >= budget_cpu_s:
                break
            run = run_case(session, case, argv, TIMEOUT, speed=SPEED)
            runs += 1
            bug = planted_bug(run.outcome, run.exit, run.output or "") \
                if run.outcome in ("crash", "hang") else None
            if bug and bug not in found:
                found[bug] = cpu_seconds() - start
    return {"cpu_s": cpu_seconds() - start, "runs": runs, "found": found,
            "cases": len(all_cases(session, None, None, 0, None, None, ""))}


def planted(build: Path, seconds: float, scratch: Path) -> dict:
    searched = fuzz_planted(build, seconds, scratch)
    campaign = faults_planted(build, searched["budget_cpu_s"])
    figures = {
        "planted_bugs": len(BUGS),
        "planted_budget_cpu_s": round(searched["budget_cpu_s"], 2),
        "fuzz_planted_runs": searched["runs"],
        "fuzz_planted_bugs_found": len(searched["found"]),
        "fuzz_planted_findings": searched["findings"],
        "fuzz_planted_findings_bugs": searched["findings_bugs"],
        "fuzz_planted_findings_other": searched["findings_other"],
        "faults_planted_runs": campaign["runs"],
        "faults_planted_cases": campaign["cases"],
        "faults_planted_cpu_s": round(campaign["cpu_s"], 2),
        "faults_planted_bugs_found": len(campaign["found"]),
    }
    figures["fuzz_vs_faults_planted_found_ratio"] = (
        round(len(searched["found"]) / len(campaign["found"]), 2) if campaign["found"] else None)
    for name, found in (("fuzz", searched["found"]), ("faults", campaign["found"])):
        for bug in BUGS:
            if bug in found:
                figures[f"{name}_cpu_s_to_bug_{bug.replace('-', '_')}"] = round(found[bug], 2)
    return figures


def main() -> int:
    build = Path(sys.argv[1])
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 2000
    seconds = float(sys.argv[3]) if len(sys.argv) > 3 else 120.0
    workdir = sys.argv[4] if len(sys.argv) > 4 else None
    for program in ("planted-scan", "planted_scan_fuzz"):
        if not (build / "bin" / program).exists():
            print(f"fuzz_bench.py: {build / 'bin' / program} is missing: configure "
                  f"{build} with -DWIRETAPE_BENCH=ON (make bench does)", file=sys.stderr)
            return 2
    if workdir:
        os.makedirs(workdir, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="wiretape-fuzz-bench-", dir=workdir) as scratch:
        figures = in_process(build, runs, Path(scratch))
        figures.update(as_processes(build, max(runs // 100, 10), Path(scratch)))
        figures.update(planted(build, seconds, Path(scratch)))
    figures["cpus"] = os.cpu_count()
    figures["load_average"] = round(os.getloadavg()[0], 1)
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
