"""How a command fails: the exit codes and the one mapping of failures to
them (exit_code_for).

Exit codes:
  0  ok (Ctrl-C included)
  1  the checked thing failed: replay mismatch, damaged session file, diff
     found a difference, unused data under unused=error
  2  usage error: bad arguments or option strings
  3  runtime error: device or file I/O
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_USAGE = 2
EXIT_RUNTIME = 3


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

    from ..children import CommandNotStarted

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
