"""``wiretape stats``: the figures of a session (records, bytes, duration,
events, header), streamed: memory does not grow with the file's size; and
the latency from each request to the first byte of its response, paired
by the one segmentation into exchanges (C++), per request frame name with a
profile."""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Any, Dict, List, Optional, Tuple

from .. import _core
from ..session import DIRECTIONS, SessionPath, header_text, open_session, warn_if_unfinished
from .channels import channel_names, several_channels

__all__ = ["stats", "SessionStats", "ChannelStats", "Latency"]

#: The percentiles stats gives of latencies.
PERCENTILES = (50, 90, 99)


@dataclasses.dataclass(frozen=True)
class Latency:
    """How long a device took to answer: from the time the request's last
    byte was written (the tx record that completed it) to the time of its
    response's first rx record, over the requests that were answered. ``name``: the
    request frame's name under a profile (``VV``, ``GD`` for SCIP), or
    ``all``. Percentiles by nearest rank."""

    name: str
    requests: int
    p50_s: float
    p90_s: float
    p99_s: float
    max_s: float

    def text(self) -> str:
        return (f"{self.requests} {'request' if self.requests == 1 else 'requests'}: "
                f"p50 {_ms(self.p50_s)}, p90 {_ms(self.p90_s)}, p99 {_ms(self.p99_s)}, "
                f"max {_ms(self.max_s)}")


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.3f} ms"


def _percentile(ordered: List[int], percent: int) -> int:
    return ordered[max(0, math.ceil(percent / 100 * len(ordered)) - 1)]


def _latency(name: str, waits_ns: List[int]) -> Latency:
    ordered = sorted(waits_ns)
    p50, p90, p99 = (_percentile(ordered, p) / 1e9 for p in PERCENTILES)
    return Latency(name, len(ordered), p50, p90, p99, ordered[-1] / 1e9)


class _LatencyMeter:
    """One channel's answered requests, paired in C++ by the one
    segmentation (``_core.LatencyMeter``: each exchange's request end to
    its response start, as the replay cuts exchanges), fed the records as
    they stream by."""

    def __init__(self, header: _core.SessionHeader, channel: int, profile: Optional[str]):
        self._profile = profile
        self._meter = _core.LatencyMeter(header, channel=channel, profile=profile)
        self.feed = self._meter.feed

    @property
    def every(self) -> List[int]:
        return [answered.wait_ns for answered in self._meter.answered]

    @property
    def waits(self) -> Dict[str, List[int]]:
        named: Dict[str, List[int]] = {}
        if self._profile is not None:
            for answered in self._meter.answered:
                named.setdefault(answered.request_name, []).append(answered.wait_ns)
        return named

    def result(self) -> List[Latency]:
        """One Latency over every request (``all``), and with a profile one
        per request frame name, most frequent first; empty when no request
        was answered."""
        return _latencies(self.every, self.waits)


def _latencies(every: List[int], waits: Dict[str, List[int]]) -> List[Latency]:
    if not every:
        return []
    named = sorted(waits.items(), key=lambda item: (-len(item[1]), item[0]))
    return [_latency("all", every)] + [_latency(name, values) for name, values in named]


def _all_channels(meters: "Dict[int, _LatencyMeter]") -> List[Latency]:
    """The latencies over every channel: each channel's requests answered
    on that channel (a request on one port is not answered on another)."""
    every: List[int] = []
    waits: Dict[str, List[int]] = {}
    for meter in meters.values():
        every.extend(meter.every)
        for name, values in meter.waits.items():
            waits.setdefault(name, []).extend(values)
    return _latencies(every, waits)


