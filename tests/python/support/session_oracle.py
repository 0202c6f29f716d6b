"""Sessions built from exchanges, and the ORACLE that says what a replay of
them must serve (DESIGN §17, "Combination tests").

A session is a list of `Exchange`s (request frames the client writes, response
frames the device answers) and a split plan: where the response bytes are cut
into rx records. `write_session` writes it with the bound SessionWriter.

The oracle computes what the client must receive from those exchanges alone:
it never calls the replay engine, nor any wiretape code that decides what to
serve (no profile, no framer, no fault plan of the library). It knows the
rules from the documentation (docs/replay.md, docs/faults.md):

- the response fix of each profile: `modbus-tcp` serves the client's
  transaction id in every response frame; a declared `echo=OFFSET:LEN` copies
  those bytes of the client's request into each response frame at the same
  offset, and with `checksum=` the checksum is recomputed over the fixed
  frame; `lines` and no profile fix nothing. Fixes are by frame, whatever the
  records' boundaries (DESIGN §17);
- the recording's events (DESIGN §25, "Combinations"; docs/replay.md
  "Entitlement", "Modem lines and break", "Flushes on open"): the client
  makes the settings, DTR and break events recorded before a request
  (checked in order under check=timing, and DTR and break under check=data
  where the recording holds the device's lines); a recorded flush is made
  by the client too (rx after k recorded flushes waits for k of the
  client's in match=sequence); the device's line changes are served like
  rx in match=sequence, and only as they stand before the first request in
  match=request;
- which exchange is "exchange N" (from 0, in served order: in
  `match=sequence` the recorded order, in `match=request` the client's
  order of matches), numbered across client sessions;
- what each fault kind does to the response of that exchange (its first rx
  record for the byte faults), in `Expectation`s: exact bytes where the
  fault is deterministic, else the properties the recording decides
  (length, which positions may differ, how many bits).
"""

from __future__ import annotations

import dataclasses
import json
from typing import Dict, List, Optional, Sequence, Tuple

import wiretape

MS = 1_000_000  # ns

# The fault kinds of docs/faults.md with the amounts the tests use: small
# real waits, so that a bounded run stays fast.
FAULT_KINDS = (
    "drop", "drop:2", "corrupt", "corrupt:3", "garbage:4", "truncate", "truncate:1",
    "duplicate", "delay:20", "stall:20", "trickle", "silence", "disconnect", "reconnect:50",
)
# Faults after which a virtual device is gone for good (the bridge ends with
# a lost device, docs/faults.md "Virtual devices"): no later client session.
DEVICE_ENDING_FAULTS = ("disconnect", "reconnect")


# --- the protocols ----------------------------------------------------------------------


