"""What the commands that run a bridge share (record, replay, serve, alone,
on several channels or with a CMD after ``--``): the client side asked for,
the replay keys of the flags, the bridge's messages relayed, its wait and
its summary. Below run.py, channels.py and children.py, which import it;
it imports none of them."""

from __future__ import annotations

import time
from typing import Callable, Dict, List, Optional, Tuple

from .. import _core
from ..options import join_options, option_string, replay_keys
from ..session import NO_PROFILE
from .console import LiveLine, Output
from .errors import EXIT_OK, CheckFailed, RuntimeFailure, UsageError

# How often a waiting command wakes up to notice Ctrl-C (seconds).
POLL_S = 0.2


def meta_pairs(items: Optional[List[str]]) -> Dict[str, str]:
    metadata: Dict[str, str] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--meta {item!r}: expected KEY=VALUE")
        metadata[key.strip()] = value
    return metadata


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


def client_side(args) -> Tuple[Optional[str], Optional[str]]:
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


def replay_options_of(args) -> str:
    """The replay keys given as --timing, --speed... plus --options: a
    --profile as the replay keys it stands for (a name or a declared
    profile's), --fault as one plan."""
    pairs: List[Tuple[str, object]] = []
    profile_keys = ""
    for key in replay_keys():
        value = getattr(args, key, None)
        if value is None:
            continue
        if key == "profile":  # a replay has no default: "none" is no profile either
            if value != NO_PROFILE:
                profile_keys = _core.profile_from_spec(value).options
        else:
            pairs.append((key, value))
    # --fault is repeatable and each may hold several items: one plan,
    # checked by the replay's own parser (a bad item is an OptionError, exit 2).
    faults = [spec.text
              for spec in _core.parse_faults(";".join(getattr(args, "fault", None) or []))]
    if faults:
        pairs.append(("faults", ";".join(faults)))
    elif getattr(args, "seed", None) is not None:
        raise UsageError("--seed seeds the random choices of --fault: give --fault too")
    given = args.options or ""
    if getattr(args, "command_argv", None) and getattr(args, "speed", None) is not None:
        # --speed K -- CMD scales CMD's clock; the replay's speed= too where
        # the replay has something to scale (its clock, injected waits).
        without = join_options(option_string([p for p in pairs if p[0] != "speed"]),
                               profile_keys, given)
        if not _core.replay_speed_applies(without):
            return without
    return join_options(option_string(pairs), profile_keys, given)


def check_fault_places(args) -> None:
    """--fault KIND@WHERE past the session's end is a usage error."""
    specs = ";".join(getattr(args, "fault", None) or [])
    if not specs:
        return
    # Imported only for --fault: wiretape.faults is a fifth of a replay's
    # start-up (replay_pty_ready_ms, docs/benchmarks.md).
    from ..faults import FaultInputError, check_where

    try:
        # Exchanges counted as this replay counts them (--profile, --match, --options).
        check_where(args.file, specs, options=replay_options_of(args))
    except FaultInputError as error:
        raise UsageError(str(error)) from None
