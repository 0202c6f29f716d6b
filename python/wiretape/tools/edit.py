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
  replay treats as wildcards: a scrubbed recording still replays to the
  driver that made it. A match may span records, up to ``MAX_SPAN`` bytes.
  Redacting also clears the header's host and the serial numbers of
  ``/dev/serial/by-id`` paths, and applies the patterns to the header's
  text.
- ``drop_meta``: removes user metadata keys.

The header's ``edits`` list says what was done (never the scrubbed text).
The input is never written over."""

from __future__ import annotations

import collections
import dataclasses
import os
import re
from typing import Deque, Dict, Iterable, List, Optional, Sequence, Tuple

from .. import _core
from ..session import (DIRECTIONS, SessionPath, event_payload, is_stream, open_session,
                       raise_damage, refuse_same_file, session_files)
from .convert import session_writer

__all__ = ["edit", "EditResult", "Cut", "Redaction", "parse_cut", "parse_redaction", "MAX_SPAN"]

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


def parse_redaction(spec: str) -> Redaction:
    """``PATTERN[=REPLACEMENT]``: a regular expression (Python syntax) over
    the bytes; ``\\=`` is a literal ``=`` in the pattern."""
    split = re.search(r"(?<!\\)=", spec)
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


class _Entry:
    __slots__ = ("kind", "t_ns", "data", "marks", "settled")

    def __init__(self, kind: str, t_ns: int, data: bytes):
        self.kind = kind
        self.t_ns = t_ns
        self.data = bytearray(data) if kind in DIRECTIONS else data
        self.marks: List[Tuple[int, int]] = []
        self.settled = kind not in DIRECTIONS


class _Redactor:
    """Applies the patterns to each direction's byte stream as records
    arrive, holding back the last MAX_SPAN bytes of each direction so that
    a match spanning records is found, and hands records on in order."""

    def __init__(self, redactions: Sequence[Redaction], write):
        self.redactions = redactions
        self.write = write
        self.queue: Deque[_Entry] = collections.deque()
        self.window: Dict[str, List[_Entry]] = {kind: [] for kind in DIRECTIONS}
        self.matches = 0
        self.records = 0
        self.marked_records = 0

    def add(self, entry: _Entry) -> None:
        self.queue.append(entry)
        if entry.kind in DIRECTIONS and self.redactions:
            self._scan(entry)
        else:
            entry.settled = True
        self._drain()

    def _scan(self, entry: Optional[_Entry], kind: str = "") -> None:
        """Applies the patterns to the window of `entry`'s direction. A match
        that reaches the window's end may grow with the next record (a
        greedy pattern cut by a record boundary): it waits for it, or for
        the end of the session (entry None)."""
        final = entry is None
        window = self.window[kind if final else entry.kind]
        if final:
            if not window:
                return
        else:
            window.append(entry)
        held = sum(len(e.data) for e in window[:-1])
        while window and held - len(window[0].data) >= MAX_SPAN:
            held -= len(window[0].data)
            window.pop(0).settled = True
        starts, position = [], 0
        for e in window:
            starts.append(position)
            position += len(e.data)
        new_from = position if final else starts[-1]
        text = b"".join(bytes(e.data) for e in window)
        for redaction in self.redactions:
            for match in redaction.pattern.finditer(text):
                if match.end() < new_from:
                    continue  # applied when its last record came
                if match.end() == len(text) and not final:
                    continue  # may grow with the next record
                self.matches += 1
                scrub = redaction.scrub(match.end() - match.start())
                for e, start in zip(window, starts):
                    lo, hi = max(match.start(), start), min(match.end(), start + len(e.data))
                    if lo < hi:
                        e.data[lo - start:hi - start] = scrub[lo - match.start():hi - match.start()]
                        e.marks.append((lo - start, hi - lo))
                text = b"".join(bytes(e.data) for e in window)

    def _drain(self, everything: bool = False) -> None:
        while self.queue and (everything or self.queue[0].settled):
            entry = self.queue.popleft()
            self.marked_records += bool(entry.marks)
            for offset, length in _merged(entry.marks):
                payload = _core.event_payload("redaction", {"offset": offset, "length": length})
                self.write("redaction", entry.t_ns, payload)
            self.write(entry.kind, entry.t_ns, bytes(entry.data))
            self.records += 1

    def finish(self) -> None:
        if self.redactions:
            for kind in DIRECTIONS:
                self._scan(None, kind)
        self._drain(everything=True)


def _merged(marks: List[Tuple[int, int]]) -> List[Tuple[int, int]]:
    merged: List[Tuple[int, int]] = []
    for offset, length in sorted(marks):
        if merged and offset <= merged[-1][0] + merged[-1][1]:
            last_offset, last_length = merged[-1]
            merged[-1] = (last_offset, max(last_length, offset + length - last_offset))
        else:
            merged.append((offset, length))
    return merged


def _exchange_starts(path: str) -> List[int]:
    """The time each exchange begins (its first tx byte; for one with no
    request, its first rx), exchanges as replay numbers them
    (``_core.session_exchanges``)."""
    starts: List[int] = []
    for exchange in _core.session_exchanges(path):
        first = exchange.request_first_t_ns
        starts.append(first if first is not None else exchange.response_first_t_ns)
    return starts


def _cut_window(path: str, cut: Cut) -> Tuple[Optional[int], Optional[int]]:
    """[start, end) of the cut in the session's nanoseconds."""
    if not cut.exchanges:
        to_ns = (lambda s: None if s is None else int(round(s * 1e9)))
        return to_ns(cut.start), to_ns(cut.end)
    if is_stream(path):
        raise ValueError(f"--cut {cut.spec}: counting exchanges reads {path} twice; "
                         "give a regular file, not a pipe or FIFO")
    starts = _exchange_starts(path)

    def at(index: Optional[float], side: str) -> Optional[int]:
        if index is None:
            return None
        if index >= len(starts):
            if side == "TO" and index == len(starts):
                return None
            raise ValueError(f"--cut {cut.spec}: the session has {len(starts)} "
                             f"exchanges (0 to {len(starts) - 1}), no exchange {int(index)}")
        return starts[int(index)]

    return at(cut.start, "FROM"), at(cut.end, "TO")


