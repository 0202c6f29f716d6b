"""``record`` and ``replay`` of several channels (DESIGN.md section 19): one
bridge per named endpoint in this process. Recording bridges share one
``wiretape.Recorder`` (one file, one clock); replaying ones each open
``type=replay,file=F,channel=NAME`` (replay ports of one file share one
clock). The outcome is the worst of the channels'."""

from __future__ import annotations

import contextlib
import os
import stat
from typing import Callable, Iterator, List, Optional, Sequence, Tuple

from .. import _core
from ..options import join_options, option_string
from ..session import open_session
from .bridges import POLL_S, MessageRelay, announce_clients, bridge_summary, meta_pairs
from .bridges import replay_options_of
from .console import Output
from .endpoints import Endpoint, check_replay
from .errors import EXIT_OK, CheckFailed, RuntimeFailure, UsageError


def channel_names(file: str) -> List[str]:
    """The names of a session's channels ("" for the one channel of a file
    without named channels). A file that is not a regular file (a FIFO, a
    flexiport log's prefix, a missing file) is left to the replay, which
    refuses it at once with the reason: reading it here would wait on a
    FIFO's writer."""
    try:
        if not stat.S_ISREG(os.stat(file).st_mode):
            return [""]
    except OSError:
        return [""]
    with open_session(file) as reader:
        return [channel.name for channel in reader.header.channel_list()]


def refuse_unnamed_on_several(args, endpoints: List[Endpoint]) -> None:
    """The single-port form of ``replay`` on a file of several channels is
    a usage error naming the channels."""
    names = channel_names(args.file)
    if len(names) <= 1:
        return
    check_replay(endpoints, args.command_argv is not None, names, args.file)
    if not endpoints:  # -- CMD alone
        raise UsageError(f"{args.file} has {len(names)} channels ({', '.join(names)}): "
                         f"name the channel of each endpoint (--pty {names[0]}=PATH)")


def stream_device(endpoint: Endpoint) -> Tuple[str, str]:
    """For ``record --udp LISTEN --peer DRIVER`` without a device: (the
    device, a UDP socket bound at LISTEN that reads whatever the device
    streams to it, the client side's address: any free port of the peer's
    family)."""
    from .. import bridge

    host, port = bridge.parse_udp_address(endpoint.udp or "", "udp")
    peer_host, _ = bridge.parse_udp_address(endpoint.peer or "", "peer", 1)
    device = option_string([("type", "udp"), ("bind_host", host), ("bind_port", port)])
    import socket  # UDP only: not on every command's start-up

    family = socket.getaddrinfo(peer_host, None, type=socket.SOCK_DGRAM)[0][0]
    client = "[::]:0" if family == socket.AF_INET6 else "0.0.0.0:0"
    return device, client


def _client_sides(endpoint: Endpoint, args) -> dict:
    sides = {"pty": endpoint.pty, "listen": endpoint.listen, "udp": endpoint.udp,
             "peer": endpoint.peer, "pty_mode": args.pty_mode, "pty_group": args.pty_group}
    if endpoint.listen is not None:
        sides["backlog"] = args.backlog
    if endpoint.pty is None:
        sides["pty_mode"] = sides["pty_group"] = None
    return sides


def _check_shared_flags(args, endpoints: Sequence[Endpoint]) -> None:
    """--backlog, --pty-mode and --pty-group apply to every channel of
    their kind: one such channel at least."""
    if args.backlog is not None and not any(e.listen is not None for e in endpoints):
        raise UsageError("--backlog is the queue of TCP connections: give --listen "
                         "NAME=HOST:PORT")
    for flag, value in (("--pty-mode", args.pty_mode), ("--pty-group", args.pty_group)):
        # With -- CMD every channel is a pty.
        if (value is not None and args.command_argv is None
                and not any(e.pty is not None for e in endpoints)):
            raise UsageError(f"{flag} sets who may open the ptys: give --pty NAME=PATH too")


@contextlib.contextmanager
def channels_recorder(args, endpoints: List[Endpoint]) -> Iterator[object]:
    """The one file every channel of ``record`` is recorded into (one
    clock), closed on leaving."""
    _check_shared_flags(args, endpoints)
    header = _core.SessionHeader.starting_now()
    header.metadata = meta_pairs(args.meta)
    recorder = _core.Recorder(args.output, header,  # type: ignore[attr-defined]
                              compress=args.compress)
    try:
        yield recorder
    finally:
        recorder.close()


def record_channels(args, endpoints: List[Endpoint], out: Output) -> int:
    """``wiretape record`` with named endpoints: every channel into one file
    (with a CMD after ``--``: children.record_channels_with_command)."""
    if any(e.redirect_path is not None for e in endpoints):
        raise UsageError("--as NAME=PATH names the device path of a command: give the "
                         "command after --")
    with channels_recorder(args, endpoints) as recorder:
        return _record_into(recorder, args, endpoints, out)


def _record_into(recorder, args, endpoints: List[Endpoint], out: Output) -> int:
    from .. import bridge

    handles: List[Tuple[Endpoint, object]] = []
    try:
        for endpoint in endpoints:
            sides = _client_sides(endpoint, args)
            if endpoint.streams_to_peer:
                device, sides["udp"] = stream_device(endpoint)
            else:
                device = endpoint.device or ""  # check_record saw it given
            handles.append((endpoint, bridge.record(
                device, args.output, recorder=recorder, channel=endpoint.name,
                duration=args.duration, quiet=True, **sides)))
    except BaseException:
        _stop_all(handles)
        raise
    return _run_channels(handles, out, "record", lambda endpoint: f"recording to {args.output}",
                         quiet=args.quiet)


