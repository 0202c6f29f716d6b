"""The commands that run something: record, replay and serve (bridges,
until they end or Ctrl-C), faults (a campaign), demo. A CMD after ``--`` is
run by cli/children.py."""

from __future__ import annotations

import os
import sys
from typing import Optional

from .attach import cmd_record_attached, refuse_attach_options
from .bridges import (MessageRelay, announce_clients, check_fault_places, client_side,
                      meta_pairs, replay_options_of, run_bridge)
from .channels import (channel_names, record_channels, refuse_unnamed_on_several,
                       replay_channels, stream_device)
from .children import (record_channels_with_command, record_with_command,
                       refuse_as_without_command, replay_channels_with_command,
                       replay_with_command)
from .console import Output
from .endpoints import check_record, check_replay, collect, is_single, single
from .errors import EXIT_CHECK_FAILED, EXIT_OK, CheckFailed, UsageError
from .files import require_input

# How often a campaign writing to a log (not a terminal) says how far it is.
FAULTS_PROGRESS_EVERY_S = 5.0


# --------------------------------------------------------------------------
# bridges: record, replay, serve


def cmd_record(args, out: Output) -> int:
    if args.against is not None:
        from .drift import record_against

        return record_against(args, out, _record)
    for flag, given in (("--profile", args.profile is not None), ("--update", args.update),
                        ("--json", args.json)):
        if given:
            raise UsageError(f"{flag} goes with --against OLD (drift): without it nothing "
                             "is compared")
    if args.output is None:
        raise UsageError("the following arguments are required: -o/--output "
                         "(see wiretape record --help)")
    return _record(args, out)


def _record(args, out: Output) -> int:
    from .. import bridge

    if getattr(args, "attach", None) is not None:
        return cmd_record_attached(args, out)
    refuse_attach_options(args)
    endpoints = collect(args, ("device", "pty", "listen", "udp", "peer", "redirect_path"))
    if not is_single(endpoints):
        check_record(endpoints, with_command=args.command_argv is not None)
        if args.command_argv is not None:
            return record_channels_with_command(args, endpoints, out)
        return record_channels(args, endpoints, out)
    single(args, endpoints)
    streams_to_peer = bool(endpoints) and endpoints[0].streams_to_peer
    if args.device is None and not streams_to_peer:
        raise UsageError("the following arguments are required: --device")
    if getattr(args, "command_argv", None) is not None:
        return record_with_command(args, out)
    refuse_as_without_command(args)
    pty, listen = client_side(args)
    device, udp = args.device, args.udp
    if streams_to_peer:
        device, udp = stream_device(endpoints[0])
    handle = bridge.record(device, args.output, pty=pty, listen=listen, udp=udp,
                           peer=args.peer,
                           backlog=args.backlog, duration=args.duration, meta=meta_pairs(args.meta),
                           quiet=True, pty_mode=args.pty_mode,
                           pty_group=args.pty_group, compress=args.compress)
    return run_bridge(handle, out, "record",
                      lambda: announce_clients(handle, out,
                                               f"wiretape record: recording to {args.output}", pty,
                                               udp=args.udp is not None),
                      relay=MessageRelay(handle, out, "record", args.quiet),
                      live=not args.quiet)


def cmd_replay(args, out: Output) -> int:
    from .. import bridge
    from ..session import refuse_same_file, session_files

    endpoints = collect(args, ("pty", "listen", "udp", "peer", "redirect_path"))
    if not is_single(endpoints):
        require_input(args.file)
        check_replay(endpoints, args.command_argv is not None, channel_names(args.file),
                     args.file)
        if args.command_argv is not None:
            return replay_channels_with_command(args, endpoints, out)
        return replay_channels(args, endpoints, out)
    single(args, endpoints)
    if getattr(args, "command_argv", None) is not None:
        return replay_with_command(args, out)
    refuse_as_without_command(args)
    pty, listen = client_side(args)
    if args.protocol != "raw" and listen is None:
        raise UsageError(f"--protocol {args.protocol} is spoken over TCP: give --listen HOST:PORT")
    require_input(args.file)
    refuse_unnamed_on_several(args, endpoints)
    check_fault_places(args)
    if args.output:
        refuse_same_file(session_files(args.file), [args.output])
    handle = bridge.serve_replay(args.file, pty=pty, listen=listen, udp=args.udp,
                                 peer=args.peer, backlog=args.backlog,
                                 protocol=args.protocol,
                                 replay_options=replay_options_of(args),
                                 restart=args.restart, output=args.output,
                                 quiet=True, pty_mode=args.pty_mode,
                                 pty_group=args.pty_group)
    return run_bridge(handle, out, "replay",
                      lambda: announce_clients(handle, out,
                                               f"wiretape replay: replaying {args.file}", pty,
                                               udp=args.udp is not None),
                      must_serve=True, relay=MessageRelay(handle, out, "replay", args.quiet))


