"""``wiretape fuzz``: its flags (added to the parser by build_parser) and
the command (wiretape.fuzz does the work; docs/fuzzing.md)."""

from __future__ import annotations

import os
import sys

from .console import Output
from .errors import EXIT_CHECK_FAILED, EXIT_OK, CheckFailed, UsageError
from .files import require_input


def add_fuzz_parser(command, types) -> None:
    """The flags of ``fuzz``; `types`: the parser's argparse types by name
    (positive_int, non_negative_int, positive_seconds, speed), the same
    checks as every other command's flags."""
    _positive_int, _non_negative_int = types["positive_int"], types["non_negative_int"]
    _positive_seconds, _speed = types["positive_seconds"], types["speed"]
    fuzz = command(
        "fuzz", cmd_fuzz, "search for the device answers that break a driver",
        "Runs CMD against replays of SESSION whose device side a plan mutated (with "
        "--profile: on the profile's frames and fields, checksums recomputed; docs/"
        "fuzzing.md), a fresh virtual device per run whose path replaces {port} in CMD "
        "(or, with --as PATH, is what PATH opens). CMD must pass on the recording "
        "unchanged. A crash (a signal or a sanitizer report), a hang past --timeout, or a "
        "non-zero exit on an inert plan is a finding: minimized, re-run, deduplicated and "
        "written to --findings DIR as a .wtape session (listed in DIR/index.json) that "
        "`wiretape replay` plays back. Exit 1 if anything was found, 0 if the budget ran "
        "out with nothing, 2 on bad input. --replay DIR replays every finding of DIR "
        "instead (exit 1 if any still reproduces).")
    fuzz.add_argument("file", metavar="SESSION", nargs="?", help="the recording to mutate")
    fuzz.add_argument("--profile", metavar="P",
                      help="mutate the profile's frames and fields (default: rx records)")
    fuzz.add_argument("--runs", type=_positive_int, metavar="N",
                      help="at most N runs (default 100 unless --time is given)")
    fuzz.add_argument("--time", type=_positive_seconds, metavar="S",
                      help="stop starting runs after S seconds")
    fuzz.add_argument("--seed", type=_non_negative_int, default=0, metavar="N",
                      help="seed of the plans (default 0): the same seed, the same plans")
    fuzz.add_argument("--plan", metavar="FILE", action="append", default=[],
                      help="run this plan (hex) first; may be given again")
    fuzz.add_argument("--findings", metavar="DIR", default="findings",
                      help="where findings are written (default ./findings)")
    fuzz.add_argument("--replay", metavar="DIR",
                      help="replay every finding of DIR to CMD instead of searching")
    fuzz.add_argument("--timeout", type=_positive_seconds, default=10.0, metavar="S",
                      help="a run taking longer is a hang (default 10)")
    fuzz.add_argument("--jobs", type=_positive_int, default=1, metavar="N",
                      help="runs at once (default 1)")
    fuzz.add_argument("--listen", action="store_true", help="serve TCP: {port} becomes HOST:PORT")
    fuzz.add_argument("--as", dest="redirect_path", metavar="PATH",
                      help="CMD opens PATH itself: redirect it to the virtual device")
    fuzz.add_argument("--options", metavar="KEYS", default="",
                      help="replay keys for every run (e.g. match=request)")
    fuzz.add_argument("--speed", type=_speed, default=1.0, metavar="K",
                      help="run CMD on a clock K times faster, and the replays with it")
    fuzz.add_argument("--shard", metavar="K/N|auto",
                      help="run only shard K of N: the runs whose index is K-1 modulo N")
    fuzz.add_argument("--shards", type=_positive_int, metavar="N",
                      help="with --shard auto: the total where the CI engine gives none")
    fuzz.add_argument("--coverage", choices=("auto", "afl", "none"), default="auto",
                      help="coverage guidance from AFL++'s map: auto (when CMD's program was "
                           "built with afl-clang-fast / afl-cc), afl, none (docs/fuzzing.md)")
    fuzz.add_argument("--junit", metavar="FILE",
                      help="write the runs as JUnit XML to FILE (a test case per run)")


def cmd_fuzz(args, out: Output) -> int:
    from .. import fuzz
    from ..faults import Campaign, FaultInputError, Shard, session_digest, write_junit
    from ..faults.run import CleanRunFailed

    if args.command_argv is None:
        raise UsageError("no command after --: give the program to run, with {port} where "
                         "the device's path goes")
    target = fuzz.Target(args.command_argv, args.timeout, args.options, args.listen,
                         args.redirect_path, args.speed, args.coverage)
    try:
        if args.replay is not None:
            return _replay(fuzz, args.replay, target, out)
        if args.file is None:
            raise UsageError("give the SESSION to fuzz (or --replay DIR)")
        require_input(args.file)
        if args.shards is not None and args.shard is None:
            raise UsageError("--shards N goes with --shard auto")
        shard = Shard.parse(args.shard, shards=args.shards) if args.shard is not None else None
        plans = [fuzz.read_plan_file(path) for path in args.plan]
        result = fuzz.search(args.file, target, args.findings, profile=args.profile,
                             seed=args.seed, runs=args.runs, seconds=args.time, jobs=args.jobs,
                             shard=shard, plans=plans)
    except FaultInputError as error:
        raise UsageError(str(error)) from None
    except CleanRunFailed as failure:
        raise CheckFailed(str(failure)) from None
    if args.junit:
        write_junit(Campaign(args.file, args.seed, result.runs, planned=len(result.runs),
                             session_sha256=session_digest(args.file), shard=shard,
                             speed=args.speed), args.junit, tool="wiretape fuzz")
    out.print(f"fuzz: {len(result.runs)} runs in {result.seconds:.1f} s: "
              f"{len(result.findings)} finding{'s' if len(result.findings) != 1 else ''}"
              f" ({result.duplicates} duplicate, {result.flaky} flaky dropped)")
    if result.coverage:
        out.print(f"fuzz: coverage from AFL++: {result.edges} edges, a corpus of "
                  f"{len(result.corpus)} plans in "
                  f"{os.path.join(args.findings, fuzz.CORPUS_DIR)}")
    for finding in result.findings:
        out.print(f"{finding.kind} {os.path.join(args.findings, finding.session)}: "
                  f"{finding.signature}")
        for change in finding.changed:
            out.print(f"  changed: {change}")
        out.print(f"  reproduce: {finding.repro}")
    if result.findings:
        out.print(f"fuzz: findings listed in {os.path.join(args.findings, fuzz.INDEX)}")
    return EXIT_CHECK_FAILED if result.found else EXIT_OK


def _replay(fuzz, directory: str, target, out: Output) -> int:
    results = fuzz.replay_findings(directory, target)
    still = 0
    for finding, run, reproduces in results:
        still += reproduces
        verdict = f"still {run.outcome}" if reproduces else f"fixed ({run.outcome})"
        out.print(f"{finding.session}: {finding.kind}: {verdict}")
    out.print(f"fuzz --replay: {still} of {len(results)} findings still reproduce")
    sys.stdout.flush()
    return EXIT_CHECK_FAILED if still else EXIT_OK
