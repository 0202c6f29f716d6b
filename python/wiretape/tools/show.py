"""``wiretape show``: a session's timeline for people (text, hex) and
programs (jsonl).

Streams the session (a ``.wtape`` file or a flexiport ``name.log``): memory
does not grow with the file's size.
"""

from __future__ import annotations

import json
import os
import sys
from typing import IO, Iterator, Optional, Tuple

from .. import _core
from ..exports.jsonl import json_line, record_to_json
from ..session import DIRECTIONS as _DIRECTIONS
from ..session import SessionPath, event_of, event_payload, header_text, open_session
from ..session import printable as _printable

__all__ = ["show", "show_reporting_damage"]


def _seconds(t_ns: int) -> str:
    return f"{t_ns / 1e9:+.6f}s"


def _header_lines(reader: _core.SessionReader, path: SessionPath) -> Iterator[str]:
    """The header for people; every field from the file goes through
    header_text() (the file may hold terminal escape sequences)."""
    header = reader.header
    yield f"session {os.fspath(path)}"
    if header.version_major == 0:
        yield "  format       flexiport log (name.logr + name.logw)"
    else:
        yield f"  format       wiretape {header.version_major}.{header.version_minor}"
    if header.source_format != "wiretape":
        files = ", ".join(header_text(name) for name in header.source_files)
        details = ", ".join(f"{header_text(key)}: {header_text(value)}"
                            for key, value in sorted(header.source_details.items()))
        yield (f"  imported     from {header_text(header.source_format)}"
               + (f" ({files})" if files else "") + (f"; {details}" if details else ""))
    if header.port_type or header.port_options:
        yield f"  port         {header_text(header.port_type or '?')}: {header_text(header.port_options)}"
    if header.device_address:
        yield f"  device       {header_text(header.device_address)}"
    # The members as the header names them, in its order; those not known
    # left out.
    identity = ", ".join(f"{name}={header_text(value)}"
                         for name, value in header.device_identity.items() if value)
    if identity:
        yield f"  identity     {identity}"
    yield f"  capture      {header_text(header.capture)}"
    started = header_text(header.start_utc) if header.start_utc else "at a time not recorded"
    host = f" on {header_text(header.host)}" if header.host else ""
    yield f"  started      {started}{host}"
    if header.wiretape_version:
        yield f"  written by   wiretape {header_text(header.wiretape_version)}"
    for edit in header.edits:
        yield f"  edited       {header_text(edit)}"
    for key, value in sorted(header.metadata.items()):
        yield f"  meta         {header_text(key)}={header_text(value)}"


def _hexdump(data: bytes) -> Iterator[str]:
    for offset in range(0, len(data), 16):
        chunk = data[offset:offset + 16]
        hex_part = " ".join(f"{b:02x}" for b in chunk)
        text = "".join(chr(b) if 0x20 <= b < 0x7F else "." for b in chunk)
        yield f"    {offset:08x}  {hex_part:<47}  |{text}|"


def show(path: SessionPath, fmt: str = "text", profile: Optional[str] = None,
         out: Optional[IO[str]] = None, decode: Optional[str] = None) -> int:
    """Prints the session's timeline to ``out`` (default stdout).

    ``fmt``: ``text`` (one line per record), ``hex`` (a hex dump of each
    record) or ``jsonl`` (one JSON object per record: ``t_ns``, ``kind``,
    ``size``, ``data_hex``, and ``event`` for events). ``profile`` (text
    format) names a protocol profile (``_core.profile_names()``; ``scip`` for
    Hokuyo SCIP 2.0): the byte streams are cut into the protocol's frames,
    however the recording split them, and each frame is named. ``decode`` is
    the older name of ``profile``. Returns the number of records shown; a
    damaged file is reported at the end (on stderr for jsonl) and everything
    before the damage is shown.
    """
    return show_reporting_damage(path, fmt, profile, out, decode)[0]


def show_reporting_damage(path: SessionPath, fmt: str = "text", profile: Optional[str] = None,
                          out: Optional[IO[str]] = None, decode: Optional[str] = None,
                          wrap: Optional[int] = None
                          ) -> Tuple[int, Optional[_core.SessionError]]:
    """show(), and the damage reading stopped at (None for an intact
    session): what the command line's exit code needs, without a second
    reading, which a pipe or FIFO would not allow. With `wrap` (text format,
    for textconv), every byte of a payload is shown, `wrap` bytes a line,
    the lines after the first indented under it."""
    if fmt not in ("text", "hex", "jsonl"):
        raise ValueError(f"unknown format {fmt!r}: use text, hex or jsonl")
    if profile is not None and decode is not None and profile != decode:
        raise ValueError(f"profile={profile!r} and decode={decode!r} disagree: give one")
    profile = profile if profile is not None else decode
    framing = _core.find_profile(profile) if profile is not None else None
    out = out if out is not None else sys.stdout
    reader = open_session(path)
    count = 0
    if fmt == "jsonl":
        for record in reader:
            out.write(json_line(record_to_json(record)))
            count += 1
        if reader.damage is not None:
            print(f"wiretape: damaged: {header_text(reader.damage.message)}", file=sys.stderr)
        return count, reader.damage
    for line in _header_lines(reader, path):
        out.write(line + "\n")
    out.write("\n")
    if framing is not None and fmt == "text":
        records = _counting(reader)
        for t_ns, kind, data, description in framing.decode_session(records):
            if description is None:
                event = event_payload(data)
                description = json.dumps(event) if event else ""
            out.write(f"{_seconds(t_ns)}  {kind}  {description}\n")
        count = records.count
    else:
        for record in reader:
            count += 1
            size = f"{len(record.data):>6} B"
            if record.kind in _DIRECTIONS:
                arrow = "<-" if record.kind == "rx" else "->"
                text = (_printable(record.data) if wrap is None
                        else _printable(record.data[:wrap], wrap))
                summary = f"{arrow} {text}" if fmt == "text" else ""
                line = f"{_seconds(record.t_ns)}  {record.kind:<17} {size}  "
                out.write(f"{line}{summary}\n".rstrip() + "\n")
                if fmt == "text" and wrap is not None:
                    for at in range(wrap, len(record.data), wrap):
                        more = record.data[at:at + wrap]
                        out.write(" " * (len(line) + 3) + _printable(more, len(more)) + "\n")
                if fmt == "hex":
                    for line in _hexdump(record.data):
                        out.write(line + "\n")
            else:
                event = event_of(record)
                text = json.dumps(event, separators=(",", ":")) if event is not None else _printable(record.data)
                out.write(f"{_seconds(record.t_ns)}  {record.kind:<17} {'':>8}  {text}\n".rstrip() + "\n")
    if reader.damage is not None:
        out.write(f"\nDAMAGED at byte {reader.damage.offset}: "
                  f"{header_text(reader.damage.message)}\n")
    else:
        out.write(f"\n{count} records\n")
    return count, reader.damage


class _counting:
    """Iterates records and counts them."""

    def __init__(self, records):
        self._records = records
        self.count = 0

    def __iter__(self):
        for record in self._records:
            self.count += 1
            yield record
