"""What the exports share: wall-clock time stamps, event payloads, and
writing under a temporary name that becomes the asked-for one at the end."""

from __future__ import annotations

import contextlib
import datetime as _datetime
import json
import os
from typing import IO, Any, Dict, Iterator

from ..tools._files import check_output, open_output
from ..tools._records import SessionPath


def start_epoch_ns(header: Dict[str, Any]) -> int:
    """The session's start (wall clock, UTC) in ns since the epoch; 0 if the
    header does not say (flexiport logs carry absolute times of their own)."""
    text = header.get("start_utc") or ""
    if not isinstance(text, str) or not text:
        return 0
    text = text.strip()
    if text.endswith("Z"):
        text = text[:-1] + "+00:00"
    # fromisoformat (3.9/3.10) takes at most 6 fractional digits: split them.
    fraction_ns = 0
    main, dot, rest = text.partition(".")
    if dot:
        digits = ""
        while rest and rest[0].isdigit():
            digits += rest[0]
            rest = rest[1:]
        fraction_ns = int((digits + "000000000")[:9]) if digits else 0
        text = main + rest
    try:
        moment = _datetime.datetime.fromisoformat(text)
    except ValueError:
        return 0
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=_datetime.timezone.utc)
    return int(moment.timestamp()) * 1_000_000_000 + fraction_ns


def event_json(data: bytes) -> Any:
    """An event's payload as JSON; bytes that are not JSON as ``raw_hex``."""
    if not data:
        return {}
    try:
        return json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return {"raw_hex": data.hex()}


@contextlib.contextmanager
def replacing(dst: SessionPath) -> Iterator[IO[bytes]]:
    """A file to write that becomes `dst` only once the block completes: a
    failed or interrupted export never leaves a half-written file under the
    name asked for. Only a regular file is replaced: a symbolic link, a FIFO
    or a device at `dst` is refused (tools._files), before the work and
    again just before the rename."""
    dst = os.fspath(dst)
    check_output(dst)
    temporary = dst + ".partial"
    try:
        with open_output(temporary) as out:
            yield out
        check_output(dst)
        os.replace(temporary, dst)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise
