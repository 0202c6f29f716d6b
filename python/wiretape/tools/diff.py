"""Comparing two sessions, direction by direction.

``diff(a, b)`` compares the rx (device to host) and tx (host to device) byte
streams of two sessions. How the bytes were split into records does not
matter (a recording made by another program, or converted from flexiport's
one-byte chunks, compares equal if the bytes are the same); events are
counted in the summary but not compared. Both sessions are streamed: memory
does not depend on their size. A pipe or FIFO, which can be read only once
while each direction is compared in a reading of its own, is first copied
to a temporary file (on disk, not in memory).

With ``profile=NAME`` each direction is compared frame by frame, by the
profile's match key: fields the profile leaves out of the key (a Modbus TCP
transaction id, a MAVLink sequence number and CRC) do not make a
difference, and the first differing frame is named.

Besides the first difference of each direction's stream, the exchanges
(as a replay numbers them, ``_core.session_exchanges``, so that ``exchange
N`` is what ``faults=…@exchange:N`` means) are aligned as ``diff -u`` aligns
lines (tools/diff_exchanges.py): two runs that differ by a handshake at the
start differ by those exchanges, not by every exchange after them. Every
divergence of what the alignment pairs is listed (``max_divergences`` of
them shown; all counted): the request and the response of exchange N of A
against the exchange of B it is aligned with, each pointing at its first
differing byte, and each exchange only one session has.

Sessions of several ports (DESIGN §19) are compared channel by channel,
by name: each channel's records as a session of their own, the results
named by channel; a channel only one of them has is a difference. Two
sessions of one channel each are compared as they are, whatever their
channels' names.

``a`` and ``b`` are paths of session files (``.wtape`` or a flexiport
``name.log``) or iterables of records (objects with ``t_ns``, ``kind`` and
``data``, such as ``wiretape.Record``).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from typing import Dict, Iterable, Iterator, List, Optional, Union

from .. import _core
from ..session import DIRECTIONS, NO_PROFILE, header_text, is_stream, open_session
from .channels import capture_text, several_channels
from .diff_exchanges import (Alignment, Divergence, diff_exchanges, first_key_difference,
                             labelled, pointed)

_CONTEXT = 16

SessionLike = Union[str, "os.PathLike[str]", Iterable]


def _seconds(t_ns: Optional[int]) -> str:
    return "-" if t_ns is None else f"{t_ns / 1e9:.6f} s"


def _kind_name(kind) -> str:
    return kind if isinstance(kind, str) else str(getattr(kind, "name", kind))


class _Records:
    """The records of one session, once, with the damage (if any) noted."""

    def __init__(self, source: SessionLike):
        self.name = str(source) if isinstance(source, (str, os.PathLike)) else "<records>"
        self.damage: Optional[str] = None
        self.events = 0
        self._source = source
        self._scratch: Optional[tempfile.TemporaryDirectory] = None

    def __iter__(self) -> Iterator:
        if isinstance(self._source, (str, os.PathLike)):
            if self._scratch is None and is_stream(self._source):
                self._source = self._copy_of_stream(self._source)
            with open_session(self._source) as reader:
                yield from reader
                damage = reader.damage
                if damage is not None:
                    self.damage = damage.message
        else:
            yield from self._source

    def _copy_of_stream(self, path) -> str:
        """The records of the stream `path` (up to its damage, which is noted)
        in a temporary file, to be read once per direction."""
        self._scratch = tempfile.TemporaryDirectory(prefix="wiretape-diff-")
        copy = os.path.join(self._scratch.name, "stream.wtape")
        with open_session(path) as reader, _core.SessionWriter(copy, reader.header) as writer:
            for record in reader:
                writer.write(record.kind, record.t_ns, record.data, channel=record.channel)
            if reader.damage is not None:
                self.damage = reader.damage.message
        return copy

    def file(self) -> str:
        """A session file of these records: the file itself, or a copy of a
        stream or of records given as a list."""
        if isinstance(self._source, (str, os.PathLike)):
            if self._scratch is None and is_stream(self._source):
                self._source = self._copy_of_stream(self._source)
            return os.fspath(self._source)
        if self._scratch is None:
            self._scratch = tempfile.TemporaryDirectory(prefix="wiretape-diff-")
            copy = os.path.join(self._scratch.name, "records.wtape")
            with _core.SessionWriter(copy) as writer:
                for record in self._source:
                    writer.write(_kind_name(record.kind), record.t_ns, record.data)
            self._source_file = copy
        return self._source_file

    def close(self) -> None:
        if self._scratch is not None:
            self._scratch.cleanup()


class _Cursor:
    """The byte stream of one direction, consumed record by record.

    The current record is kept whole with a position into it, so that
    comparing long records against many short ones stays linear.
    """

    def __init__(self, records: Iterator, kind: str):
        self._records = records
        self._kind = kind
        self._data = b""
        self._pos = 0
        self.t_ns: Optional[int] = None
        self.bytes = 0
        self.records = 0
        self.ended = False

    def left(self) -> int:
        return len(self._data) - self._pos

    def peek(self, n: int) -> bytes:
        return self._data[self._pos : self._pos + n]

    def fill(self) -> bool:
        while not self.left() and not self.ended:
            try:
                record = next(self._records)
            except StopIteration:
                self.ended = True
                break
            if _kind_name(record.kind) != self._kind or not record.data:
                continue
            self._data = bytes(record.data)
            self._pos = 0
            self.t_ns = record.t_ns
            self.bytes += len(self._data)
            self.records += 1
        return self.left() > 0

    def consume(self, n: int) -> None:
        self._pos += n

    def drain(self) -> None:
        while self.fill():
            self._pos = len(self._data)


@dataclass
class DirectionDiff:
    """One direction of a comparison."""

    direction: str
    identical: bool = True
    channel: str = ""  # in a session of several channels, the channel's name
    offset: Optional[int] = None  # first differing byte, or where one ended
    time_a_ns: Optional[int] = None
    time_b_ns: Optional[int] = None
    before: bytes = b""
    at_a: bytes = b""
    at_b: bytes = b""
    bytes_a: int = 0
    bytes_b: int = 0
    records_a: int = 0
    records_b: int = 0

    def report(self) -> str:
        counts = (
            f"A {self.bytes_a} bytes in {self.records_a} records, "
            f"B {self.bytes_b} bytes in {self.records_b} records"
        )
        label = labelled(self.channel, self.direction)
        if self.identical:
            return f"{label}: identical ({counts})"
        if not self.at_a or not self.at_b:
            shorter = "A" if not self.at_a else "B"
            headline = f"{label}: {shorter} ends at byte {self.offset}"
        else:
            headline = f"{label}: first difference at byte {self.offset}"
        return "\n".join(
            [
                f"{headline} (A at {_seconds(self.time_a_ns)}, B at {_seconds(self.time_b_ns)})",
                f"  before: {_core.hex_ascii(bytes(self.before))}",
                f"  A:      {_core.hex_ascii(bytes(self.at_a))}",
                f"  B:      {_core.hex_ascii(bytes(self.at_b))}",
                f"  {counts}",
            ]
        )


@dataclass
class DiffResult:
    """The outcome of diff(): identical, per-direction details, report()."""

    a: str
    b: str
    directions: List[Union[DirectionDiff, "FrameDiff"]] = field(default_factory=list)
    damage_a: Optional[str] = None
    damage_b: Optional[str] = None
    # the exchanges aligned (one per channel compared), every divergence of
    # what differs: the first ones, and how many
    alignments: List[Alignment] = field(default_factory=list)
    divergences: List[Divergence] = field(default_factory=list)
    divergence_count: int = 0
    # channels of sessions of several ports that only one has: name -> "A" or "B"
    only_in: Dict[str, str] = field(default_factory=dict)

    @property
    def identical(self) -> bool:
        return not self.only_in and all(d.identical for d in self.directions)

    @property
    def damaged(self) -> bool:
        """Either session is damaged: compared up to the damage, and, as for
        every command reading a damaged session, ``wiretape diff`` exits 1."""
        return bool(self.damage_a or self.damage_b)

    def __bool__(self) -> bool:  # truthy when the sessions differ, like a diff
        return not self.identical

    def __getitem__(self, direction) -> Union[DirectionDiff, "FrameDiff"]:
        """``result["rx"]``; in sessions of several channels ``result["gps", "rx"]``."""
        channel, name = direction if isinstance(direction, tuple) else ("", direction)
        for d in self.directions:
            if d.direction == name and d.channel == channel:
                return d
        raise KeyError(direction)

    def report(self) -> str:
        lines = [f"A: {self.a}", f"B: {self.b}"]
        for channel, which in self.only_in.items():
            lines.append(f"channel {header_text(channel)}: only in {which}")
        lines += [d.report() for d in self.directions]
        if not self.identical:
            lines += [f"by exchange: {alignment.summary()}" for alignment in self.alignments]
        if self.divergence_count:
            shown = len(self.divergences)
            more = (f" (the first {shown} of {self.divergence_count}; --max shows more)"
                    if shown < self.divergence_count else "")
            lines.append(f"{self.divergence_count} "
                         f"{'divergence' if self.divergence_count == 1 else 'divergences'}"
                         f" by exchange{more}:")
            for divergence in self.divergences:
                lines += divergence.report()
        for name, damage in (("A", self.damage_a), ("B", self.damage_b)):
            if damage:
                lines.append(f"{name} is damaged; compared up to the damage: {damage}")
        lines.append("sessions are identical" if self.identical else "sessions differ")
        return "\n".join(lines)

    def to_json(self) -> dict:
        """What report() says, for programs (``wiretape diff --json``)."""
        return {"a": self.a, "b": self.b, "identical": self.identical,
                "damage_a": self.damage_a, "damage_b": self.damage_b,
                "only_in": dict(self.only_in),
                "directions": [_direction_json(d) for d in self.directions],
                "alignments": [alignment.to_json() for alignment in self.alignments],
                "divergence_count": self.divergence_count,
                "divergences": [divergence.to_json() for divergence in self.divergences]}


def _direction_json(direction: Union[DirectionDiff, "FrameDiff"]) -> dict:
    fields = {name: value.hex() if isinstance(value, (bytes, bytearray)) else value
              for name, value in vars(direction).items()}
    fields["identical"] = direction.identical
    return fields


def _compare(a: _Records, b: _Records, direction: str) -> DirectionDiff:
    ca, cb = _Cursor(iter(a), direction), _Cursor(iter(b), direction)
    result = DirectionDiff(direction)
    history = b""
    offset = 0
    while True:
        has_a, has_b = ca.fill(), cb.fill()
        if not has_a and not has_b:
            break
        n = min(ca.left(), cb.left())
        chunk_a, chunk_b = ca.peek(n), cb.peek(n)
        if n and chunk_a == chunk_b:
            history = (history + chunk_a[-_CONTEXT:])[-_CONTEXT:]
            offset += n
            ca.consume(n)
            cb.consume(n)
            continue
        same = 0
        while same < n and chunk_a[same] == chunk_b[same]:
            same += 1
        history = (history + chunk_a[:same][-_CONTEXT:])[-_CONTEXT:]
        ca.consume(same)
        cb.consume(same)
        result.identical = False
        result.offset = offset + same
        result.before = history
        result.at_a = ca.peek(_CONTEXT)
        result.at_b = cb.peek(_CONTEXT)
        result.time_a_ns = ca.t_ns if ca.left() else None
        result.time_b_ns = cb.t_ns if cb.left() else None
        break
    ca.drain()
    cb.drain()
    result.bytes_a, result.bytes_b = ca.bytes, cb.bytes
    result.records_a, result.records_b = ca.records, cb.records
    return result


@dataclass
class FrameDiff:
    """One direction compared frame by frame with a profile."""

    direction: str
    identical: bool = True
    channel: str = ""  # in a session of several channels, the channel's name
    frames_a: int = 0
    frames_b: int = 0
    index: int = -1  # of the first differing frame
    frame_a: Optional[bytes] = None
    frame_b: Optional[bytes] = None
    describe_a: str = ""
    describe_b: str = ""
    time_a_ns: Optional[int] = None
    time_b_ns: Optional[int] = None
    byte: int = 0  # the first differing byte of the frames that the key compares

    def report(self) -> str:
        counts = f"A: {self.frames_a} frames, B: {self.frames_b} frames"
        label = labelled(self.channel, self.direction)
        if self.identical:
            return f"{label}: identical by key ({counts})"
        lines = [f"{label}: first difference at frame {self.index} "
                 f"(A at {_seconds(self.time_a_ns)}, B at {_seconds(self.time_b_ns)})"]
        for name, frame, description in (("A", self.frame_a, self.describe_a),
                                         ("B", self.frame_b, self.describe_b)):
            if frame is None:
                lines.append(f"  {name}:      (no more frames)")
            else:
                lines.append(f"  {name}:      {description}")
        lines.append(f"  at byte {self.byte} of the frame:")
        lines += pointed(self.frame_a, self.frame_b, self.byte)
        lines.append(f"  {counts}")
        return "\n".join(lines)


def _frames(profile, source, direction: str):
    for t_ns, kind, data, description in profile.decode_session(source):
        if description is not None and kind == direction:
            yield t_ns, bytes(data), description


def _compare_frames(profile, a, b, direction: str) -> FrameDiff:
    result = FrameDiff(direction)
    frames_a, frames_b = _frames(profile, a, direction), _frames(profile, b, direction)
    while True:
        next_a, next_b = next(frames_a, None), next(frames_b, None)
        if next_a is None and next_b is None:
            break
        if next_a is not None:
            result.frames_a += 1
        if next_b is not None:
            result.frames_b += 1
        if not result.identical:
            continue
        same = (next_a is not None and next_b is not None
                and profile.match_key(next_a[1]) == profile.match_key(next_b[1]))
        if same:
            continue
        result.identical = False
        result.index = max(result.frames_a, result.frames_b) - 1
        if next_a is not None:
            result.time_a_ns, result.frame_a, result.describe_a = next_a
        if next_b is not None:
            result.time_b_ns, result.frame_b, result.describe_b = next_b
        if next_a is not None and next_b is not None:
            result.byte = first_key_difference(next_a[1], next_b[1], profile.match_key)
    return result


def diff(a: SessionLike, b: SessionLike, profile: Optional[str] = None,
         max_divergences: int = 10) -> DiffResult:
    """Compares sessions ``a`` and ``b``: the first divergence per direction,
    and every divergence by exchange (the first `max_divergences` kept in
    ``divergences``, all counted in ``divergence_count``).

    Raises wiretape.PortError if a file cannot be opened, SessionError if
    it is not a session; a damaged file is compared up to its damage, which
    the report mentions (and ``damaged`` says).
    """
    if not isinstance(a, (str, os.PathLike)):
        a = list(a)
    if not isinstance(b, (str, os.PathLike)):
        b = list(b)
    if all(isinstance(x, (str, os.PathLike)) and not is_stream(x) for x in (a, b)):
        # (a pipe is read once: its records are compared as one stream)
        headers = [_header_of(os.fspath(x)) for x in (a, b)]
        if any(header is not None and several_channels(header) for header in headers):
            records_a, records_b = _Records(a), _Records(b)
            try:
                return _diff_channels(records_a, records_b, headers, profile, max_divergences)
            finally:
                records_a.close()
                records_b.close()
    if profile is not None and profile != NO_PROFILE:
        framing = _core.profile_from_spec(profile)
        result = DiffResult(str(a) if isinstance(a, (str, os.PathLike)) else "(records)",
                            str(b) if isinstance(b, (str, os.PathLike)) else "(records)")
        for direction in DIRECTIONS:
            sources = [os.fspath(x) if isinstance(x, (str, os.PathLike)) else x for x in (a, b)]
            result.directions.append(_compare_frames(framing, sources[0], sources[1], direction))
        if not result.identical:
            records_a, records_b = _Records(a), _Records(b)
            try:
                _add_divergences(result, records_a, records_b, profile, max_divergences)
            finally:
                records_a.close()
                records_b.close()
        return result
    records_a, records_b = _Records(a), _Records(b)
    result = DiffResult(records_a.name, records_b.name)
    try:
        for direction in DIRECTIONS:
            result.directions.append(_compare(records_a, records_b, direction))
        if not result.identical:
            _add_divergences(result, records_a, records_b, None, max_divergences)
    finally:
        records_a.close()
        records_b.close()
    result.damage_a, result.damage_b = records_a.damage, records_b.damage
    return result


def _header_of(path: str) -> Optional[_core.SessionHeader]:
    try:
        return open_session(path).header
    except _core.SessionError:
        return None  # not a session: the comparison below says so


def _diff_channels(a: _Records, b: _Records, headers: List[Optional[_core.SessionHeader]],
                   profile: Optional[str], keep: int) -> DiffResult:
    """Sessions of several channels compared channel by channel, by name."""
    result = DiffResult(a.name, b.name)
    names = [[channel.name for channel in header.channel_list()] if header is not None else []
             for header in headers]
    order = names[0] + [name for name in names[1] if name not in names[0]]
    with tempfile.TemporaryDirectory(prefix="wiretape-diff-") as scratch:
        for name in order:
            if name not in names[1] or name not in names[0]:
                result.only_in[name] = "A" if name in names[0] else "B"
                continue
            parts = []
            for side, (records, header) in enumerate(zip((a, b), headers)):
                part = os.path.join(scratch, f"{'ab'[side]}.wtape")
                damage = _channel_copy(records.file(), header, name, part)
                if damage and side == 0:
                    result.damage_a = result.damage_a or damage
                elif damage:
                    result.damage_b = result.damage_b or damage
                parts.append(part)
            part_result = diff(parts[0], parts[1], profile,
                               max(0, keep - len(result.divergences)))
            for direction in part_result.directions:
                direction.channel = name
                result.directions.append(direction)
            for divergence in part_result.divergences:
                divergence.channel = name
            for alignment in part_result.alignments:
                alignment.channel = name
            result.alignments += part_result.alignments
            result.divergences += part_result.divergences
            result.divergence_count += part_result.divergence_count
    return result


def _channel_copy(path: str, header: _core.SessionHeader, name: str, copy: str
                  ) -> Optional[str]:
    """One channel's records as a session of its own (its port members in
    the header, so that it is numbered into exchanges as a replay of that
    channel numbers them); the damage reading stopped at, if any."""
    channel = header.find_channel(name)
    own = _core.SessionHeader.from_dict(header.to_dict())
    own.channels = []
    own.port_options, own.port_type = channel.port_options, channel.port_type
    own.capture = capture_text(channel.capture)
    own.device_address = channel.device_address
    with _core.SessionReader(path, channel=channel.id) as reader, \
            _core.SessionWriter(copy, own) as writer:
        for record in reader:
            writer.write(record.kind, record.t_ns, record.data)
        return reader.damage.message if reader.damage is not None else None


def _add_divergences(result: DiffResult, a: _Records, b: _Records, profile: Optional[str],
                     keep: int) -> None:
    """Every divergence by exchange, from files (a damaged one has no
    exchanges to align: the first differences above are all there is)."""
    # A name or a declared profile, read by the replay's rule; "none": none.
    framing = (_core.profile_from_spec(profile)
               if profile is not None and profile != NO_PROFILE else None)
    try:
        by_exchange = diff_exchanges(a.file(), b.file(), framing, keep)
    except _core.SessionError:
        return
    result.alignments = [by_exchange.alignment]
    result.divergences, result.divergence_count = by_exchange.divergences, by_exchange.count


__all__ = ["diff", "Alignment", "DiffResult", "DirectionDiff", "Divergence", "FrameDiff"]
