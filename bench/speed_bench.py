#!/usr/bin/env python3
"""The scaled clock's figures (bench/run.py, group "speed"): prints one JSON
line. Usage: speed_bench.py HOKUYO_SCAN RUNS

The Hokuyo campaign (docs/faults.md, "The Hokuyo campaign": every fault
kind at every exchange of the Hokuyo recordings, taken in turn until RUNS;
default replay keys, causal timing, hokuyo-scan's own 2 s timeouts) run
with wiretape.faults.campaign, --jobs 1:
- speed1_s: at --speed 1 (real time);
- speed10_s: at --speed 10 (hokuyo-scan on the scaled clock, replays
  speed=10);
- same_outcomes: whether the two give the same (kind, where, outcome) runs.
"""

import json
import sys
import time
from pathlib import Path

from wiretape import faults

ROOT = Path(__file__).resolve().parent.parent
RECORDINGS = ROOT / "examples" / "hokuyo" / "recordings"


def main() -> int:
    program, runs = sys.argv[1], int(sys.argv[2])
    plan = []  # (session, argv, kinds)
    total = 0
    for name in ("urg04lx_gd", "urg04lx_gs_wrap", "urg04lx_md", "utm30lx_me"):
        session = str(RECORDINGS / f"{name}.wtape")
        args = json.loads((RECORDINGS / f"{name}.json").read_text())["args"]
        chosen = faults.cases(session)[:max(0, runs - total)]
        total += len(chosen)
        if chosen:
            plan.append((session, [program, "--port", "{port}", *args],
                         [case.spec for case in chosen]))

    def campaign(speed):
        outcomes = []
        started = time.perf_counter()
        with faults._quiet_stderr(True):
            for session, argv, kinds in plan:
                try:
                    result = faults.campaign(session, argv, kinds=kinds, timeout=30,
                                             speed=speed)
                except faults.CleanRunFailed:
                    # A loaded machine can make hokuyo-scan miss a reply by its
                    # timeout (0.2 s of slack at K=10): an outcome that differs.
                    outcomes += [("clean", session.rsplit("/", 1)[-1], "error")]
                    continue
                outcomes += [(run.kind, run.where, run.outcome) for run in result.runs]
        return time.perf_counter() - started, outcomes

    speed1_s, speed1 = campaign(1.0)
    speed10_s, speed10 = campaign(10.0)
    print(json.dumps({"runs": total, "sessions": len(plan), "speed1_s": speed1_s,
                      "speed10_s": speed10_s, "same_outcomes": speed1 == speed10,
                      "differing": [[a, b] for a, b in zip(speed1, speed10) if a != b][:5]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