def cmd_serve(args, out: Output) -> int:
    from .. import bridge

    if args.max_monitors is not None and not args.shared:
        raise UsageError("--max-monitors limits the monitors of --shared: give --shared too")
    if args.max_monitors is not None and args.max_monitors < 1:
        raise UsageError(f"--max-monitors must be at least 1, not {args.max_monitors}")
    max_monitors = (bridge.DEFAULT_MAX_MONITORS if args.max_monitors is None
                    else args.max_monitors)
    handle = bridge.serve(args.device, args.listen, output=args.output,
                          protocol=args.protocol, shared=args.shared,
                          max_monitors=max_monitors, reopen=args.reopen,
                          backlog=args.backlog, quiet=True, compress=args.compress)
    return run_bridge(handle, out, "serve",
                      lambda: announce_clients(handle, out, "wiretape serve: serving"),
                      relay=MessageRelay(handle, out, "serve", args.quiet))


# --------------------------------------------------------------------------
# faults, demo


def cmd_faults(args, out: Output) -> int:
    from .. import faults
    from ..session import refuse_same_file, session_files

    if args.command_argv is None:
        raise UsageError("no command after --: give the program to run, with {port} where "
                         "the device's path goes")
    require_input(args.file)
    reports = [path for path in (args.json, args.junit) if path]
    if reports:
        refuse_same_file(session_files(args.file), reports)
    if args.json and args.junit and os.path.abspath(args.json) == os.path.abspath(args.junit):
        raise UsageError(f"--json and --junit are both {args.json}: give two files")
    kinds = [kind for kind in (args.kinds or "").split(",") if kind.strip()] or None
    try:
        if args.shards is not None and args.shard is None:
            raise UsageError("--shards N goes with --shard auto")
        shard = (faults.Shard.parse(args.shard, shards=args.shards)
                 if args.shard is not None else None)
        result = faults.campaign(args.file, args.command_argv, kinds=kinds, budget=args.budget,
                                 seed=args.seed, timeout=args.timeout, jobs=args.jobs,
                                 replay_options=args.options, listen=args.listen,
                                 as_path=args.redirect_path, shard=shard, speed=args.speed,
                                 progress=sys.stderr,
                                 progress_every=None if sys.stderr.isatty() else
                                 FAULTS_PROGRESS_EVERY_S)
    except faults.FaultInputError as error:
        raise UsageError(str(error)) from None
    except faults.CleanRunFailed as failure:
        raise CheckFailed(str(failure)) from None
    except faults.CampaignInterrupted as interruption:
        # The runs so far, as a finished campaign gives them; main() then
        # exits 130/143.
        partial = interruption.campaign
        out.note(f"faults: interrupted after {len(partial.runs)} of {partial.planned} runs")
        _report_campaign(partial, args, out)
        raise
    _report_campaign(result, args, out)
    return EXIT_CHECK_FAILED if result.failed else EXIT_OK


def cmd_faults_merge(args, out: Output) -> int:
    from .. import faults
    from ..session import refuse_same_file

    for path in args.files:
        require_input(path)
    reports = [path for path in (args.json, args.junit) if path]
    if reports:
        refuse_same_file(args.files, reports)
    try:
        result = faults.merge(args.files, note=lambda text: out.note(f"faults merge: {text}"))
    except faults.FaultInputError as error:
        raise UsageError(str(error)) from None
    _report_campaign(result, args, out)
    return EXIT_CHECK_FAILED if result.failed else EXIT_OK


def _report_campaign(result, args, out: Output) -> None:
    from .. import faults

    table = faults.table(result)  # what it cannot show is refused before anything is written
    if args.json:
        faults.write_json(result, args.json)
    if args.junit:
        faults.write_junit(result, args.junit)
    out.print(table)
    for run in result.runs:
        if run.repro:
            out.print(f"{run.outcome} {run.kind}@{run.where}: {run.repro}")
            # What CMD said last (a sanitizer's report, a backtrace...).
            for line in run.output.splitlines()[-_OUTPUT_TAIL_LINES:]:
                out.print(f"  | {line}")


# How much of a crashed or hung run's output the campaign shows.
_OUTPUT_TAIL_LINES = 20


def cmd_demo(args, out: Output) -> int:
    from .. import demo

    return int(demo.run() or 0)
