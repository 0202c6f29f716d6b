#!/usr/bin/env python3
"""The fault campaign's figures (bench/run.py, group "faults"): prints one
JSON line. Usage: faults_bench.py HOKUYO_SCAN RUNS

Cases: every fault kind at every exchange of the Hokuyo recordings, taken in
turn until RUNS. Measured, each run with its own virtual device, hokuyo-scan
at --timeout 0.5, replays at timing=none:
- campaign_s: wiretape.faults.campaign over the cases, --jobs 1;
- loop_s: the same faulty replays, one by one from a plain loop;
- clean_s: RUNS clean replays, the same way as the loop;
- campaign_jobs2_s: the campaign again with --jobs 2;
- inert_s: RUNS replays the same way with the fault machinery on but no
  fault firing (faults=drop@p:0): what injecting costs by itself.
Faulty runs take longer than clean ones by what the driver does about the
fault (its 0.5 s timeouts, a delay's wait): campaign_s / clean_s includes
that; campaign_s / loop_s and inert_s / clean_s do not.
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
    plan = []  # (session, argv, cases)
    total = 0
    for name in ("urg04lx_gd", "urg04lx_gs_wrap", "urg04lx_md", "utm30lx_me"):
        session = str(RECORDINGS / f"{name}.wtape")
        args = json.loads((RECORDINGS / f"{name}.json").read_text())["args"]
        argv = [program, "--port", "{port}", *args, "--timeout", "0.5"]
        chosen = faults.cases(session)[:max(0, runs - total)]
        total += len(chosen)
        if chosen:
            plan.append((session, argv, chosen))
    options = "timing=none"

    def timed(work):
        started = time.perf_counter()
        work()
        return time.perf_counter() - started

    def campaign(jobs):
        def work():
            with faults._quiet_stderr(True):
                for session, argv, chosen in plan:
                    kinds = [case.spec for case in chosen]
                    faults.campaign(session, argv, kinds=kinds, jobs=jobs,
                                    replay_options=options, timeout=30)
        return work

    def loop(clean, inert=False):
        def work():
            with faults._quiet_stderr(True):
                for session, argv, chosen in plan:
                    for case in chosen:
                        if inert:
                            case = faults.FaultCase("drop", "p:0")
                        faults.run_case(session, None if clean else case, argv, 30, options)
        return work

    # The campaign also runs each session once clean first: one clean run
    # per session is added to the loops for a fair count.
    extra_clean = len(plan)
    figures = {"runs": total, "sessions": extra_clean}
    figures["campaign_s"] = timed(campaign(1))
    figures["loop_s"] = timed(loop(False)) + timed(lambda: [faults.run_case(
        s, None, a, 30, options) for s, a, _ in plan])
    figures["clean_s"] = timed(loop(True)) + timed(lambda: [faults.run_case(
        s, None, a, 30, options) for s, a, _ in plan])
    figures["campaign_jobs2_s"] = timed(campaign(2))
    figures["inert_s"] = timed(loop(False, inert=True)) + timed(lambda: [faults.run_case(
        s, None, a, 30, options) for s, a, _ in plan])
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
