"""The stages between a session's records and the writer of ``wiretape
edit --redact``: the redactor scrubs each direction's byte stream, matches
spanning records; the resealer recomputes the checksums of the frames
holding scrubbed bytes (``Profile.recompute_checksums``). Both hold records
until their bytes can no longer change, at most HOLD_LIMIT bytes."""

from __future__ import annotations

import collections
import itertools
from typing import Callable, Deque, Dict, List, Sequence, Tuple

from ..session import DIRECTIONS
from .edit_specs import Redaction

__all__ = ["Entry", "Redactor", "Resealer", "merged_marks", "MAX_SPAN", "HOLD_LIMIT",
           "LOOKBEHIND"]

#: How far back a match may reach into a direction's earlier records.
MAX_SPAN = 4096


class Entry:
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
        self.entries: Deque[Tuple[int, Entry]] = collections.deque()
        self.scanned_end = 0  # the stream offset the last scan reached
        self.unscanned = 0  # bytes added since
        self.resume = [0] * patterns  # per pattern: where its next match may begin


class Redactor:
    """Applies the patterns to each direction's byte stream and hands the
    records on in order once their bytes can no longer change.

    Linear in the stream: each direction is searched once MAX_SPAN new bytes
    have come (or at the end), from where the last match ended but at most
    MAX_SPAN bytes before the previous search's end, so that a match may
    span records; matches are scrubbed in place, never by joining the held
    records again (which made many matches, or many small records,
    quadratic)."""

    def __init__(self, redactions: Sequence[Redaction], hand_on: Callable[[Entry], None]):
        self.redactions = redactions
        self.hand_on = hand_on
        self.queue: Deque[Entry] = collections.deque()
        self.held = 0  # bytes in the queue
        # one byte stream per channel and direction
        self.streams: Dict[Tuple[int, str], _Stream] = {}
        self.matches = 0

    def _stream(self, entry: Entry) -> _Stream:
        key = (entry.channel, entry.kind)
        stream = self.streams.get(key)
        if stream is None:
            stream = self.streams[key] = _Stream(len(self.redactions))
        return stream

    def add(self, entry: Entry, redact: bool = True) -> None:
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


class Resealer:
    """Between the redactor and the writer: frames each direction with a
    protocol profile and has it recompute the checksums of every whole frame
    holding scrubbed bytes (``Profile.recompute_checksums``), writing the
    changed bytes back into the records they fall in. A record is held until
    every frame it is part of is complete (a frame is at most 1 MiB), or
    until HOLD_LIMIT bytes wait behind it. A tx byte so changed is marked
    as scrubbed too: replay without the profile then takes it as a
    wildcard, as the client's own checksum is over the unscrubbed bytes."""

    def __init__(self, profile, hand_on: Callable[[Entry], None]):
        self.profile = profile
        self.hand_on = hand_on
        # per (channel, direction): each channel's bytes are framed apart
        self.framers: Dict[Tuple[int, str], object] = {}
        self.fed: Dict[Tuple[int, str], int] = {}  # stream bytes given to the framer
        self.framed: Dict[Tuple[int, str], int] = {}  # stream bytes in complete frames
        self.entries: Dict[Tuple[int, str], List[Tuple[int, Entry]]] = {}
        self.first: Dict[Tuple[int, str], int] = {}  # the first entry a next frame may hold
        self.queue: Deque[Tuple[Entry, int]] = collections.deque()
        self.held = 0
        self.frames = 0  # frames whose checksums changed
        self.missed = 0  # ... of which a changed byte was in a record already written

    def add(self, entry: Entry) -> None:
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


def merged_marks(marks: List[Tuple[int, int]]) -> List[Tuple[int, int]]:
    merged: List[Tuple[int, int]] = []
    for offset, length in sorted(marks):
        if merged and offset <= merged[-1][0] + merged[-1][1]:
            last_offset, last_length = merged[-1]
            merged[-1] = (last_offset, max(last_length, offset + length - last_offset))
        else:
            merged.append((offset, length))
    return merged
