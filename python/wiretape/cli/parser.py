"""The command line's arguments: build_parser() (every command, its flags
and their help), the checks of single values (argparse types), and
split_command() for the CMD after ``--``."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Callable, List, Optional, Sequence, Tuple

from .. import __version__, _core
from ..options import option_keys
from ..session import NO_PROFILE
from .files import cmd_convert, cmd_diff, cmd_edit, cmd_show, cmd_stats, cmd_verify, cmd_view
from .fuzz_command import add_fuzz_parser
from .ports import cmd_ports
from .attach import add_attach_arguments
from .run import cmd_demo, cmd_faults, cmd_faults_merge, cmd_record, cmd_replay, cmd_serve


# --------------------------------------------------------------------------
# argument types


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



def _key_value(key) -> Callable[[str], object]:
    """An argparse type: a value of the key table's replay row ``key``,
    checked by the replay's own reading of it (type and range, in C++)."""
    def check(text: str) -> object:
        try:
            return _core.option_value("replay", key.name, text)
        except _core.OptionError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    return check


def _add_replay_keys(parser: argparse.ArgumentParser) -> None:
    """The replay keys the CLI mirrors as flags (``--at-end`` for at_end),
    made from the key table (docs/options.md): names, choices, ranges,
    defaults and help are the table's. --fault is a flag of its own."""
    for key in option_keys("replay"):
        if key.flag != "--" + key.name.replace("_", "-"):
            continue
        help_text = f"{key.help} (default {key.default})" if key.default else key.help
        if key.name == "profile":  # profiles are registered at run time
            parser.add_argument(key.flag, dest=key.name, type=_profile_spec, metavar="PROFILE",
                                help=f"{help_text}: {_PROFILE_HELP}")
        elif key.type == "choice":
            parser.add_argument(key.flag, dest=key.name, choices=tuple(key.choices),
                                help=help_text)
        else:
            parser.add_argument(key.flag, dest=key.name, type=_key_value(key),
                                metavar=key.name.upper(), help=help_text)


def _profile_spec(text: str) -> str:
    """An argparse type: a --profile value, read by _core.profile_from_spec
    (a name, or a declared profile's keys); ``none`` says no profile, not
    even the session's (wiretape.session.chosen_profile)."""
    if text.strip() == NO_PROFILE:
        return NO_PROFILE
    try:
        _core.profile_from_spec(text)
    except _core.OptionError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text.strip()


_SESSION_DEFAULT = "the session's --meta profile=NAME, else none"
_PROFILE_HELP = (", ".join(_core.profile_names()) + ", a declared profile "
                 "('framing=...,ignore=...,echo=...,checksum=...', docs/replay.md), or none")

def _kind_list(text: str) -> Tuple[str, ...]:
    from ..tools.show import check_kinds

    kinds = tuple(kind.strip() for kind in text.split(",") if kind.strip())
    try:
        check_kinds(kinds)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return kinds


