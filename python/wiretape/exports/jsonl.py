"""The JSON Lines form of a session: a first line ``{"header": {...}}``, then
one JSON object per record, as ``wiretape show --format jsonl`` prints it
(``t_ns``, ``kind``, ``size``, ``data_hex`` and, for events, ``event``).
A session of named channels (its header has ``channels``) gives each
record its channel's name as ``channel``; a session without them is
written as before, without that member.
``wiretape convert`` reads it back (wiretape.tools.convert)."""

from __future__ import annotations

import json
from typing import Any, Dict, Iterable, Mapping, Optional

from .. import _core
from ..session import SessionPath, event_of, open_output
from ._common import exported_header

__all__ = ["write_records", "record_to_json", "channel_names"]


def record_to_json(record: _core.Record, channel: Optional[str] = None) -> Dict[str, Any]:
    """The JSON object of one record: ``t_ns``, ``kind``, ``size``,
    ``data_hex``, for events ``event``, and ``channel`` when given (the
    name of the record's channel, in a session of named channels)."""
    out: Dict[str, Any] = {
        "t_ns": record.t_ns,
        "kind": record.kind,
        "size": len(record.data),
        "data_hex": record.data.hex(),
    }
    event = event_of(record)
    if event is not None:
        out["event"] = event
    if channel is not None:
        out["channel"] = channel
    return out


def channel_names(header: Mapping[str, Any]) -> Optional[Dict[int, str]]:
    """Channel id to name for a header (as to_dict gives it) of named
    channels; None for a session without them (one unnamed channel)."""
    channels = header.get("channels") or []
    if not channels:
        return None
    return {channel["id"]: channel["name"] for channel in channels}


def json_line(value: Dict[str, Any]) -> str:
    """One line of the file: compact JSON and a newline."""
    return json.dumps(value, separators=(",", ":")) + "\n"


def write_records(dst: SessionPath, header: Dict[str, Any],
                  records: Iterable[_core.Record]) -> int:
    """Writes `header` and `records` to `dst`; returns the number of records.
    The file is written as it goes: what came before a failure stays."""
    count = 0
    header = exported_header(header)
    names = channel_names(header)
    with open_output(dst, text=True) as out:
        out.write(json_line({"header": header}))
        for record in records:
            # A reader gives no record of a channel its header does not list.
            channel = names[record.channel] if names is not None else None
            out.write(json_line(record_to_json(record, channel)))
            count += 1
    return count

