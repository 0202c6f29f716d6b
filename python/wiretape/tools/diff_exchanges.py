"""Two sessions' exchanges aligned, as ``diff -u`` aligns lines, and the
divergences of what differs (the "by exchange" part of tools/diff.py).

The exchanges are the one segmentation's (``_core.session_exchanges``,
DESIGN §17), numbered as a replay numbers them, by frames with a profile.
Each is keyed by its request and its response (frame by frame by the
profile's match key with one, so that what the key leaves out does not
differ). The keys of A and B are aligned by a longest common subsequence:
the common prefix and suffix first, then Myers' O(ND) difference over what
is left, which gives up past ``MAX_EDITS`` differences (the rest is then
paired by position, and the summary says so): the cost stays bounded on
long sessions, and two runs that differ by a handshake at the start differ
by those exchanges only, not by every exchange after them.

In a run of exchanges that differ, those with the same request are paired
first (the same question answered otherwise), then the others by position;
what is left over is only in A or only in B.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field
from typing import Callable, Iterator, List, Optional, Sequence, Tuple

from .. import _core
from ..session import open_session

#: Differences past which the alignment pairs the rest by position: Myers'
#: cost is O((N+M)·D) and its trace O(D²), so this bounds both.
MAX_EDITS = 1000

#: Runs of differences the summary names one by one; the others are counted.
_RUNS_NAMED = 5

#: Bytes shown each side of a divergence's first differing byte.
_WINDOW = 8


def _seconds(t_ns: Optional[int]) -> str:
    return "-" if t_ns is None else f"{t_ns / 1e9:.6f} s"


def labelled(channel: str, what: str) -> str:
    """`what` of a channel of a session of several ports: ``channel gps rx``."""
    from ..session import header_text

    return f"channel {header_text(channel)} {what}" if channel else what


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def pointed(a: Optional[bytes], b: Optional[bytes], at: int) -> List[str]:
    """Lines showing A and B around byte `at`, and a caret under the byte
    where they differ (hex, then the printable text)."""
    start = max(0, at - _WINDOW)
    lines = []
    for name, data in (("A", a), ("B", b)):
        if data is None:
            lines.append(f"      {name}: (nothing)")
            continue
        window = data[start:at + _WINDOW]
        hex_part = " ".join(f"{byte:02x}" for byte in window)
        text = "".join(chr(byte) if 0x20 <= byte < 0x7F else "." for byte in window)
        lead = "…" if start else " "
        tail = "…" if len(data) > at + _WINDOW else " "
        lines.append(f"      {name}: {lead}{hex_part:<{3 * 2 * _WINDOW - 1}}{tail} |{text}|")
    column = at - start
    hex_caret = " " * (3 * column) + "^^"
    text_caret = " " * column + "^"
    lines.append(f"          {hex_caret:<{3 * 2 * _WINDOW - 1}}   {text_caret}")
    return lines


def first_difference(a: bytes, b: bytes) -> int:
    same = 0
    for byte_a, byte_b in zip(a, b):
        if byte_a != byte_b:
            break
        same += 1
    return same


def first_key_difference(a: bytes, b: bytes, key) -> int:
    """The first byte where A and B differ that the key compares: B's byte
    put in A changes A's key (a Modbus TCP transaction id differs first, but
    it is not what differs by key). The first difference when none alone does."""
    key_a = key(a)
    for at in range(min(len(a), len(b))):
        if a[at] != b[at] and key(a[:at] + b[at:at + 1] + a[at + 1:]) != key_a:
            return at
    return first_difference(a, b)


# --------------------------------------------------------------------------
# the exchanges of one session


Exchange = Tuple[List[bytes], List[bytes], Optional[int], Optional[int]]


class ExchangeParts:
    """The exchanges of a session file with their bytes, one at a time:
    (request pieces, response pieces, request time, response time), a piece
    being a frame with a profile, else all of that direction's bytes."""

    def __init__(self, path: str, profile: Optional[_core.Profile]):
        self._path = path
        self._profile = profile

    def __iter__(self) -> Iterator[Exchange]:
        exchanges = _core.session_exchanges(
            self._path, options=self._profile.options if self._profile is not None else "")
        if self._profile is not None:
            for exchange in exchanges:
                yield ([bytes(f) for f in exchange.request_frames],
                       [bytes(f) for f in exchange.response_frames],
                       exchange.request_first_t_ns, exchange.response_first_t_ns)
            return
        ends = iter([(exchange.end_record, exchange) for exchange in exchanges])
        end, exchange = next(ends, (None, None))
        parts = {"tx": bytearray(), "rx": bytearray()}
        with open_session(self._path) as reader:
            for index, record in enumerate(reader):
                while end is not None and index >= end:
                    yield (_pieces(parts["tx"]), _pieces(parts["rx"]),
                           exchange.request_first_t_ns, exchange.response_first_t_ns)
                    parts = {"tx": bytearray(), "rx": bytearray()}
                    end, exchange = next(ends, (None, None))
                if end is None:
                    break
                if record.kind in parts:
                    parts[record.kind] += record.data
        if end is not None:
            yield (_pieces(parts["tx"]), _pieces(parts["rx"]),
                   exchange.request_first_t_ns, exchange.response_first_t_ns)


