"""The wiretape command line's entry: main() parses the arguments, runs the
command, prints a failure as one line and returns its exit code
(cli/errors.py); SIGTERM ends a command as Ctrl-C does."""

from __future__ import annotations

import os
import signal
import sys
from typing import Optional, Sequence

from .console import Output, describe, silence_stdout
from .errors import EXIT_OK, EXIT_USAGE, Interrupted, exit_code_for, exit_for_signal
from .parser import ParserError, ParserExit, build_parser, split_command


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Runs the command line; returns the exit code."""
    out = Output()
    parser = build_parser()
    own_arguments, command_argv = split_command(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(own_arguments)
    except ParserError as error:
        error.parser.print_usage(sys.stderr)
        out.error(error.parser.prog, str(error))
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


# Commands that are batch work whatever their arguments; any command with
# -- CMD is too.
_BATCH_COMMANDS = frozenset({"convert", "edit", "faults", "faults merge", "diff", "show", "stats",
                             "verify", "view"})


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
