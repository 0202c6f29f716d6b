"""The wiretape command line: record, replay, serve, faults, show, stats,
verify, edit, convert, diff, ports, demo (docs/cli.md).

main.py runs a command (exit codes: errors.py), parser.py declares the
arguments, console.py prints, run.py holds the commands that run something
(bridges, fault campaigns, the demo), children.py a bridge with a CMD after
``--``, files.py the commands on session files, ports.py ``ports``.
"""

from .errors import (EXIT_CHECK_FAILED, EXIT_OK, EXIT_RUNTIME, EXIT_USAGE, CheckFailed,
                     RuntimeFailure, UsageError, exit_code_for)
from .main import main
from .parser import build_parser, split_command
from .ports import serial_ports
from .bridges import replay_options_of

__all__ = ["main", "build_parser", "split_command", "exit_code_for", "replay_options_of",
           "serial_ports", "EXIT_OK", "EXIT_CHECK_FAILED", "EXIT_USAGE", "EXIT_RUNTIME",
           "UsageError", "CheckFailed", "RuntimeFailure"]
