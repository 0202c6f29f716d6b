"""``record/replay ... -- CMD``: a bridge that runs a command with a
hard-coded device path redirected to its pty (wiretape.redirect, on
wiretape.children.Child) and ends when the command does."""

from __future__ import annotations

import os
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

from .bridges import (POLL_S, MessageRelay, announce_clients, check_fault_places, meta_pairs,
                      replay_options_of, run_bridge)
from .channels import (channel_names, channel_replay_options, channels_recorder,
                       check_replay_channels, refuse_unnamed_on_several, report_channels)
from .console import Output, describe
from .endpoints import Endpoint
from .errors import CheckFailed, RuntimeFailure, UsageError, exit_code_for
from .files import require_input


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
                               line_channel=lines.path, compress=args.compress)
        return _run_bridge_with_command(
            handle, out, "record", args.command_argv, path,
            lambda: announce_clients(handle, out,
                                     f"wiretape record: recording to {args.output}", link),
            must_use_path=True, line_channel=lines.path, quiet=args.quiet)


def replay_with_command(args, out: Output) -> int:
    from .. import bridge
    from ..redirect import LineChannelPath, recorded_device_path, recorded_identity
    from ..session import refuse_same_file, session_files

    pty, link = _command_client_side(args)
    require_input(args.file)
    # A file of several channels: each needs its NAME= when given; -- CMD
    # alone redirects each channel's recorded path.
    given = {dest: getattr(args, dest) for dest in ("pty", "redirect_path")
             if getattr(args, dest) is not None}
    if given:
        refuse_unnamed_on_several(args, [Endpoint("", given)])
    elif len(channel_names(args.file)) > 1:
        return replay_channels_with_command(args, [], out)
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


class _CommandChannel:
    """One channel of a command's session: its bridge and the path CMD opens
    for it. (Not a dataclass: see session.ProfileChoice.)"""

    def __init__(self, name: str, path: str, link: Optional[str], device: Optional[str]):
        self.name = name
        self.path = path
        self.link = link
        self.device = device  # the endpoint's --device NAME=OPTS (recording)
        self.line_channel: Any = None  # redirect.LineChannelPath
        self.identity: Optional[Dict[str, str]] = None
        self.handle: Any = None  # bridge.BridgeHandle


def _command_channels(endpoints, path_of: Callable[[Any], Optional[str]],
                      no_path: Callable[[str], str]) -> List[_CommandChannel]:
    """The channels of `endpoints` (pty client sides only), each with the
    path CMD opens for it (--as NAME=PATH, else `path_of`), each path once."""
    from ..redirect import MAX_REDIRECTED_DEVICES, LineChannelPath

    if not endpoints:
        raise UsageError("no channel to redirect: give --as NAME=PATH")
    if len(endpoints) > MAX_REDIRECTED_DEVICES:
        raise UsageError(f"{len(endpoints)} channels with a command after --: at most "
                         f"{MAX_REDIRECTED_DEVICES} device paths are redirected")
    channels: List[_CommandChannel] = []
    seen: Dict[str, str] = {}
    for endpoint in endpoints:
        for dest in ("listen", "udp"):
            if endpoint.get(dest) is not None:
                raise UsageError(f"{endpoint.flag(dest)} cannot be used with a command "
                                 "after --: the command's device paths are redirected to ptys")
        path = endpoint.redirect_path or path_of(endpoint)
        if not path:
            raise UsageError(no_path(endpoint.name))
        _check_redirect_path(path)
        if path in seen:
            raise UsageError(f"--as {endpoint.name}={path}: channel {seen[path]!r} is "
                             "redirected from the same path: give each channel its own "
                             f"--as {endpoint.name}=PATH")
        seen[path] = endpoint.name
        channels.append(_CommandChannel(endpoint.name, path, endpoint.pty, endpoint.device))
    for channel in channels:
        channel.line_channel = LineChannelPath()
    return channels


def _close_line_channels(channels: List[_CommandChannel]) -> None:
    for channel in channels:
        if channel.line_channel is not None:
            channel.line_channel.close()


def record_channels_with_command(args, endpoints, out: Output) -> int:
    """``record --device NAME=OPTS ... -- CMD``: one bridge per channel into
    one file, CMD with each channel's path redirected to its pty."""
    with channels_recorder(args, endpoints) as recorder:
        return _record_channels_into(recorder, args, endpoints, out)


def _record_channels_into(recorder, args, endpoints, out: Output) -> int:
    from .. import bridge
    from ..redirect import device_path_of

    _require_command(args)
    channels = _command_channels(
        endpoints, lambda endpoint: device_path_of(endpoint.device or ""),
        lambda name: (f"--device {name}=... has no device path to redirect: give the "
                      f"path the command opens with --as {name}=PATH"))
    try:
        for channel in channels:
            channel.handle = bridge.record(
                channel.device or "", args.output, recorder=recorder, channel=channel.name,
                pty=channel.link if channel.link is not None else True,
                duration=args.duration, quiet=True, pty_mode=args.pty_mode,
                pty_group=args.pty_group, line_channel=channel.line_channel.path)
        return _run_bridges_with_command(
            channels, out, "record", args.command_argv, f"recording to {args.output}",
            must_use_path=True, quiet=args.quiet)
    finally:
        _stop_channels(channels)
        _close_line_channels(channels)


