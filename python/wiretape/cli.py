"""The wiretape command line: record, replay, serve, show, stats, verify,
convert, diff, ports, demo.

Exit codes (one place: :func:`exit_code_for`):
  0  ok (Ctrl-C included)
  1  the checked thing failed: replay mismatch, damaged session file, diff
     found a difference, unused data under unused=error
  2  usage error: bad arguments or option strings
  3  runtime error: device or file I/O
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from . import __version__, _core

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_USAGE = 2
EXIT_RUNTIME = 3

# How often a waiting command wakes up to notice Ctrl-C (seconds).
_POLL_S = 0.2


class UsageError(Exception):
    """Arguments that make no sense together (exit 2)."""


class CheckFailed(Exception):
    """The checked thing failed (exit 1); the message says what."""


class RuntimeFailure(Exception):
    """A device or file could not be used (exit 3)."""


def exit_code_for(error: BaseException) -> int:
    """The exit code of an exception that ended a command: the one mapping of
    exception classes to exit codes."""
    import wiretape

    from .redirect import CommandNotStarted

    if isinstance(error, KeyboardInterrupt):
        return EXIT_OK
    if isinstance(error, CommandNotStarted):
        return error.exit_code  # 127 or 126, as a shell says
    if isinstance(error, (CheckFailed, wiretape.ReplayMismatch, wiretape.SessionError)):
        return EXIT_CHECK_FAILED
    if isinstance(error, (UsageError, wiretape.OptionError)):
        return EXIT_USAGE
    if isinstance(error, (RuntimeFailure, OSError, NotImplementedError, RuntimeError)):
        return EXIT_RUNTIME  # PortError and PortClosed are OSErrors
    if isinstance(error, (ValueError, TypeError)):
        return EXIT_USAGE  # a bad value given on the command line
    return EXIT_RUNTIME


def _describe(error: BaseException) -> str:
    """One line naming the problem."""
    if isinstance(error, NotImplementedError):
        text = str(error) or "this command"
        return f"{text} (not available in this build)"
    if isinstance(error, OSError) and not str(error).strip():
        return type(error).__name__
    if isinstance(error, OSError) and error.filename and error.strerror and \
            type(error).__module__ == "builtins":
        return f"{error.filename}: {error.strerror}"
    text = str(error).strip()
    if not text:
        return type(error).__name__
    if isinstance(error, (UsageError, CheckFailed, RuntimeFailure)):
        return text
    import wiretape

    if isinstance(error, (wiretape.ReplayMismatch,)):
        return "replay mismatch: " + text
    return text


# --------------------------------------------------------------------------
# output


class _Output:
    """stdout and stderr, with colour (rich) when they are terminals."""

    def __init__(self) -> None:
        self._console = None
        self._error_console = None
        try:
            import rich.console

            if sys.stdout.isatty():
                self._console = rich.console.Console(highlight=False)
            if sys.stderr.isatty():
                self._error_console = rich.console.Console(stderr=True, highlight=False)
        except ImportError:  # colour is a nicety
            pass

    def print(self, text: str = "", style: Optional[str] = None) -> None:
        if self._console is not None and style:
            self._console.print(text, style=style, markup=False, soft_wrap=True)
        else:
            print(text, flush=True)

    def note(self, text: str) -> None:
        """A progress or status message (stderr)."""
        if self._error_console is not None:
            self._error_console.print(text, style="cyan", markup=False, soft_wrap=True)
        else:
            print(text, file=sys.stderr, flush=True)

    def error(self, prog: str, text: str) -> None:
        line = f"{prog}: error: {text}"
        if self._error_console is not None:
            self._error_console.print(line, style="bold red", markup=False, soft_wrap=True)
        else:
            print(line, file=sys.stderr, flush=True)

    def table(self, columns: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
        if self._console is not None:
            import rich.table

            table = rich.table.Table(*columns, box=None, header_style="bold")
            for row in rows:
                table.add_row(*row)
            self._console.print(table)
            return
        widths = [max([len(c)] + [len(r[i]) for r in rows]) for i, c in enumerate(columns)]
        for row in [list(columns)] + [list(r) for r in rows]:
            print("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip())


# --------------------------------------------------------------------------
# argument helpers


def _meta_pairs(items: Optional[List[str]]) -> Dict[str, str]:
    metadata: Dict[str, str] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--meta {item!r}: expected KEY=VALUE")
        metadata[key.strip()] = value
    return metadata


def _require_input(path: str) -> None:
    """A session file given to read must be there (exit 3 otherwise); a
    flexiport ``name.log`` stands for ``name.logr`` + ``name.logw``."""
    if os.path.exists(path):
        if os.path.isdir(path):
            raise RuntimeFailure(f"{path}: is a directory, not a session file")
        return
    if path.endswith(".log") and (os.path.exists(path + "r") or os.path.exists(path + "w")):
        return
    raise RuntimeFailure(f"{path}: no such file")


def _number_checker(what: str, minimum: float, inclusive: bool, unit: str = ""):
    """An argparse type: a float of `what` above `minimum` (or at it, when
    `inclusive`), with a message that names the rule broken."""
    suffix = f" {unit}" if unit else ""

    def check(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if not (value >= minimum if inclusive else value > minimum):
            bound = f"{minimum:g}{suffix} or more" if inclusive else f"more than {minimum:g}{suffix}"
            raise argparse.ArgumentTypeError(f"{text!r}: must be {bound}")
        return value

    return check


_positive_seconds = _number_checker("a number of seconds", 0, inclusive=False, unit="seconds")
_positive_float = _number_checker("a number", 0, inclusive=False)
_non_negative_float = _number_checker("a number", 0, inclusive=True)


def _non_negative_int(text: str) -> int:
    """An argparse type: a whole number, 0 or more (a seed)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 0 or value > 2**63 - 1:
        raise argparse.ArgumentTypeError(f"{text!r}: must be from 0 to 2**63-1")
    return value


