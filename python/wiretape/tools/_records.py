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

#: The record kinds that carry bytes (rx, tx); every other kind is an event.
DIRECTIONS = tuple(kind["name"] for kind in _core.RECORD_KINDS if not kind["is_event"])


def open_session(path: SessionPath) -> _core.SessionReader:
    """A reader streaming the session's records.

    The rule for damaged input, the same in every command (docs/cli.md):
    a file that cannot be opened or read (missing, permission denied, neither
    a regular file nor a pipe or FIFO, which is read as a stream) raises
    PortError here, an OSError: exit 3. A file that is
    not a session, or is damaged, is read up to the damage, every record
    before it is used (shown, counted, compared, converted), and then
    raise_damage() raises the damage, a SessionError: exit 1
    (cli.exit_code_for maps both)."""
    return _core.SessionReader(os.fspath(path))


def raise_damage(reader: _core.SessionReader) -> None:
    """Raises the session's damage (SessionError, exit 1), if reading it
    stopped at some; call it once the records before the damage are used."""
    damage = reader.damage
    if damage is not None:
        raise damage


def header_fields(reader: _core.SessionReader) -> Dict[str, Any]:
    """The session header's fields as a dict the caller may change, for
    output as JSON (exports, jsonl); read ``reader.header``'s attributes
    otherwise."""
    return dict(reader.header.to_dict())


def event_of(record: _core.Record) -> Optional[Dict[str, Any]]:
    """The event's JSON object, or None for rx/tx and unparsable payloads."""
    if record.kind in DIRECTIONS:
        return None
    return event_payload(record.data)


def event_payload(data: bytes) -> Optional[Dict[str, Any]]:
    """An event record's payload as a JSON object ({} when empty), or None
    when it is not one."""
    if not data:
        return {}
    try:
        value = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    return value if isinstance(value, dict) else None


def escape_bytes(data: bytes) -> str:
    """Printable ASCII kept, the rest as escapes (\\r, \\n, \\xNN): safe on a
    terminal (C++'s escape_bytes, as in mismatch reports)."""
    return _core.escape_bytes(bytes(data), len(data))


def header_text(value: object) -> str:
    """A session header's text (port options, host, metadata keys and
    values...) as it may reach a terminal: the only way header text is
    printed. The file is anyone's, so every character that is not printable
    (control characters such as ESC, DEL, C1 controls, bidirectional
    overrides, line separators) and the backslash are escaped as payload
    bytes are (escape_bytes of their UTF-8: ``\\x1b``, ``\\n``, ``\\\\``);
    printable letters of any script are kept."""
    text = value if isinstance(value, str) else str(value)
    if text.isprintable() and "\\" not in text:
        return text
    return "".join(
        char if char.isprintable() and char != "\\"
        else escape_bytes(char.encode("utf-8", "surrogatepass"))
        for char in text
    )


def printable(data: bytes, limit: int = 64) -> str:
    """The first `limit` bytes as escape_bytes() text, and how many more there are."""
    return _core.escape_bytes(bytes(data), limit)