def replay_channels_with_command(args, endpoints, out: Output) -> int:
    """``replay FILE [--as NAME=PATH ...] -- CMD`` of a file of several
    channels: one replay of each of the file's channels (channel=NAME, on
    one clock), CMD with each channel's path (its --as, else the recorded
    one) redirected to its pty."""
    from .. import bridge
    from ..redirect import recorded_device_path, recorded_identity

    check_replay_channels(args, endpoints)
    _require_command(args)
    require_input(args.file)
    check_fault_places(args)
    given = {endpoint.name: endpoint for endpoint in endpoints}
    every = [given.get(name) or Endpoint(name) for name in channel_names(args.file)]
    channels = _command_channels(
        every, lambda endpoint: recorded_device_path(args.file, endpoint.name),
        lambda name: (f"{args.file}: channel {name!r} names no device path: give the "
                      f"path the command opens with --as {name}=PATH"))
    try:
        for channel in channels:
            channel.identity = recorded_identity(args.file, channel.name)
            channel.handle = bridge.serve_replay(
                args.file, pty=channel.link if channel.link is not None else True,
                replay_options=channel_replay_options(args, channel.name), restart=args.restart, quiet=True,
                pty_mode=args.pty_mode, pty_group=args.pty_group,
                line_channel=channel.line_channel.path)
        return _run_bridges_with_command(
            channels, out, "replay", args.command_argv, f"replaying {args.file}",
            must_serve=True, outlive_injected_loss=True, speed=args.speed or 1.0,
            quiet=args.quiet)
    finally:
        _stop_channels(channels)
        _close_line_channels(channels)


def _stop_channels(channels: List[_CommandChannel]) -> None:
    started = [channel.handle for channel in channels if channel.handle is not None]
    for handle in started:
        handle.stop()
    for handle in started:
        handle.wait()


def _run_bridges_with_command(channels: List[_CommandChannel], out: Output, what: str,
                              argv: Sequence[str], doing: str, must_serve: bool = False,
                              must_use_path: bool = False, outlive_injected_loss: bool = False,
                              speed: float = 1.0, quiet: bool = False) -> int:
    """_run_bridge_with_command for several channels: CMD runs with every
    channel's path redirected to its bridge's pty; the bridges end when CMD
    exits, and CMD is ended when a bridge fails (a mismatch) or every one
    has ended. The outcome is the worst channel's; each path CMD never
    opened is named."""
    from ..redirect import RedirectedCommand, RedirectedDevice

    relays = [MessageRelay(channel.handle, out, f"{what}: {channel.name}", quiet)
              for channel in channels]
    try:
        for channel in channels:
            announce_clients(channel.handle, out, f"wiretape {what}: {channel.name}: {doing}",
                             channel.link)
            out.note(f"wiretape {what}: {channel.name}: running {' '.join(argv)} with "
                     f"{channel.path} -> {channel.handle.pty_path}")
        first, rest = channels[0], channels[1:]
        command = RedirectedCommand(
            argv, first.path, first.handle.pty_path, relay=True, identity=first.identity,
            line_channel=first.line_channel.path, speed=speed,
            more_devices=[RedirectedDevice(channel.path, channel.handle.pty_path,
                                           channel.identity, channel.line_channel.path)
                          for channel in rest])
    except BaseException:
        _stop_channels(channels)
        raise
    ended_by_us = False
    ends = _BridgeEnds([channel.handle for channel in channels])
    try:
        bridges_ended = False
        while command.poll() is None:
            for relay in relays:
                relay.poll()
            if bridges_ended:
                command.child.wait(POLL_S)
                continue
            running = [channel for channel in channels if not channel.handle.wait(0)]
            ended = [channel for channel in channels if channel not in running]
            failed = [channel for channel in ended if not channel.handle.result().ok]
            if running and not failed:
                ends.wait_with(command.child, POLL_S)
                continue
            bridges_ended = True
            if outlive_injected_loss and any(channel.handle.result().ended_by_fault
                                             for channel in ended):
                out.note(f"wiretape {what}: an injected fault lost a device; {command.name} "
                         "goes on until it exits")
                continue
            which = (failed or ended)[0].name
            out.note(f"wiretape {what}: {which}: ended before {command.name}; ending it")
            ended_by_us = True
            break
        command.end()
        for channel in channels:
            _wait_for_client_close(channel.handle)
    except KeyboardInterrupt:
        ended_by_us = True
        out.note(f"wiretape {what}: stopping")
        command.end()
    finally:
        _stop_channels(channels)
        ends.close()
    for relay in relays:
        relay.poll()
    status = command.exit_status()
    unused = [channel for number, channel in enumerate(channels)
              if not (command.used_device_path(number) or _client_connected(channel.handle))]
    sanitizer = command.sanitizer_report()
    command.close()
    for channel in unused:
        _note_never_opened(out, what, command.name, channel.path)
    never_opened = None
    if unused and must_use_path and not ended_by_us:
        never_opened = (f"{command.name} never opened {unused[0].path}: nothing was "
                        f"recorded from channel {unused[0].name}")
    return _outcome_with_command(
        out, what, command.name, status, sanitizer, ended_by_us, never_opened,
        lambda: report_channels([(channel, channel.handle) for channel in channels], out,
                                what, must_serve))


