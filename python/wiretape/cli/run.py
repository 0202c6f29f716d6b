"""The commands that run something: record, replay and serve (bridges,
until they end or Ctrl-C), faults (a campaign), demo. A CMD after ``--`` is
run by cli/children.py."""

from __future__ import annotations

import sys
from typing import Callable, Dict, List, Optional, Tuple

from .console import LiveLine, Output
from .errors import EXIT_CHECK_FAILED, EXIT_OK, CheckFailed, RuntimeFailure, UsageError
from .files import require_input

# How often a waiting command wakes up to notice Ctrl-C (seconds).
POLL_S = 0.2
# How often a campaign writing to a log (not a terminal) says how far it is.
FAULTS_PROGRESS_EVERY_S = 5.0


def meta_pairs(items: Optional[List[str]]) -> Dict[str, str]:
    metadata: Dict[str, str] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--meta {item!r}: expected KEY=VALUE")
        metadata[key.strip()] = value
    return metadata


def _format_number(value: float) -> str:
    return repr(int(value)) if float(value).is_integer() else repr(value)


# --------------------------------------------------------------------------
# bridges: record, replay, serve


class MessageRelay:
    """Prints a bridge's diagnostics (client connects, device losses...) as
    the command's own lines, `wiretape CMD: ...`: the CLI runs its bridges
    quiet and relays what messages() holds, so every line has one style.
    `quiet` (--quiet): nothing is printed."""

    def __init__(self, handle, out: Output, what: str, quiet: bool = False):
        self._handle = handle
        self._out = out
        self._what = what
        self._quiet = quiet
        self._seen: List[str] = []

    def poll(self) -> None:
        messages = self._handle.messages()
        fresh = _after(self._seen, messages)
        self._seen = messages
        if not self._quiet:
            for message in fresh:
                self._out.note(f"wiretape {self._what}: {message}")


def _after(seen: List[str], messages: List[str]) -> List[str]:
    """The messages not seen before. The bridge keeps its last 1000 only, so
    once full the list shifts: the new ones follow the longest end of `seen`
    that `messages` starts with."""
    if messages[:len(seen)] == seen:
        return messages[len(seen):]
    for start in range(1, len(seen)):
        overlap = seen[start:]
        if messages[:len(overlap)] == overlap:
            return messages[len(overlap):]
    return messages


def _elapsed(seconds: float) -> str:
    minutes, seconds = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{seconds:02d}" if hours else f"{minutes}:{seconds:02d}"