def _session_output(text: str) -> str:
    """An argparse type: the session file a bridge records into (-o). An
    empty name would silently record nothing."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "the file name is empty: give the session file to write (.wtape)")
    return text


def _pty_mode(text: str) -> int:
    """An argparse type: the permission bits of a pty, in octal (0660, 666,
    0o666)."""
    digits = text.strip()
    if digits[:2] in ("0o", "0O"):
        digits = digits[2:]
    try:
        mode = int(digits, 8)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not an octal mode (such as 0660 or 0666)") from None
    if not 0 <= mode <= 0o777:
        raise argparse.ArgumentTypeError(
            f"{text!r} has bits beyond the permission bits 0777")
    return mode


def _pty_group(text: str) -> str:
    """An argparse type: a group by name or number that exists (a number
    is taken as it stands, as chown takes it)."""
    import grp

    name = text.strip()
    if name.isdigit():
        return name
    try:
        grp.getgrnam(name)
    except KeyError:
        raise argparse.ArgumentTypeError(f"there is no group {text!r}") from None
    return name


def _udp_address(what: str, minimum_port: int):
    """An argparse type: a HOST:PORT for UDP, checked as the bridge will (a
    bad one is a usage error naming the flag)."""
    def check(text: str) -> str:
        from .bridge import parse_udp_address

        try:
            parse_udp_address(text, what, minimum_port)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return text
    return check


def _format_number(value: float) -> str:
    return repr(int(value)) if float(value).is_integer() else repr(value)


# --------------------------------------------------------------------------
# bridges: record, replay, serve


def _run_bridge(handle, out: _Output, what: str, announce: Callable[[], None],
                must_serve: bool = False) -> int:
    """Announces a started bridge and waits until it ends or Ctrl-C (or
    SIGTERM, see main) stops it; prints the outcome; returns the exit code.
    `must_serve`: a replay that served its clients none of the recording's
    rx failed (exit 1), however it ended."""
    try:
        announce()
        while not handle.wait(_POLL_S):
            pass
    except KeyboardInterrupt:
        out.note(f"{what}: stopping")
        handle.stop()
        handle.wait()
    result = handle.result()
    figures = ", ".join(f"{key}={value}" for key, value in result.stats.items() if value)
    out.note(f"{what}: {result.outcome}" + (f" ({figures})" if figures else ""))
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


def _client_side(args) -> Tuple[Optional[str], Optional[str]]:
    if args.pty is None and args.listen is None and args.udp is None:
        raise UsageError("give where the client connects: --pty PATH or --listen HOST:PORT "
                         "(datagrams: --udp HOST:PORT)")
    if getattr(args, "peer", None) is not None and args.udp is None:
        raise UsageError("--peer is where --udp sends datagrams: give --udp HOST:PORT too")
    if args.pty is None:
        for flag, value in (("--pty-mode", args.pty_mode), ("--pty-group", args.pty_group)):
            if value is not None:
                raise UsageError(f"{flag} sets who may open the pty: give --pty PATH too")
    return args.pty, args.listen


def _announce(handle, out: _Output, what: str, link: Optional[str] = None,
              udp: bool = False) -> None:
    where = []
    if handle.pty_path:
        where.append(f"pty {link} -> {handle.pty_path}" if link else f"pty {handle.pty_path}")
    if handle.address:
        where.append(f"{'udp' if udp else 'tcp'} {handle.address}")
    out.note(f"{what}: {handle.device_description}; clients use "
             + (", ".join(where) or "the client side") + "; Ctrl-C ends")


def cmd_record(args, out: _Output) -> int:
    from . import bridge

    if getattr(args, "command_argv", None) is not None:
        return _record_with_command(args, out)
    _refuse_as_without_command(args)
    pty, listen = _client_side(args)
    handle = bridge.record(args.device, args.output, pty=pty, listen=listen, udp=args.udp,
                           duration=args.duration, meta=_meta_pairs(args.meta),
                           quiet=args.quiet, pty_mode=args.pty_mode,
                           pty_group=args.pty_group)
    return _run_bridge(handle, out, "record",
                       lambda: _announce(handle, out, f"recording to {args.output}", pty,
                                         udp=args.udp is not None))


_REPLAY_KEYS = ("timing", "speed", "check", "match", "tolerance", "unmatched",
                "repeat", "unused", "at_end", "profile", "gap")


def replay_options_of(args) -> str:
    """The replay keys given as --timing, --speed... plus --options."""
    pairs = []
    for key in _REPLAY_KEYS:
        value = getattr(args, key, None)
        if value is None:
            continue
        if isinstance(value, float):
            value = _format_number(value)
        pairs.append(f"{key}={value}")
    faults = [item.strip() for spec in (getattr(args, "fault", None) or [])
              for item in spec.split(";") if item.strip()]
    if faults:
        from ._core import quote_option_value

        pairs.append("faults=" + quote_option_value(";".join(faults)))
    elif getattr(args, "seed", None) is not None:
        raise UsageError("--seed seeds the random choices of --fault: give --fault too")
    if faults and getattr(args, "seed", None) is not None:
        pairs.append(f"seed={args.seed}")
    if args.options:
        pairs.append(args.options.strip().strip(","))
    return ",".join(pairs)


def cmd_replay(args, out: _Output) -> int:
    from . import bridge
    from .tools._files import refuse_same_file, session_files

    if getattr(args, "command_argv", None) is not None:
        return _replay_with_command(args, out)
    _refuse_as_without_command(args)
    pty, listen = _client_side(args)
    _require_input(args.file)
    _check_fault_places(args)
    if args.output:
        refuse_same_file(session_files(args.file), [args.output])
    handle = bridge.serve_replay(args.file, pty=pty, listen=listen, udp=args.udp,
                                 peer=args.peer, replay_options=replay_options_of(args),
                                 restart=args.restart, output=args.output,
                                 quiet=args.quiet, pty_mode=args.pty_mode,
                                 pty_group=args.pty_group)
    return _run_bridge(handle, out, "replay",
                       lambda: _announce(handle, out, f"replaying {args.file}", pty,
                                         udp=args.udp is not None),
                       must_serve=True)


def _positive_int(text: str) -> int:
    value = _non_negative_int(text)
    if value == 0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be 1 or more")
    return value


def _check_fault_places(args) -> None:
    """--fault KIND@WHERE past the session's end is a usage error."""
    from .faults import FaultInputError, check_where

    specs = ";".join(getattr(args, "fault", None) or [])
    if not specs:
        return
    try:
        check_where(args.file, specs)
    except FaultInputError as error:
        raise UsageError(str(error)) from None


