"""``wiretape show``: a session's timeline for people (text, hex) and
programs (jsonl).

Streams the session (a ``.wtape`` file or a flexiport ``name.log``): memory
does not grow with the file's size.
"""

from __future__ import annotations

import json
import os
import sys
from typing import IO, Iterable, Iterator, Optional

from .. import _core
from ..exports.jsonl import json_line, record_to_json
from ._records import DIRECTIONS as _DIRECTIONS
from ._records import SessionPath, event_of, header_fields, open_session
from ._records import printable as _printable

__all__ = ["show", "SCIP_COMMANDS"]


def _seconds(t_ns: int) -> str:
    return f"{t_ns / 1e9:+.6f}s"


def _header_lines(reader: _core.SessionReader, path: SessionPath) -> Iterator[str]:
    header = header_fields(reader)
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


# ============================================================================
# SCIP 2.0 decoding (Hokuyo laser scanners), for --decode scip. This block
# stands alone: it goes when the C++ protocol profile of SCIP decodes for
# show.
# ============================================================================

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


# ============================================================================
# end of SCIP 2.0 decoding
# ============================================================================


def show(path: SessionPath, fmt: str = "text", decode: Optional[str] = None,
         out: Optional[IO[str]] = None) -> int:
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
    reader = open_session(path)
    count = 0
    if fmt == "jsonl":
        for record in reader:
            out.write(json_line(record_to_json(record)))
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
                event = event_of(item)
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
                event = event_of(record)
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