def _size(count: int) -> str:
    """A byte count for people: 512 B, 12.3 kB, 4.5 MB."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= scale:
            return f"{count / scale:.1f} {unit}"
    return f"{count} B"


def live_counts(stats, elapsed_s: float) -> str:
    """The live line of a recording on a terminal: elapsed time, bytes each
    way, records written, clients."""
    counts = dict(stats.items())
    line = (f"{_elapsed(elapsed_s)}  {_size(counts.get('bytes_to_device', 0))} to the device, "
            f"{_size(counts.get('bytes_from_device', 0))} from it, "
            f"{plural(counts.get('records_written', 0), 'record')}")
    clients = counts.get("clients_accepted", 0)
    return line + (f", {plural(clients, 'client')}" if clients else "")


def run_bridge(handle, out: Output, what: str, announce: Callable[[], None],
               must_serve: bool = False, relay: Optional[MessageRelay] = None,
               live: bool = False) -> int:
    """Announces a started bridge and waits until it ends or Ctrl-C (or
    SIGTERM, see main) stops it; prints the outcome; returns the exit code.
    `must_serve`: a replay that served its clients none of the recording's
    rx failed (exit 1), however it ended. `relay` prints the bridge's
    messages as they come; `live`: a line of live counts on a terminal."""
    import time

    relay = relay if relay is not None else MessageRelay(handle, out, what, quiet=True)
    started = time.monotonic()
    with (out.live() if live else LiveLine(None)) as line:
        try:
            announce()
            while not handle.wait(POLL_S):
                relay.poll()
                if line.shown:
                    line.update(f"wiretape {what}: " +
                                live_counts(handle.stats(), time.monotonic() - started))
        except KeyboardInterrupt:
            out.note(f"wiretape {what}: stopping")
            handle.stop()
            handle.wait()
    relay.poll()
    result = handle.result()
    summary = bridge_summary(result.stats)
    out.note(f"wiretape {what}: {result.outcome}" + (f": {summary}" if summary else ""))
    if result.ok:
        if must_serve and result.nothing_served:
            raise CheckFailed(result.nothing_served)
        return EXIT_OK
    message = result.message or result.outcome
    if result.outcome == "mismatch":
        if not message.startswith("replay mismatch"):
            message = f"replay mismatch: {message}"
        raise CheckFailed(message)
    raise RuntimeFailure(message)


def plural(count: int, one: str, many: str = "") -> str:
    """``1 record``, ``2 records``: the count and the word agreeing with it."""
    return f"{count} {one if count == 1 else (many or one + 's')}"


# How a bridge's counters read in its last line, in this order; a counter
# not named here reads as its name.
_SUMMARY = (
    ("records_written", lambda n: plural(n, "record") + " written"),
    ("bytes_to_device", lambda n: plural(n, "byte") + " to the device"),
    ("bytes_from_device", lambda n: plural(n, "byte") + " from it"),
    ("clients_accepted", lambda n: plural(n, "client")),
    ("clients_refused", lambda n: plural(n, "client") + " refused"),
    ("settings_changes", lambda n: plural(n, "settings change")),
    ("device_losses", lambda n: "the device lost " + plural(n, "time")),
    ("device_reopens", lambda n: "reopened " + plural(n, "time")),
    ("bytes_dropped", lambda n: plural(n, "byte") + " dropped"),
    ("datagrams_refused", lambda n: plural(n, "datagram") + " refused by the peer"),
    ("datagrams_from_others", lambda n: plural(n, "datagram") + " from others dropped"),
)


def bridge_summary(stats) -> str:
    """A bridge's counters for people: ``12 records written, 340 bytes to
    the device, 1 client`` (the counters at zero left out)."""
    counts = dict(stats.items())
    parts = [say(counts.pop(key)) for key, say in _SUMMARY if counts.get(key)]
    parts += [f"{key.replace('_', ' ')} {value}" for key, value in counts.items() if value]
    return ", ".join(parts)


def _client_side(args) -> Tuple[Optional[str], Optional[str]]:
    if args.pty is None and args.listen is None and args.udp is None:
        raise UsageError("give where the client connects: --pty PATH or --listen HOST:PORT "
                         "(datagrams: --udp HOST:PORT)")
    if getattr(args, "peer", None) is not None and args.udp is None:
        raise UsageError("--peer is where --udp sends datagrams: give --udp HOST:PORT too")
    if getattr(args, "backlog", None) is not None and args.listen is None:
        raise UsageError("--backlog is the queue of TCP connections: give --listen HOST:PORT")
    if args.pty is None:
        for flag, value in (("--pty-mode", args.pty_mode), ("--pty-group", args.pty_group)):
            if value is not None:
                raise UsageError(f"{flag} sets who may open the pty: give --pty PATH too")
    return args.pty, args.listen


def announce_clients(handle, out: Output, what: str, link: Optional[str] = None,
                     udp: bool = False) -> None:
    where = []
    if handle.pty_path:
        where.append(f"pty {link} -> {handle.pty_path}" if link else f"pty {handle.pty_path}")
    if handle.address:
        where.append(f"{'udp' if udp else 'tcp'} {handle.address}")
    out.note(f"{what}: {handle.device_description}; clients use "
             + (", ".join(where) or "the client side") + "; Ctrl-C ends")


def cmd_record(args, out: Output) -> int:
    from .. import bridge
    from .children import record_with_command, refuse_as_without_command

    if getattr(args, "command_argv", None) is not None:
        return record_with_command(args, out)
    refuse_as_without_command(args)
    pty, listen = _client_side(args)
    handle = bridge.record(args.device, args.output, pty=pty, listen=listen, udp=args.udp,
                           backlog=args.backlog, duration=args.duration, meta=meta_pairs(args.meta),
                           quiet=True, pty_mode=args.pty_mode,
                           pty_group=args.pty_group)
    return run_bridge(handle, out, "record",
                      lambda: announce_clients(handle, out,
                                               f"wiretape record: recording to {args.output}", pty,
                                               udp=args.udp is not None),
                      relay=MessageRelay(handle, out, "record", args.quiet),
                      live=not args.quiet)


def replay_options_of(args) -> str:
    """The replay keys given as --timing, --speed... plus --options."""
    from .._core import parse_faults, quote_option_value
    from ..options import replay_keys

    pairs = []
    for key in replay_keys():
        value = getattr(args, key, None)
        if value is None:
            continue
        if isinstance(value, float):
            value = _format_number(value)
        pairs.append(f"{key}={value}")
    # --fault is repeatable and each may hold several items: one plan,
    # checked by the replay's own parser (a bad item is an OptionError, exit 2).
    faults = [spec.text for spec in parse_faults(";".join(getattr(args, "fault", None) or []))]
    if faults:
        pairs.append("faults=" + quote_option_value(";".join(faults)))
    elif getattr(args, "seed", None) is not None:
        raise UsageError("--seed seeds the random choices of --fault: give --fault too")
    if args.options:
        pairs.append(args.options.strip().strip(","))
    return ",".join(pairs)


def cmd_replay(args, out: Output) -> int:
    from .. import bridge
    from ..session import refuse_same_file, session_files
    from .children import refuse_as_without_command, replay_with_command

    if getattr(args, "command_argv", None) is not None:
        return replay_with_command(args, out)
    refuse_as_without_command(args)
    pty, listen = _client_side(args)
    if args.protocol != "raw" and listen is None:
        raise UsageError(f"--protocol {args.protocol} is spoken over TCP: give --listen HOST:PORT")
    require_input(args.file)
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


def check_fault_places(args) -> None:
    """--fault KIND@WHERE past the session's end is a usage error."""
    from ..faults import FaultInputError, check_where

    specs = ";".join(getattr(args, "fault", None) or [])
    if not specs:
        return
    try:
        # Exchanges counted as this replay counts them (--profile, --match, --options).
        check_where(args.file, specs, options=replay_options_of(args))
    except FaultInputError as error:
        raise UsageError(str(error)) from None


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
                          backlog=args.backlog, quiet=True)
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
    if args.json:
        refuse_same_file(session_files(args.file), [args.json])
    kinds = [kind for kind in (args.kinds or "").split(",") if kind.strip()] or None
    try:
        shard = faults.Shard.parse(args.shard) if args.shard is not None else None
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
        _report_campaign(partial, args.json, out)
        raise
    _report_campaign(result, args.json, out)
    return EXIT_CHECK_FAILED if result.failed else EXIT_OK


def cmd_faults_merge(args, out: Output) -> int:
    from .. import faults
    from ..session import refuse_same_file

    for path in args.files:
        require_input(path)
    if args.json:
        refuse_same_file(args.files, [args.json])
    try:
        result = faults.merge(args.files)
    except faults.FaultInputError as error:
        raise UsageError(str(error)) from None
    _report_campaign(result, args.json, out)
    return EXIT_CHECK_FAILED if result.failed else EXIT_OK


def _report_campaign(result, json_path: Optional[str], out: Output) -> None:
    from .. import faults

    if json_path:
        faults.write_json(result, json_path)
    out.print(faults.table(result))
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
