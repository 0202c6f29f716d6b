"""The wiretape command line's entry: main() parses the arguments, runs the
command, prints a failure as one line and returns its exit code
(cli/errors.py); SIGTERM ends a command as Ctrl-C does."""

from __future__ import annotations

import argparse
import os
import signal
import sys
from typing import Optional, Sequence

from .console import Output, describe, silence_stdout, undecodable_text_escaped
from .errors import EXIT_OK, EXIT_USAGE, Interrupted, exit_code_for, exit_for_signal
from .parser import ParserError, ParserExit, build_parser, command_run_alone, split_command


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Runs the command line; returns the exit code."""
    with undecodable_text_escaped():
        return _main(argv)


def _main(argv: Optional[Sequence[str]]) -> int:
    out = Output()
    own_arguments, command_argv = split_command(sys.argv[1:] if argv is None else argv)
    # Only the command run needs its parser; anything else (no command, a
    # mistyped one, an option before it) is answered from them all.
    parser = build_parser(only=command_run_alone(own_arguments))
    try:
        args = parser.parse_args(own_arguments)
    except ParserError as error:
        where, message = unknown_option_message(parser, own_arguments, str(error))
        if message is None:  # a typo can leave a required flag missing: name the typo
            where, message = mistyped_option(parser, own_arguments)
        where = where or error.parser
        out.error(where.prog, with_help_hint(where, message or str(error)))
        return EXIT_USAGE
    except ParserExit as done:
        return int(done.status or 0)
    if getattr(args, "handler", None) is None:
        parser.print_help(sys.stderr)
        out.error("wiretape", "a command is required")
        return EXIT_USAGE
    prog = f"wiretape {args.command}"
    args.command_argv = command_argv
    interruption = _Interruption()
    try:
        status = _run(args, out, prog)
    finally:
        interruption.restore()
    if interruption.signum is not None and is_batch_work(args):
        return exit_for_signal(interruption.signum)
    return status


def unknown_option_message(parser, arguments: Sequence[str], message: str):
    """For argparse's "unrecognized arguments": (the parser of the command
    they were given to, one line naming the first and the option it was
    probably meant to be); (None, None) for any other error."""
    prefix = "unrecognized arguments: "
    if not message.startswith(prefix):
        return None, None
    unknown = message[len(prefix):].split()[0]
    flag = unknown.split("=", 1)[0]
    commands = _subcommands(parser)
    named = next((a for a in arguments if not a.startswith("-")), None)
    if named in commands:
        return commands[named], _unknown_of(commands[named], unknown)
    own = _option_strings(parser)
    import difflib  # only a usage error needs it
    close = difflib.get_close_matches(flag, own, n=1, cutoff=0.6)
    if close:
        return parser, f"unknown option {unknown!r} (did you mean {close[0]}?)"
    elsewhere = []
    for name, sub in sorted(commands.items()):
        near = difflib.get_close_matches(flag, _option_strings(sub), n=1, cutoff=0.8)
        if near:
            elsewhere.append(f"wiretape {name} {near[0]}")
    hint = f"; did you mean {' or '.join(elsewhere[:3])}?" if elsewhere else ""
    return parser, (f"unknown option {unknown!r}: wiretape's own options are --help and "
                    f"--version; a command's options go after it (wiretape COMMAND --help)"
                    + hint)


def _unknown_of(sub, unknown: str) -> str:
    """One line naming the argument `unknown` a command does not take, and
    the option it was probably meant to be."""
    flag = unknown.split("=", 1)[0]
    import difflib  # only a usage error needs it
    close = difflib.get_close_matches(flag, _option_strings(sub), n=1, cutoff=0.6)
    hint = f" (did you mean {close[0]}?)" if close else f" (see {sub.prog} --help)"
    what = "unknown option" if flag.startswith("-") else "unexpected argument"
    return f"{what} {unknown!r}{hint}"


def mistyped_option(parser, arguments: Sequence[str]):
    """For any other error of a command: (its parser, one line naming the
    first --flag it does not know) when there is one (``--ouput f`` leaves
    -o missing, and the typo is the mistake to name); (None, None) else."""
    commands = _subcommands(parser)
    named = next((a for a in arguments if not a.startswith("-")), None)
    if named not in commands:
        return None, None
    sub = commands[named]
    known = _option_strings(sub)
    for argument in arguments[arguments.index(named) + 1:]:
        flag = argument.split("=", 1)[0]
        if not flag.startswith("--") or flag == "--":
            continue
        if not any(option.startswith(flag) for option in known):  # argparse takes prefixes
            return sub, _unknown_of(sub, argument)
    return None, None


def with_help_hint(parser, message: str) -> str:
    """A usage error as the one line docs/cli.md promises: the problem, then
    where to read more unless it already says what was meant or what is
    valid (argparse's usage block before it would bury the line that
    matters)."""
    if any(said in message for said in ("did you mean", "choose from", "--help")):
        return message
    return f"{message} (see {parser.prog} --help)"


def _subcommands(parser) -> dict:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _option_strings(parser) -> list:
    return [option for action in parser._actions for option in action.option_strings
            if option.startswith("--")]


# Commands that are batch work whatever their arguments; any command with
# -- CMD is too.
_BATCH_COMMANDS = frozenset({"convert", "edit", "faults", "faults merge", "fuzz", "diff", "show",
                             "stats", "verify", "view"})


def is_batch_work(args) -> bool:
    """Batch work interrupted exits 130/143; a service ends normally."""
    return args.command in _BATCH_COMMANDS or getattr(args, "command_argv", None) is not None


def _run(args, out: Output, prog: str) -> int:
    try:
        return int(args.handler(args, out) or 0)
    except KeyboardInterrupt:
        return EXIT_OK  # main() turns it into 130/143 for batch work
    except BrokenPipeError:  # the reader of our output went away (| head)
        silence_stdout()
        return EXIT_OK
    except Exception as error:  # every failure: one line, a code, no traceback
        if os.environ.get("WIRETAPE_DEBUG"):
            import traceback

            traceback.print_exc()
        out.error(prog, describe(error))
        return exit_code_for(error)


class _Interruption:
    """Turns SIGINT and SIGTERM into ``Interrupted`` (a KeyboardInterrupt)
    while a command runs, and remembers which arrived first."""

    def __init__(self):
        self.signum: Optional[int] = None
        self._previous = {}
        for signum in (signal.SIGINT, signal.SIGTERM):
            try:
                if signal.getsignal(signum) is signal.SIG_IGN:
                    continue  # a shell's background job ignores SIGINT: so do we
                self._previous[signum] = signal.signal(signum, self._handle)
            except ValueError:  # not the main thread (main() called from a thread)
                pass

    def _handle(self, signum, frame):
        if self.signum is None:
            self.signum = signum
        raise Interrupted(signum)

    def restore(self) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
