"""``record/replay ... -- CMD``: a bridge that runs a command with a
hard-coded device path redirected to its pty (wiretape.redirect, on
wiretape.children.Child) and ends when the command does."""

from __future__ import annotations

import os
import time
from typing import Callable, Dict, Optional, Sequence, Tuple

from .console import Output, describe
from .errors import CheckFailed, RuntimeFailure, UsageError, exit_code_for
from .files import require_input
from .run import (POLL_S, MessageRelay, announce_clients, meta_pairs, replay_options_of,
                  run_bridge)


def refuse_as_without_command(args) -> None:
    if args.redirect_path is not None:
        raise UsageError("--as PATH names the device path of a command: give the "
                         "command after --")


def _command_client_side(args) -> Tuple[object, Optional[str]]:
    """The pty of a bridge that runs a command: --pty PATH links it there,
    else it has no link (the command reaches it through the shim)."""
    if not args.command_argv:
        raise UsageError("no command after --: give the program to run, e.g. "
                         "-- ./driver --port /dev/ttyUSB0")
    for flag, value in (("--listen", args.listen), ("--udp", args.udp),
                        ("--backlog", getattr(args, "backlog", None))):
        if value is not None:
            raise UsageError(f"{flag} cannot be used with a command after --: the "
                             "command's device path is redirected to a pty")
    return (args.pty if args.pty is not None else True), args.pty


def record_with_command(args, out: Output) -> int:
    from .. import bridge
    from ..redirect import LineChannelPath, device_path_of

    pty, link = _command_client_side(args)
    options = bridge.device_options(args.device)
    path = args.redirect_path or device_path_of(options)
    if not path:
        raise UsageError(f"--device {args.device!r} has no device path to redirect: give "
                         "the path the command opens with --as PATH")
    _check_redirect_path(path)
    with LineChannelPath() as lines:
        handle = bridge.record(args.device, args.output, pty=pty, duration=args.duration,
                               meta=meta_pairs(args.meta), quiet=True,
                               pty_mode=args.pty_mode, pty_group=args.pty_group,
                               line_channel=lines.path)
        return _run_bridge_with_command(
            handle, out, "record", args.command_argv, path,
            lambda: announce_clients(handle, out,
                                     f"wiretape record: recording to {args.output}", link),
            must_use_path=True, line_channel=lines.path, quiet=args.quiet)


def replay_with_command(args, out: Output) -> int:
    from .. import bridge
    from ..redirect import LineChannelPath, recorded_device_path, recorded_identity
    from ..session import refuse_same_file, session_files

    from .run import check_fault_places

    pty, link = _command_client_side(args)
    require_input(args.file)
    # A --fault past the session's end is a usage error before CMD starts.
    check_fault_places(args)
    if args.output:
        refuse_same_file(session_files(args.file), [args.output])
    path = args.redirect_path or recorded_device_path(args.file)
    if not path:
        raise UsageError(f"{args.file}: the recording names no device path: give the "
                         "path the command opens with --as PATH")
    _check_redirect_path(path)
    with LineChannelPath() as lines:
        handle = bridge.serve_replay(args.file, pty=pty,
                                     replay_options=replay_options_of(args),
                                     restart=args.restart, output=args.output,
                                     quiet=True, pty_mode=args.pty_mode,
                                     pty_group=args.pty_group, line_channel=lines.path)
        return _run_bridge_with_command(
            handle, out, "replay", args.command_argv, path,
            lambda: announce_clients(handle, out, f"wiretape replay: replaying {args.file}",
                                     link),
            must_serve=True, outlive_injected_loss=True, identity=recorded_identity(args.file),
            line_channel=lines.path, speed=args.speed or 1.0, quiet=args.quiet)


def _check_redirect_path(path: str) -> None:
    if not os.path.isabs(path):
        raise UsageError(f"--as {path!r}: the device path must be absolute "
                         "(as /dev/ttyUSB0)")


def _client_has_closed(handle) -> bool:
    """True when the pty's last client event is a close, or there was none."""
    for message in reversed(handle.messages()):
        if message.startswith("client closed"):
            return True
        if message.startswith("client connected"):
            return False
    return True


def _client_connected(handle) -> bool:
    return any(message.startswith(("client connected", "client closed"))
               for message in handle.messages())


