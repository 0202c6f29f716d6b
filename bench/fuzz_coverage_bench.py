#!/usr/bin/env python3
"""AFL++ coverage guidance against blind plans (DESIGN §27, docs/fuzzing.md
"Coverage from AFL++"): prints one JSON line. Usage: fuzz_coverage_bench.py
[SEEDS [RUNS [WORKDIR [MODES]]]] (defaults 10, 100, the temporary folder,
afl,none).

tests/python/fuzz/programs/two_step_driver.c, built with afl-clang-fast,
crashes only when the device's reply meets two conditions one after the
other. `wiretape fuzz` of its one-exchange recording at --speed 10, for
each seed 0..SEEDS-1 with RUNS runs, with coverage (--coverage afl) and
without (--coverage none): how many seeds found the crash, and the mean
run index of the first crashing run over those that did (a finding is
reached at that run; minimization comes after). Skips, saying so, without
afl-clang-fast."""

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Dict, List, Optional

import wiretape
from wiretape import fuzz

ROOT = Path(__file__).resolve().parent.parent
DRIVER = ROOT / "tests" / "python" / "fuzz" / "programs" / "two_step_driver.c"


def first_crash(result: fuzz.Search) -> Optional[int]:
    return next((run.case for run in result.runs if run.outcome == "crash"), None)


def main() -> int:
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 100
    workdir = sys.argv[3] if len(sys.argv) > 3 else None
    compiler = shutil.which("afl-clang-fast")
    if compiler is None:
        print(json.dumps({"skipped": "afl-clang-fast is not installed (Debian package afl++)"}))
        return 0
    with tempfile.TemporaryDirectory(prefix="wiretape-fuzz-coverage-", dir=workdir) as scratch:
        work = Path(scratch)
        program = work / "two_step_driver"
        subprocess.run([compiler, "-O1", "-o", str(program), str(DRIVER)], check=True,
                       capture_output=True)
        session = work / "reply.wtape"
        with wiretape.SessionWriter(str(session), port_type="serial") as writer:
            writer.write("tx", 0, b"Q\n")
            writer.write("rx", 1_000_000, b"ABC")
        figures: Dict[str, object] = {"seeds": seeds, "runs": runs}
        for mode in sys.argv[4].split(",") if len(sys.argv) > 4 else ("afl", "none"):
            found: List[int] = []
            corpus: List[int] = []
            per_seed: List[Optional[int]] = []
            for seed in range(seeds):
                target = fuzz.Target([str(program), "{port}"], timeout=10.0, speed=10.0,
                                     coverage=mode)
                result = fuzz.search(str(session), target, str(work / f"findings-{mode}-{seed}"),
                                     seed=seed, runs=runs)
                at = first_crash(result)
                per_seed.append(at)
                if at is not None:
                    found.append(at)
                corpus.append(len(result.corpus))
            figures[f"{mode}_seeds_found"] = len(found)
            figures[f"{mode}_first_crash_run_by_seed"] = per_seed
            figures[f"{mode}_mean_first_crash_run"] = (round(sum(found) / len(found), 1)
                                                       if found else None)
            if mode == "afl":
                figures["afl_mean_corpus"] = round(sum(corpus) / len(corpus), 1)
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
