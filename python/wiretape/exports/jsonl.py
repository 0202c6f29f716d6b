"""The JSON Lines form of a session: a first line ``{"header": {...}}``, then
one JSON object per record, as ``wiretape show --format jsonl`` prints it
(``t_ns``, ``kind``, ``size``, ``data_hex`` and, for events, ``event``).
``wiretape convert`` reads it back (wiretape.tools.convert)."""

from __future__ import annotations

import json
from typing import Any, Dict, Iterable

from .. import _core
from ..session import SessionPath, event_of, open_output

__all__ = ["write_records", "record_to_json"]


def record_to_json(record: _core.Record) -> Dict[str, Any]:
    """The JSON object of one record: ``t_ns``, ``kind``, ``size``,
    ``data_hex`` and, for events, ``event``."""
    out: Dict[str, Any] = {
        "t_ns": record.t_ns,
        "kind": record.kind,
        "size": len(record.data),
        "data_hex": record.data.hex(),
    }
    event = event_of(record)
    if event is not None:
        out["event"] = event
    return out


def json_line(value: Dict[str, Any]) -> str:
    """One line of the file: compact JSON and a newline."""
    return json.dumps(value, separators=(",", ":")) + "\n"


def write_records(dst: SessionPath, header: Dict[str, Any],
                  records: Iterable[_core.Record]) -> int:
    """Writes `header` and `records` to `dst`; returns the number of records.
    The file is written as it goes: what came before a failure stays."""
    count = 0
    with open_output(dst, text=True) as out:
        out.write(json_line({"header": header}))
        for record in records:
            out.write(json_line(record_to_json(record)))
            count += 1
    return count