def _seconds_of_session(text: str) -> float:
    try:
        value = float(text.strip().rstrip("s"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds")
    return value


def _speed(text: str) -> float:
    """An argparse type: --speed K of faults, checked as the replay key
    ``speed`` is (a finite number above 0)."""
    key = next(key for key in option_keys("replay") if key.name == "speed")
    return float(_key_value(key)(text))  # type: ignore[arg-type]


def _positive_int(text: str) -> int:
    value = _non_negative_int(text)
    if value == 0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be 1 or more")
    return value


def _backlog(text: str) -> int:
    """An argparse type: a listen backlog, 1 to 2**31-1 (the kernel caps it
    at net.core.somaxconn)."""
    value = _positive_int(text)
    if value > 2**31 - 1:
        raise argparse.ArgumentTypeError(f"{text!r}: must be from 1 to 2**31-1")
    return value


def _add_backlog(parser) -> None:
    parser.add_argument("--backlog", type=_backlog, metavar="N",
                        help="with --listen: how many connections the kernel completes "
                             "before they are accepted (default 4096; the kernel caps it "
                             "at net.core.somaxconn)")


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
        from ..bridge import parse_udp_address

        try:
            parse_udp_address(text, what, minimum_port)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return text
    return check


# --------------------------------------------------------------------------
# the parser

_DESCRIPTION = "Record and replay the wire-level session between a driver and its device."

_EXIT_CODES = """exit codes: 0 ok (Ctrl-C included); 1 the checked thing failed (replay
mismatch, damaged file, diff found a difference, unused data under
unused=error); 2 usage error; 3 runtime error (device or file I/O)."""

_DEVICE_NOTE = """--device takes a port option string (type=tcp,host=10.0.0.5,port=10940), a
bare path, which means type=serial,device=PATH, or rfc2217://HOST:PORT (a line
exported by ser2net or a labgrid exporter), which means
type=rfc2217,host=HOST,port=PORT."""

_EPILOG = _EXIT_CODES + "\n" + _DEVICE_NOTE

# What follows `--` on the usage line of the commands that run a program.
_COMMAND_USAGE = {
    "record": "[-- CMD [ARG...]]",
    "replay": "[-- CMD [ARG...]]",
    "faults": "-- CMD [ARG...] {port} [ARG...]",
    "fuzz": "-- CMD [ARG...] {port} [ARG...]",
}


# The form of several channels, a second usage line (docs/cli.md).
_CHANNELS_USAGE = {
    "record": "wiretape record -o FILE (--device NAME=OPTS (--pty NAME=PATH | "
              "--listen NAME=HOST:PORT | --udp NAME=HOST:PORT [--peer NAME=HOST:PORT]))... "
              "[--duration S] [--meta KEY=VALUE] [-q]",
    "replay": "wiretape replay FILE (--pty NAME=PATH | --listen NAME=HOST:PORT | "
              "--udp NAME=HOST:PORT [--peer NAME=HOST:PORT])... [replay keys...]",
}


# The end of --help of the commands a newcomer starts with: one device
# first, then -- CMD, then several channels (docs/cli.md has each).
_EXAMPLES = {
    "record": """examples:
  wiretape record --device /dev/ttyUSB0 --pty /tmp/ttyLidar -o scan.wtape
  wiretape record --device type=tcp,host=10.0.0.5,port=10940 --listen 127.0.0.1:10940 -o scan.wtape
  wiretape record --device /dev/ttyUSB0 -o scan.wtape -- ./driver --port /dev/ttyUSB0
  wiretape record --attach 4242 --path /dev/ttyUSB0 -o driver.wtape
  wiretape record -o nav.wtape --device gps=/dev/ttyUSB0 --pty gps=/tmp/gps \\
      --device rtk=type=tcp,host=caster,port=2101 --listen rtk=127.0.0.1:2101""",
    "replay": """examples:
  wiretape replay scan.wtape --pty /tmp/ttyLidar
  wiretape replay scan.wtape --listen 127.0.0.1:10940 --match request
  wiretape replay scan.wtape --as /dev/ttyUSB0 -- ./driver --port /dev/ttyUSB0
  wiretape replay nav.wtape --pty gps=/tmp/gps --listen rtk=127.0.0.1:2101""",
}


def _finish_help(name: str, sub: argparse.ArgumentParser) -> None:
    """The usage line shows the CMD after ``--`` (argparse never sees it),
    the one-device form before the form of several channels; the note on
    --device is only where there is a --device, after the examples."""
    has_device = any("--device" in action.option_strings for action in sub._actions)
    sub.epilog = _EPILOG if has_device else _EXIT_CODES
    if name in _EXAMPLES:
        sub.epilog = _EXAMPLES[name] + "\n\n" + sub.epilog
    if name in _COMMAND_USAGE:
        usage = sub.format_usage().rstrip()
        sub.usage = usage[len("usage: "):] + " " + _COMMAND_USAGE[name]
    if name in _CHANNELS_USAGE:
        sub.usage += "\n       " + _CHANNELS_USAGE[name]


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of exiting, so main() returns codes."""

    def error(self, message):  # noqa: D401 - argparse's hook
        raise ParserError(self, message)

    def _check_value(self, action, value):
        # A mistyped command gets the one it was probably meant to be, not
        # the list of every command (argparse's own message).
        if isinstance(action, argparse._SubParsersAction) and value not in action.choices:
            # 0.7: "shwo" is show and "replya" replay, "teleport" is not ports
            import difflib  # only a usage error needs it
            near = difflib.get_close_matches(value, list(action.choices), n=1, cutoff=0.7)
            hint = f" (did you mean {near[0]}?)" if near else f" (see {self.prog} --help)"
            raise argparse.ArgumentError(None, f"unknown command {value!r}{hint}")
        super()._check_value(action, value)

    def exit(self, status=0, message=None):
        if message:
            print(message, file=sys.stderr if status else sys.stdout, end="")
        raise ParserExit(status)


class ParserError(Exception):
    def __init__(self, parser, message):
        super().__init__(message)
        self.parser = parser


class ParserExit(Exception):
    def __init__(self, status):
        super().__init__(status)
        self.status = status


def _named(check: Callable[[str], str]) -> Callable[[str], str]:
    """An argparse type for an endpoint flag: its value after an optional
    ``NAME=`` prefix (cli/endpoints.py) checked by `check`; the text is
    kept whole, for endpoints.collect() to split."""
    def check_value(text: str) -> str:
        from .endpoints import split_name

        check(split_name(text)[1])
        return text
    return check_value


# The NAME= prefix every endpoint flag takes (DESIGN.md section 19).
_NAMED = ("; NAME=... names its channel (repeatable, one per channel: "
          "a session of several ports)")


def _add_client_side(parser, verb: str) -> None:
    # One client side per channel: endpoints.py checks it, per NAME.
    side = parser
    side.add_argument("--pty", metavar="[NAME=]PATH", action="append",
                      help=f"{verb} on a new pseudo-terminal, linked at PATH (the "
                           "client opens PATH as if it were the device)" + _NAMED)
    side.add_argument("--listen", metavar="[NAME=]HOST:PORT", action="append",
                      help=f"{verb} on TCP: the client connects to HOST:PORT "
                           "(PORT alone means 127.0.0.1:PORT; 0 picks a free port)" + _NAMED)
    side.add_argument("--udp", metavar="[NAME=]HOST:PORT", action="append",
                      type=_named(_udp_address("udp", 0)),
                      help=f"{verb} over UDP: the client sends datagrams to HOST:PORT "
                           "and gets the device's back, one datagram per record "
                           "(0 picks a free port)" + _NAMED)
    parser.add_argument("--pty-mode", dest="pty_mode", type=_pty_mode, metavar="MODE",
                        help="with --pty: the terminal's permission bits, octal "
                             "(default 0660, as a serial device)")
    parser.add_argument("--pty-group", dest="pty_group", type=_pty_group, metavar="NAME|GID",
                        help="with --pty: the terminal's group (default dialout where it "
                             "exists, else this process's group)")


def _add_redirect(parser, default: str) -> None:
    parser.add_argument("--as", dest="redirect_path", metavar="[NAME=]PATH", action="append",
                        help="with -- CMD: the device path CMD opens, redirected to the "
                             f"pty ({default})" + _NAMED)


_COMMANDS_WITH_CMD = ("record", "replay", "faults", "fuzz")

# Every command build_parser() declares, in its order.
COMMAND_NAMES = ("record", "replay", "faults", "fuzz", "faults merge", "serve", "ports", "show",
                 "stats", "view", "edit", "verify", "convert", "diff", "demo")


def split_command(argv: Sequence[str]) -> Tuple[List[str], Optional[List[str]]]:
    """wiretape's own arguments and the CMD after ``--`` of ``record`` and
    ``replay`` (None when there is no ``--``; [] when nothing follows it)."""
    arguments = list(argv)
    if arguments[:2] == ["faults", "merge"]:
        # A command of two words (a session named merge is given as ./merge).
        return ["faults merge"] + arguments[2:], None
    if arguments and arguments[0] in _COMMANDS_WITH_CMD and "--" in arguments:
        separator = arguments.index("--")
        return arguments[:separator], arguments[separator + 1:]
    return arguments, None


class _UndeclaredArguments:
    """Stands for the parser of a command that is not run: its arguments are
    taken and dropped. Making every command's parser and declaring its
    arguments is most of the parser's cost, paid at every start."""

    def add_argument(self, *args, **kwargs) -> None:
        pass

    def set_defaults(self, **kwargs) -> None:
        pass

    def add_argument_group(self, *args, **kwargs) -> "_UndeclaredArguments":
        return self

    def add_mutually_exclusive_group(self, *args, **kwargs) -> "_UndeclaredArguments":
        return self


def command_run_alone(arguments: Sequence[str]) -> Optional[str]:
    """The command whose parser alone parses `arguments`: a known command
    given first (before it, ``--help`` or ``--version`` is wiretape's own
    and needs every command); None else."""
    first = arguments[0] if arguments else None
    return first if first in COMMAND_NAMES else None


def _terminal_columns() -> int:
    """shutil.get_terminal_size().columns, as argparse's help asks it, but
    without importing shutil (and bz2 and lzma with it) for a command line
    that prints no help: argparse makes a formatter for every argument
    declared (replay_as_overhead_ratio, docs/benchmarks.md)."""
    try:
        columns = int(os.environ["COLUMNS"])
    except (KeyError, ValueError):
        columns = 0
    if columns <= 0:
        try:
            columns = os.get_terminal_size(sys.__stdout__.fileno()).columns  # type: ignore[union-attr]
        except (AttributeError, ValueError, OSError):
            columns = 0
    return columns or 80


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """argparse's RawDescriptionHelpFormatter, its width found as argparse
    finds it (the terminal's columns less 2) without importing shutil."""

    def __init__(self, prog, indent_increment=2, max_help_position=24, width=None, **more):
        if width is None:
            width = _terminal_columns() - 2
        super().__init__(prog, indent_increment, max_help_position, width, **more)


def build_parser(only: Optional[str] = None) -> argparse.ArgumentParser:
    """The command line's parser. With `only`, a command's name, that
    command alone: for a command line that names it first, which needs no
    other (wiretape --help and a mistyped command's "did you mean" need
    them all)."""
    parser = _Parser(prog="wiretape", description=_DESCRIPTION, epilog=_EPILOG,
                     formatter_class=_HelpFormatter)
    parser.add_argument("--version", action="version", version=f"wiretape {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    declared = []

    def command(name: str, handler: Callable, help_text: str, description: str = ""):
        assert name in COMMAND_NAMES, name
        if only is not None and name != only:
            return _UndeclaredArguments()
        sub = commands.add_parser(name, help=help_text, description=description or help_text,
                                  epilog=_EPILOG,
                                  formatter_class=_HelpFormatter)
        sub.set_defaults(handler=handler)
        declared.append(name)
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
        "the device and recorded. A pty has no modem lines: with -- CMD the preload "
        "shim emulates DTR/RTS, CTS/DSR/RI/CD, break and custom baud for CMD, applied "
        "to the device and recorded.")
    record.add_argument("--device", metavar="[NAME=]OPTS", action="append",
                        help="the real device: a port option string or a serial device path"
                             + _NAMED)
    _add_client_side(record, "the driver connects")
    record.add_argument("--peer", metavar="[NAME=]HOST:PORT", action="append",
                        type=_named(_udp_address("peer", 1)),
                        help="with --udp: send the device's datagrams to HOST:PORT from "
                             "the start; without a --device of its name, the device "
                             "streams datagrams to --udp and each is forwarded to "
                             "HOST:PORT and recorded as rx" + _NAMED)
    _add_backlog(record)
    record.add_argument("-o", "--output", metavar="FILE", type=_session_output,
                        help="the session file to write (.wtape); required but with "
                             "--against (default there: OLD's name with .new before .wtape)")
    record.add_argument("--duration", type=_positive_seconds, metavar="S",
                        help="stop after S seconds (default: until Ctrl-C)")
    record.add_argument("--compress", choices=("none", "zstd"), default="none",
                        help="record in zstd chunks (format 2.0; docs/session-format.md)")
    record.add_argument("--meta", action="append", metavar="KEY=VALUE",
                        help="free metadata for the session header (repeatable)")
    record.add_argument("-q", "--quiet", action="store_true", help="no client/device messages")
    _add_redirect(record, "default: the --device's path")
    add_attach_arguments(record)
    record.add_argument("--against", metavar="OLD", type=_session_output,
                        help="drift: once recorded, compare the new recording with the stored "
                             "recording OLD by exchange and report every place the device "
                             "now answers differently (exit 1 on drift, 0 when it answers "
                             "as recorded; docs/cli.md \"Drift\")")
    record.add_argument("--profile", type=_profile_spec, metavar="PROFILE",
                        help="with --against: compare through the profile's match key, so "
                             "the fields it leaves out (masks) never drift (default: OLD's "
                             f"--meta profile=NAME, else none): {_PROFILE_HELP}")
    record.add_argument("--update", action="store_true",
                        help="with --against: when the run passed (the recording and any "
                             "-- CMD succeeded), write the new recording in OLD's place "
                             "atomically, drift or not")
    record.add_argument("--json", action="store_true",
                        help="with --against: print one JSON document of the places that "
                             "drifted instead of the report (the run's output goes to "
                             "stderr); the same exit status")

    replay = command(
        "replay", cmd_replay, "replay a recording as a virtual device (pty, TCP or UDP)",
        "The recording becomes a virtual device any program can open: a "
        "pseudo-terminal (--pty PATH), a TCP server (--listen HOST:PORT) or a UDP "
        "socket (--udp HOST:PORT; one datagram per recorded record). Each "
        "connection (an open of the pty) is a client session: with --match sequence the "
        "k-th continues at the recording's k-th client connect, with --match request "
        "connection order is free; a close and reopen at once is two sessions "
        "(--restart starts the whole recording over for each client). With --as PATH -- CMD ARG... it runs CMD with PATH redirected to its "
        "pty and ends when CMD does (exit: CMD's status when it failed, else the "
        "replay's). The replay keys are those of type=replay (docs/options.md). Exit 1 on a "
        "mismatch, and when the recording has rx but no client was served any of it "
        "(no client connected, nothing matched, or the greeting was lost).")
    replay.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    _add_client_side(replay, "the client connects")
    _add_backlog(replay)
    _add_replay_keys(replay)
    replay.add_argument("--options", metavar="KEYS",
                        help="further replay keys as an option string (k=v,k=v)")
    replay.add_argument("--peer", metavar="[NAME=]HOST:PORT", action="append",
                        type=_named(_udp_address("peer", 1)),
                        help="with --udp: send the device's datagrams to HOST:PORT from "
                             "the start (default: to the last sender, once one has sent)"
                             + _NAMED)
    replay.add_argument("--protocol", choices=("raw", "rfc2217"), default="raw",
                        help="with --listen: raw bytes or RFC 2217, for pyserial's "
                             "rfc2217:// (the client sets the line and reads the recorded "
                             "modem lines; default raw)")
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
    faults.add_argument("--speed", type=_speed, default=1.0, metavar="K",
                        help="run CMD on a clock K times faster, and the replays with it "
                             "(--timeout is on CMD's clock; default 1)")
    faults.add_argument("--shard", metavar="K/N|auto",
                        help="run only shard K of N: the cases whose index is K-1 modulo N "
                             "(merge the shards' --json with 'wiretape faults merge'); auto: "
                             "from Bazel's, a Kubernetes Indexed Job's or GitLab's variables")
    faults.add_argument("--shards", type=_positive_int, metavar="N",
                        help="with --shard auto: the total of a Kubernetes Indexed Job "
                             "(JOB_COMPLETION_INDEX gives only the index)")
    faults.add_argument("--junit", metavar="FILE",
                        help="write the runs as JUnit XML to FILE (a test case per run)")

    add_fuzz_parser(command, {"positive_int": _positive_int, "non_negative_int": _non_negative_int,
                              "positive_seconds": _positive_seconds, "speed": _speed})

    merge = command(
        "faults merge", cmd_faults_merge, "one campaign's table from the --json of its shards",
        "Merges the --json files of a campaign run in shards (wiretape faults ... --shard "
        "K/N --json FILE, every K once) into one table and JSON, as one unsharded run "
        "gives them. Refuses files of different sessions, seeds, kinds, budgets or replay "
        "keys, a missing or repeated shard and an interrupted one (exit 2). Exit 1 if "
        "any run crashed or hung (docs/faults.md).")
    merge.add_argument("files", nargs="+", metavar="FILE.json",
                       help="the --json of each shard")
    merge.add_argument("--json", metavar="FILE", help="write the merged runs as JSON to FILE")
    merge.add_argument("--junit", metavar="FILE",
                       help="write the merged runs as JUnit XML to FILE (a test case per run)")

    serve = command(
        "serve", cmd_serve, "share a local device with remote programs over TCP",
        "Shares a local device over TCP (raw bytes, or RFC 2217 so that remote "
        "programs can set the line), recording on the server side with -o.")
    serve.add_argument("--device", required=True, metavar="OPTS",
                       help="the device: a port option string or a serial device path")
    serve.add_argument("--listen", required=True, metavar="HOST:PORT",
                       help="where clients connect (PORT alone means 127.0.0.1:PORT)")
    serve.add_argument("--compress", choices=("none", "zstd"), default="none",
                       help="with -o: record in zstd chunks (format 2.0)")
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
    _add_backlog(serve)
    serve.add_argument("-q", "--quiet", action="store_true", help="no client messages")

    ports = command("ports", cmd_ports, "list serial devices (by-id paths, USB ids)")
    ports.add_argument("--json", action="store_true", help="print JSON")

    show = command("show", cmd_show, "print a session's timeline")
    show.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    show.add_argument("--format", choices=("text", "hex", "jsonl"), default="text",
                      help="text (default), hex dump, or one JSON object per record")
    show.add_argument("--profile", type=_profile_spec, metavar="PROFILE",
                      help="cut the bytes into a protocol's frames and name them "
                           f"(default: {_SESSION_DEFAULT}): {_PROFILE_HELP}")
    show.add_argument("--decode", choices=("scip",),
                      help="the older name of --profile scip")
    show.add_argument("--textconv", action="store_true",
                      help="for git's diff.textconv: no file name, exit 0 when damaged")
    show.add_argument("--no-start", dest="no_start", action="store_true",
                      help="with --textconv (implies it): leave out the start time and host")
    show.add_argument("--no-times", dest="no_times", action="store_true",
                      help="with --textconv (implies it): leave out each record's time")
    show.add_argument("--color", choices=("auto", "always", "never"), default="auto",
                      help="colour: auto (default) on a terminal unless NO_COLOR is set")
    show.add_argument("--kind", type=_kind_list, metavar="K[,K]",
                      help="only records of these kinds (tx, rx, settings, ...)")
    show.add_argument("--from", dest="start_s", type=_seconds_of_session, metavar="S",
                      help="only records at or after S seconds of session time (the first "
                           "column)")
    show.add_argument("--to", dest="end_s", type=_seconds_of_session, metavar="S",
                      help="only records at or before S seconds of session time")
    show.add_argument("--grep", metavar="PATTERN",
                      help="only tx and rx records whose bytes match PATTERN (a Python bytes "
                           "regular expression; \\x00 escapes work)")
    show.add_argument("--full", action="store_true",
                      help="every byte of each payload (not the first 64)")
    show.add_argument("--channel", metavar="NAME", action="append", default=[],
                      help="only records of this channel of a session of several ports "
                           "(may be repeated)")

    stats = command("stats", cmd_stats, "figures of a session (exit 1 if damaged)")
    stats.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    stats.add_argument("--json", action="store_true", help="print JSON")
    stats.add_argument("--profile", type=_profile_spec, metavar="PROFILE",
                       help="latency per request frame name of a protocol "
                            f"(default: {_SESSION_DEFAULT}): {_PROFILE_HELP}")

    view = command(
        "view", cmd_view, "a session as a timeline in one HTML page, for a browser",
        "Writes one self-contained HTML page (no network access: script, styles and data "
        "inline) with a zoomable timeline of the session: tx, rx and events lanes, the "
        "exchanges, a profile's frames, faults, a replay's mismatch, and a hex/ASCII pane. "
        "Open it in any browser.")
    view.add_argument("file", metavar="SESSION", help="the session (.wtape or flexiport name.log)")
    view.add_argument("-o", "--output", metavar="FILE.html",
                      help="the page to write (default: SESSION with .html for its suffix)")
    view.add_argument("--campaign", metavar="FILE.json",
                      help="a `wiretape faults --json` file of this session: its runs on the "
                           "exchanges they faulted")
    view.add_argument("--profile", type=_profile_spec, metavar="PROFILE",
                      help="name the frames by a protocol profile "
                           f"(default: {_SESSION_DEFAULT}): {_PROFILE_HELP}")
    view.add_argument("-q", "--quiet", action="store_true", help="no summary")

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
    edit.add_argument("--profile", type=_profile_spec, metavar="PROFILE",
                      help="the protocol whose checksums --redact recomputes over scrubbed "
                           f"bytes (default: {_SESSION_DEFAULT}): {_PROFILE_HELP}")
    edit.add_argument("--channel", metavar="NAME", action="append", default=[],
                      help="--cut and --redact work on this channel only (may be repeated); "
                           "the other channels' records are kept as they are")
    edit.add_argument("--drop-meta", metavar="KEY", action="append", default=[],
                      help="remove this --meta key (may be repeated)")
    edit.add_argument("--compress", choices=("none", "zstd"), default="none",
                      help="write OUT in zstd chunks (format 2.0; docs/session-format.md)")
    edit.add_argument("-q", "--quiet", action="store_true", help="no summary")

    verify = command("verify", cmd_verify, "check every record of a session (exit 1 if damaged)")
    verify.add_argument("file", metavar="FILE", help="the session (.wtape or flexiport name.log)")
    verify.add_argument("--json", action="store_true", help="print JSON")
    verify.add_argument("--repair", action="store_true",
                        help="append the per-channel index to a session of several channels "
                             "that lacks it (an intact file only)")

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
    convert.add_argument("--stream", metavar="[NAME=]FILTER", action="append",
                         help="--from pcap: the conversation to import: tcp:N or udp:N (as "
                              "listed when there are several), or a tshark display filter; "
                              "repeated as NAME=FILTER, each conversation becomes the channel "
                              "NAME of one session")
    convert.add_argument("--device-addr", dest="device_addr", metavar="[NAME=]IP:PORT",
                         action="append",
                         help="--from pcap: the device's side of the conversation (default: "
                              "the TCP server; for UDP the lower port); with named streams, "
                              "NAME=IP:PORT for the channel NAME (repeatable)")
    convert.add_argument("--compress", choices=("none", "zstd"), default="none",
                         help="a .wtape output in zstd chunks (format 2.0; docs/session-format.md)")
    convert.add_argument("--allow-gaps", dest="allow_gaps", action="store_true",
                         help="--from pcap: import a capture that lost bytes, with a "
                              "capture_gap event where they are missing (default: refuse it)")
    convert.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")

    diff = command("diff", cmd_diff,
                   "where two sessions differ: the first difference per direction, the "
                   "exchanges aligned as diff -u aligns lines, every divergence by exchange "
                   "(exit 1 if they differ)")
    diff.add_argument("a", metavar="A", help="a session")
    diff.add_argument("b", metavar="B", help="another session")
    diff.add_argument("--profile", type=_profile_spec, metavar="PROFILE",
                      help="compare frame by frame by the profile's match key (fields it "
                           f"leaves out do not differ; default: {_SESSION_DEFAULT}): "
                           f"{_PROFILE_HELP}")
    diff.add_argument("--max", dest="max_divergences", type=_non_negative_int, default=10,
                      metavar="N", help="show the first N divergences by exchange (default "
                                        "10; all are counted)")
    diff.add_argument("--json", action="store_true",
                      help="the same comparison as JSON: directions, the exchanges' alignment, "
                           "divergences")

    command("demo", cmd_demo,
            "record a simulated Hokuyo scanner, replay it without it, compare (make demo)")
    for name in declared:
        _finish_help(name, commands.choices[name])
    return parser