def _pieces(data: bytearray) -> List[bytes]:
    return [bytes(data)] if data else []


def _keys(parts: ExchangeParts, key: Callable) -> Tuple[List[int], List[int]]:
    """Each exchange's key (request and response) and its request's key,
    as hashes: two numbers per exchange, however long the session. (Two
    exchanges that differ yet share a 64-bit hash would align as the same;
    each direction's first difference is still found byte by byte.)"""
    whole: List[int] = []
    requests: List[int] = []
    for request, response, _, _ in parts:
        request_key = tuple(key(piece) for piece in request)
        requests.append(hash(request_key))
        whole.append(hash((request_key, tuple(key(piece) for piece in response))))
    return whole, requests


# --------------------------------------------------------------------------
# the alignment


@dataclass
class Block:
    """A run of the alignment, in order: ``same`` (`count` exchanges equal in
    A and B), ``changed`` (`count` pairs that differ), ``only_a`` (`count`
    exchanges of A from `a_start`, B having none there: B's next is
    `b_start`), ``only_b`` (the same for B)."""

    kind: str
    a_start: int
    b_start: int
    count: int

    def to_json(self) -> dict:
        return {"kind": self.kind, "a_start": self.a_start, "b_start": self.b_start,
                "count": self.count}


@dataclass
class Alignment:
    """How the exchanges of A and B line up (``blocks``, in order), and from
    which exchanges of A and B on they are paired by position because they
    differ by more than MAX_EDITS (None: aligned to the end)."""

    exchanges_a: int
    exchanges_b: int
    blocks: List[Block] = field(default_factory=list)
    by_position_from: Optional[Tuple[int, int]] = None
    channel: str = ""

    @property
    def identical(self) -> bool:
        return all(block.kind == "same" for block in self.blocks)

    def summary(self) -> str:
        """One line: what differs, where (``3 exchanges only in A at the
        start; the rest is identical``)."""
        if self.identical:
            text = (f"all {_plural(self.exchanges_a, 'exchange')} identical"
                    if self.exchanges_a else "no exchanges")
            return labelled(self.channel, text) if self.channel else text
        parts: List[str] = []
        runs = [at for at, block in enumerate(self.blocks) if block.kind != "same"]
        for at in runs[:_RUNS_NAMED]:
            block = self.blocks[at]
            if block.kind == "changed":
                verb = "differs" if block.count == 1 else "differ"
                parts.append(f"{_plural(block.count, 'exchange')} {verb} "
                             f"({_numbers(block, 'changed')})")
                continue
            side = "A" if block.kind == "only_a" else "B"
            parts.append(f"{_plural(block.count, 'exchange')} only in {side} "
                         f"{self._where(at)} ({_numbers(block, block.kind)})")
        if len(runs) > _RUNS_NAMED:
            left = [self.blocks[at] for at in runs[_RUNS_NAMED:]]
            parts.append(f"{_plural(len(left), 'more run')} of differences "
                         f"({_plural(sum(block.count for block in left), 'exchange')})")
        if any(block.kind == "same" for block in self.blocks):
            parts.append("the rest is identical")
        if self.by_position_from is not None:
            a, b = self.by_position_from
            parts.append(f"past {MAX_EDITS} differences, from exchange {a} of A and {b} of B "
                         "on, paired by position")
        text = "; ".join(parts)
        return labelled(self.channel, text) if self.channel else text

    def _where(self, at: int) -> str:
        before = [block for block in self.blocks[:at] if block.kind == "same"]
        after = [block for block in self.blocks[at + 1:] if block.kind == "same"]
        if not before:
            return "at the start"
        if not after:
            return "at the end"
        last = before[-1]
        a, b = last.a_start + last.count - 1, last.b_start + last.count - 1
        return f"after exchange {a}" if a == b else f"after exchange {a} of A ({b} of B)"

    def pairs(self) -> Iterator[Tuple[Optional[int], Optional[int]]]:
        """The exchanges that differ, in order: (A's, B's), None for the
        side that has none."""
        for block in self.blocks:
            if block.kind == "same":
                continue
            for n in range(block.count):
                if block.kind == "changed":
                    yield block.a_start + n, block.b_start + n
                elif block.kind == "only_a":
                    yield block.a_start + n, None
                elif block.kind == "only_b":
                    yield None, block.b_start + n

    def to_json(self) -> dict:
        return {"channel": self.channel, "exchanges_a": self.exchanges_a,
                "exchanges_b": self.exchanges_b, "summary": self.summary(),
                "blocks": [block.to_json() for block in self.blocks],
                "by_position_from": (list(self.by_position_from)
                                     if self.by_position_from is not None else None)}


