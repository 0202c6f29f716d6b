"""What the exports share: wall-clock time stamps, event payloads, and
writing under a temporary name that becomes the asked-for one at the end."""

from __future__ import annotations

import contextlib
import json
import os
from typing import IO, Any, Dict, Iterator

from .. import _core
from ..session import (SessionPath, check_output, check_regular_output, is_written_through,
                       open_output, open_regular_output)


def start_epoch_ns(header: Dict[str, Any]) -> int:
    """The session's start (wall clock, UTC) in ns since the epoch, read by
    the session model's rule (``_core.parse_start_utc``); 0 if the header
    does not say or says what no header may (flexiport logs carry absolute
    times of their own)."""
    text = header.get("start_utc") or ""
    if not isinstance(text, str) or not text:
        return 0
    try:
        start = _core.parse_start_utc(text)
    except _core.OptionError:
        return 0
    return start if start is not None else 0


def event_json(data: bytes) -> Any:
    """An event's payload as JSON; bytes that are not JSON as ``raw_hex``."""
    if not data:
        return {}
    try:
        return json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return {"raw_hex": data.hex()}


class _CountingPosition:
    """A FIFO or device written through, whose tell() is the number of bytes
    written: writers that note offsets (mcap) need it, and such a file
    cannot tell where it is."""

    def __init__(self, out: IO[bytes]):
        self._out = out
        self._position = 0

    def write(self, data) -> int:
        written = self._out.write(data)
        self._position += len(data)
        return written

    def tell(self) -> int:
        return self._position

    def flush(self) -> None:
        self._out.flush()


@contextlib.contextmanager
def replacing(dst: SessionPath) -> Iterator[IO[bytes]]:
    """A file to write that becomes `dst` only once the block completes: a
    failed or interrupted export never leaves a half-written file under the
    name asked for (DESIGN §6, "Special files"). A regular file is replaced
    by renaming; through a symbolic link, the link's target is (the link
    stays). What is not a regular file (a FIFO, a device) is written through,
    in place, never renamed over. A directory or a socket is refused
    (session.py)."""
    dst = os.fspath(dst)
    check_output(dst)
    if is_written_through(dst):
        with open_output(dst) as out:
            yield _CountingPosition(out)  # type: ignore[misc]
        return
    target = os.path.realpath(dst)
    temporary = target + ".partial"
    try:
        handle = open_regular_output(temporary)
    except OSError as error:
        if error.errno is None or error.filename != temporary:
            raise
        # The user never typed the .partial name: theirs is the one to name.
        raise OSError(error.errno, error.strerror, dst) from None
    try:
        with handle as out:
            yield out
        check_regular_output(target)  # nothing else appeared there meanwhile
        os.replace(temporary, target)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise
