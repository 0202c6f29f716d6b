"""The wiretape command line's entry: main() parses the arguments, runs the
command, prints a failure as one line and returns its exit code
(cli/errors.py); SIGTERM ends a command as Ctrl-C does."""

from __future__ import annotations

import os
import signal
import sys
from typing import Optional, Sequence

from .console import Output, describe, silence_stdout
from .errors import EXIT_OK, EXIT_USAGE, exit_code_for
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
        silence_stdout()
        return EXIT_OK
    except Exception as error:  # every failure: one line, a code, no traceback
        if os.environ.get("WIRETAPE_DEBUG"):
            import traceback

            traceback.print_exc()
        out.error(prog, describe(error))
        return exit_code_for(error)
    finally:
        if previous_sigterm is not None:
            signal.signal(signal.SIGTERM, previous_sigterm)


def _sigterm_as_interrupt(signum, frame):
    raise KeyboardInterrupt
