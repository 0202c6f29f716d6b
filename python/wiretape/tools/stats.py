"""``wiretape stats``: the figures of a session (records, bytes, duration,
events, header), streamed: memory does not grow with the file's size."""

from __future__ import annotations

import dataclasses
import os
from typing import Any, Dict, List, Optional, Tuple

from .. import _core
from ..session import DIRECTIONS, SessionPath, header_text, open_session

__all__ = ["stats", "SessionStats"]


@dataclasses.dataclass(frozen=True)
class SessionStats:
    """The figures of one session; ``to_json()`` is what ``stats --json`` prints."""

    path: str
    records: int
    rx_records: int
    tx_records: int
    event_records: int
    rx_bytes: int
    tx_bytes: int
    first_t_ns: Optional[int]  # None: no records
    last_t_ns: Optional[int]
    duration_s: float  # first to last record
    events: Dict[str, int]  # count per event kind
    header: _core.SessionHeader
    # where and why reading stopped early (None when not damaged)
    damaged: bool
    damage_offset: Optional[int]
    damage_message: Optional[str]

    def __getattr__(self, name: str) -> Any:
        # The header's members read as the result's own (stats.port_type).
        if name == "header":
            raise AttributeError(name)
        return getattr(self.header, name)

    def to_json(self) -> Dict[str, Any]:
        """The counts and the header's members (as SessionHeader.to_dict
        names them) in one object."""
        out = {field.name: getattr(self, field.name) for field in dataclasses.fields(self)
               if field.name != "header"}
        return {**out, **self.header.to_dict()}

    def text_rows(self) -> List[Tuple[str, str]]:
        """(name, value) rows for people, as ``wiretape stats`` prints them:
        empty fields left out, and every text from the file through
        header_text() (a file may hold terminal escape sequences)."""
        rows: List[Tuple[str, str]] = [("path", self.path)]
        for name in ("port_type", "port_options", "capture", "start_utc", "host",
                     "wiretape_version", "source_format", "device_address"):
            value = getattr(self, name)
            if value:
                rows.append((name, header_text(value)))
        if self.source_files:
            rows.append(("source_files", ", ".join(header_text(f) for f in self.source_files)))
        for edit in self.edits:
            rows.append(("edit", header_text(edit)))
        for name in ("records", "rx_records", "rx_bytes", "tx_records", "tx_bytes",
                     "event_records"):
            rows.append((name, str(getattr(self, name))))
        rows.append(("duration_s", f"{self.duration_s:.6f}"))
        if self.events:
            rows.append(("events", ", ".join(f"{kind} {count}"
                                             for kind, count in sorted(self.events.items()))))
        if self.metadata:
            rows.append(("metadata", ", ".join(f"{header_text(key)}={header_text(value)}"
                                               for key, value in sorted(self.metadata.items()))))
        if self.damaged:
            rows.append(("damaged", f"at byte {self.damage_offset}: "
                                    f"{header_text(self.damage_message or '')}"))
        return rows


def stats(path: SessionPath) -> SessionStats:
    """Counts the records and bytes of each direction and the events of each
    kind; a damaged file is counted up to the damage, which the result names."""
    reader = open_session(path)
    count = {"rx": 0, "tx": 0}
    size = {"rx": 0, "tx": 0}
    events: Dict[str, int] = {}
    records = 0
    first: Optional[int] = None
    last: Optional[int] = None
    for record in reader:
        records += 1
        first = record.t_ns if first is None else min(first, record.t_ns)
        last = record.t_ns if last is None else max(last, record.t_ns)
        if record.kind in DIRECTIONS:
            count[record.kind] += 1
            size[record.kind] += len(record.data)
        else:
            events[record.kind] = events.get(record.kind, 0) + 1
    header = reader.header
    damage = reader.damage
    return SessionStats(
        path=os.fspath(path),
        records=records,
        rx_records=count["rx"],
        tx_records=count["tx"],
        event_records=sum(events.values()),
        rx_bytes=size["rx"],
        tx_bytes=size["tx"],
        first_t_ns=first,
        last_t_ns=last,
        duration_s=(last - first) / 1e9 if first is not None and last is not None else 0.0,
        events=events,
        header=header,
        damaged=damage is not None,
        damage_offset=damage.offset if damage is not None else None,
        damage_message=damage.message if damage is not None else None,
    )