def check_replay_channels(args, endpoints: List[Endpoint]) -> None:
    """The usage errors of ``replay`` with named endpoints, with or without
    a CMD after ``--``."""
    if args.output:
        raise UsageError("-o records what the clients do on one port: with several "
                         "channels it is not supported yet")
    _check_shared_flags(args, endpoints)
    for endpoint in endpoints:
        if args.protocol != "raw" and endpoint.listen is None:
            raise UsageError(f"--protocol {args.protocol} is spoken over TCP: channel "
                             f"{endpoint.name!r} has no --listen {endpoint.name}=HOST:PORT")


def channel_replay_options(args, name: str) -> str:
    """The replay keys of channel `name`: the flags' and ``channel=NAME``."""
    return join_options(replay_options_of(args), option_string([("channel", name)]))


def replay_channels(args, endpoints: List[Endpoint], out: Output) -> int:
    """``wiretape replay`` with named endpoints: one virtual device per
    channel, on one clock (with a CMD after ``--``:
    children.replay_channels_with_command)."""
    from .. import bridge

    if any(e.redirect_path is not None for e in endpoints):
        raise UsageError("--as NAME=PATH names the device path of a command: give the "
                         "command after --")
    check_replay_channels(args, endpoints)
    handles: List[Tuple[Endpoint, object]] = []
    try:
        for endpoint in endpoints:
            handles.append((endpoint, bridge.serve_replay(
                args.file, replay_options=channel_replay_options(args, endpoint.name),
                protocol=args.protocol,
                restart=args.restart, quiet=True, **_client_sides(endpoint, args))))
    except BaseException:
        _stop_all(handles)
        raise
    named = {endpoint.name for endpoint in endpoints}
    left_out = [name for name in channel_names(args.file) if name not in named]
    return _run_channels(handles, out, "replay", lambda endpoint: f"replaying {args.file}",
                         must_serve=True, quiet=args.quiet, left_out=left_out)


def _stop_all(handles) -> None:
    for _, handle in handles:
        handle.stop()
    for _, handle in handles:
        handle.wait()


def _run_channels(handles, out: Output, what: str, doing: Callable[[Endpoint], str],
                  must_serve: bool = False, quiet: bool = True,
                  left_out: Sequence[str] = ()) -> int:
    """Announces each channel's bridge, waits until every one has ended
    (a failed or mismatched one ends the others: the session is one) or
    Ctrl-C, relaying each one's messages with its name; prints each
    channel's outcome and the channels `left_out`; raises the worst."""

    relays = [MessageRelay(handle, out, f"{what}: {endpoint.name}", quiet)
              for endpoint, handle in handles]
    try:
        for endpoint, handle in handles:
            announce_clients(handle, out, f"wiretape {what}: {endpoint.name}: "
                             f"{doing(endpoint)}", endpoint.pty,
                             udp=endpoint.udp is not None)
        while True:
            running = [handle for _, handle in handles if not handle.wait(0)]
            if not running:
                break
            if any(not handle.result().ok for _, handle in handles if handle not in running):
                break
            running[0].wait(POLL_S)
            for relay in relays:
                relay.poll()
    except KeyboardInterrupt:
        out.note(f"wiretape {what}: stopping")
    _stop_all(handles)
    for relay in relays:
        relay.poll()
    return report_channels(handles, out, what, must_serve, left_out)


def report_channels(handles, out: Output, what: str, must_serve: bool,
                    left_out: Sequence[str] = ()) -> int:
    """Prints each ended channel's outcome, then a note naming each channel
    of the file `left_out` (no endpoint named it: allowed, so no failure,
    but a user who forgot one can tell); raises the worst failure (the
    command's), else returns EXIT_OK. `handles`: (endpoint, handle) pairs,
    each endpoint with its .name."""

    failures: List[Tuple[int, str]] = []
    for endpoint, handle in handles:
        result = handle.result()
        summary = bridge_summary(result.stats)
        out.note(f"wiretape {what}: {endpoint.name}: {result.outcome}"
                 + (f": {summary}" if summary else ""))
        failure = _failure_of(result, must_serve)
        if failure is not None:
            rank, message = failure
            failures.append((rank, f"channel {endpoint.name}: {message}"))
    for name in left_out:
        out.note(f"wiretape {what}: {name}: not replayed (no endpoint names channel {name}; "
                 f"give --pty {name}=PATH, --listen {name}=HOST:PORT or --udp {name}=HOST:PORT "
                 "to serve it)")
    if not failures:
        return EXIT_OK
    rank, message = max(failures, key=lambda failure: failure[0])
    if rank == _RUNTIME:
        raise RuntimeFailure(message)
    raise CheckFailed(message)


# How bad a channel's outcome is: the worst one is the command's.
_NOTHING_SERVED, _MISMATCH, _RUNTIME = 1, 2, 3


def _failure_of(result, must_serve: bool) -> Optional[Tuple[int, str]]:
    if result.ok:
        if must_serve and result.nothing_served:
            return _NOTHING_SERVED, result.nothing_served
        return None
    message = result.message or result.outcome
    if result.outcome == "mismatch":
        if not message.startswith("replay mismatch"):
            message = f"replay mismatch: {message}"
        return _MISMATCH, message
    return _RUNTIME, message
