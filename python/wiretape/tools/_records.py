"""Reading a session for the tools and the exports: opening it, its header,
its events, its bytes as text. Every tool reads through here, so a session
is opened and described the same way everywhere."""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Optional, Union

from .. import _core

#: A session file: a ``.wtape`` or a flexiport ``name.log`` (for
#: ``name.logr`` + ``name.logw``).
SessionPath = Union[str, "os.PathLike[str]"]

DIRECTIONS = ("rx", "tx")


def open_session(path: SessionPath) -> _core.SessionReader:
    """A reader streaming the session's records; raises SessionError when
    the file cannot be read at all."""
    return _core.SessionReader(os.fspath(path))


def header_fields(reader: _core.SessionReader) -> Dict[str, Any]:
    """The session header's fields, as a dict the caller may change."""
    return dict(reader.header)


def event_of(record: _core.Record) -> Optional[Dict[str, Any]]:
    """The event's JSON object, or None for rx/tx and unparsable payloads."""
    if record.kind in DIRECTIONS:
        return None
    if not record.data:
        return {}
    try:
        value = json.loads(record.data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    return value if isinstance(value, dict) else None


def escape_bytes(data: bytes) -> str:
    """Printable ASCII kept, the rest as Python-style escapes (\\r, \\n, \\xNN)."""
    out = []
    for byte in data:
        if byte == 0x5C:
            out.append("\\\\")
        elif 0x20 <= byte < 0x7F:
            out.append(chr(byte))
        elif byte == 0x0A:
            out.append("\\n")
        elif byte == 0x0D:
            out.append("\\r")
        elif byte == 0x09:
            out.append("\\t")
        else:
            out.append(f"\\x{byte:02x}")
    return "".join(out)


def printable(data: bytes, limit: int = 64) -> str:
    """The first `limit` bytes as escape_bytes() text, and how many more there are."""
    text = escape_bytes(data[:limit])
    if len(data) > limit:
        text += f"... (+{len(data) - limit} bytes)"
    return text
