"""Exports of a session to Wireshark (pcapng) and Foxglove (mcap).

Both keep every record of the session, in order, stamped with wall-clock time
(the session's start time plus the record's offset since the device opened).

pcapng (open with Wireshark or ``tshark -r``):
  * link type ``LINKTYPE_USER0`` (147): the payload is the bytes as they
    crossed the wire, with no framing added; Wireshark shows them as data
    (hex + ASCII), or decodes them if you map DLT User 0 to a dissector
    (Preferences > Protocols > DLT_USER);
  * three interfaces: 0 ``rx`` (device to host), 1 ``tx`` (host to device)
    and 2 ``events`` (open, close, settings changes...: the payload is the
    event's name, a space and its JSON); filter with ``frame.interface_id``
    or ``frame.interface_name``;
  * each packet also carries the pcapng direction flag (inbound for rx,
    outbound for tx) and, for events, a comment;
  * timestamps in nanoseconds (``if_tsresol`` = 9); the section header's
    comment holds the session header (JSON).

mcap (open with Foxglove):
  * topics ``/wiretape/rx``, ``/wiretape/tx`` and ``/wiretape/events``;
  * message encoding ``json`` with a JSON Schema (schema encoding
    ``jsonschema``), one message per record::

        {"t_ns": 1200, "kind": "rx", "size": 3,
         "data": "AQID",            # base64 (contentEncoding: base64)
         "text": "\\x01\\x02\\x03"}  # the bytes, printable ASCII kept,
                                    # the rest escaped, for reading in
                                    # Foxglove's Raw Messages panel

    events carry their JSON object in ``event`` as well;
  * log and publish time: the record's wall-clock time in nanoseconds;
  * a metadata record ``wiretape`` holds the session header's fields.
"""

from __future__ import annotations

import base64
import contextlib
import datetime as _datetime
import json
import os
import struct
from typing import Any, Dict, Iterable, Iterator, Optional, Tuple

__all__ = ["write_pcapng", "write_mcap", "LINKTYPE_USER0", "escape_bytes"]

LINKTYPE_USER0 = 147

_PCAPNG_SHB = 0x0A0D0D0A
_PCAPNG_IDB = 0x00000001
_PCAPNG_EPB = 0x00000006
_BYTE_ORDER_MAGIC = 0x1A2B3C4D

_OPT_END = 0
_OPT_COMMENT = 1
_SHB_USERAPPL = 4
_IF_NAME = 2
_IF_DESCRIPTION = 3
_IF_TSRESOL = 9
_EPB_FLAGS = 2

_EPB_INBOUND = 0x1
_EPB_OUTBOUND = 0x2

# Interface numbers in the pcapng file.
_INTERFACES = (
    ("rx", "device to host (rx)"),
    ("tx", "host to device (tx)"),
    ("events", "port events: open, close, settings, modem lines, break"),
)
_RX_INTERFACE, _TX_INTERFACE, _EVENT_INTERFACE = 0, 1, 2


# --------------------------------------------------------------------------
# reading the session


def _open_session(src) -> Any:
    try:
        from . import _core
    except ImportError as error:  # pragma: no cover - the extension is built with the package
        raise RuntimeError(f"wiretape's extension is not available: {error}") from error
    reader_class = getattr(_core, "SessionReader", None)
    if reader_class is None:
        raise RuntimeError("this wiretape build cannot read session files (no SessionReader)")
    return reader_class(os.fspath(src))


def _header_dict(reader) -> Dict[str, Any]:
    header = getattr(reader, "header", None)
    if header is None:
        return {}
    if isinstance(header, dict):
        return dict(header)
    # An object with attributes: keep the public, plain ones.
    fields = {}
    for name in dir(header):
        if name.startswith("_"):
            continue
        value = getattr(header, name)
        if isinstance(value, (str, int, float, bool, dict, list)) or value is None:
            fields[name] = value
    return fields


def _start_epoch_ns(header: Dict[str, Any]) -> int:
    """The session's start (wall clock, UTC) in ns since the epoch; 0 if the
    header does not say (flexiport logs carry absolute times of their own)."""
    text = header.get("start_utc") or header.get("start") or ""
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