def cmd_faults(args, out: _Output) -> int:
    from . import faults

    if args.command_argv is None:
        raise UsageError("no command after --: give the program to run, with {port} where "
                         "the device's path goes")
    _require_input(args.file)
    kinds = [kind for kind in (args.kinds or "").split(",") if kind.strip()] or None
    try:
        result = faults.campaign(args.file, args.command_argv, kinds=kinds, budget=args.budget,
                                 seed=args.seed, timeout=args.timeout, jobs=args.jobs,
                                 replay_options=args.options, listen=args.listen,
                                 as_path=args.redirect_path,
                                 progress=sys.stderr if sys.stderr.isatty() else None)
    except faults.FaultInputError as error:
        raise UsageError(str(error)) from None
    except faults.CleanRunFailed as failure:
        raise CheckFailed(str(failure)) from None
    out.print(faults.table(result))
    for run in result.runs:
        if run.repro:
            out.print(f"{run.outcome} {run.kind}@{run.where}: {run.repro}")
    if args.json:
        faults.write_json(result, args.json)
    return EXIT_CHECK_FAILED if result.failed else EXIT_OK


# --------------------------------------------------------------------------
# a command with a hard-coded device path: record/replay ... -- CMD


def _refuse_as_without_command(args) -> None:
    if args.redirect_path is not None:
        raise UsageError("--as PATH names the device path of a command: give the "
                         "command after --")


def _command_client_side(args) -> Tuple[object, Optional[str]]:
    """The pty of a bridge that runs a command: --pty PATH links it there,
    else it has no link (the command reaches it through the shim)."""
    if not args.command_argv:
        raise UsageError("no command after --: give the program to run, e.g. "
                         "-- ./driver --port /dev/ttyUSB0")
    for flag, value in (("--listen", args.listen), ("--udp", args.udp)):
        if value is not None:
            raise UsageError(f"{flag} cannot be used with a command after --: the "
                             "command's device path is redirected to a pty")
    return (args.pty if args.pty is not None else True), args.pty


def _record_with_command(args, out: _Output) -> int:
    from . import bridge
    from .redirect import device_path_of

    pty, link = _command_client_side(args)
    options = bridge.device_options(args.device)
    path = args.redirect_path or device_path_of(options)
    if not path:
        raise UsageError(f"--device {args.device!r} has no device path to redirect: give "
                         "the path the command opens with --as PATH")
    _check_redirect_path(path)
    handle = bridge.record(args.device, args.output, pty=pty, duration=args.duration,
                           meta=_meta_pairs(args.meta), quiet=args.quiet,
                           pty_mode=args.pty_mode, pty_group=args.pty_group)
    return _run_bridge_with_command(
        handle, out, "record", args.command_argv, path,
        lambda: _announce(handle, out, f"recording to {args.output}", link))


def _replay_with_command(args, out: _Output) -> int:
    from . import bridge
    from .redirect import recorded_device_path
    from .tools._files import refuse_same_file, session_files

    pty, link = _command_client_side(args)
    _require_input(args.file)
    if args.output:
        refuse_same_file(session_files(args.file), [args.output])
    path = args.redirect_path or recorded_device_path(args.file)
    if not path:
        raise UsageError(f"{args.file}: the recording names no device path: give the "
                         "path the command opens with --as PATH")
    _check_redirect_path(path)
    handle = bridge.serve_replay(args.file, pty=pty, replay_options=replay_options_of(args),
                                 restart=args.restart, output=args.output,
                                 quiet=args.quiet, pty_mode=args.pty_mode,
                                 pty_group=args.pty_group)
    return _run_bridge_with_command(
        handle, out, "replay", args.command_argv, path,
        lambda: _announce(handle, out, f"replaying {args.file}", link), must_serve=True)


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


