"""The JSON Lines form of a session: a first line ``{"header": {...}}``, then
one JSON object per record, as ``wiretape show --format jsonl`` prints it
(``t_ns``, ``kind``, ``size``, ``data_hex`` and, for events, ``event``).
A session of named channels (its header has ``channels``) gives each
record its channel's name as ``channel``; a session without them is
written as before, without that member.
Its reader, read_records(), is beside the writer: ``wiretape convert``
reads the form back through it."""

from __future__ import annotations

import json
from typing import Any, Dict, Iterable, Iterator, Mapping, Optional

from .. import _core
from ..session import SessionPath, event_of, open_input, open_output

__all__ = ["write_records", "record_to_json", "channel_names", "read_records",
           "looks_like_reserial"]


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
    """Channel id to name for a header (its JSON layout, as to_dict gives it) of named
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
    names = channel_names(header)
    with open_output(dst, text=True) as out:
        out.write(json_line({"header": header}))
        for record in records:
            # A reader gives no record of a channel its header does not list.
            channel = names[record.channel] if names is not None else None
            out.write(json_line(record_to_json(record, channel)))
            count += 1
    return count


def looks_like_reserial(item: object) -> bool:
    """A line of a pytest-reserial cassette: {"TEST": {"rx": ..., "tx": ...}}."""
    return (isinstance(item, dict) and len(item) == 1
            and isinstance(next(iter(item.values())), dict)
            and {"rx", "tx"} & set(next(iter(item.values()))))


# --- reading -----------------------------------------------------------------
#
# One validation layer for the whole jsonl source: every problem a line can
# have is raised as SessionError naming the file, the line and the field, so
# the CLI reports it in one line with exit 1 (a damaged session file, as for
# .wtape sources) and what came before the bad line is converted.

class _BadLine(Exception):
    """A problem of one line; read_records adds the file and line number."""


def _json_type(value) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return f"the number {value!r:.40}"
    if isinstance(value, str):
        return f"the string {value!r:.40}"
    return "an array" if isinstance(value, list) else "an object"


def _record_kinds():
    return {kind["name"]: kind for kind in _core.RECORD_KINDS}


# Members only the flat header layout had: wiretape up to 0.1.0, before
# issue 36 (DESIGN §25), wrote SessionHeader.to_dict()'s flat dict of then
# as the header line; the file's own JSON layout replaced it.
_FLAT_ONLY = ("version_major", "version_minor", "source_format", "source_files",
              "source_details")


def _flat_header(value: Dict[str, Any]) -> Dict[str, Any]:
    """A header line in the flat layout of wiretape up to 0.1.0 (before issue
    36) as the file's JSON layout: the version dropped (the writer writes its
    own) and the source members back in their ``source`` object (none for a
    session recorded by wiretape). Kept for reading old files only."""
    layout = {key: item for key, item in value.items() if key not in _FLAT_ONLY}
    source_format = value.get("source_format")
    if source_format not in (None, "", "wiretape"):
        details = value.get("source_details") or {}
        if not isinstance(details, dict):
            raise _BadLine(f"header.source_details: expected an object, got {_json_type(details)}")
        layout["source"] = {**details, "format": source_format,
                            "files": value.get("source_files") or []}
    return layout


def _jsonl_header(value) -> _core.SessionHeader:
    """The header line's object (the file's header JSON, or the flat layout
    of older files) as a SessionHeader: its members are checked by the bound
    type, and what a writer would refuse (docs/session-format.md#limits) is
    reported at this line rather than by the writer."""
    if not isinstance(value, dict):
        raise _BadLine(f"header: expected a JSON object, got {_json_type(value)}")
    if any(key in value for key in _FLAT_ONLY):
        value = _flat_header(value)
    try:
        header = _core.SessionHeader.from_dict(value)
        header.to_json()
    except _core.OptionError as error:
        raise _BadLine(f"header.{error.key}: {error}") from None
    except (TypeError, ValueError) as error:
        raise _BadLine(f"header: {error}") from None
    return header


def _jsonl_t_ns(item: dict) -> int:
    if "t_ns" not in item:
        if looks_like_reserial(item):
            raise _BadLine("this is a pytest-reserial cassette, not wiretape's jsonl: "
                           "convert it with --from reserial")
        raise _BadLine("t_ns: missing (every record needs t_ns, kind and data_hex)")
    t_ns = item["t_ns"]
    if isinstance(t_ns, bool) or not isinstance(t_ns, int):
        raise _BadLine(f"t_ns: expected a whole number of nanoseconds, got {_json_type(t_ns)}")
    if not 0 <= t_ns <= _core.MAX_RECORD_T_NS:
        shown = str(t_ns) if len(str(t_ns)) <= 30 else f"a number of {len(str(t_ns))} digits"
        raise _BadLine(f"t_ns: out of range 0..{_core.MAX_RECORD_T_NS}: {shown}")
    return t_ns


def _jsonl_kind(item: dict, kinds: dict):
    """The record's kind: its name, or for kinds without one its code."""
    if "kind" in item:
        kind = item["kind"]
        if isinstance(kind, str):
            if kind not in kinds:
                raise _BadLine(f"kind: unknown record kind {kind[:40]!r}: one of "
                               f"{', '.join(kinds)}")
            return kind
        if isinstance(kind, bool) or not isinstance(kind, int):
            raise _BadLine(f"kind: expected a record kind name, got {_json_type(kind)}")
        field = "kind"
    elif "kind_code" in item:
        kind = item["kind_code"]
        field = "kind_code"
    else:
        raise _BadLine("kind: missing (every record needs t_ns, kind and data_hex)")
    if isinstance(kind, bool) or not isinstance(kind, int) or not 0 <= kind <= 255:
        raise _BadLine(f"{field}: expected a record kind code 0..255, got {_json_type(kind)}")
    return kind


def _jsonl_data(item: dict, kind, kinds: dict) -> bytes:
    if "data_hex" in item:
        text = item["data_hex"]
        if not isinstance(text, str):
            raise _BadLine(f"data_hex: expected a string of hex digits, got {_json_type(text)}")
        try:
            data = bytes.fromhex(text)
        except ValueError as error:
            raise _BadLine(f"data_hex: not hex: {error}") from None
    elif "event" in item:
        event = item["event"]
        if not isinstance(event, dict):
            raise _BadLine(f"event: expected a JSON object, got {_json_type(event)}")
        try:
            data = _core.event_payload(kind, event)
        except ValueError as error:
            raise _BadLine(f"event: {error}") from None
    elif kind in kinds and kinds[kind]["is_event"]:
        data = b""
    else:
        raise _BadLine("data_hex: missing (every data record needs t_ns, kind and data_hex)")
    return data


def _header_channel_ids(header: Optional[_core.SessionHeader]) -> Dict[str, int]:
    """Channel name to id, for a header of named channels; {} otherwise."""
    if header is None:
        return {}
    return {channel.name: channel.id for channel in header.channels}


def _jsonl_channel(item: dict, channel_ids: Dict[str, int]) -> int:
    """The record's channel id from its ``channel`` (a name the header's
    ``channels`` gives); 0, the only channel, when it has none."""
    if "channel" not in item:
        return 0
    name = item["channel"]
    if not isinstance(name, str):
        raise _BadLine(f"channel: expected the name of one of the header's channels, got "
                       f"{_json_type(name)}")
    if not channel_ids:
        raise _BadLine(f"channel: {name[:40]!r}, but the header names no channels (a "
                       f"session of one port: its records have no channel)")
    if name not in channel_ids:
        raise _BadLine(f"channel: unknown channel {name[:40]!r}: the header's channels are "
                       f"{', '.join(channel_ids)}")
    return channel_ids[name]


def _jsonl_line(text: str, channel_ids: Dict[str, int]):
    """("header", SessionHeader) or ("record", (kind, t_ns, data, channel))
    for one line; `channel_ids`: the channels the header named."""
    try:
        item = json.loads(text)
    except RecursionError:
        raise _BadLine("not JSON: nested too deeply") from None
    except json.JSONDecodeError as error:  # its own "line 1" would mislead
        raise _BadLine(f"not JSON: {error.msg} at column {error.colno}") from None
    except ValueError as error:  # an integer of more digits than Python converts
        raise _BadLine(f"not JSON: {error}") from None
    if not isinstance(item, dict):
        raise _BadLine(f"expected a JSON object, got {_json_type(item)}")
    if "header" in item:
        return "header", _jsonl_header(item["header"])
    kinds = _record_kinds()
    t_ns = _jsonl_t_ns(item)
    kind = _jsonl_kind(item, kinds)
    data = _jsonl_data(item, kind, kinds)
    channel = _jsonl_channel(item, channel_ids)
    problem = _core.record_content_problem(kind, t_ns, data)
    if problem is not None:
        raise _BadLine(f"record: {problem}")
    return "record", (kind, t_ns, data, channel)


def read_records(path: str) -> Iterator[tuple]:
    """(SessionHeader or None) first, then (kind, t_ns, data, channel) per
    record (channel: the id of the channel the record names, else 0).

    Raises SessionError ("PATH:LINE: FIELD: problem", offset = the line's
    first byte) at the first bad line, after yielding every record before it.
    """
    with open_input(path) as handle:
        header_seen = False
        records_seen = False
        channel_ids: Dict[str, int] = {}
        offset = 0
        for number, raw in enumerate(handle, start=1):
            line_offset, offset = offset, offset + len(raw)
            try:
                text = raw.decode("utf-8").strip()
                if not text:
                    continue
                what, value = _jsonl_line(text, channel_ids)
                if what == "header" and records_seen:
                    raise _BadLine("header: must be the first line, before every record")
                if what == "header" and header_seen:
                    raise _BadLine("header: a second header line")
            except UnicodeDecodeError as error:
                raise _core.SessionError(
                    f"{path}:{number}: not UTF-8 text ({error.reason} at column "
                    f"{error.start + 1})", line_offset) from None
            except _BadLine as problem:
                raise _core.SessionError(f"{path}:{number}: {problem}", line_offset) from None
            if what == "header":
                header_seen = True
                channel_ids = _header_channel_ids(value)
                yield ("header", value)
                continue
            if not header_seen:
                header_seen = True
                yield ("header", None)
            records_seen = True
            yield ("record", value)
        if not header_seen:
            yield ("header", None)