def _records(reader) -> Iterator[Tuple[int, str, bytes]]:
    for record in reader:
        kind = record.kind
        if not isinstance(kind, str):
            kind = str(kind).rsplit(".", 1)[-1]
        data = record.data
        if isinstance(data, str):
            data = data.encode("latin-1")
        yield int(record.t_ns), kind, bytes(data)


def _event_json(data: bytes) -> Any:
    if not data:
        return {}
    try:
        return json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return {"raw_hex": data.hex()}


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


# --------------------------------------------------------------------------
# pcapng


def _pad4(data: bytes) -> bytes:
    return data + b"\0" * (-len(data) % 4)


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + _pad4(value)


def _options(options: Iterable[Tuple[int, bytes]]) -> bytes:
    body = b"".join(_option(code, value) for code, value in options)
    return body + struct.pack("<HH", _OPT_END, 0) if body else b""


def _block(block_type: int, body: bytes) -> bytes:
    length = 12 + len(body)
    return struct.pack("<II", block_type, length) + body + struct.pack("<I", length)


def _section_header(comment: str) -> bytes:
    from . import __version__

    body = struct.pack("<IHHq", _BYTE_ORDER_MAGIC, 1, 0, -1)
    body += _options(
        [
            (_OPT_COMMENT, comment.encode("utf-8")),
            (_SHB_USERAPPL, f"wiretape {__version__}".encode("utf-8")),
        ]
    )
    return _block(_PCAPNG_SHB, body)


def _interface(name: str, description: str) -> bytes:
    body = struct.pack("<HHI", LINKTYPE_USER0, 0, 0)  # snaplen 0: no limit
    body += _options(
        [
            (_IF_NAME, name.encode("utf-8")),
            (_IF_DESCRIPTION, description.encode("utf-8")),
            (_IF_TSRESOL, bytes([9])),
        ]
    )
    return _block(_PCAPNG_IDB, body)


def _packet(interface: int, timestamp_ns: int, payload: bytes, flags: int,
            comment: Optional[str] = None) -> bytes:
    body = struct.pack(
        "<IIIII",
        interface,
        (timestamp_ns >> 32) & 0xFFFFFFFF,
        timestamp_ns & 0xFFFFFFFF,
        len(payload),
        len(payload),
    )
    body += _pad4(payload)
    options = []
    if flags:
        options.append((_EPB_FLAGS, struct.pack("<I", flags)))
    if comment:
        options.append((_OPT_COMMENT, comment.encode("utf-8")))
    body += _options(options)
    return _block(_PCAPNG_EPB, body)


@contextlib.contextmanager
def _replacing(dst):
    """A file to write that becomes `dst` only once the block completes: a
    failed or interrupted export never leaves a half-written file under the
    name asked for."""
    temporary = os.fspath(dst) + ".partial"
    try:
        with open(temporary, "wb") as out:
            yield out
        os.replace(temporary, dst)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise


def write_pcapng(src, dst) -> Dict[str, int]:
    """Writes the session `src` (a .wtape, or a flexiport ``name.log``) to
    `dst` as pcapng; returns counts of what was written
    (``{"rx": n, "tx": n, "events": n}``)."""
    reader = _open_session(src)
    header = _header_dict(reader)
    start_ns = _start_epoch_ns(header)
    counts = {"rx": 0, "tx": 0, "events": 0}
    with _replacing(dst) as out:
        out.write(_section_header(json.dumps(header, sort_keys=True, default=str)))
        for name, description in _INTERFACES:
            out.write(_interface(name, description))
        for t_ns, kind, data in _records(reader):
            stamp = start_ns + t_ns
            if kind == "rx":
                out.write(_packet(_RX_INTERFACE, stamp, data, _EPB_INBOUND))
                counts["rx"] += 1
            elif kind == "tx":
                out.write(_packet(_TX_INTERFACE, stamp, data, _EPB_OUTBOUND))
                counts["tx"] += 1
            else:
                event = json.dumps(_event_json(data), sort_keys=True)
                payload = f"{kind} {event}".encode("utf-8")
                out.write(_packet(_EVENT_INTERFACE, stamp, payload, 0,
                                  comment=f"wiretape event: {kind}"))
                counts["events"] += 1
    return counts


