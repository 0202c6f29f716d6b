"""Reading session files for people and programs: show, stats, verify.

Every function takes a ``.wtape`` file or a flexiport log (``name.log`` for
``name.logr`` + ``name.logw``) and streams it: memory does not grow with the
file's size.
"""

from __future__ import annotations

import json
import os
import sys
from typing import IO, Iterable, Iterator, Optional

from . import _core

__all__ = ["show", "stats", "verify", "record_to_json", "SCIP_COMMANDS"]

_DIRECTIONS = ("rx", "tx")


def _reader(path) -> "_core.SessionReader":
    return _core.SessionReader(os.fspath(path))


def _event(record) -> Optional[dict]:
    """The event's JSON object, or None for rx/tx and unparsable payloads."""
    if record.kind in _DIRECTIONS:
        return None
    if not record.data:
        return {}
    try:
        value = json.loads(record.data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    return value if isinstance(value, dict) else None


def record_to_json(record) -> dict:
    """The JSON object of one record as ``show(fmt="jsonl")`` prints it:
    ``t_ns``, ``kind``, ``size``, ``data_hex`` and, for events, ``event``."""
    out = {
        "t_ns": record.t_ns,
        "kind": record.kind,
        "size": len(record.data),
        "data_hex": record.data.hex(),
    }
    event = _event(record)
    if event is not None:
        out["event"] = event
    return out


def _printable(data: bytes, limit: int = 64) -> str:
    """The bytes as text: printable ASCII kept, the rest escaped."""
    parts = []
    for byte in data[:limit]:
        if byte == 0x0A:
            parts.append("\\n")
        elif byte == 0x0D:
            parts.append("\\r")
        elif byte == 0x09:
            parts.append("\\t")
        elif byte == 0x5C:
            parts.append("\\\\")
        elif 0x20 <= byte < 0x7F:
            parts.append(chr(byte))
        else:
            parts.append(f"\\x{byte:02x}")
    text = "".join(parts)
    if len(data) > limit:
        text += f"... (+{len(data) - limit} bytes)"
    return text


def _seconds(t_ns: int) -> str:
    return f"{t_ns / 1e9:+.6f}s"


def _header_lines(reader, path) -> Iterator[str]:
    header = reader.header
    yield f"session {os.fspath(path)}"
    if header["source_format"] == "flexiport":
        yield "  format       flexiport log (name.logr + name.logw)"
        meta = json.loads(header["metadata_json"] or "{}")
        yield (
            f"  flexiport    reads: {meta.get('flexiport_read_format', '?')} format, "
            f"writes: {meta.get('flexiport_write_format', '?')} format"
        )
        return
    yield f"  format       wiretape {header['version_major']}.{header['version_minor']}"
    yield f"  port         {header['port_type'] or '?'}: {header['port_options']}"
    yield f"  capture      {header['capture']}"
    yield f"  started      {header['start_utc']} on {header['host'] or '?'}"
    yield f"  written by   wiretape {header['wiretape_version']}"
    for key, value in sorted(header["metadata"].items()):
        yield f"  meta         {key}={value}"


def _hexdump(data: bytes) -> Iterator[str]:
    for offset in range(0, len(data), 16):
        chunk = data[offset:offset + 16]
        hex_part = " ".join(f"{b:02x}" for b in chunk)
        text = "".join(chr(b) if 0x20 <= b < 0x7F else "." for b in chunk)
        yield f"    {offset:08x}  {hex_part:<47}  |{text}|"


# --- SCIP 2.0 (Hokuyo laser scanners) ---------------------------------------

SCIP_COMMANDS = {
    "VV": "version information",
    "PP": "sensor parameters",
    "II": "sensor state",
    "BM": "laser on",
    "QT": "laser off",
    "RS": "reset",
    "RT": "partial reset",
    "TM": "time synchronisation",
    "CR": "motor speed",
    "SS": "bit rate",
    "HS": "high sensitivity",
    "GD": "single scan (3-character ranges)",
    "GS": "single scan (2-character ranges)",
    "GE": "single scan with intensities",
    "MD": "continuous scans (3-character ranges)",
    "MS": "continuous scans (2-character ranges)",
    "ME": "continuous scans with intensities",
    "SC": "SCIP 1.1 switch",
}


def _scip_describe(direction: str, message: bytes) -> str:
    lines = message.split(b"\n")
    echo = lines[0].decode("ascii", "replace")
    name = "SCIP2.0" if echo.startswith("SCIP2.0") else echo[:2]
    meaning = "switch to SCIP 2.0" if name == "SCIP2.0" else SCIP_COMMANDS.get(name, "unknown command")
    if direction == "tx":
        command = _printable(message.rstrip(b"\n"), 40)
        return f"{command:<24} {name}: {meaning}"
    status = lines[1].decode("ascii", "replace")[:2] if len(lines) > 1 else "??"
    body = [line for line in lines[2:] if line]
    status_text = {"00": "ok", "99": "scan data"}.get(status, "status")
    return (
        f"{_printable(lines[0], 24):<24} reply to {name} ({meaning}): "
        f"{status_text} {status}, {len(body)} data lines, {len(message)} bytes"
    )


def _scip_messages(records: Iterable) -> Iterator[tuple]:
    """SCIP messages of both directions, re-assembled from the records
    however the recording split them: a command ends with LF, a reply with
    an empty line (LF LF). Yields (t_ns of the first byte, kind, bytes) and
    events as (t_ns, kind, record)."""
    pending = {"rx": bytearray(), "tx": bytearray()}
    started = {"rx": 0, "tx": 0}
    for record in records:
        kind = record.kind
        if kind not in _DIRECTIONS:
            yield record.t_ns, kind, record
            continue
        buffer = pending[kind]
        for byte in record.data:
            if not buffer:
                started[kind] = record.t_ns
            buffer.append(byte)
            done = (
                buffer.endswith(b"\n\n") if kind == "rx" else buffer.endswith(b"\n")
            ) or (kind == "rx" and buffer == b"\n")
            if done:
                yield started[kind], kind, bytes(buffer)
                buffer.clear()
    for kind, buffer in pending.items():
        if buffer:
            yield started[kind], kind, bytes(buffer)


def show(path, fmt: str = "text", decode: Optional[str] = None, out: Optional[IO[str]] = None) -> int:
    """Prints the session's timeline to ``out`` (default stdout).

    ``fmt``: ``text`` (one line per record), ``hex`` (a hex dump of each
    record) or ``jsonl`` (one JSON object per record: ``t_ns``, ``kind``,
    ``size``, ``data_hex``, and ``event`` for events). ``decode="scip"``
    re-assembles Hokuyo SCIP 2.0 commands and replies (text format). Returns
    the number of records shown; a damaged file is reported at the end (on
    stderr for jsonl) and everything before the damage is shown.
    """
    if fmt not in ("text", "hex", "jsonl"):
        raise ValueError(f"unknown format {fmt!r}: use text, hex or jsonl")
    if decode not in (None, "scip"):
        raise ValueError(f"unknown decoder {decode!r}: the decoder available is scip")
    out = out if out is not None else sys.stdout
    reader = _reader(path)
    count = 0
    if fmt == "jsonl":
        for record in reader:
            out.write(json.dumps(record_to_json(record), separators=(",", ":")) + "\n")
            count += 1
        if reader.damage is not None:
            print(f"wiretape: damaged: {reader.damage.message}", file=sys.stderr)
        return count
    for line in _header_lines(reader, path):
        out.write(line + "\n")
    out.write("\n")
    if decode == "scip" and fmt == "text":
        records = _counting(reader)
        for t_ns, kind, item in _scip_messages(records):
            if kind in _DIRECTIONS:
                out.write(f"{_seconds(t_ns)}  {kind}  {_scip_describe(kind, item)}\n")
            else:
                event = _event(item)
                text = json.dumps(event) if event else ""
                out.write(f"{_seconds(t_ns)}  {kind}  {text}\n")
        count = records.count
    else:
        for record in reader:
            count += 1
            size = f"{len(record.data):>6} B"
            if record.kind in _DIRECTIONS:
                arrow = "<-" if record.kind == "rx" else "->"
                summary = f"{arrow} {_printable(record.data)}" if fmt == "text" else ""
                out.write(f"{_seconds(record.t_ns)}  {record.kind:<17} {size}  {summary}\n".rstrip() + "\n")
                if fmt == "hex":
                    for line in _hexdump(record.data):
                        out.write(line + "\n")
            else:
                event = _event(record)
                text = json.dumps(event, separators=(",", ":")) if event is not None else _printable(record.data)
                out.write(f"{_seconds(record.t_ns)}  {record.kind:<17} {'':>8}  {text}\n".rstrip() + "\n")
    if reader.damage is not None:
        out.write(f"\nDAMAGED at byte {reader.damage.offset}: {reader.damage.message}\n")
    else:
        out.write(f"\n{count} records\n")
    return count


class _counting:
    """Iterates records and counts them."""

    def __init__(self, records):
        self._records = records
        self.count = 0

    def __iter__(self):
        for record in self._records:
            self.count += 1
            yield record


def stats(path) -> dict:
    """Figures of a session: ``records``, ``rx_records``, ``tx_records``,
    ``event_records``, ``rx_bytes``, ``tx_bytes``, ``duration_s`` (first to
    last record), ``first_t_ns``, ``last_t_ns``, ``events`` (count per
    kind), ``damaged`` (and ``damage_offset``, ``damage_message``), plus the
    header's fields (``capture``, ``port_type``, ``port_options``,
    ``start_utc``, ``host``, ``wiretape_version``, ``metadata``,
    ``source_format``)."""
    reader = _reader(path)
    result = {
        "path": os.fspath(path),
        "records": 0,
        "rx_records": 0,
        "tx_records": 0,
        "event_records": 0,
        "rx_bytes": 0,
        "tx_bytes": 0,
        "first_t_ns": None,
        "last_t_ns": None,
        "duration_s": 0.0,
        "events": {},
    }
    first = last = None
    for record in reader:
        result["records"] += 1
        if first is None:
            first = record.t_ns
        first = min(first, record.t_ns)
        last = record.t_ns if last is None else max(last, record.t_ns)
        if record.kind in _DIRECTIONS:
            result[f"{record.kind}_records"] += 1
            result[f"{record.kind}_bytes"] += len(record.data)
        else:
            result["event_records"] += 1
            result["events"][record.kind] = result["events"].get(record.kind, 0) + 1
    if first is not None:
        result["first_t_ns"] = first
        result["last_t_ns"] = last
        result["duration_s"] = (last - first) / 1e9
    header = reader.header
    for key in ("capture", "port_type", "port_options", "start_utc", "host",
                "wiretape_version", "source_format", "version_major", "version_minor"):
        result[key] = header[key]
    result["metadata"] = dict(header["metadata"])
    damage = reader.damage
    result["damaged"] = damage is not None
    result["damage_offset"] = damage.offset if damage is not None else None
    result["damage_message"] = damage.message if damage is not None else None
    return result


def verify(path) -> dict:
    """Checks every record's CRC and length. Never raises for a bad file:
    returns ``{"ok", "path", "records", "offset", "message"}`` where
    ``offset``/``message`` say where and why reading stopped (None if ok)."""
    result = {"ok": True, "path": os.fspath(path), "records": 0, "offset": None, "message": None}
    try:
        reader = _reader(path)
    except _core.SessionError as error:
        result.update(ok=False, offset=error.offset, message=str(error))
        return result
    for _ in reader:
        result["records"] += 1
    if reader.damage is not None:
        result.update(ok=False, offset=reader.damage.offset, message=reader.damage.message)
    return result