def _run_bridge_with_command(handle, out: Output, what: str, argv: Sequence[str],
                             device_path: str, announce: Callable[[], None],
                             must_serve: bool = False, must_use_path: bool = False,
                             outlive_injected_loss: bool = False,
                             identity: Optional[Dict[str, str]] = None,
                             line_channel: Optional[str] = None, speed: float = 1.0,
                             quiet: bool = False) -> int:
    """Runs CMD with `device_path` redirected to the bridge's pty; the bridge
    ends when CMD exits. The exit status is CMD's when it failed, else the
    bridge's (docs/cli.md); a bridge that ends first (a mismatch, --duration)
    ends CMD, except, with `outlive_injected_loss`, a replay ended by an
    injected device loss: CMD is left to react to it and exit by itself.
    CMD's output is captured and relayed; a sanitizer report in it fails a
    CMD that exits 0. `must_use_path`: a CMD that never opened the path
    fails (a replay fails anyway: its client never came). `line_channel`:
    the bridge's socket for the shim's serial lines. At `speed` K, CMD's
    clock runs K times faster (replay --speed K -- CMD)."""
    from ..redirect import RedirectedCommand

    relay = MessageRelay(handle, out, what, quiet)
    try:
        announce()
        out.note(f"wiretape {what}: running {' '.join(argv)} with {device_path} -> "
                 f"{handle.pty_path}")
        command = RedirectedCommand(argv, device_path, handle.pty_path, relay=True,
                                    identity=identity, line_channel=line_channel,
                                    speed=speed)
    except BaseException:
        handle.stop()
        handle.wait()
        raise
    # CMD's status counts only when CMD ended by itself: not when Ctrl-C, or
    # the bridge ending first, ended it.
    ended_by_us = False
    try:
        bridge_ended = False
        while command.poll() is None:
            relay.poll()
            if bridge_ended:
                command.child.wait(POLL_S)
            elif handle.wait(POLL_S):
                bridge_ended = True
                if outlive_injected_loss and handle.result().ended_by_fault:
                    out.note(f"wiretape {what}: an injected fault lost the device; {command.name} "
                             "goes on until it exits")
                    continue
                out.note(f"wiretape {what}: ended before {command.name}; ending it")
                ended_by_us = True
                break
        # What CMD left running in its group ends with it; its output is
        # read until then.
        command.end()
        # What CMD wrote last is read from the pty before the bridge stops:
        # the bridge sees the terminal's last close after CMD's exit.
        _wait_for_client_close(handle)
    except KeyboardInterrupt:
        ended_by_us = True
        out.note(f"wiretape {what}: stopping")
        command.end()
    finally:
        handle.stop()
        handle.wait()
    status = command.exit_status()
    # The shim notes each use of the path; a bind mount is seen as the pty's
    # client arriving.
    used = command.used_device_path() or _client_connected(handle)
    sanitizer = command.sanitizer_report()
    command.close()
    if not used:
        out.note(f"wiretape {what}: {command.name} never opened {device_path} (the shim reaches "
                 "dynamically linked programs; a static one is reached as root, through a "
                 "bind mount, only where the path exists)")
    try:
        verdict = run_bridge(handle, out, what, lambda: None, must_serve=must_serve,
                             relay=relay)
        if not used and must_use_path and not ended_by_us:
            raise CheckFailed(f"{command.name} never opened {device_path}: nothing was "
                              "recorded from it")
    except (CheckFailed, RuntimeFailure) as error:
        if ended_by_us or status == 0:
            raise
        out.error(f"wiretape {what}", describe(error))
        verdict = exit_code_for(error)
    if sanitizer is not None and status == 0 and not ended_by_us:
        raise CheckFailed(f"{command.name} exited 0 but printed a sanitizer report: {sanitizer}")
    if ended_by_us or status == 0:
        return verdict
    out.note(f"wiretape {what}: {command.name} exited with status {status}")
    return status


# How long a bridge has to see the terminal's last close after CMD's exit.
_CLIENT_CLOSE_DEADLINE_S = 5.0


def _wait_for_client_close(handle) -> None:
    import time

    end = time.monotonic() + _CLIENT_CLOSE_DEADLINE_S
    while not _client_has_closed(handle) and time.monotonic() < end:
        if handle.wait(0.01):  # the bridge ended: no close will come
            return
