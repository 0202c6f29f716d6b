"""``wiretape edit IN OUT``: cut a session down and scrub it before it is
shared (DESIGN §15, docs/cli.md "edit").

- ``cut``: keep the part from FROM to TO (seconds, or exchanges with an
  ``e`` suffix). What was in force at the cut point stays: every record
  before the client's first write (the open, the device's greeting, the
  first settings) is kept, and the settings, modem lines and connected
  client of the moment the cut begins follow it; the cut part is moved back
  in time to start right after the greeting.
- ``redact``: a regular expression over the rx and tx bytes; each match is
  overwritten (with ``*``, or REPLACEMENT repeated to the match's length,
  so lengths and framing stay) and marked by a ``redaction`` event, which
  replay treats as wildcards. A match may span records, up to ``MAX_SPAN``
  bytes. Redacting scrubs every place a value appears (DESIGN §23): it also
  clears the header's host, the device identity's serial number (and its
  part of the identity's by-id name) and the serial numbers of
  ``/dev/serial/by-id`` paths, and applies the patterns to the header's text (port options,
  device address, metadata values, import source) and to every string of
  every event (an open's description, a client's peer...). With a protocol
  profile, the checksums of each frame holding scrubbed bytes are
  recomputed (``Profile.recompute_checksums``), so that a scrubbed
  recording still replays to the driver that made it.
- ``drop_meta``: removes user metadata keys.
- ``channels``: a session of several ports (DESIGN §19) is edited channel
  by channel on its one clock: each channel's bytes are searched and framed
  apart, and its greeting and state are its own. ``--cut`` without
  ``channels`` cuts every channel by the one window and moves them back
  together; with ``channels`` only those channels are cut and redacted
  (the part kept stays at its time, so that the channels keep their order)
  and the others' records are kept as they are. The ``channels`` header
  member is kept.

The header's ``edits`` list says what was done (never the scrubbed text).
The input is never written over."""

from __future__ import annotations

import collections
import dataclasses
import itertools
import os
import pickle
import re
import signal
import stat
import sys
from typing import Callable, Deque, Dict, Iterable, List, Optional, Sequence, Tuple

from .. import _core
from ..session import (DIRECTIONS, SessionPath, event_payload, is_stream, open_session,
                       raise_damage, refuse_same_file, session_files)
from .channels import UnknownChannel, choose_channels, several_channels
from .convert import session_writer

__all__ = ["edit", "edit_in_child", "default_profile", "EditResult", "Cut", "Redaction", "parse_cut", "parse_redaction", "MAX_SPAN"]

#: How far back a match may reach into a direction's earlier records.
MAX_SPAN = 4096

#: A by-id link names the adapter's serial number: what identifies a user.
_BY_ID = re.compile(r"(/dev/serial/by-(?:id|path)/)[^,\s\"]+")
_BY_ID_REPLACEMENT = r"\1redacted"


@dataclasses.dataclass(frozen=True)
class Cut:
    """The part of a session to keep: [start, end) in seconds, or in
    exchanges (numbered from 0, as in mismatch reports) when ``exchanges``."""

    start: Optional[float]
    end: Optional[float]
    exchanges: bool = False
    spec: str = ""  # as given, for messages

    def describe(self) -> str:
        def side(value: Optional[float]) -> str:
            return "" if value is None else f"{value:g}"
        unit = "exchanges" if self.exchanges else "s"
        return f"cut {side(self.start)}:{side(self.end)} {unit}"


