"""What the command line prints: stdout and stderr (in colour on a
terminal), and a failure as one line naming the problem."""

from __future__ import annotations

import codecs
import contextlib
import io
import os
import sys
from typing import Iterator, Optional, Sequence

from .errors import CheckFailed, RuntimeFailure, UsageError

#: The error handler with which the command line prints text that its
#: stream's encoding cannot hold (undecodable_text_escaped).
UNDECODABLE = "wiretape.undecodable"


def _undecodable_as_escapes(error: UnicodeError):
    """Lone surrogates, by which Python holds the bytes of a name that are
    not UTF-8 (a path such as b"n\\xff.wtape", PEP 383), as ``\\xNN``, as
    C++'s messages show such bytes; any other character the stream cannot
    encode as ``\\uNNNN``."""
    if not isinstance(error, UnicodeEncodeError):
        raise error
    text = error.object[error.start:error.end]
    return "".join(f"\\x{ord(char) - 0xDC00:02x}" if 0xDC80 <= ord(char) <= 0xDCFF
                   else f"\\u{ord(char):04x}" for char in text), error.end


codecs.register_error(UNDECODABLE, _undecodable_as_escapes)


@contextlib.contextmanager
def undecodable_text_escaped() -> Iterator[None]:
    """While a command runs, stdout and stderr print a path that is not
    UTF-8 with those bytes as \\xNN, where a strict stream (a UTF-8 locale)
    would fail the command and a C locale's would send the raw bytes to the
    terminal; their error handlers are restored after."""
    saved = []
    for stream in (sys.stdout, sys.stderr):
        errors = getattr(stream, "errors", None)
        reconfigure = getattr(stream, "reconfigure", None)
        if errors is None or reconfigure is None:
            continue
        try:
            reconfigure(errors=UNDECODABLE)
        except (ValueError, io.UnsupportedOperation):
            continue
        saved.append((stream, errors))
    try:
        yield
    finally:
        for stream, errors in saved:
            try:
                stream.reconfigure(errors=errors)
            except (ValueError, io.UnsupportedOperation):
                pass


def describe(error: BaseException) -> str:
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


class Output:
    """stdout and stderr, with colour (rich) when they are terminals.

    rich is imported when a line in colour is first printed, not before: a
    command that prints nothing through it (show writes its own colours)
    does not pay for rich's import, a quarter of show's time."""

    def __init__(self) -> None:
        self._consoles: dict = {}

    def _terminal(self, stderr: bool):
        """rich's console of stdout or stderr when that is a terminal, else None."""
        if stderr not in self._consoles:
            console = None
            try:
                if (sys.stderr if stderr else sys.stdout).isatty():
                    import rich.console

                    console = rich.console.Console(stderr=stderr, highlight=False)
            except (ImportError, ValueError):  # colour is a nicety; a closed stream has none
                pass
            self._consoles[stderr] = console
        return self._consoles[stderr]

    @property
    def _console(self):
        return self._terminal(stderr=False)

    @property
    def _error_console(self):
        return self._terminal(stderr=True)

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

    def live(self) -> "LiveLine":
        """A status line redrawn in place on stderr while work goes on: on a
        terminal only (nothing at all otherwise)."""
        return LiveLine(self._error_console)

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


class LiveLine:
    """One line on a terminal's stderr, redrawn in place (rich.live) and
    gone when the work ends; notes printed meanwhile go above it. With no
    terminal (`console` None) it does nothing."""

    # The line is redrawn when update() says so, not by a thread of rich's.
    def __init__(self, console) -> None:
        self._live = None
        if console is not None:
            import rich.live

            self._live = rich.live.Live(console=console, transient=True, auto_refresh=False,
                                        redirect_stdout=False, redirect_stderr=False)

    @property
    def shown(self) -> bool:
        return self._live is not None

    def __enter__(self) -> "LiveLine":
        if self._live is not None:
            self._live.start()
        return self

    def update(self, text: str) -> None:
        if self._live is not None:
            import rich.text

            self._live.update(rich.text.Text(text, style="cyan", no_wrap=True,
                                             overflow="ellipsis"), refresh=True)

    def __exit__(self, *exc) -> None:
        if self._live is not None:
            self._live.stop()


def silence_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