@dataclasses.dataclass(frozen=True)
class ChannelStats:
    """The figures of one channel of a session of several ports."""

    id: int
    name: str
    records: int
    rx_records: int
    tx_records: int
    event_records: int
    rx_bytes: int
    tx_bytes: int
    latency: Tuple[Latency, ...] = ()

    def text_rows(self) -> List[Tuple[str, str]]:
        label = f"channel {header_text(self.name) if self.name else f'#{self.id}'}"
        rows = [(label, f"{self.records} records: rx {self.rx_records} ({self.rx_bytes} B), "
                        f"tx {self.tx_records} ({self.tx_bytes} B), "
                        f"events {self.event_records}")]
        for latency in self.latency:
            name = "" if latency.name == "all" else f" {header_text(latency.name)}"
            rows.append((f"  latency{name}", latency.text()))
        return rows


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
    # request to first response byte (see Latency); why it is missing, if it is
    latency: Tuple[Latency, ...] = ()
    latency_note: Optional[str] = None
    # per channel, for a session of several ports (empty otherwise); the
    # figures above are the totals over every channel
    channel_stats: Tuple[ChannelStats, ...] = ()

    def __getattr__(self, name: str) -> Any:
        # The header's members read as the result's own (stats.port_type).
        if name == "header":
            raise AttributeError(name)
        return getattr(self.header, name)

    def to_json(self) -> Dict[str, Any]:
        """The counts, the file's format version and the header as the file
        holds it (SessionHeader.to_dict(), the header JSON's layout) in one
        object."""
        out = {field.name: getattr(self, field.name) for field in dataclasses.fields(self)
               if field.name not in ("header", "latency", "channel_stats")}
        # The version is the file's, not a member of the header JSON.
        out["version_major"] = self.header.version_major
        out["version_minor"] = self.header.version_minor
        out["latency"] = [dataclasses.asdict(latency) for latency in self.latency]
        out["channel_stats"] = [dataclasses.asdict(channel) for channel in self.channel_stats]
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
        for latency in self.latency:
            label = "latency" if latency.name == "all" else f"latency {header_text(latency.name)}"
            rows.append((label, latency.text()))
        if self.latency_note:
            rows.append(("latency", self.latency_note))
        for channel in self.channel_stats:
            rows.extend(channel.text_rows())
        if self.metadata:
            rows.append(("metadata", ", ".join(f"{header_text(key)}={header_text(value)}"
                                               for key, value in sorted(self.metadata.items()))))
        if self.damaged:
            rows.append(("damaged", f"at byte {self.damage_offset}: "
                                    f"{header_text(self.damage_message or '')}"))
        return rows


def stats(path: SessionPath, profile: Optional[str] = None) -> SessionStats:
    """Counts the records and bytes of each direction and the events of each
    kind, and the latency of each answered request (see Latency; named by
    `profile`'s frame names when given); a damaged file is counted up to
    the damage, which the result names."""
    if profile is not None:
        _core.profile_from_spec(profile)  # a bad spec fails first, naming its key
    # Each channel is its own conversation: its requests, its responses.
    meters: Dict[int, _LatencyMeter] = {}
    reader = open_session(path)
    count = {"rx": 0, "tx": 0}
    size = {"rx": 0, "tx": 0}
    events: Dict[str, int] = {}
    # per channel: [records, rx records, tx records, events, rx bytes, tx bytes]
    per_channel: Dict[int, List[int]] = {}
    records = 0
    first: Optional[int] = None
    last: Optional[int] = None
    for record in reader:
        records += 1
        first = record.t_ns if first is None else min(first, record.t_ns)
        last = record.t_ns if last is None else max(last, record.t_ns)
        channel = record.channel
        meter = meters.get(channel)
        if meter is None:
            meter = meters[channel] = _LatencyMeter(reader.header, channel, profile)
        meter.feed(record.kind, record.t_ns, record.data)
        figures = per_channel.get(channel)
        if figures is None:
            figures = per_channel[channel] = [0, 0, 0, 0, 0, 0]
        figures[0] += 1
        if record.kind in DIRECTIONS:
            count[record.kind] += 1
            size[record.kind] += len(record.data)
            rx = record.kind == "rx"
            figures[1 if rx else 2] += 1
            figures[4 if rx else 5] += len(record.data)
        else:
            events[record.kind] = events.get(record.kind, 0) + 1
            figures[3] += 1
    header = reader.header
    damage = reader.damage
    warn_if_unfinished(reader)
    measured = _all_channels(meters)
    channel_stats: List[ChannelStats] = []
    if several_channels(header) or set(per_channel) - {0}:
        names = channel_names(header)
        for channel in sorted(set(names) | set(per_channel)):
            figures = per_channel.get(channel, [0] * 6)
            latency = meters[channel].result() if channel in meters else []
            channel_stats.append(ChannelStats(
                id=channel, name=names.get(channel, ""), records=figures[0],
                rx_records=figures[1], tx_records=figures[2], event_records=figures[3],
                rx_bytes=figures[4], tx_bytes=figures[5], latency=tuple(latency)))
    note = ("not measured: no request is followed by a response"
            if not measured and count["tx"] and count["rx"] else None)
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
        latency=tuple(measured),
        latency_note=note,
        channel_stats=tuple(channel_stats),
    )