_STATE_EVENTS = ("settings", "modem_lines")


class _Cutter:
    """Keeps the greeting, the state in force at the cut and the cut part,
    moved back in time; feeds what it keeps on."""

    def __init__(self, start: Optional[int], end: Optional[int], keep):
        self.start, self.end, self.keep = start, end, keep
        self.in_greeting = True
        self.first_write = 0  # when the client first wrote: where the cut part resumes
        self.state: Dict[str, Tuple[str, int, bytes]] = {}
        self.client: Optional[Tuple[str, int, bytes]] = None
        # Client sessions by the bridge's rule (C++): a monitor's connect or
        # disconnect does not change the client in force.
        self.sessions = _core.ClientSessionTracker()
        self.shift = 0
        self.started = start is None or start == 0
        self.closing: Optional[Tuple[str, int, bytes]] = None

    def add(self, kind: str, t_ns: int, data: bytes) -> None:
        if self.in_greeting and not (kind == "tx" and data):
            self.keep(kind, t_ns, data)
            return
        if self.in_greeting:
            self.in_greeting = False
            self.first_write = t_ns
        if self.end is not None and t_ns >= self.end:
            if kind in ("close", "device_lost") and self.closing is None:
                self.closing = (kind, t_ns, data)
            return
        if not self.started:
            if t_ns < self.start:
                self._remember(kind, t_ns, data)
                return
            self._begin(t_ns)
        self.keep(kind, t_ns - self.shift, data)

    def _remember(self, kind: str, t_ns: int, data: bytes) -> None:
        if kind in _STATE_EVENTS:
            key = kind
            if kind == "modem_lines":
                key += ":" + ",".join(sorted((event_payload(data) or {}).keys()))
            self.state[key] = (kind, t_ns, data)
        elif kind in ("client_connect", "client_disconnect"):
            change = self.sessions.feed(kind, data)
            if change == "began":
                self.client = (kind, t_ns, data)
            elif change == "ended":
                self.client = None

    def _begin(self, t_ns: int) -> None:
        self.started = True
        resume = self.first_write
        self.shift = max(0, self.start - resume)
        held = sorted(list(self.state.values()) + ([self.client] if self.client else []),
                      key=lambda item: item[1])
        for kind, _, data in held:
            self.keep(kind, resume, data)

    def finish(self) -> None:
        if not self.started and self.start is not None:
            self._begin(self.start)
        if self.closing is not None:
            kind, t_ns, data = self.closing
            self.keep(kind, (self.end if self.end is not None else t_ns) - self.shift, data)


