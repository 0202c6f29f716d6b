"""How a command fails: the exit codes and the one mapping of failures to
them (exit_code_for).

Exit codes:
  0  ok (Ctrl-C included)
  1  the checked thing failed: replay mismatch, damaged session file, diff
     found a difference, unused data under unused=error
  2  usage error: bad arguments or option strings
  3  runtime error: device or file I/O
  130, 143  batch work (convert, edit, faults, anything with -- CMD) ended
     by SIGINT or SIGTERM; services (record, replay and serve without
     -- CMD) end normally on them instead (DESIGN §8, §23)
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_USAGE = 2
EXIT_RUNTIME = 3


def exit_for_signal(signum: int) -> int:
    """The exit status of batch work a signal interrupted, as a shell
    reports a death by that signal (130 for SIGINT, 143 for SIGTERM)."""
    return 128 + signum


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived; ``signum`` says which. A KeyboardInterrupt,
    so code that already ends cleanly on Ctrl-C ends cleanly on both."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


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