def _run_bridge_with_command(handle, out: _Output, what: str, argv: Sequence[str],
                             device_path: str, announce: Callable[[], None],
                             must_serve: bool = False) -> int:
    """Runs CMD with `device_path` redirected to the bridge's pty; the bridge
    ends when CMD exits. The exit status is CMD's when it failed, else the
    bridge's (docs/cli.md); a bridge that ends first (a mismatch, --duration)
    ends CMD."""
    from .redirect import RedirectedCommand

    try:
        announce()
        out.note(f"{what}: running {' '.join(argv)} with {device_path} -> {handle.pty_path}")
        command = RedirectedCommand(argv, device_path, handle.pty_path)
    except BaseException:
        handle.stop()
        handle.wait()
        raise
    # CMD's status counts only when CMD ended by itself: not when Ctrl-C, or
    # the bridge ending first, ended it.
    ended_by_us = False
    try:
        while command.poll() is None:
            if handle.wait(_POLL_S):
                out.note(f"{what}: ended before {command.name}; ending it")
                ended_by_us = True
                command.end()
                break
        # What CMD wrote last is read from the pty before the bridge stops:
        # the bridge sees the terminal's last close after CMD's exit.
        _wait_for_client_close(handle)
    except KeyboardInterrupt:
        ended_by_us = True
        out.note(f"{what}: stopping")
        command.end()
    finally:
        handle.stop()
        handle.wait()
    status = command.exit_status()
    # The shim notes each use of the path; a bind mount is seen as the pty's
    # client arriving.
    used = command.used_device_path() or _client_connected(handle)
    command.close()
    if not used:
        out.note(f"{what}: {command.name} never opened {device_path} (the shim reaches "
                 "dynamically linked programs; a static one is reached as root, through a "
                 "bind mount, only where the path exists)")
    try:
        verdict = _run_bridge(handle, out, what, lambda: None, must_serve=must_serve)
    except (CheckFailed, RuntimeFailure) as error:
        if ended_by_us or status == 0:
            raise
        out.error(f"wiretape {what}", _describe(error))
        verdict = exit_code_for(error)
    if ended_by_us or status == 0:
        return verdict
    out.note(f"{what}: {command.name} exited with status {status}")
    return status


# How long a bridge has to see the terminal's last close after CMD's exit.
_CLIENT_CLOSE_DEADLINE_S = 5.0


def _wait_for_client_close(handle) -> None:
    import time

    end = time.monotonic() + _CLIENT_CLOSE_DEADLINE_S
    while not _client_has_closed(handle) and time.monotonic() < end:
        if handle.wait(0.01):  # the bridge ended: no close will come
            return


def cmd_serve(args, out: _Output) -> int:
    from . import bridge

    if args.max_monitors is not None and not args.shared:
        raise UsageError("--max-monitors limits the monitors of --shared: give --shared too")
    if args.max_monitors is not None and args.max_monitors < 1:
        raise UsageError(f"--max-monitors must be at least 1, not {args.max_monitors}")
    max_monitors = (bridge.DEFAULT_MAX_MONITORS if args.max_monitors is None
                    else args.max_monitors)
    handle = bridge.serve(args.device, args.listen, output=args.output,
                          protocol=args.protocol, shared=args.shared,
                          max_monitors=max_monitors, reopen=args.reopen, quiet=args.quiet)
    return _run_bridge(handle, out, "serve", lambda: _announce(handle, out, "serving"))


# --------------------------------------------------------------------------
# files: show, stats, verify, convert, diff


def cmd_show(args, out: _Output) -> int:
    from .tools.show import show_reporting_damage

    _require_input(args.file)
    if args.textconv or args.no_start or args.no_times:
        return _show_textconv(args)
    profile = args.profile or args.decode
    if args.profile and args.decode and args.profile != args.decode:
        raise UsageError(f"--profile {args.profile} and --decode {args.decode} disagree: give one")
    if profile and args.format != "text":
        option = "--profile" if args.profile else "--decode"
        raise UsageError(f"{option} works with --format text only")
    try:
        _, damage = show_reporting_damage(args.file, fmt=args.format, profile=profile)
    except BrokenPipeError:  # `wiretape show big.wtape | head`
        _silence_stdout()
        return EXIT_OK
    # show reports damage itself and shows everything before it.
    return EXIT_OK if damage is None else EXIT_CHECK_FAILED


def _show_textconv(args) -> int:
    """show --textconv: the text git's diff.textconv runs (tools/textconv)."""
    from .tools.textconv import textconv

    if args.format == "jsonl" or args.profile or args.decode:
        raise UsageError("--textconv, --no-start and --no-times work with --format text or "
                         "hex, without --profile")
    try:
        textconv(args.file, fmt=args.format, start=not args.no_start, times=not args.no_times)
    except BrokenPipeError:
        _silence_stdout()
    # A damaged file is a line of the text: git shows the diff all the same.
    return EXIT_OK


def _silence_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def _print_stats(stats, out: _Output) -> None:
    rows = stats.text_rows()
    width = max([len("wiretape_version")] + [len(name) for name, _ in rows])
    for name, value in rows:
        out.print(f"{name:<{width}}  {value}", style="bold red" if name == "damaged" else None)


def cmd_stats(args, out: _Output) -> int:
    from .tools.stats import stats as session_stats

    _require_input(args.file)
    result = session_stats(args.file)
    if args.json:
        print(json.dumps(result.to_json(), indent=2, sort_keys=True, default=str))
    else:
        _print_stats(result, out)
    return EXIT_CHECK_FAILED if result.damaged else EXIT_OK