class _BridgeEnds:
    """The ends of some bridges as a pipe that becomes readable, to wait for
    them and CMD's exit together (Child.wait's `wake_fd`) instead of in
    steps: a thread per bridge waits for its end (a bridge has no
    descriptor of its own). close() once the bridges are stopped: it joins
    the threads."""

    def __init__(self, handles):
        import threading  # only a command's bridge needs it, not every start-up

        self._read_fd, self._write_fd = os.pipe()
        os.set_blocking(self._read_fd, False)
        self._threads = [threading.Thread(target=self._wait_for, args=(handle,),
                                          name="wiretape-bridge-end", daemon=True)
                         for handle in handles]
        for thread in self._threads:
            thread.start()

    def wait_with(self, child, timeout: float) -> None:
        """Waits up to `timeout` seconds for `child`'s exit or a bridge's
        end; each end wakes one wait."""
        child.wait(timeout, self._read_fd)
        try:
            os.read(self._read_fd, 1)
        except BlockingIOError:
            pass

    def _wait_for(self, handle) -> None:
        handle.wait()
        os.write(self._write_fd, b"x")

    def close(self) -> None:
        for thread in self._threads:
            thread.join()
        os.close(self._read_fd)
        os.close(self._write_fd)


def _require_command(args) -> None:
    if not args.command_argv:
        raise UsageError("no command after --: give the program to run, e.g. "
                         "-- ./driver --port /dev/ttyUSB0")


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
    ends = _BridgeEnds([handle])
    try:
        bridge_ended = False
        while command.poll() is None:
            relay.poll()
            if bridge_ended:
                command.child.wait(POLL_S)
                continue
            ends.wait_with(command.child, POLL_S)
            if handle.wait(0):
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
        ends.close()
    status = command.exit_status()
    # The shim notes each use of the path; a bind mount is seen as the pty's
    # client arriving.
    used = command.used_device_path() or _client_connected(handle)
    sanitizer = command.sanitizer_report()
    command.close()
    if not used:
        _note_never_opened(out, what, command.name, device_path)
    never_opened = None
    if not used and must_use_path and not ended_by_us:
        never_opened = f"{command.name} never opened {device_path}: nothing was recorded from it"
    return _outcome_with_command(
        out, what, command.name, status, sanitizer, ended_by_us, never_opened,
        lambda: run_bridge(handle, out, what, lambda: None, must_serve=must_serve, relay=relay))


def _note_never_opened(out: Output, what: str, command_name: str, path: str) -> None:
    out.note(f"wiretape {what}: {command_name} never opened {path} (the shim reaches "
             "dynamically linked programs; a static one is reached as root, through a "
             "bind mount, only where the path exists)")


def _outcome_with_command(out: Output, what: str, command_name: str, status: int,
                          sanitizer: Optional[str], ended_by_us: bool,
                          never_opened: Optional[str], bridge_verdict: Callable[[], int]) -> int:
    """The exit status of ``record/replay ... -- CMD``: the bridges' verdict
    (`bridge_verdict()`) when CMD exited 0 or wiretape ended it, else CMD's
    status (after saying what the bridges found); `never_opened`, when CMD
    never opened a path it had to, is a failure of its own."""
    try:
        verdict = bridge_verdict()
        if never_opened is not None:
            raise CheckFailed(never_opened)
    except (CheckFailed, RuntimeFailure) as error:
        if ended_by_us or status == 0:
            raise
        out.error(f"wiretape {what}", describe(error))
        verdict = exit_code_for(error)
    if sanitizer is not None and status == 0 and not ended_by_us:
        raise CheckFailed(f"{command_name} exited 0 but printed a sanitizer report: {sanitizer}")
    if ended_by_us or status == 0:
        return verdict
    out.note(f"wiretape {what}: {command_name} exited with status {status}")
    return status


# How long a bridge has to see the terminal's last close after CMD's exit.
_CLIENT_CLOSE_DEADLINE_S = 5.0


def _wait_for_client_close(handle) -> None:

    end = time.monotonic() + _CLIENT_CLOSE_DEADLINE_S
    while not _client_has_closed(handle) and time.monotonic() < end:
        if handle.wait(0.01):  # the bridge ended: no close will come
            return