@dataclasses.dataclass(frozen=True)
class Redaction:
    """A pattern over payload bytes and what its matches become."""

    pattern: "re.Pattern[bytes]"
    replacement: bytes = b"*"

    def scrub(self, length: int) -> bytes:
        if len(self.replacement) == 1:
            return self.replacement * length
        return (self.replacement * (length // len(self.replacement) + 1))[:length]


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--cut {where} {text!r} is not a number") from None
    if not value >= 0 or value == float("inf"):
        raise ValueError(f"--cut {where} {text!r} must be a finite number >= 0")
    return value


def parse_cut(spec: str) -> Cut:
    """``FROM:TO``: seconds (``1.5:4``, ``1.5s:4s``) or exchanges (``3e:7e``);
    either side may be empty (from the start, to the end)."""
    grammar = "expected FROM:TO in seconds (1.5:4) or exchanges (3e:7e), either side may be empty"
    if spec.count(":") != 1:
        raise ValueError(f"--cut {spec!r}: {grammar}")
    sides = [side.strip() for side in spec.split(":")]
    units = {side[-1] for side in sides if side and side[-1] in "se"}
    if len(units) > 1:
        raise ValueError(f"--cut {spec!r}: both sides must count the same (seconds or exchanges)")
    exchanges = units == {"e"}
    values: List[Optional[float]] = []
    for where, side in zip(("FROM", "TO"), sides):
        if side and side[-1] in "se":
            side = side[:-1]
        values.append(_number(side, where) if side else None)
    start, end = values
    if exchanges and any(v is not None and v != int(v) for v in values):
        raise ValueError(f"--cut {spec!r}: exchanges are whole numbers")
    if start is not None and end is not None and end <= start:
        raise ValueError(f"--cut {spec!r}: TO must be after FROM")
    if start is None and end is None:
        raise ValueError(f"--cut {spec!r}: {grammar}")
    return Cut(start, end, exchanges, spec)


#: The ``=`` between PATTERN and REPLACEMENT: not escaped, not a lookaround's.
_SEPARATOR = re.compile(r"(?<!\\)(?<!\(\?)(?<!\(\?<)(?<!\(\?P)=")


def parse_redaction(spec: str) -> Redaction:
    """``PATTERN[=REPLACEMENT]``: a regular expression (Python syntax) over
    the bytes; ``\\=`` is a literal ``=`` in the pattern, and so is the
    ``=`` of the regex syntax ``(?=``, ``(?<=`` and ``(?P=``."""
    split = _SEPARATOR.search(spec)
    pattern_text, replacement = (spec, "*") if split is None else (
        spec[:split.start()], spec[split.end():])
    if not pattern_text:
        raise ValueError(f"--redact {spec!r}: the pattern is empty")
    if not replacement:
        raise ValueError(f"--redact {spec!r}: the replacement is empty (leave out =... for *)")
    try:
        pattern = re.compile(pattern_text.encode("utf-8"))
    except re.error as error:
        raise ValueError(f"--redact {spec!r}: not a regular expression: {error}") from None
    if pattern.fullmatch(b"") is not None or pattern.search(b"") is not None:
        raise ValueError(f"--redact {spec!r}: the pattern matches the empty string")
    return Redaction(pattern, replacement.encode("utf-8"))


@dataclasses.dataclass(frozen=True)
class EditResult:
    """What edit() did."""

    records: int  # records written
    matches: int  # redacted matches
    redacted_records: int  # records with redacted bytes
    edits: Tuple[str, ...]  # what this edit added to the header's edits list
    profile: Optional[str] = None  # the profile whose checksums were recomputed
    resealed_frames: int = 0  # frames whose checksums it recomputed
    unsealed_frames: int = 0  # ... a byte of which was already written (HOLD_LIMIT)


class _Entry:
    """A record on its way to the output: rx and tx bytes may still change
    (redaction, checksums recomputed) until the stages before the writer
    settle them."""

    __slots__ = ("kind", "t_ns", "data", "marks", "settled", "written", "channel")

    def __init__(self, kind: str, t_ns: int, data: bytes, channel: int = 0):
        self.channel = channel
        self.kind = kind
        self.t_ns = t_ns
        self.data = data
        self.marks: List[Tuple[int, int]] = []  # (offset, length) scrubbed
        self.settled = kind not in DIRECTIONS or not data
        self.written = False


#: How many bytes before a search the redactor keeps for a lookbehind.
LOOKBEHIND = 256

#: How many bytes of records the stages before the writer hold at most
#: while one direction waits for more bytes: past it, that direction is
#: settled as if it had ended (a match or frame reaching further is cut
#: there), so that memory stays bounded.
HOLD_LIMIT = 8 << 20


class _Stream:
    """One direction's bytes held by the redactor: ``buffer`` from stream
    offset ``base`` on, ``marked`` a byte per byte (1: scrubbed), and the
    records not yet settled with the offset each begins at."""

    __slots__ = ("buffer", "marked", "base", "entries", "scanned_end", "unscanned", "resume")

    def __init__(self, patterns: int):
        self.buffer = bytearray()
        self.marked = bytearray()
        self.base = 0
        self.entries: Deque[Tuple[int, _Entry]] = collections.deque()
        self.scanned_end = 0  # the stream offset the last scan reached
        self.unscanned = 0  # bytes added since
        self.resume = [0] * patterns  # per pattern: where its next match may begin


class _Redactor:
    """Applies the patterns to each direction's byte stream and hands the
    records on in order once their bytes can no longer change.

    Linear in the stream: each direction is searched once MAX_SPAN new bytes
    have come (or at the end), from where the last match ended but at most
    MAX_SPAN bytes before the previous search's end, so that a match may
    span records; matches are scrubbed in place, never by joining the held
    records again (which made many matches, or many small records,
    quadratic)."""

    def __init__(self, redactions: Sequence[Redaction], hand_on: Callable[[_Entry], None]):
        self.redactions = redactions
        self.hand_on = hand_on
        self.queue: Deque[_Entry] = collections.deque()
        self.held = 0  # bytes in the queue
        # one byte stream per channel and direction
        self.streams: Dict[Tuple[int, str], _Stream] = {}
        self.matches = 0

    def _stream(self, entry: _Entry) -> _Stream:
        key = (entry.channel, entry.kind)
        stream = self.streams.get(key)
        if stream is None:
            stream = self.streams[key] = _Stream(len(self.redactions))
        return stream

    def add(self, entry: _Entry, redact: bool = True) -> None:
        self.queue.append(entry)
        if not self.redactions or not redact:
            entry.settled = True
        if not entry.settled:
            stream = self._stream(entry)
            stream.entries.append((stream.base + len(stream.buffer), entry))
            stream.buffer += entry.data
            stream.marked += bytes(len(entry.data))
            stream.unscanned += len(entry.data)
            self.held += len(entry.data)
            if stream.unscanned >= MAX_SPAN:
                self._scan(stream, final=False)
        self._drain()
        while self.held > HOLD_LIMIT and self.queue and not self.queue[0].settled:
            self._scan(self._stream(self.queue[0]), final=True)
            self._drain()

    def finish(self) -> None:
        for stream in self.streams.values():
            self._scan(stream, final=True)
        self._drain()

    def _scan(self, stream: _Stream, final: bool) -> None:
        """Applies the patterns to what `stream` holds. A match that
        reaches its end may grow with the next bytes (a greedy pattern cut
        by a record boundary): unless `final`, it waits for them."""
        buffer, base, end = stream.buffer, stream.base, len(stream.buffer)
        floor = stream.scanned_end - MAX_SPAN
        marked = stream.marked
        for index, redaction in enumerate(self.redactions):
            position = max(0, max(floor, stream.resume[index]) - base)
            scrub = redaction.scrub
            # Over the bytes as the patterns before this one left them.
            for match in redaction.pattern.finditer(bytes(buffer), position):
                start, stop = match.span()
                if stop == end and not final:
                    stream.resume[index] = base + start
                    break
                if stop == start:  # an empty match (a lookaround) scrubs nothing
                    continue
                buffer[start:stop] = scrub(stop - start)
                marked[start:stop] = b"\x01" * (stop - start)
                self.matches += 1
                stream.resume[index] = base + stop
        stream.scanned_end = base + end
        stream.unscanned = 0
        # No later search begins before `settled`: records ending there are done.
        settled = base + end if final else min(
            [max(resume, stream.scanned_end - MAX_SPAN) for resume in stream.resume] or [base + end])
        while stream.entries:
            offset, entry = stream.entries[0]
            size = len(entry.data)
            if offset + size > settled:
                break
            stream.entries.popleft()
            at = offset - base
            entry.data = bytes(buffer[at:at + size])
            entry.marks = _runs(stream.marked, at, at + size)
            entry.settled = True
        # Bytes before the next search stay a little, for lookbehinds:
        # '(?<=SERI:)[^;]*' scrubs only the value.
        keep_from = min(settled, stream.entries[0][0] if stream.entries else base + end)
        keep_from -= LOOKBEHIND
        if keep_from > base:
            del buffer[:keep_from - base]
            del stream.marked[:keep_from - base]
            stream.base = keep_from

    def _drain(self) -> None:
        while self.queue and self.queue[0].settled:
            entry = self.queue.popleft()
            if entry.kind in DIRECTIONS:
                self.held -= len(entry.data)
            self.hand_on(entry)


def _runs(marked: bytearray, start: int, stop: int) -> List[Tuple[int, int]]:
    """The (offset from `start`, length) of each run of marked bytes in
    marked[start:stop]."""
    runs: List[Tuple[int, int]] = []
    at = marked.find(1, start, stop)
    while at != -1:
        run_end = marked.find(0, at, stop)
        if run_end == -1:
            run_end = stop
        runs.append((at - start, run_end - at))
        at = marked.find(1, run_end, stop)
    return runs


class _Resealer:
    """Between the redactor and the writer: frames each direction with a
    protocol profile and has it recompute the checksums of every whole frame
    holding scrubbed bytes (``Profile.recompute_checksums``), writing the
    changed bytes back into the records they fall in. A record is held until
    every frame it is part of is complete (a frame is at most 1 MiB), or
    until HOLD_LIMIT bytes wait behind it. A tx byte so changed is marked
    as scrubbed too: replay without the profile then takes it as a
    wildcard, as the client's own checksum is over the unscrubbed bytes."""

    def __init__(self, profile, hand_on: Callable[[_Entry], None]):
        self.profile = profile
        self.hand_on = hand_on
        # per (channel, direction): each channel's bytes are framed apart
        self.framers: Dict[Tuple[int, str], object] = {}
        self.fed: Dict[Tuple[int, str], int] = {}  # stream bytes given to the framer
        self.framed: Dict[Tuple[int, str], int] = {}  # stream bytes in complete frames
        self.entries: Dict[Tuple[int, str], List[Tuple[int, _Entry]]] = {}
        self.first: Dict[Tuple[int, str], int] = {}  # the first entry a next frame may hold
        self.queue: Deque[Tuple[_Entry, int]] = collections.deque()
        self.held = 0
        self.frames = 0  # frames whose checksums changed
        self.missed = 0  # ... of which a changed byte was in a record already written

    def add(self, entry: _Entry) -> None:
        end = 0
        if entry.kind in DIRECTIONS and entry.data:
            kind = (entry.channel, entry.kind)
            if kind not in self.framers:
                self.framers[kind] = self.profile.framer(entry.kind)
                self.fed[kind] = self.framed[kind] = self.first[kind] = 0
                self.entries[kind] = []
            self.entries[kind].append((self.fed[kind], entry))
            self.fed[kind] += len(entry.data)
            end = self.fed[kind]
            self.held += len(entry.data)
            for frame, how in self.framers[kind].feed(entry.data, entry.t_ns):
                self._frame(kind, frame, how)
        self.queue.append((entry, end))
        self._drain()

    def finish(self) -> None:
        for kind, framer in self.framers.items():
            tail = framer.finish()
            if tail is not None:
                self._frame(kind, *tail)
        self._drain()

    def _frame(self, key: Tuple[int, str], frame: bytes, how: str) -> None:
        kind = key[1]
        start = self.framed[key]
        stop = self.framed[key] = start + len(frame)
        entries, first = self.entries[key], self.first[key]
        while first < len(entries) and entries[first][0] + len(entries[first][1].data) <= start:
            first += 1
        if first > 4096:
            del entries[:first]
            first = 0
        self.first[key] = first
        if how not in ("delimited", "broken"):
            return  # cut short or cut at the size limit: no whole frame to seal
        held = []
        scrubbed = False
        for offset, entry in itertools.islice(entries, first, None):
            if offset >= stop:
                break
            held.append((offset, entry))
            lo, hi = max(start, offset) - offset, min(stop, offset + len(entry.data)) - offset
            scrubbed = scrubbed or any(at < hi and at + length > lo for at, length in entry.marks)
        if not scrubbed:
            return
        sealed = self.profile.recompute_checksums(kind, frame)
        if sealed == frame:
            return
        self.frames += 1
        missed = False
        for at in (i for i in range(len(frame)) if frame[i] != sealed[i]):
            where = start + at
            for offset, entry in held:
                if offset <= where < offset + len(entry.data):
                    if entry.written:
                        missed = True
                        break
                    if not isinstance(entry.data, bytearray):
                        entry.data = bytearray(entry.data)
                    entry.data[where - offset] = sealed[at]
                    if kind == "tx":
                        entry.marks.append((where - offset, 1))
                    break
        self.missed += missed

    def _drain(self) -> None:
        while self.queue:
            entry, end = self.queue[0]
            if end > self.framed.get((entry.channel, entry.kind), end) and self.held <= HOLD_LIMIT:
                break
            self.queue.popleft()
            if end:
                self.held -= len(entry.data)
            entry.written = True
            self.hand_on(entry)


def _merged(marks: List[Tuple[int, int]]) -> List[Tuple[int, int]]:
    merged: List[Tuple[int, int]] = []
    for offset, length in sorted(marks):
        if merged and offset <= merged[-1][0] + merged[-1][1]:
            last_offset, last_length = merged[-1]
            merged[-1] = (last_offset, max(last_length, offset + length - last_offset))
        else:
            merged.append((offset, length))
    return merged


def _exchange_starts(path: str, channel: str = "") -> List[int]:
    """The time each exchange begins (its first tx byte; for one with no
    request, its first rx), exchanges as replay numbers them
    (``_core.session_exchanges``; per channel in a session of several)."""
    starts: List[int] = []
    options = f"channel={channel}" if channel else ""
    for exchange in _core.session_exchanges(path, options=options):
        first = exchange.request_first_t_ns
        starts.append(first if first is not None else exchange.response_first_t_ns)
    return starts


def _cut_window(path: str, cut: Cut, channel: str = ""
                ) -> Tuple[Optional[int], Optional[int]]:
    """[start, end) of the cut in the session's nanoseconds; exchanges are
    `channel`'s (named in a session of several channels)."""
    if not cut.exchanges:
        to_ns = (lambda s: None if s is None else int(round(s * 1e9)))
        return to_ns(cut.start), to_ns(cut.end)
    if is_stream(path):
        raise ValueError(f"--cut {cut.spec}: counting exchanges reads {path} twice; "
                         "give a regular file, not a pipe or FIFO")
    starts = _exchange_starts(path, channel)

    def at(index: Optional[float], side: str) -> Optional[int]:
        if index is None:
            return None
        if index >= len(starts):
            if side == "TO" and index == len(starts):
                return None
            whose = f"channel {channel} of the session" if channel else "the session"
            raise ValueError(f"--cut {cut.spec}: {whose} has {len(starts)} "
                             f"exchanges (0 to {len(starts) - 1}), no exchange {int(index)}")
        return starts[int(index)]

    return at(cut.start, "FROM"), at(cut.end, "TO")


_STATE_EVENTS = ("settings", "modem_lines")
# The lines the host sets (a modem_lines event's dtr, rts); the device's
# inputs (cts, dsr, ri, cd) are served, and held over a cut.
_HOST_LINES = {"dtr", "rts"}


class _Cutter:
    """Keeps the greeting, the state in force at the cut and the cut part,
    moved back in time; feeds what it keeps on (``keep(channel, kind,
    t_ns, data)``).

    The channels of a session share its one clock: the cut part of every
    channel resumes where the session's client first wrote (on any
    channel), moved back by one shift. Each channel has its own greeting
    (the records before its client's first write), settings, modem lines
    and client: a greeting that ends after the session's first write but
    before the cut is held over the cut, as the state is. With `move`
    false the part kept stays at its time (a cut of some channels only)."""

    def __init__(self, start: Optional[int], end: Optional[int], keep, move: bool = True):
        self.start, self.end, self.keep = start, end, keep
        self.move = move
        self.greeting_channels: Dict[int, bool] = {}  # channel: still in its greeting
        self.first_write: Optional[int] = None  # when a client first wrote: where the cut part resumes
        self.state: Dict[Tuple[int, str], Tuple[int, str, int, bytes]] = {}
        self.greetings: List[Tuple[int, str, int, bytes]] = []  # held over the cut
        self.clients: Dict[int, Tuple[int, str, int, bytes]] = {}
        # Client sessions by the bridge's rule (C++): a monitor's connect or
        # disconnect does not change the client in force.
        self.sessions: Dict[int, _core.ClientSessionTracker] = {}
        self.shift = 0
        self.started = start is None or start == 0
        self.closing: Dict[int, Tuple[str, int, bytes]] = {}

    def add(self, kind: str, t_ns: int, data: bytes, channel: int = 0) -> None:
        in_greeting = self.greeting_channels.setdefault(channel, True)
        if in_greeting and not (kind == "tx" and data):
            if self.first_write is None:
                self.keep(channel, kind, t_ns, data)
                return
            if not self.started:
                if t_ns < self.start:
                    if self.move:
                        # after the session's first write, before the cut: held over it
                        self.greetings.append((channel, kind, t_ns, data))
                    else:
                        self.keep(channel, kind, t_ns, data)
                    return
                self._begin(t_ns)
            if self.end is None or t_ns < self.end:
                self.keep(channel, kind, t_ns - self.shift, data)
            return
        if in_greeting:
            self.greeting_channels[channel] = False
            if self.first_write is None:
                self.first_write = t_ns
        if self.end is not None and t_ns >= self.end:
            if kind in ("close", "device_lost") and channel not in self.closing:
                self.closing[channel] = (kind, t_ns, data)
            return
        if not self.started:
            if t_ns < self.start:
                self._remember(channel, kind, t_ns, data)
                return
            self._begin(t_ns)
        self.keep(channel, kind, t_ns - self.shift, data)

    def _remember(self, channel: int, kind: str, t_ns: int, data: bytes) -> None:
        if kind in _STATE_EVENTS:
            key = kind
            if kind == "modem_lines":
                members = sorted((event_payload(data) or {}).keys())
                if set(members) & _HOST_LINES:
                    # The client's own line changes are checked on replay:
                    # held over the cut they would be changes it never made.
                    return
                key += ":" + ",".join(members)
            self.state[(channel, key)] = (channel, kind, t_ns, data)
        elif kind in ("client_connect", "client_disconnect"):
            sessions = self.sessions.get(channel)
            if sessions is None:
                sessions = self.sessions[channel] = _core.ClientSessionTracker()
            change = sessions.feed(kind, data)
            if change == "began":
                self.clients[channel] = (channel, kind, t_ns, data)
            elif change == "ended":
                self.clients.pop(channel, None)

    def _begin(self, t_ns: int) -> None:
        self.started = True
        resume = self.first_write if self.first_write is not None else 0
        if not self.move:
            # the held state goes just before the cut part, which stays where it was
            resume = self.start
        self.shift = max(0, self.start - resume) if self.move else 0
        held = sorted(self.greetings + list(self.state.values()) + list(self.clients.values()),
                      key=lambda item: item[2])
        for channel, kind, _, data in held:
            self.keep(channel, kind, resume, data)

    def finish(self) -> None:
        if not self.started and self.start is not None:
            self._begin(self.start)
        for channel, (kind, t_ns, data) in sorted(self.closing.items(),
                                                  key=lambda item: item[1][1]):
            self.keep(channel, kind, (self.end if self.end is not None else t_ns) - self.shift,
                      data)


def _scrub_text(text: str, redactions: Sequence[Redaction]) -> str:
    return _apply_patterns(_BY_ID.sub(_BY_ID_REPLACEMENT, text), redactions)


def _apply_patterns(text: str, redactions: Sequence[Redaction]) -> str:
    data = text.encode("utf-8", "surrogatepass")
    for redaction in redactions:
        data = redaction.pattern.sub(lambda m: redaction.scrub(len(m.group(0))), data)
    return data.decode("utf-8", "replace")


def _scrub_value(value, redactions: Sequence[Redaction]):
    """Every string in a JSON value scrubbed (lists and objects walked)."""
    if isinstance(value, str):
        return _scrub_text(value, redactions)
    if isinstance(value, list):
        return [_scrub_value(item, redactions) for item in value]
    if isinstance(value, dict):
        return {key: _scrub_value(item, redactions) for key, item in value.items()}
    return value


def _scrub_header(header, redactions: Sequence[Redaction],
                  chosen: Optional[frozenset] = None) -> None:
    """Every header field that can name the device, the machine or a user:
    the host is cleared, and so is the device identity's serial number
    with its part of the by-id name (DESIGN §20); the port options, the
    device's address, metadata values, the rest of the device identity and
    where an import came from are scrubbed."""
    header.host = ""
    if chosen is None or 0 in chosen:
        _scrub_port(header, redactions)
    if header.channels:
        # A session of several ports: each chosen channel's port members
        # (the top-level ones are channel 0's, written from it).
        channels = list(header.channels)
        for channel in channels:
            if chosen is None or channel.id in chosen:
                _scrub_port(channel, redactions)
        header.channels = channels
    header.metadata = {key: _scrub_text(value, redactions)
                       for key, value in header.metadata.items()}
    header.source_files = [_scrub_text(name, redactions) for name in header.source_files]
    header.source_details = {key: _scrub_text(value, redactions)
                             for key, value in header.source_details.items()}


def _scrub_port(port, redactions: Sequence[Redaction]) -> None:
    """A header's (or a channel's) port members: the identity's serial
    number cleared by the session model's rule, the rest scrubbed."""
    if isinstance(port, _core.SessionHeader):
        port.clear_device_serial()
        identity = port.device_identity
    elif port.device_identity is not None:
        # The rule of clearing the serial number lives in SessionHeader.
        holder = _core.SessionHeader()
        holder.device_identity = port.device_identity
        holder.clear_device_serial()
        identity = holder.device_identity
    else:
        identity = None
    if identity is not None:
        # The by-id name keeps what is not the serial number (vendor, model,
        # interface), so that replay still presents it: only the patterns apply.
        port.device_identity = {key: _apply_patterns(value, redactions)
                                for key, value in dict(identity).items()}
    port.port_options = _scrub_text(port.port_options, redactions)
    port.device_address = _scrub_text(port.device_address, redactions)


def _scrubbed_event(kind: str, data: bytes, redactions: Sequence[Redaction]) -> bytes:
    """An event's payload with every string in it scrubbed: the open's
    description, a client's peer address, a device_lost's error... (by-id
    serial numbers and the patterns), made anew by the record-kind table (a
    member it does not know is a ValueError naming it). A payload that is
    not JSON has the patterns applied to its bytes."""
    payload = event_payload(data)
    if payload is None:
        for redaction in redactions:
            data = redaction.pattern.sub(lambda m: redaction.scrub(len(m.group(0))), data)
        return data
    if not payload:
        return data
    changed = _scrub_value(payload, redactions)
    if changed == payload:
        return data
    return _core.event_payload(kind, changed)


#: The metadata key that names the protocol profile of a recording
#: (``--meta profile=scip``): edit's default profile.
PROFILE_META_KEY = "profile"


def default_profile(header) -> Optional[str]:
    """The profile a recording names in its metadata (``profile=NAME``, a
    known profile), else None."""
    name = header.metadata.get(PROFILE_META_KEY)
    return name if name in _core.profile_names() else None


def _profile(spec: str):
    """The profile `spec` names, or declares (``framing=...,checksum=...``)."""
    try:
        if "=" in spec:
            return _core.declared_profile(spec)
        return _core.find_profile(spec)
    except _core.OptionError as error:
        raise ValueError(f"--profile {spec!r}: {error}") from None


def _remove_output(dst: str, before: Optional[os.stat_result]) -> None:
    """Removes what an interrupted edit wrote to `dst`: a regular file it
    created or wrote over (an output that is not a regular file, a FIFO or
    /dev/stdout, is written through and cannot be taken back)."""
    try:
        now = os.stat(dst)
    except OSError:
        return
    if not stat.S_ISREG(now.st_mode):
        return
    if before is not None and (before.st_ino, before.st_mtime_ns, before.st_size) == (
            now.st_ino, now.st_mtime_ns, now.st_size):
        return  # never opened: the file there is not ours
    try:
        os.unlink(dst)
    except OSError:
        pass


def _stat_or_none(path: str) -> Optional[os.stat_result]:
    try:
        return os.stat(path)
    except OSError:
        return None


def edit(src: SessionPath, dst: SessionPath, cut: Optional[Cut] = None,
         redact: Iterable[Redaction] = (), drop_meta: Iterable[str] = (),
         profile: Optional[str] = "", channels: Iterable[str] = ()) -> EditResult:
    """Writes an edited copy of the session `src` to `dst` (a .wtape).
    `profile`: the protocol profile whose checksums are recomputed over
    scrubbed bytes, a name or a declared profile's keys
    (``framing=...,checksum=...``); "" (the default) for the one the
    session's metadata names (``profile=NAME``), None for none. Raises
    ValueError for an edit that does not fit the session (a metadata key it
    lacks, an exchange past its end) or an unknown profile; SessionError after
    writing what came before when `src` is damaged. Interrupted
    (KeyboardInterrupt), it removes the output it was writing.
    `channels`: names of channels of a session of several ports that
    `cut` and `redact` apply to (empty: every channel); the other
    channels' records are kept as they are (see the module's notes)."""
    src, dst = os.fspath(src), os.fspath(dst)
    redactions = list(redact)
    drop = list(drop_meta)
    channels = list(channels)
    if cut is None and not redactions and not drop:
        raise ValueError("nothing to edit: give --cut, --redact or --drop-meta")
    if channels and cut is None and not redactions:
        raise ValueError("--channel limits --cut and --redact: give one of them")
    refuse_same_file(session_files(src), [dst])
    reader = open_session(src)
    header = reader.header
    try:
        chosen = choose_channels(header, channels, src)
    except UnknownChannel as error:
        raise UnknownChannel(f"--channel: {error}") from None
    if cut is not None and cut.exchanges and several_channels(header) and len(channels) != 1:
        raise ValueError(f"--cut {cut.spec}: exchanges are numbered per channel in a session "
                         "of several channels: give one --channel NAME to count them on")
    if profile == "":
        profile = default_profile(header)
    framing = _profile(profile) if profile is not None and redactions else None
    metadata = dict(header.metadata)
    for key in drop:
        if key not in metadata:
            known = ", ".join(sorted(metadata)) or "none"
            raise ValueError(f"--drop-meta {key!r}: {src} has no metadata key {key!r} "
                             f"(its keys: {known})")
        del metadata[key]
    header.metadata = metadata
    counted_on = channels[0] if cut is not None and cut.exchanges and channels else ""
    window = _cut_window(src, cut, counted_on) if cut is not None else (None, None)

    earlier_edits = list(header.edits)
    edits: List[str] = []
    limited = "" if chosen is None else " of channel" + ("s " if len(channels) > 1 else " ") \
        + ", ".join(sorted(set(channels)))
    if cut is not None:
        edits.append(cut.describe() + limited)
    if redactions:
        _scrub_header(header, redactions, chosen)
    edits += [f"dropped meta {key}" for key in drop]

    if redactions:
        # The header comes first, before any match is found: it names the
        # patterns' count; the redaction events say where each match was.
        count = len(redactions)
        sealed = f"; checksums recomputed ({framing.name})" if framing is not None else ""
        edits.append(f"redacted {count} pattern{'s' if count != 1 else ''}{limited}"
                     f" (host and by-id serial numbers cleared{sealed})")
    header.edits = earlier_edits + edits
    before = _stat_or_none(dst)
    counts = {"records": 0, "marked": 0}
    try:
        with session_writer(dst, header) as writer:
            def emit(entry: _Entry) -> None:
                marks = _merged(entry.marks)
                for offset, length in marks:
                    payload = _core.event_payload("redaction", {"offset": offset, "length": length})
                    writer.write("redaction", entry.t_ns, payload, channel=entry.channel)
                writer.write(entry.kind, entry.t_ns, bytes(entry.data), channel=entry.channel)
                counts["records"] += 1
                counts["marked"] += bool(marks)

            resealer = _Resealer(framing, emit) if framing is not None else None
            redactor = _Redactor(redactions, resealer.add if resealer is not None else emit)

            def keep(channel: int, kind: str, t_ns: int, data: bytes) -> None:
                if redactions and kind not in DIRECTIONS:
                    data = _scrubbed_event(kind, data, redactions)
                redactor.add(_Entry(kind, t_ns, data, channel))

            cutter = (_Cutter(window[0], window[1], keep, move=chosen is None)
                      if cut is not None else None)
            for record in reader:
                channel = record.channel
                if chosen is not None and channel not in chosen:
                    redactor.add(_Entry(record.kind, record.t_ns, record.data, channel),
                                 redact=False)
                elif cutter is not None:
                    cutter.add(record.kind, record.t_ns, record.data, channel)
                else:
                    keep(channel, record.kind, record.t_ns, record.data)
            if cutter is not None:
                cutter.finish()
            redactor.finish()
            if resealer is not None:
                resealer.finish()
    except KeyboardInterrupt:
        _remove_output(dst, before)
        raise
    raise_damage(reader)
    return EditResult(records=counts["records"], matches=redactor.matches,
                      redacted_records=counts["marked"], edits=tuple(edits),
                      profile=framing.name if framing is not None else None,
                      resealed_frames=resealer.frames if resealer is not None else 0,
                      unsealed_frames=resealer.missed if resealer is not None else 0)


def edit_in_child(src: SessionPath, dst: SessionPath, **options) -> EditResult:
    """edit() in a forked child while this process only waits for it.

    Python's ``re`` does not look at signals while it matches, so a
    catastrophic pattern (``(a+)+$`` over a long ``aaa...b``) would hold
    SIGINT and SIGTERM off for as long as it runs, and the command could
    neither end nor remove its partial output. Waiting on a pipe, this
    process takes the signal at once (its handler raises
    KeyboardInterrupt): it kills the child, removes the output and lets the
    command exit 130/143. A fork costs about a millisecond; running the
    matching in a thread would not help (``re`` holds the GIL throughout).
    The child's outcome, a result or an exception, comes back pickled."""
    src, dst = os.fspath(src), os.fspath(dst)
    before = _stat_or_none(dst)
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    reading, writing = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: never returns into the caller's code
        status = 1
        try:
            os.close(reading)
            _end_with_parent()
            for signum in (signal.SIGINT, signal.SIGTERM):
                # A signal the caller ignores stays ignored (a background job's SIGINT).
                if signal.getsignal(signum) is not signal.SIG_IGN:
                    signal.signal(signum, signal.SIG_DFL)
            try:
                outcome = ("result", edit(src, dst, **options))
            except BaseException as error:  # every failure goes to the parent
                outcome = ("error", error)
            try:
                message = pickle.dumps(outcome)
            except Exception:
                message = pickle.dumps(("error", RuntimeError(str(outcome[1]))))
            with os.fdopen(writing, "wb") as pipe:
                pipe.write(message)
            status = 0
        finally:
            os._exit(status)
    os.close(writing)
    try:
        with os.fdopen(reading, "rb") as pipe:
            message = pipe.read()
        _, wait_status = os.waitpid(pid, 0)
    except BaseException:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        _remove_output(dst, before)
        raise
    if not message:
        _remove_output(dst, before)
        raise RuntimeError(f"edit {src} -> {dst}: the editing process ended without a result "
                           f"({_described_status(wait_status)})")
    kind, value = pickle.loads(message)
    if kind == "error":
        raise value
    return value


def _end_with_parent() -> None:
    """The child ends when its parent does, however the parent ended (even
    SIGKILL): a catastrophic match must not outlive the command as an orphan
    holding its output pipes. Linux only (prctl PR_SET_PDEATHSIG)."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _described_status(wait_status: int) -> str:
    if os.WIFSIGNALED(wait_status):
        return f"killed by signal {os.WTERMSIG(wait_status)}"
    return f"exit status {os.waitstatus_to_exitcode(wait_status)}"