def cmd_verify(args, out: _Output) -> int:
    from .tools.verify import verify

    _require_input(args.file)
    result = verify(args.file)
    if args.json:
        print(json.dumps(result.to_json(), indent=2, sort_keys=True, default=str))
    elif result.ok:
        out.print(f"{args.file}: ok, {result.records} records", style="green")
    else:
        out.print(f"{args.file}: DAMAGED at byte {result.offset} after "
                  f"{result.records} good records: {result.message}", style="bold red")
    return EXIT_OK if result.ok else EXIT_CHECK_FAILED


def cmd_convert(args, out: _Output) -> int:
    from .tools.convert import convert

    _require_input(args.input)
    progress = sys.stderr.isatty() and not args.quiet
    result = convert(args.input, args.output, from_format=args.from_format,
                     to_format=args.to_format, progress=progress,
                     flexiport_format=args.flexiport_format,
                     stream=args.stream, device_addr=args.device_addr, test=args.test)
    if not args.quiet:
        out.note(f"converted {result.records} records: {args.input} "
                 f"({result.from_format}) -> {args.output} ({result.to_format})")
    return EXIT_OK


def cmd_diff(args, out: _Output) -> int:
    from .tools.diff import diff

    _require_input(args.a)
    _require_input(args.b)
    result = diff(args.a, args.b, profile=args.profile)
    for line in result.report().splitlines():
        style = None
        if line == "sessions are identical":
            style = "green"
        elif line == "sessions differ" or "damaged" in line:
            style = "bold red"
        out.print(line, style=style)
    return EXIT_OK if result.identical and not result.damaged else EXIT_CHECK_FAILED


def cmd_edit(args, out: _Output) -> int:
    from .tools.edit import edit, parse_cut, parse_redaction

    _require_input(args.input)
    cut = parse_cut(args.cut) if args.cut is not None else None
    redactions = [parse_redaction(spec) for spec in args.redact]
    result = edit(args.input, args.output, cut=cut, redact=redactions, drop_meta=args.drop_meta)
    if not args.quiet:
        done = "; ".join(result.edits)
        matches = (f", {result.matches} matches redacted in {result.redacted_records} records"
                   if redactions else "")
        out.note(f"edited {args.input} -> {args.output}: {result.records} records{matches} ({done})")
    return EXIT_OK


# --------------------------------------------------------------------------
# ports, demo


def _by_id_links(directory: str = "/dev/serial/by-id") -> Dict[str, List[str]]:
    """Real device path -> the stable /dev/serial/by-id links to it."""
    links: Dict[str, List[str]] = {}
    try:
        names = sorted(os.listdir(directory))
    except OSError:  # no USB serial devices, or not Linux
        return links
    for name in names:
        path = os.path.join(directory, name)
        links.setdefault(os.path.realpath(path), []).append(path)
    return links


def serial_ports() -> List[dict]:
    """The serial devices the OS knows: device, by-id paths, USB ids, text."""
    from serial.tools import list_ports

    by_id = _by_id_links()
    ports = []
    for info in sorted(list_ports.comports(), key=lambda p: p.device):
        vid_pid = None
        if info.vid is not None and info.pid is not None:
            vid_pid = f"{info.vid:04x}:{info.pid:04x}"
        description = info.description if info.description not in (None, "n/a") else ""
        ports.append({
            "device": info.device,
            "by_id": by_id.get(os.path.realpath(info.device), []),
            "vid_pid": vid_pid,
            "description": description,
            "manufacturer": info.manufacturer,
            "product": info.product,
            "serial_number": info.serial_number,
            "location": info.location,
            "hwid": info.hwid,
        })
    return ports


def cmd_ports(args, out: _Output) -> int:
    ports = serial_ports()
    if args.json:
        print(json.dumps(ports, indent=2))
        return EXIT_OK
    if not ports:
        out.note("no serial ports found")
        return EXIT_OK
    rows = [(p["device"], "\n".join(p["by_id"]) or "-", p["vid_pid"] or "-",
             p["description"] or "-") for p in ports]
    out.table(("device", "by-id", "usb", "description"), rows)
    return EXIT_OK


def cmd_demo(args, out: _Output) -> int:
    from . import demo

    return int(demo.run() or 0)


# --------------------------------------------------------------------------
# the parser


_DESCRIPTION = "Record and replay the wire-level session between a driver and its device."