def _numbers(block: Block, kind: str) -> str:
    def span(start: int) -> str:
        return str(start) if block.count == 1 else f"{start}-{start + block.count - 1}"

    if kind == "only_a":
        return "A " + span(block.a_start)
    if kind == "only_b":
        return "B " + span(block.b_start)
    if block.a_start == block.b_start:
        return span(block.a_start)
    return f"A {span(block.a_start)}, B {span(block.b_start)}"


def common_runs(a: Sequence[int], b: Sequence[int], max_edits: int = MAX_EDITS
                ) -> Optional[List[Tuple[int, int, int]]]:
    """The runs (i, j, length) where a[i:i+length] == b[j:j+length] of a
    longest common subsequence of `a` and `b`, in order (Myers' greedy
    O((N+M)·D) algorithm); None when they differ by more than `max_edits`
    insertions and deletions."""
    n, m = len(a), len(b)
    offset = max_edits + 1
    v = array("q", [0]) * (2 * offset + 1)
    trace: List[array] = []
    found = False
    for d in range(max_edits + 1):
        trace.append(v[:])
        for k in range(-d, d + 1, 2):
            if k == -d or (k != d and v[offset + k - 1] < v[offset + k + 1]):
                x = v[offset + k + 1]
            else:
                x = v[offset + k - 1] + 1
            y = x - k
            while x < n and y < m and a[x] == b[y]:
                x += 1
                y += 1
            v[offset + k] = x
            if x >= n and y >= m:
                found = True
                break
        if found:
            break
    if not found:
        return None
    matches: List[Tuple[int, int]] = []
    x, y = n, m
    for d in range(len(trace) - 1, -1, -1):
        before = trace[d]
        k = x - y
        if k == -d or (k != d and before[offset + k - 1] < before[offset + k + 1]):
            previous_k = k + 1
        else:
            previous_k = k - 1
        previous_x = before[offset + previous_k] if d else 0
        previous_y = previous_x - previous_k if d else 0
        while x > previous_x and y > previous_y:
            x -= 1
            y -= 1
            matches.append((x, y))
        x, y = previous_x, previous_y
    matches.reverse()
    runs: List[Tuple[int, int, int]] = []
    for i, j in matches:
        if runs and runs[-1][0] + runs[-1][2] == i and runs[-1][1] + runs[-1][2] == j:
            runs[-1] = (runs[-1][0], runs[-1][1], runs[-1][2] + 1)
        else:
            runs.append((i, j, 1))
    return runs


class _Builder:
    """Blocks appended in order, neighbours of one kind merged."""

    def __init__(self) -> None:
        self.blocks: List[Block] = []

    def add(self, kind: str, a_start: int, b_start: int, count: int) -> None:
        if count <= 0:
            return
        last = self.blocks[-1] if self.blocks else None
        if last is not None and last.kind == kind:
            step_a = 0 if kind == "only_b" else last.count
            step_b = 0 if kind == "only_a" else last.count
            if last.a_start + step_a == a_start and last.b_start + step_b == b_start:
                last.count += count
                return
        self.blocks.append(Block(kind, a_start, b_start, count))

    def by_position(self, keys_a, keys_b, a0: int, a1: int, b0: int, b1: int) -> None:
        """A[a0:a1] against B[b0:b1] pair by pair, the longer one's rest alone."""
        paired = min(a1 - a0, b1 - b0)
        for n in range(paired):
            same = keys_a[a0 + n] == keys_b[b0 + n]
            self.add("same" if same else "changed", a0 + n, b0 + n, 1)
        self.add("only_a", a0 + paired, b0 + paired, a1 - a0 - paired)
        self.add("only_b", a0 + paired, b0 + paired, b1 - b0 - paired)