# --------------------------------------------------------------------------
# mcap

MCAP_TOPICS = {"rx": "/wiretape/rx", "tx": "/wiretape/tx", "events": "/wiretape/events"}

_BYTES_SCHEMA = {
    "title": "wiretape.Bytes",
    "description": "Bytes that crossed the wire in one direction (one record of a wiretape session)",
    "type": "object",
    "properties": {
        "t_ns": {"type": "integer", "description": "ns since the device was opened"},
        "kind": {"type": "string", "enum": ["rx", "tx"],
                 "description": "rx: device to host; tx: host to device"},
        "size": {"type": "integer", "description": "number of bytes"},
        "data": {"type": "string", "contentEncoding": "base64",
                 "description": "the bytes, base64"},
        "text": {"type": "string",
                 "description": "the bytes with printable ASCII kept and the rest escaped"},
    },
    "required": ["t_ns", "kind", "size", "data"],
}

_EVENT_SCHEMA = {
    "title": "wiretape.Event",
    "description": "A port event of a wiretape session (open, close, settings, modem lines, break...)",
    "type": "object",
    "properties": {
        "t_ns": {"type": "integer", "description": "ns since the device was opened"},
        "kind": {"type": "string", "description": "the event's name"},
        "event": {"type": "object", "description": "the event's JSON payload"},
    },
    "required": ["t_ns", "kind", "event"],
}


def write_mcap(src, dst) -> Dict[str, int]:
    """Writes the session `src` to `dst` as MCAP (see the module's text for
    the topics and encoding); returns counts of what was written."""
    try:
        from mcap.writer import Writer
    except ImportError as error:
        raise RuntimeError("the mcap export needs the 'mcap' package: pip install mcap") from error
    from . import __version__

    reader = _open_session(src)
    header = _header_dict(reader)
    start_ns = _start_epoch_ns(header)
    counts = {"rx": 0, "tx": 0, "events": 0}
    with _replacing(dst) as out:
        writer = Writer(out)
        writer.start(profile="", library=f"wiretape {__version__}")
        bytes_schema = writer.register_schema(
            name="wiretape.Bytes", encoding="jsonschema",
            data=json.dumps(_BYTES_SCHEMA).encode("utf-8"))
        event_schema = writer.register_schema(
            name="wiretape.Event", encoding="jsonschema",
            data=json.dumps(_EVENT_SCHEMA).encode("utf-8"))
        channels = {
            "rx": writer.register_channel(topic=MCAP_TOPICS["rx"], message_encoding="json",
                                          schema_id=bytes_schema),
            "tx": writer.register_channel(topic=MCAP_TOPICS["tx"], message_encoding="json",
                                          schema_id=bytes_schema),
            "events": writer.register_channel(topic=MCAP_TOPICS["events"],
                                              message_encoding="json",
                                              schema_id=event_schema),
        }
        sequence = 0
        for t_ns, kind, data in _records(reader):
            if kind in ("rx", "tx"):
                channel = channels[kind]
                message = {"t_ns": t_ns, "kind": kind, "size": len(data),
                           "data": base64.b64encode(data).decode("ascii"),
                           "text": escape_bytes(data)}
                counts[kind] += 1
            else:
                channel = channels["events"]
                message = {"t_ns": t_ns, "kind": kind, "event": _event_json(data)}
                counts["events"] += 1
            stamp = start_ns + t_ns
            writer.add_message(channel_id=channel, log_time=stamp, publish_time=stamp,
                               data=json.dumps(message).encode("utf-8"), sequence=sequence)
            sequence += 1
        writer.add_metadata(
            name="wiretape",
            data={key: value if isinstance(value, str) else json.dumps(value, default=str)
                  for key, value in header.items()})
        writer.finish()
    return counts