def crc16_modbus(data: bytes) -> bytes:
    """CRC-16/MODBUS, low byte first (as a declared `crc16-modbus` carries it)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc.to_bytes(2, "little")


@dataclasses.dataclass(frozen=True)
class Protocol:
    """What the oracle knows of a profile: its replay keys and its response fix."""

    name: str  # "none", "lines", "modbus-tcp", "declared" or "declared-checksum"
    keys: str  # replay keys selecting it ("" for none)
    # The bytes of a request frame that a response frame takes over at the
    # same offsets: (offset, length) pairs; () when the profile fixes nothing.
    echo: Tuple[Tuple[int, int], ...] = ()
    # A CRC-16/MODBUS in a frame's last two bytes, over the bytes before it.
    checksum: bool = False

    def sealed(self, frame: bytes) -> bytes:
        """The frame with its checksum made right for its bytes."""
        return frame[:-2] + crc16_modbus(frame[:-2]) if self.checksum else frame

    def fix(self, response_frame: bytes, client_request: bytes) -> bytes:
        fixed = bytearray(response_frame)
        for offset, length in self.echo:
            fixed[offset:offset + length] = client_request[offset:offset + length]
        return self.sealed(bytes(fixed)) if bytes(fixed) != response_frame else response_frame

    def vary(self, request: bytes, salt: int) -> bytes:
        """The request as a client whose run-to-run fields differ from the
        recording writes it (another transaction id, another echoed field,
        its checksum right for them): the same match key, other bytes."""
        varied = bytearray(request)
        for offset, length in self.echo:
            for i in range(offset, offset + length):
                varied[i] = (varied[i] + 0x5A + salt) & 0xFF
        return self.sealed(bytes(varied))


NO_PROFILE = Protocol("none", "")
LINES = Protocol("lines", "profile=lines")
# Modbus TCP: MBAP header = transaction id (2), protocol id (2, zero),
# length (2, what follows it), unit id (1); then the PDU.
MODBUS_TCP = Protocol("modbus-tcp", "profile=modbus-tcp", echo=((0, 2),))
# A declared protocol: two id bytes, a length byte, that many payload bytes
# (frame = 3 + length); the id is echoed into responses.
DECLARED_FRAMING = "length:2:1:3"
DECLARED = Protocol("declared", f"framing={DECLARED_FRAMING},echo=0:2", echo=((0, 2),))
# The same with a checksum: two id bytes, a length byte, that many payload
# bytes, a CRC-16/MODBUS (frame = 5 + length); `echo=` and `checksum=`
# together: the echoed id changes the response's checksum.
DECLARED_CHECKSUM = Protocol("declared-checksum",
                             "framing=length:2:1:5,echo=0:2,checksum=crc16-modbus@-2",
                             echo=((0, 2),), checksum=True)
PROTOCOLS = {p.name: p for p in (NO_PROFILE, LINES, MODBUS_TCP, DECLARED, DECLARED_CHECKSUM)}


def line_frame(text: bytes) -> bytes:
    return text.replace(b"\n", b".") + b"\n"


def modbus_frame(transaction_id: int, unit: int, pdu: bytes) -> bytes:
    assert 1 <= len(pdu) <= 253
    return (transaction_id.to_bytes(2, "big") + b"\x00\x00" + (len(pdu) + 1).to_bytes(2, "big")
            + bytes([unit]) + pdu)


def declared_frame(frame_id: bytes, payload: bytes) -> bytes:
    assert len(frame_id) == 2 and len(payload) < 256
    return frame_id + bytes([len(payload)]) + payload


def checksummed_frame(frame_id: bytes, payload: bytes) -> bytes:
    return DECLARED_CHECKSUM.sealed(declared_frame(frame_id, payload) + b"\0\0")


# --- sessions -------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Exchange:
    """One request frame and the response frames the device sent for it."""

    request: bytes
    responses: Tuple[bytes, ...]

    @property
    def response(self) -> bytes:
        return b"".join(self.responses)


# How records split the response frames (the dimension of DESIGN §17):
FRAME_PER_RECORD = "frame-per-record"  # one frame per rx record
SPLIT_FRAMES = "split-frames"  # frames cut at random offsets over several records
FRAMES_TOGETHER = "frames-together"  # several frames in one record
SPLITS = (FRAME_PER_RECORD, SPLIT_FRAMES, FRAMES_TOGETHER)


def response_records(exchange: Exchange, split: str, cuts: Sequence[int] = ()) -> List[bytes]:
    """The rx records of one exchange's response under `split`. For
    SPLIT_FRAMES, `cuts` are offsets into the response (taken modulo its
    length; 0 and duplicates ignored): at least one cut falls inside a frame
    when the response has more than one byte."""
    if split == FRAME_PER_RECORD:
        return list(exchange.responses)
    if split == FRAMES_TOGETHER:
        return [exchange.response]
    response = exchange.response
    points = {c % len(response) for c in cuts} - {0}
    if not points and len(response) > 1:
        points = {len(response) // 2 or 1}
    bounds = [0] + sorted(points) + [len(response)]
    return [response[a:b] for a, b in zip(bounds, bounds[1:])]


def records_align_with_frames(exchange: Exchange, records: Sequence[bytes]) -> bool:
    """True when every rx record is exactly one whole response frame."""
    return list(records) == list(exchange.responses)


def request_records(exchange: Exchange, split: str, cuts: Sequence[int] = ()) -> List[bytes]:
    """The tx records of one exchange's request: under SPLIT_FRAMES the
    request frame is cut in two at `cuts[0]` (modulo its length), as a
    driver that writes a command in two calls is recorded; else whole."""
    request = exchange.request
    if split != SPLIT_FRAMES or len(request) < 2 or not cuts:
        return [request]
    at = cuts[0] % (len(request) - 1) + 1
    return [request[:at], request[at:]]


# The device's modem inputs as a recording holds them: (cts, dsr, ri, cd).
Lines = Tuple[bool, bool, bool, bool]
# What a replay reports before the recording says anything of the device's
# lines: a modem with the line up (docs/replay.md "Modem lines and break").
LINE_UP: Lines = (True, True, False, True)


@dataclasses.dataclass(frozen=True)
class ClientEvent:
    """Something the recording shows the client doing besides writing:
    `flush` (flush_input), `baud` (set_baud, a settings event), `dtr`
    (set_dtr, a modem_lines event of the host's output), `break`
    (send_break of `value` ms)."""

    kind: str
    value: int = 0

    def record(self) -> Tuple[str, bytes]:
        """The record kind and payload the recording holds."""
        if self.kind == "flush":
            return "flush_input", b"{}"
        if self.kind == "baud":
            return "settings", json.dumps({"baud": self.value}).encode()
        if self.kind == "dtr":
            return "modem_lines", json.dumps({"dtr": bool(self.value), "applied": True}).encode()
        return "break", json.dumps({"duration_ms": self.value, "applied": True}).encode()

    def make(self, port) -> None:
        """What the client does for it on a `type=replay` port."""
        if self.kind == "flush":
            port.flush_input()
        elif self.kind == "baud":
            port.set_baud(self.value)
        elif self.kind == "dtr":
            port.set_dtr(bool(self.value))
        else:
            port.send_break(self.value / 1000)


def lines_payload(lines: Lines) -> bytes:
    cts, dsr, ri, cd = lines
    return json.dumps({"cts": cts, "dsr": dsr, "ri": ri, "cd": cd}).encode()


# How a recording of several client sessions delimits them: a TCP client
# each time (its own peer), a pty client that closes and reopens (peer
# `pty` each time), or that with `--restart` (the proxy closes and reopens
# the device for the new client: close and open{restarted} before its
# client_connect).
REOPENS = ("tcp", "pty", "restart")


@dataclasses.dataclass
class Session:
    """A session as written: for each client session, its exchanges, the
    rx records of each exchange's response and the tx records of its
    request; and what else the recording holds around them."""

    client_sessions: List[List[Exchange]]
    records: List[List[List[bytes]]]  # [client session][exchange] -> rx records
    tx_records: List[List[List[bytes]]]  # [client session][exchange] -> tx records
    greeting: bytes = b""  # rx before the first request (released at open, or at connect)
    # [client session][exchange] -> the client's events recorded before its request.
    client_events: Optional[List[List[Tuple[ClientEvent, ...]]]] = None
    # [client session][exchange] -> the device's lines recorded between the
    # request and the response, or None.
    device_lines: Optional[List[List[Optional[Lines]]]] = None
    # The device's lines recorded at open (before any greeting), or None.
    initial_lines: Optional[Lines] = None
    reopen: str = "tcp"  # REOPENS

    def events_before(self, part: int, exchange: int) -> Tuple[ClientEvent, ...]:
        return self.client_events[part][exchange] if self.client_events else ()

    def lines_before_response(self, part: int, exchange: int) -> Optional[Lines]:
        return self.device_lines[part][exchange] if self.device_lines else None

    def holds_device_lines(self) -> bool:
        return self.initial_lines is not None or any(
            lines is not None for part in self.device_lines or () for lines in part)

    @property
    def exchanges(self) -> List[Exchange]:
        return [e for part in self.client_sessions for e in part]

    @property
    def response_records(self) -> List[List[bytes]]:
        return [r for part in self.records for r in part]


def build_session(client_sessions: Sequence[Sequence[Exchange]], split: str,
                  cuts: Sequence[int] = (), greeting: bytes = b"", **around) -> Session:
    """`around`: Session's client_events, device_lines, initial_lines, reopen."""
    records = [[response_records(e, split, cuts) for e in part] for part in client_sessions]
    tx_records = [[request_records(e, split, cuts) for e in part] for part in client_sessions]
    return Session([list(part) for part in client_sessions], records, tx_records, greeting,
                   **around)


def connect(peer: str, role: str = "control") -> bytes:
    return json.dumps({"peer": peer, "role": role}).encode()


def disconnect(peer: str) -> bytes:
    return json.dumps({"peer": peer, "reason": "disconnected"}).encode()


MONITOR_PEER = "127.0.0.1:40000"
# A monitor (`serve --shared`) in the first client session: none; one that
# joins before its first exchange and stays past its end; or one that
# leaves after that first exchange. Monitors make no client session.
MONITORS = ("", "stays", "leaves")
# What the device says while no client is connected: never served.
TO_NOBODY = b"said to nobody\n"


def layout(session: Session, monitor: str = "") -> Tuple[List[Tuple[str, int, bytes]], List[int]]:
    """The records of `session` ((kind, t_ns, data), 1 ms apart, so that
    causal timing stays fast) and the recorded time of each exchange's first
    tx record. Each exchange is its client's events, the planned tx records,
    the device's line change, the planned rx records. Several client
    sessions are delimited as the proxy records them (`session.reopen`):
    client_connect ... client_disconnect, with rx said to nobody between
    them, and a `monitor` (MONITORS) in the first."""
    several = len(session.client_sessions) > 1
    records: List[Tuple[str, int, bytes]] = [("open", 0, b"{}")]
    tx_times: List[int] = []

    def add(kind, data):
        records.append((kind, len(records) * MS, data))

    def peer(number):
        return f"127.0.0.1:{40001 + number}" if session.reopen == "tcp" else "pty"

    if session.initial_lines is not None:
        add("modem_lines", lines_payload(session.initial_lines))
    for number, (part_records, part_tx) in enumerate(zip(session.records, session.tx_records)):
        if several:
            if number:
                add("rx", TO_NOBODY)
                if session.reopen == "restart":
                    add("close", b"{}")
                    add("open", json.dumps({"description": "replay", "restarted": True}).encode())
            add("client_connect", connect(peer(number)))
        if number == 0 and session.greeting:
            add("rx", session.greeting)
        for position, (rx_records, requests) in enumerate(zip(part_records, part_tx)):
            if several and monitor and number == 0 and position == 0:
                add("client_connect", connect(MONITOR_PEER, "monitor"))
            for client_event in session.events_before(number, position):
                add(*client_event.record())
            tx_times.append(len(records) * MS)
            for data in requests:
                add("tx", data)
            lines = session.lines_before_response(number, position)
            if lines is not None:
                add("modem_lines", lines_payload(lines))
            for data in rx_records:
                add("rx", data)
            if several and monitor == "leaves" and number == 0 and position == 0:
                add("client_disconnect", disconnect(MONITOR_PEER))
        if several:
            add("client_disconnect", disconnect(peer(number)))
            if monitor == "stays" and number == 0:
                add("client_disconnect", disconnect(MONITOR_PEER))
    add("close", b"{}")
    return records, tx_times


def write_session(path, session: Session, port_type: str = "serial", monitor: str = "") -> str:
    """Writes `session` (its `layout`) with the bound SessionWriter."""
    with wiretape.SessionWriter(str(path), capture="wire", port_type=port_type,
                                port_options=f"type={port_type}") as writer:
        for kind, t_ns, data in layout(session, monitor)[0]:
            writer.write(kind, t_ns, data)
    return str(path)


def recorded_tx_times(session: Session) -> List[int]:
    """The recorded time (ns) of each exchange's first tx record, as
    write_session writes them (with no monitor)."""
    return layout(session)[1]


def served_lines(session: Session, match: str, asked: int) -> Lines:
    """The device's lines a client of the first client session sees once
    exchange `asked` (recorded order) has been served: in match=sequence
    the last change recorded up to its response; in match=request the
    lines as they stand before the first request."""
    lines = session.initial_lines or LINE_UP
    if match == "request":
        return lines
    for position in range(asked + 1):
        lines = session.lines_before_response(0, position) or lines
    return lines


# --- the oracle ------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Fault:
    kind: str  # as in FAULT_KINDS, e.g. "drop:2"
    exchange: int  # exchange:N, counted in served order across client sessions

    @property
    def name(self) -> str:
        return self.kind.split(":")[0]

    @property
    def amount(self) -> Optional[int]:
        return int(self.kind.split(":")[1]) if ":" in self.kind else None

    @property
    def option(self) -> str:
        return f"{self.kind}@exchange:{self.exchange}"


@dataclasses.dataclass
class Expectation:
    """What the client must get for one exchange it asks.

    `exact`: the bytes, when the fault (or none) decides them all. Otherwise
    `length` and `check(got) -> problem or ""` say what the recording decides.
    `closed`: the read raises PortClosed (the device went away) after `exact`
    (b"" for the fault's exchange). `silent_from_here`: nothing more, ever.
    `back_after_loss`: reconnect: PortClosed first, then later exchanges answer.
    `at_least_s`: the real wait a fault adds (delay, stall, trickle): the
    whole response cannot have come sooner after the request.
    """

    exact: Optional[bytes] = None
    length: Optional[int] = None
    check: Optional[object] = None
    closed: bool = False
    silent: bool = False
    back_after_loss: bool = False
    at_least_s: float = 0.0

    @property
    def count(self) -> int:
        return len(self.exact) if self.exact is not None else self.length


def served_order(exchanges: Sequence[Exchange], client_requests: Sequence[bytes],
                 protocol: Protocol, match: str) -> List[int]:
    """Which recorded exchange answers each request the client writes. In
    sequence mode the recorded order; in request mode the first unused
    exchange (recorded order) whose request has the same match key."""
    if match == "sequence":
        return list(range(len(client_requests)))
    used, order = set(), []
    for request in client_requests:
        key = match_key(request, protocol)
        found = next(i for i, e in enumerate(exchanges)
                     if i not in used and match_key(e.request, protocol) == key)
        used.add(found)
        order.append(found)
    return order


def match_key(request: bytes, protocol: Protocol) -> bytes:
    """The bytes compared: a request without the fields that vary (the ones a
    response takes over) and, for lines, without the delimiter."""
    key = bytearray(request)
    for offset, length in protocol.echo:
        key[offset:offset + length] = b"\x00" * length
    if protocol.checksum:
        key = key[:-2]
    if protocol.name == "lines":
        key = key.rstrip(b"\n")
    return bytes(key)


def fixed_response(exchange: Exchange, client_request: bytes, protocol: Protocol) -> bytes:
    """The response with the profile's fix applied frame by frame."""
    return b"".join(protocol.fix(frame, client_request) for frame in exchange.responses)


def expect(exchanges: Sequence[Exchange], records: Sequence[Sequence[bytes]],
           client_requests: Sequence[bytes], protocol: Protocol, match: str,
           fault: Optional[Fault]) -> List[Expectation]:
    """What the client must receive for each request it writes, in its
    order. `records[i]` are exchange i's rx records as recorded."""
    order = served_order(exchanges, client_requests, protocol, match)
    expectations = []
    silenced = False
    for served, (recorded, request) in enumerate(zip(order, client_requests)):
        response = fixed_response(exchanges[recorded], request, protocol)
        if silenced:
            expectations.append(Expectation(exact=b"", silent=True))
            continue
        if fault is None or fault.exchange != served:
            expectations.append(Expectation(exact=response))
            continue
        first = len(records[recorded][0])  # the fault acts on the first rx record
        expectation = faulty(fault, response, first)
        silenced = expectation.silent
        expectations.append(expectation)
        if expectation.closed:
            break  # the device is gone: nothing after
    return expectations


def faulty(fault: Fault, response: bytes, first: int) -> Expectation:
    """What one fault makes of `response`, whose first rx record holds its
    first `first` bytes (docs/faults.md's table)."""
    head, rest = response[:first], response[first:]
    name, amount = fault.name, fault.amount
    if name in ("delay", "stall"):
        # Late, or with a gap inside, the same bytes.
        return Expectation(exact=response, at_least_s=amount / 1000)
    if name == "trickle":
        # One byte at a time, `amount` ms (default 1) apart.
        return Expectation(exact=response, at_least_s=(len(response) - 1) * (amount or 1) / 1000)
    if name == "drop" and amount is None:
        return Expectation(exact=b"")
    if name == "truncate":
        keep = min(len(head) // 2 if amount is None else amount, len(head))
        return Expectation(exact=head[:keep])
    if name == "duplicate":
        return Expectation(exact=head + head + rest)
    if name == "silence":
        return Expectation(exact=b"", silent=True)
    if name == "disconnect":
        return Expectation(exact=b"", closed=True)
    if name == "reconnect":
        return Expectation(exact=b"", back_after_loss=True)
    if name == "drop":
        lost = min(amount, len(head))

        def dropped(got):
            for at in range(len(head) - lost + 1):
                if got == head[:at] + head[at + lost:] + rest:
                    return ""
            return f"not the response with {lost} contiguous bytes of its first record removed"

        return Expectation(length=len(response) - lost, check=dropped)
    if name == "corrupt":
        flips = amount or 1

        def corrupted(got):
            if got[first:] != rest:
                return "bytes after the first record changed"
            bits = sum(bin(a ^ b).count("1") for a, b in zip(got, head))
            # Flips may land on the same bit twice and cancel.
            if bits > flips or bits % 2 != flips % 2:
                return f"{bits} bits differ, {flips} flips were asked"
            return ""

        return Expectation(length=len(response), check=corrupted)
    if name == "garbage":
        extra = amount

        def inserted(got):
            for at in range(len(head) + 1):
                if got[:at] == head[:at] and got[at + extra:] == head[at:] + rest:
                    return ""
            return f"not the response with {extra} bytes inserted in its first record"

        return Expectation(length=len(response) + extra, check=inserted)
    raise ValueError(f"the oracle does not know fault {fault.kind!r}")
