"""The MCAP export (Foxglove); see the package's text for the topics and
the message encoding."""

from __future__ import annotations

import base64
import json
from typing import Any, Dict

from .._core import __version__
from ..session import (DIRECTIONS, SessionPath, escape_bytes, header_fields, open_session,
                       raise_damage, refuse_same_file, session_files)
from ._common import event_json, replacing, start_epoch_ns

__all__ = ["write_mcap", "MCAP_TOPICS", "channel_topic"]

MCAP_TOPICS = {"rx": "/wiretape/rx", "tx": "/wiretape/tx", "events": "/wiretape/events"}

_BYTES_SCHEMA = {
    "title": "wiretape.Bytes",
    "description": "Bytes that crossed the wire in one direction (one record of a wiretape session)",
    "type": "object",
    "properties": {
        "t_ns": {"type": "integer", "description": "ns since the device was opened"},
        "kind": {"type": "string", "enum": list(DIRECTIONS),
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


# A session of named channels (DESIGN §19): one mcap channel per session
# channel, so one schema for both kinds of record: a record's ``kind`` says
# which members it has (those of wiretape.Bytes or of wiretape.Event).
_RECORD_SCHEMA = {
    "title": "wiretape.Record",
    "description": "One record of a channel of a wiretape session: bytes that crossed "
                   "(kind rx or tx) or a port event",
    "type": "object",
    "properties": {
        **_BYTES_SCHEMA["properties"],
        "kind": {"type": "string",
                 "description": "rx: device to host; tx: host to device; else the event's name"},
        "channel": {"type": "string", "description": "the session channel's name"},
        "event": _EVENT_SCHEMA["properties"]["event"],
    },
    "required": ["t_ns", "kind", "channel"],
}


def channel_topic(name: str) -> str:
    """The mcap topic of the session channel `name`."""
    return f"/wiretape/{name}"


def _message(t_ns: int, kind: str, data: bytes) -> Dict[str, Any]:
    if kind in DIRECTIONS:
        return {"t_ns": t_ns, "kind": kind, "size": len(data),
                "data": base64.b64encode(data).decode("ascii"), "text": escape_bytes(data)}
    return {"t_ns": t_ns, "kind": kind, "event": event_json(data)}


def write_mcap(src: SessionPath, dst: SessionPath) -> Dict[str, int]:
    """Writes the session `src` to `dst` as MCAP (see wiretape.exports for
    the topics and encoding); returns counts of what was written. A damaged
    session is written up to the damage, then its SessionError is raised."""
    try:
        from mcap.writer import Writer
    except ImportError as error:
        raise RuntimeError("the mcap export needs the 'mcap' package: pip install mcap") from error

    refuse_same_file(session_files(src), [dst])
    reader = open_session(src)
    header = header_fields(reader)
    start_ns = start_epoch_ns(header)
    counts = {"rx": 0, "tx": 0, "events": 0}
    with replacing(dst) as out:
        writer = Writer(out)
        writer.start(profile="", library=f"wiretape {__version__}")
        if header.get("channels"):
            record_schema = writer.register_schema(
                name="wiretape.Record", encoding="jsonschema",
                data=json.dumps(_RECORD_SCHEMA).encode("utf-8"))
            by_channel = {
                channel["id"]: (channel["name"], writer.register_channel(
                    topic=channel_topic(channel["name"]), message_encoding="json",
                    schema_id=record_schema,
                    metadata={"port_type": str(channel.get("port_type") or ""),
                              "port_options": str(channel.get("port_options") or "")}))
                for channel in header["channels"]}
        else:
            bytes_schema = writer.register_schema(
                name="wiretape.Bytes", encoding="jsonschema",
                data=json.dumps(_BYTES_SCHEMA).encode("utf-8"))
            event_schema = writer.register_schema(
                name="wiretape.Event", encoding="jsonschema",
                data=json.dumps(_EVENT_SCHEMA).encode("utf-8"))
            by_kind = {
                "rx": writer.register_channel(topic=MCAP_TOPICS["rx"], message_encoding="json",
                                              schema_id=bytes_schema),
                "tx": writer.register_channel(topic=MCAP_TOPICS["tx"], message_encoding="json",
                                              schema_id=bytes_schema),
                "events": writer.register_channel(topic=MCAP_TOPICS["events"],
                                                  message_encoding="json",
                                                  schema_id=event_schema),
            }
        sequence = 0
        for record in reader:
            t_ns, kind, data = record.t_ns, record.kind, record.data
            message = _message(t_ns, kind, data)
            counts[kind if kind in DIRECTIONS else "events"] += 1
            if header.get("channels"):
                name, mcap_channel = by_channel[record.channel]
                message["channel"] = name
            else:
                mcap_channel = by_kind[kind if kind in DIRECTIONS else "events"]
            stamp = start_ns + t_ns
            writer.add_message(channel_id=mcap_channel, log_time=stamp, publish_time=stamp,
                               data=json.dumps(message).encode("utf-8"), sequence=sequence)
            sequence += 1
        writer.add_metadata(
            name="wiretape",
            data={key: value if isinstance(value, str) else json.dumps(value, default=str)
                  for key, value in header.items()})
        writer.finish()
    raise_damage(reader)  # after the rename: the export keeps what came before
    return counts
