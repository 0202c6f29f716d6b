"""``wiretape show --textconv``: a session as text for git's ``textconv``
(docs/cli.md, "textconv"), so that ``git diff`` of two recordings of the
same run shows only what really changed.

It is ``show``'s timeline without what differs between any two files: the
file's name (git hands over a temporary copy, whose name changes on every
run) is left out, and with ``start=False`` so are the start time and the
host, which differ between two recordings of one run, and with
``times=False`` each record's time (a run recorded again differs in every
time stamp, by a little). Every byte of every record is shown (show cuts
payloads at 64 bytes), 64 bytes a line, so that a changed byte shows in the
diff as the one line holding it. A damaged file is
shown up to the damage, which is a line of the text: git still shows the
diff.
"""

from __future__ import annotations

import os
import re
import sys
from typing import IO, Optional, Tuple

from .. import _core
from ..session import SessionPath
from .show import show_reporting_damage

__all__ = ["textconv"]

#: What stands for the file's name where show would print it.
FILE_PLACEHOLDER = "FILE"

# A record line of show's timeline starts with its time: "+0.000123s  ".
_RECORD_TIME = re.compile(r"^[+-]\d+\.\d+s  ")

#: Payload bytes a line: a long payload goes on over lines of its own.
BYTES_PER_LINE = 64


class _StableLines:
    """A text stream that passes show's lines on, less the file's name and,
    if asked, the start time and host."""

    def __init__(self, out: IO[str], path: str, start: bool, times: bool):
        self._out = out
        self._path = path
        self._start = start
        self._times = times
        self._pending = ""
        self._in_header = True
        # How much of the last record line its time took: its payload's
        # further lines are indented under it, and lose as much.
        self._time_width = 0

    def write(self, text: str) -> int:
        self._pending += text
        while "\n" in self._pending:
            line, self._pending = self._pending.split("\n", 1)
            self._line(line)
        return len(text)

    def _line(self, line: str) -> None:
        if self._in_header:
            if line == "":
                self._in_header = False
            elif line.startswith("session "):
                return
            elif not self._start and line.lstrip().startswith("started "):
                return
        elif not self._times:
            time = _RECORD_TIME.match(line)
            if time:
                self._time_width = time.end()
                line = line[time.end():]
            else:
                # (a hex dump's lines are indented less than any time)
                continued = self._time_width and line.startswith(" " * self._time_width)
                line = line[self._time_width:] if continued else line
        if self._path:
            line = line.replace(self._path, FILE_PLACEHOLDER)
        self._out.write(line + "\n")

    def flush(self) -> None:
        if self._pending:
            self._line(self._pending)
            self._pending = ""
        self._out.flush()


def textconv(path: SessionPath, fmt: str = "text", start: bool = True, times: bool = True,
             out: Optional[IO[str]] = None) -> Tuple[int, Optional[_core.SessionError]]:
    """Writes the session's timeline for a diff to `out` (default stdout):
    ``show`` in `fmt` (text or hex) less the file's name, less the start
    time and host when `start` is false, and less each record's time when
    `times` is false. Returns the number of records and
    the damage (None for an intact file), which the text also names."""
    if fmt not in ("text", "hex"):
        raise ValueError(f"textconv shows text or hex, not {fmt!r}")
    stable = _StableLines(out if out is not None else sys.stdout, os.fspath(path), start,
                          times)
    try:
        return show_reporting_damage(path, fmt=fmt, out=stable,  # type: ignore[arg-type]
                                     wrap=BYTES_PER_LINE)
    finally:
        stable.flush()