def align(keys_a: Sequence[int], keys_b: Sequence[int], requests_a: Sequence[int],
          requests_b: Sequence[int], max_edits: int = MAX_EDITS) -> Alignment:
    """The alignment of two sessions' exchanges, given their keys and their
    requests' keys (_keys)."""
    result = Alignment(len(keys_a), len(keys_b))
    built = _Builder()
    n, m = len(keys_a), len(keys_b)
    prefix = 0
    while prefix < n and prefix < m and keys_a[prefix] == keys_b[prefix]:
        prefix += 1
    suffix = 0
    while (suffix < n - prefix and suffix < m - prefix
           and keys_a[n - 1 - suffix] == keys_b[m - 1 - suffix]):
        suffix += 1
    built.add("same", 0, 0, prefix)
    middle_a, middle_b = keys_a[prefix:n - suffix], keys_b[prefix:m - suffix]
    runs = common_runs(middle_a, middle_b, max_edits)
    if runs is None:
        result.by_position_from = (prefix, prefix)
        built.by_position(keys_a, keys_b, prefix, n - suffix, prefix, m - suffix)
    else:
        i, j = prefix, prefix
        for run_i, run_j, length in runs + [(n - suffix - prefix, m - suffix - prefix, 0)]:
            _pair_requests(built, requests_a, requests_b, i, prefix + run_i, j, prefix + run_j,
                           max_edits)
            built.add("same", prefix + run_i, prefix + run_j, length)
            i, j = prefix + run_i + length, prefix + run_j + length
    built.add("same", n - suffix, m - suffix, suffix)
    result.blocks = built.blocks
    return result


def _pair_requests(built: _Builder, requests_a, requests_b, a0: int, a1: int, b0: int,
                   b1: int, max_edits: int) -> None:
    """A run of exchanges that differ (A[a0:a1] against B[b0:b1]): those with
    the same request paired, the others by position between them."""
    if a0 == a1 or b0 == b1:
        _unpaired(built, a0, a1, b0, b1)
        return
    runs = common_runs(requests_a[a0:a1], requests_b[b0:b1], max_edits) or []
    i, j = a0, b0
    for run_i, run_j, length in runs + [(a1 - a0, b1 - b0, 0)]:
        _unpaired(built, i, a0 + run_i, j, b0 + run_j)
        built.add("changed", a0 + run_i, b0 + run_j, length)
        i, j = a0 + run_i + length, b0 + run_j + length


def _unpaired(built: _Builder, a0: int, a1: int, b0: int, b1: int) -> None:
    """Exchanges whose requests differ too: paired by position as changed,
    the longer side's rest alone."""
    paired = min(a1 - a0, b1 - b0)
    built.add("changed", a0, b0, paired)
    built.add("only_a", a0 + paired, b0 + paired, a1 - a0 - paired)
    built.add("only_b", a0 + paired, b0 + paired, b1 - b0 - paired)


# --------------------------------------------------------------------------
# the divergences of what the alignment pairs


@dataclass
class Divergence:
    """Exchange `exchange_a` of A against `exchange_b` of B differs in
    `direction` ("tx": the request, "rx": the response) from byte `offset`
    of that part of the exchange; the exchange of a side that has none is
    None, and so are its bytes."""

    exchange_a: Optional[int]
    exchange_b: Optional[int]
    direction: str
    offset: int
    time_a_ns: Optional[int]
    time_b_ns: Optional[int]
    bytes_a: Optional[bytes]
    bytes_b: Optional[bytes]
    frame_a: str = ""  # with a profile: the frames' descriptions
    frame_b: str = ""
    channel: str = ""  # in a session of several channels (exchanges are numbered per channel)

    @property
    def exchange(self) -> int:
        """A's number of the exchange, B's when only B has it."""
        return self.exchange_a if self.exchange_a is not None else int(self.exchange_b or 0)

    def _name(self) -> str:
        a, b = self.exchange_a, self.exchange_b
        if a is None or b is None or a == b:
            return f"exchange {self.exchange}"
        return f"exchange {a} of A, {b} of B"

    def report(self) -> List[str]:
        part = "request" if self.direction == "tx" else "response"
        exchange = labelled(self.channel, self._name())
        if self.bytes_a is None or self.bytes_b is None:
            missing = "A" if self.bytes_a is None else "B"
            head = f"  {exchange} {part} ({self.direction}): {missing} has none"
        else:
            head = (f"  {exchange} {part} ({self.direction}) differs at byte "
                    f"{self.offset} (A at {_seconds(self.time_a_ns)}, "
                    f"B at {_seconds(self.time_b_ns)})")
        lines = [head]
        for name, frame in (("A", self.frame_a), ("B", self.frame_b)):
            if frame:
                lines.append(f"      {name} is {frame}")
        return lines + pointed(self.bytes_a, self.bytes_b, self.offset)

    def to_json(self) -> dict:
        return {"channel": self.channel, "exchange_a": self.exchange_a,
                "exchange_b": self.exchange_b, "direction": self.direction,
                "offset": self.offset, "time_a_ns": self.time_a_ns, "time_b_ns": self.time_b_ns,
                "bytes_a": self.bytes_a.hex() if self.bytes_a is not None else None,
                "bytes_b": self.bytes_b.hex() if self.bytes_b is not None else None,
                "frame_a": self.frame_a, "frame_b": self.frame_b}