_EPILOG = """exit codes: 0 ok (Ctrl-C included); 1 the checked thing failed (replay
mismatch, damaged file, diff found a difference, unused data under
unused=error); 2 usage error; 3 runtime error (device or file I/O).
--device takes a port option string (type=tcp,host=10.0.0.5,port=10940) or a
bare path, which means type=serial,device=PATH."""


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of exiting, so main() returns codes."""

    def error(self, message):  # noqa: D401 - argparse's hook
        raise _ArgumentError(self, message)

    def exit(self, status=0, message=None):
        if message:
            print(message, file=sys.stderr if status else sys.stdout, end="")
        raise _ParserExit(status)


class _ArgumentError(Exception):
    def __init__(self, parser, message):
        super().__init__(message)
        self.parser = parser


class _ParserExit(Exception):
    def __init__(self, status):
        super().__init__(status)
        self.status = status


def _add_client_side(parser, verb: str) -> None:
    side = parser.add_mutually_exclusive_group()
    side.add_argument("--pty", metavar="PATH",
                      help=f"{verb} on a new pseudo-terminal, linked at PATH (the "
                           "client opens PATH as if it were the device)")
    side.add_argument("--listen", metavar="HOST:PORT",
                      help=f"{verb} on TCP: the client connects to HOST:PORT "
                           "(PORT alone means 127.0.0.1:PORT; 0 picks a free port)")
    side.add_argument("--udp", metavar="HOST:PORT", type=_udp_address("udp", 0),
                      help=f"{verb} over UDP: the client sends datagrams to HOST:PORT "
                           "and gets the device's back, one datagram per record "
                           "(0 picks a free port)")
    parser.add_argument("--pty-mode", dest="pty_mode", type=_pty_mode, metavar="MODE",
                        help="with --pty: the terminal's permission bits, octal "
                             "(default 0660, as a serial device)")
    parser.add_argument("--pty-group", dest="pty_group", type=_pty_group, metavar="NAME|GID",
                        help="with --pty: the terminal's group (default dialout where it "
                             "exists, else this process's group)")


def _add_redirect(parser, default: str) -> None:
    parser.add_argument("--as", dest="redirect_path", metavar="PATH",
                        help="with -- CMD: the device path CMD opens, redirected to the "
                             f"pty ({default})")


_COMMANDS_WITH_CMD = ("record", "replay", "faults")


def split_command(argv: Sequence[str]) -> Tuple[List[str], Optional[List[str]]]:
    """wiretape's own arguments and the CMD after ``--`` of ``record`` and
    ``replay`` (None when there is no ``--``; [] when nothing follows it)."""
    arguments = list(argv)
    if arguments and arguments[0] in _COMMANDS_WITH_CMD and "--" in arguments:
        separator = arguments.index("--")
        return arguments[:separator], arguments[separator + 1:]
    return arguments, None


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="wiretape", description=_DESCRIPTION, epilog=_EPILOG,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"wiretape {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    def command(name: str, handler: Callable, help_text: str, description: str = ""):
        sub = commands.add_parser(name, help=help_text, description=description or help_text,
                                  epilog=_EPILOG,
                                  formatter_class=argparse.RawDescriptionHelpFormatter)
        sub.set_defaults(handler=handler)
        return sub

    record = command(
        "record", cmd_record, "record a driver's session with a device (transparent proxy)",
        "A transparent proxy: the driver under test opens the --pty PATH (or connects "
        "to --listen HOST:PORT, or sends datagrams to --udp HOST:PORT) as if it were "
        "the device; every byte both ways is "
        "forwarded to the --device and recorded. With -- CMD ARG... the proxy runs "
        "CMD with the device's path (or --as PATH) redirected to its pty and ends "
        "when CMD does. Ctrl-C ends cleanly. On a pty the "
        "terminal settings the driver sets (baud, parity, stop bits) are applied to "
        "the device and recorded; a pty has no modem lines.")
    record.add_argument("--device", required=True, metavar="OPTS",
                        help="the real device: a port option string or a serial device path")
    _add_client_side(record, "the driver connects")
    record.add_argument("-o", "--output", required=True, metavar="FILE", type=_session_output,
                        help="the session file to write (.wtape)")
    record.add_argument("--duration", type=_positive_seconds, metavar="S",
                        help="stop after S seconds (default: until Ctrl-C)")
    record.add_argument("--meta", action="append", metavar="KEY=VALUE",
                        help="free metadata for the session header (repeatable)")
    record.add_argument("-q", "--quiet", action="store_true", help="no client/device messages")
    _add_redirect(record, "default: the --device's path")

    replay = command(
        "replay", cmd_replay, "replay a recording as a virtual device (pty, TCP or UDP)",
        "The recording becomes a virtual device any program can open: a "
        "pseudo-terminal (--pty PATH), a TCP server (--listen HOST:PORT) or a UDP "
        "socket (--udp HOST:PORT; one datagram per recorded record). A "
        "client that closes and reopens continues the session (--restart starts it "
        "over). With --as PATH -- CMD ARG... it runs CMD with PATH redirected to its "
        "pty and ends when CMD does (exit: CMD's status when it failed, else the "
        "replay's). The replay keys are those of type=replay (docs/options.md). Exit 1 on a "
        "mismatch, and when the recording has rx but no client was served any of it "
        "(no client connected, nothing matched, or the greeting was lost).")
    replay.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    _add_client_side(replay, "the client connects")
    replay.add_argument("--timing", choices=("none", "session", "causal"),
                        help="when recorded replies are released (default causal)")
    replay.add_argument("--speed", type=_positive_float, help="rate multiplier (default 1.0)")
    replay.add_argument("--check", choices=("off", "data", "timing"),
                        help="what is compared against the recording (default data)")
    replay.add_argument("--match", choices=("sequence", "request"),
                        help="sequence: one stream; request: answer matching requests "
                             "in any order (default sequence)")
    replay.add_argument("--tolerance", type=_non_negative_float, metavar="MS",
                        help="timing tolerance in milliseconds for --check timing (default 100)")
    replay.add_argument("--unmatched", choices=("error", "silent"),
                        help="bytes matching no request: error or ignore (default error)")
    replay.add_argument("--repeat", choices=("none", "last", "cycle"),
                        help="used-up exchanges under --match request (default none)")
    replay.add_argument("--unused", choices=("ignore", "warn", "error"),
                        help="recorded data never consumed at close (default warn)")
    replay.add_argument("--at-end", dest="at_end", choices=("silent", "closed"),
                        help="after the last record (default silent)")
    replay.add_argument("--profile", choices=tuple(_core.profile_names()), metavar="NAME",
                        help="a protocol profile: requests are frames matched by key, "
                             "responses fixed: " + ", ".join(_core.profile_names()))
    replay.add_argument("--gap", type=_non_negative_float, metavar="MS",
                        help="--match request: ms of quiet a complete request waits for a "
                             "longer one recorded earlier (default 50)")
    replay.add_argument("--options", metavar="KEYS",
                        help="further replay keys as an option string (k=v,k=v)")
    replay.add_argument("--peer", metavar="HOST:PORT", type=_udp_address("peer", 1),
                        help="with --udp: send the device's datagrams to HOST:PORT from "
                             "the start (default: to the last sender, once one has sent)")
    replay.add_argument("--restart", action="store_true",
                        help="each new client starts the session over")
    replay.add_argument("-o", "--output", metavar="FILE", type=_session_output,
                        help="also record what the client does to FILE")
    replay.add_argument("-q", "--quiet", action="store_true", help="no client messages")
    replay.add_argument("--fault", action="append", metavar="KIND@WHERE",
                        help="inject a fault (repeatable, or ';'-joined): drop, corrupt, "
                             "garbage, truncate, duplicate, delay:MS, stall:MS, trickle, "
                             "silence, disconnect, reconnect:MS at exchange:N, rx:N, "
                             "t:SECONDS, every:K or p:P (docs/faults.md)")
    replay.add_argument("--seed", type=_non_negative_int, metavar="S",
                        help="seed of the faults' random choices (default 0)")
    _add_redirect(replay, "default: the recorded device's path")

    faults = command(
        "faults", cmd_faults, "a fault campaign: run a driver against faulty replays",
        "Runs CMD once against a clean replay of SESSION (it must pass), then once "
        "per fault (kind x exchange, sampled by --seed within --budget), each against "
        "a fresh virtual device whose path replaces {port} in CMD (or, with --as PATH, "
        "is what PATH opens). Each run is ok (exit 0), error (failed cleanly, in "
        "time), crash (a signal or a sanitizer report) or hang (past --timeout). "
        "Prints a table per kind and exchange and a one-line reproduction of every "
        "crash and hang; exit 1 if there was any (docs/faults.md).")
    faults.add_argument("file", metavar="SESSION", help="the session to replay")
    faults.add_argument("--kinds", metavar="KINDS",
                        help="comma-separated fault kinds (default all: drop, corrupt, "
                             "garbage, truncate, duplicate, delay, stall, trickle, silence, "
                             "disconnect, reconnect); KIND@WHERE runs one place only")
    faults.add_argument("--budget", type=_positive_int, metavar="N",
                        help="at most N fault runs, sampled by --seed (default: all)")
    faults.add_argument("--seed", type=_non_negative_int, default=0, metavar="S",
                        help="seed of the sampling and of the faults (default 0)")
    faults.add_argument("--timeout", type=_positive_seconds, default=10.0, metavar="S",
                        help="a run taking longer is a hang (default 10)")
    faults.add_argument("--jobs", type=_positive_int, default=1, metavar="N",
                        help="runs at once (default 1)")
    faults.add_argument("--json", metavar="FILE", help="write the runs as JSON to FILE")
    faults.add_argument("--listen", action="store_true",
                        help="serve TCP: {port} becomes HOST:PORT")
    faults.add_argument("--as", dest="redirect_path", metavar="PATH",
                        help="CMD opens PATH itself: redirect it to the virtual device")
    faults.add_argument("--options", metavar="KEYS", default="",
                        help="replay keys for every run (e.g. timing=none,match=request)")

    serve = command(
        "serve", cmd_serve, "share a local device with remote programs over TCP",
        "Shares a local device over TCP (raw bytes, or RFC 2217 so that remote "
        "programs can set the line), recording on the server side with -o.")
    serve.add_argument("--device", required=True, metavar="OPTS",
                       help="the device: a port option string or a serial device path")
    serve.add_argument("--listen", required=True, metavar="HOST:PORT",
                       help="where clients connect (PORT alone means 127.0.0.1:PORT)")
    serve.add_argument("-o", "--output", metavar="FILE", type=_session_output,
                       help="record the session to FILE")
    serve.add_argument("--protocol", choices=("raw", "rfc2217"), default="raw",
                       help="raw bytes or RFC 2217 (default raw)")
    serve.add_argument("--shared", action="store_true",
                       help="later clients may connect to monitor (read-only)")
    serve.add_argument("--max-monitors", dest="max_monitors", type=int, metavar="N",
                       help="with --shared: at most N monitors at once, more are refused "
                            "(default 16)")
    serve.add_argument("--reopen", action="store_true",
                       help="wait for a device that went away to come back")
    serve.add_argument("-q", "--quiet", action="store_true", help="no client messages")

    ports = command("ports", cmd_ports, "list serial devices (by-id paths, USB ids)")
    ports.add_argument("--json", action="store_true", help="print JSON")

    show = command("show", cmd_show, "print a session's timeline")
    show.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    show.add_argument("--format", choices=("text", "hex", "jsonl"), default="text",
                      help="text (default), hex dump, or one JSON object per record")
    show.add_argument("--profile", choices=tuple(_core.profile_names()), metavar="NAME",
                      help="cut the bytes into a protocol's frames and name them: "
                           + ", ".join(_core.profile_names()))
    show.add_argument("--decode", choices=("scip",),
                      help="the older name of --profile scip")
    show.add_argument("--textconv", action="store_true",
                      help="for git's diff.textconv: no file name, exit 0 when damaged")
    show.add_argument("--no-start", dest="no_start", action="store_true",
                      help="with --textconv (implies it): leave out the start time and host")
    show.add_argument("--no-times", dest="no_times", action="store_true",
                      help="with --textconv (implies it): leave out each record's time")

    stats = command("stats", cmd_stats, "figures of a session (exit 1 if damaged)")
    stats.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    stats.add_argument("--json", action="store_true", help="print JSON")

    edit = command(
        "edit", cmd_edit, "cut a session down and scrub it before sharing it",
        "Writes an edited copy of IN to OUT (never over IN). --cut keeps a part "
        "(the greeting and the settings in force at the cut stay); --redact "
        "overwrites every match of a regular expression in the rx and tx bytes and "
        "marks it, so replay treats those bytes as wildcards and the scrubbed "
        "recording still replays to the driver that made it (it also clears the "
        "header's host and /dev/serial/by-id serial numbers); --drop-meta removes "
        "a metadata key. The header's edits list says what was done.")
    edit.add_argument("input", metavar="IN", help="the session to edit")
    edit.add_argument("output", metavar="OUT", help="the edited session to write (.wtape)")
    edit.add_argument("--cut", metavar="FROM:TO",
                      help="keep FROM to TO: seconds (1.5:4) or exchanges (3e:7e, numbered "
                           "from 0 as in mismatch reports); either side may be empty")
    edit.add_argument("--redact", metavar="PATTERN[=REPLACEMENT]", action="append", default=[],
                      help="a regular expression over the bytes (\\= for a literal =); "
                           "matches become REPLACEMENT repeated to their length (default *); "
                           "may be repeated")
    edit.add_argument("--drop-meta", metavar="KEY", action="append", default=[],
                      help="remove this --meta key (may be repeated)")
    edit.add_argument("-q", "--quiet", action="store_true", help="no summary")

    verify = command("verify", cmd_verify, "check every record of a session (exit 1 if damaged)")
    verify.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    verify.add_argument("--json", action="store_true", help="print JSON")

    convert = command(
        "convert", cmd_convert, "convert between session formats",
        "Converts IN to OUT. Formats: wiretape (.wtape), flexiport (name.log = "
        "name.logr + name.logw), jsonl, and the exports pcapng (Wireshark) and "
        "mcap (Foxglove); a packet capture (pcap, pcapng) is read with --from pcap. "
        "A format not given is taken from the file name.")
    convert.add_argument("input", metavar="IN", help="the session to read")
    convert.add_argument("output", metavar="OUT", help="the file to write")
    convert.add_argument("--from", dest="from_format",
                         choices=("wiretape", "flexiport", "jsonl", "pcap", "reserial", "umockdev"),
                         help="format of IN (default: from its name or content; reserial and "
                              "umockdev are always named)")
    convert.add_argument("--test", metavar="NAME",
                         help="--from reserial: the test of the cassette to import "
                              "(needed when it holds several)")
    convert.add_argument("--to", dest="to_format",
                         choices=("wiretape", "flexiport", "jsonl", "pcapng", "mcap"),
                         help="format of OUT (default: from its name)")
    convert.add_argument("--flexiport-format", choices=("new", "old"), default="new",
                         help="for a flexiport OUT: flexiport's new log format (from "
                              "2008-07, the default) or the old one")
    convert.add_argument("--stream", metavar="FILTER",
                         help="--from pcap: the conversation to import: tcp:N or udp:N (as "
                              "listed when there are several), or a tshark display filter")
    convert.add_argument("--device-addr", dest="device_addr", metavar="IP:PORT",
                         help="--from pcap: the device's side of the conversation (default: "
                              "the TCP server; for UDP the lower port)")
    convert.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")

    diff = command("diff", cmd_diff,
                   "first divergence of two sessions, per direction (exit 1 if they differ)")
    diff.add_argument("a", metavar="A", help="a session")
    diff.add_argument("b", metavar="B", help="another session")
    diff.add_argument("--profile", choices=tuple(_core.profile_names()), metavar="NAME",
                      help="compare frame by frame by the profile's match key (fields it "
                           "leaves out do not differ): " + ", ".join(_core.profile_names()))

    command("demo", cmd_demo,
            "record a simulated Hokuyo scanner, replay it without it, compare (make demo)")
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Runs the command line; returns the exit code."""
    out = _Output()
    parser = build_parser()
    own_arguments, command_argv = split_command(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(own_arguments)
    except _ArgumentError as error:
        error.parser.print_usage(sys.stderr)
        out.error(error.parser.prog, str(error))
        return EXIT_USAGE
    except _ParserExit as done:
        return int(done.status or 0)
    if getattr(args, "handler", None) is None:
        parser.print_help(sys.stderr)
        out.error("wiretape", "a command is required")
        return EXIT_USAGE
    prog = f"wiretape {args.command}"
    args.command_argv = command_argv
    # SIGTERM ends a command as Ctrl-C does: cleanly, files complete, exit 0.
    previous_sigterm = None
    try:
        previous_sigterm = signal.signal(signal.SIGTERM, _sigterm_as_interrupt)
    except ValueError:  # not the main thread (main() called from a thread)
        pass
    try:
        return int(args.handler(args, out) or 0)
    except KeyboardInterrupt:
        return EXIT_OK
    except BrokenPipeError:  # the reader of our output went away (| head)
        _silence_stdout()
        return EXIT_OK
    except Exception as error:  # every failure: one line, a code, no traceback
        if os.environ.get("WIRETAPE_DEBUG"):
            import traceback

            traceback.print_exc()
        out.error(prog, _describe(error))
        return exit_code_for(error)
    finally:
        if previous_sigterm is not None:
            signal.signal(signal.SIGTERM, previous_sigterm)


def _sigterm_as_interrupt(signum, frame):
    raise KeyboardInterrupt


if __name__ == "__main__":
    sys.exit(main())