def _scrub_header_text(text: str, redactions: Sequence[Redaction]) -> str:
    text = _BY_ID.sub(_BY_ID_REPLACEMENT, text)
    data = text.encode("utf-8", "surrogatepass")
    for redaction in redactions:
        data = redaction.pattern.sub(lambda m: redaction.scrub(len(m.group(0))), data)
    return data.decode("utf-8", "replace")


def _scrubbed_event(kind: str, data: bytes) -> bytes:
    """Event payloads name devices too (open's description): by-id serial
    numbers are cleared there, the payload made anew by the record-kind
    table (a member it does not know is a ValueError naming it)."""
    payload = event_payload(data)
    if not payload:
        return data
    changed = {key: _BY_ID.sub(_BY_ID_REPLACEMENT, value) if isinstance(value, str) else value
               for key, value in payload.items()}
    if changed == payload:
        return data
    return _core.event_payload(kind, changed)


def edit(src: SessionPath, dst: SessionPath, cut: Optional[Cut] = None,
         redact: Iterable[Redaction] = (), drop_meta: Iterable[str] = ()) -> EditResult:
    """Writes an edited copy of the session `src` to `dst` (a .wtape).
    Raises ValueError for an edit that does not fit the session (a metadata
    key it lacks, an exchange past its end); SessionError after writing
    what came before when `src` is damaged."""
    src, dst = os.fspath(src), os.fspath(dst)
    redactions = list(redact)
    drop = list(drop_meta)
    if cut is None and not redactions and not drop:
        raise ValueError("nothing to edit: give --cut, --redact or --drop-meta")
    refuse_same_file(session_files(src), [dst])
    reader = open_session(src)
    header = reader.header
    metadata = dict(header.metadata)
    for key in drop:
        if key not in metadata:
            known = ", ".join(sorted(metadata)) or "none"
            raise ValueError(f"--drop-meta {key!r}: {src} has no metadata key {key!r} "
                             f"(its keys: {known})")
        del metadata[key]
    header.metadata = metadata
    window = _cut_window(src, cut) if cut is not None else (None, None)

    earlier_edits = list(header.edits)
    edits: List[str] = []
    if cut is not None:
        edits.append(cut.describe())
    if redactions:
        header.host = ""
        header.port_options = _scrub_header_text(header.port_options, redactions)
        header.metadata = {key: _scrub_header_text(value, redactions)
                           for key, value in metadata.items()}
    edits += [f"dropped meta {key}" for key in drop]

    if redactions:
        # The header comes first, before any match is found: it names the
        # patterns' count; the redaction events say where each match was.
        count = len(redactions)
        edits.append(f"redacted {count} pattern{'s' if count != 1 else ''}"
                     " (host and by-id serial numbers cleared)")
    header.edits = earlier_edits + edits
    writer = session_writer(dst, header)
    with writer:
        def write(kind: str, t_ns: int, data: bytes) -> None:
            writer.write(kind, t_ns, data)

        redactor = _Redactor(redactions, write)

        def keep(kind: str, t_ns: int, data: bytes) -> None:
            if redactions and kind not in DIRECTIONS:
                data = _scrubbed_event(kind, data)
            redactor.add(_Entry(kind, t_ns, data))

        cutter = _Cutter(window[0], window[1], keep) if cut is not None else None
        for record in reader:
            if cutter is not None:
                cutter.add(record.kind, record.t_ns, record.data)
            else:
                keep(record.kind, record.t_ns, record.data)
        if cutter is not None:
            cutter.finish()
        redactor.finish()
    raise_damage(reader)
    return EditResult(records=redactor.records, matches=redactor.matches,
                      redacted_records=redactor.marked_records, edits=tuple(edits))