def _differs_at(pieces_a: List[bytes], pieces_b: List[bytes], key) -> Optional[int]:
    """The offset (in the pieces joined) of the first byte of the first
    piece whose key differs, None when every key is the same."""
    offset = 0
    for at in range(max(len(pieces_a), len(pieces_b))):
        if at >= len(pieces_a) or at >= len(pieces_b):
            return offset
        piece_a, piece_b = pieces_a[at], pieces_b[at]
        if key(piece_a) != key(piece_b):
            return offset + first_key_difference(piece_a, piece_b, key)
        offset += len(piece_a)
    return None


def _request_name(framing, direction: str, pieces: Optional[List[bytes]]) -> str:
    """A request's description under a profile (it is one frame): which
    command differs."""
    if framing is None or direction != "tx" or not pieces:
        return ""
    return framing.describe("tx", pieces[0])


class _Seek:
    """Exchange N of a session's exchanges, for N increasing: one pass."""

    def __init__(self, parts: ExchangeParts):
        self._exchanges = iter(parts)
        self._next = 0

    def at(self, index: int) -> Exchange:
        while True:
            exchange = next(self._exchanges)
            self._next += 1
            if self._next - 1 == index:
                return exchange


@dataclass
class ExchangeDiff:
    """What diff() reports by exchange: the alignment, the first divergences
    kept, and how many there are."""

    alignment: Alignment
    divergences: List[Divergence]
    count: int


def diff_exchanges(path_a: str, path_b: str, framing: Optional[_core.Profile],
                   keep: int) -> ExchangeDiff:
    """The exchanges of two session files aligned (by the profile's match
    key with `framing`), and the divergences of those that differ: the first
    `keep` of them, and how many there are."""
    key = framing.match_key if framing is not None else (lambda piece: piece)
    keys_a, requests_a = _keys(ExchangeParts(path_a, framing), key)
    keys_b, requests_b = _keys(ExchangeParts(path_b, framing), key)
    alignment = align(keys_a, keys_b, requests_a, requests_b)
    found: List[Divergence] = []
    total = 0
    seek_a, seek_b = _Seek(ExchangeParts(path_a, framing)), _Seek(ExchangeParts(path_b, framing))
    for index_a, index_b in alignment.pairs():
        part_a = seek_a.at(index_a) if index_a is not None else None
        part_b = seek_b.at(index_b) if index_b is not None else None
        for direction, slot, time_slot in (("tx", 0, 2), ("rx", 1, 3)):
            pieces_a = part_a[slot] if part_a is not None else None
            pieces_b = part_b[slot] if part_b is not None else None
            if not pieces_a and not pieces_b:
                continue
            if pieces_a is not None and pieces_b is not None:
                # with a profile, what its match key leaves out does not differ
                offset = _differs_at(pieces_a, pieces_b, key)
                if offset is None:
                    continue
            else:
                offset = 0
            total += 1
            if len(found) >= keep:
                continue
            found.append(Divergence(
                index_a, index_b, direction, offset,
                part_a[time_slot] if part_a is not None else None,  # type: ignore[misc]
                part_b[time_slot] if part_b is not None else None,  # type: ignore[misc]
                b"".join(pieces_a) if pieces_a is not None else None,
                b"".join(pieces_b) if pieces_b is not None else None,
                _request_name(framing, direction, pieces_a),
                _request_name(framing, direction, pieces_b)))
    return ExchangeDiff(alignment, found, total)


__all__ = ["Alignment", "Block", "Divergence", "ExchangeDiff", "MAX_EDITS", "align",
           "common_runs", "diff_exchanges", "pointed"]
