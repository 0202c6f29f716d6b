"""``convert --from pcap``: one TCP conversation or UDP flow of a packet
capture (pcap or pcapng, as tcpdump, dumpcap or Wireshark write them)
becomes a session.

Reading the capture and putting a TCP stream back together (retransmissions
dropped, segments received out of order put back in order, overlapping
segments cut) is Wireshark's work, done by ``tshark``: a first pass lists
the packets of every conversation (``-T fields``), a second follows the one
chosen (``-z follow,tcp,yaml,N``), which gives each reassembled chunk with
its side, its packet number and its time. Nothing here reassembles.

Several conversations, each chosen by a named ``--stream NAME=FILTER``,
become the channels of one session on the capture's clock
(read_capture_channels; DESIGN §19).

Which side is the device (docs/cli.md, "convert --from pcap"):
``--device-addr IP:PORT`` when given; otherwise for TCP the side that
answered the SYN (the listening side), and when the handshake is not in the
capture the side with the lower port; for UDP the side with the lower port
(a service's well-known port), and on equal ports the destination of the
first datagram.
"""

from __future__ import annotations

import base64
import dataclasses
import datetime as _datetime
import os
import re
import shutil
from typing import Dict, Iterator, List, Optional, Sequence, Tuple

from .. import _core
from ..children import Child

__all__ = ["CaptureError", "CaptureGap", "Conversation", "conversations", "read_capture",
           "read_capture_channels", "split_name", "is_capture"]

# A capture's first four bytes: pcap (both byte orders, micro- and
# nanosecond variants) and pcapng's section header block.
_CAPTURE_MAGICS = (
    b"\xa1\xb2\xc3\xd4", b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\x3c\x4d", b"\x4d\x3c\xb2\xa1",
    b"\x0a\x0d\x0d\x0a",
)

_FIELDS = (
    "frame.number", "frame.time_epoch", "tcp.stream", "udp.stream",
    "ip.src", "ip.dst", "ipv6.src", "ipv6.dst",
    "tcp.srcport", "tcp.dstport", "udp.srcport", "udp.dstport",
    "tcp.flags.syn", "tcp.flags.ack", "tcp.flags.fin", "tcp.flags.reset",
    "tcp.len", "udp.length", "tcp.seq", "tcp.ack",
)

# What tshark's "follow" writes in place of bytes the capture lost: text in
# the stream, never to be taken for payload.
_MISSING_MARKER = re.compile(rb"\[([0-9]{1,20}) bytes missing in capture file\]\x00?")

_TIMEOUT_S = 600


class CaptureError(_core.SessionError):
    """A capture that cannot be imported: not a capture, truncated, no
    conversation matching, several and none chosen (exit 1)."""


def is_capture(path: str) -> bool:
    """Whether the file starts as a pcap or pcapng capture does."""
    try:
        with open(path, "rb") as handle:
            return handle.read(4) in _CAPTURE_MAGICS
    except OSError:
        return False


def _tshark() -> str:
    found = shutil.which("tshark")
    if found is None:
        raise RuntimeError("reading a capture needs tshark, which is not installed "
                           "(Debian: apt-get install tshark)")
    return found


def _epoch_ns(text: str) -> int:
    """'1795482638.583698988' as an exact count of nanoseconds."""
    whole, _, fraction = text.strip().partition(".")
    return int(whole) * 1_000_000_000 + int((fraction + "000000000")[:9])


def _utc_text(epoch_ns: int) -> Optional[str]:
    """The time as UTC text; None when no calendar date holds it (a
    timestamp near 2^64, before year 1)."""
    seconds, ns = divmod(epoch_ns, 1_000_000_000)
    try:
        moment = _datetime.datetime.fromtimestamp(seconds, tz=_datetime.timezone.utc)
    except (OverflowError, ValueError, OSError):  # OSError: EOVERFLOW from the C library
        return None
    return moment.strftime("%Y-%m-%dT%H:%M:%S") + f".{ns:09d}Z"


def _seconds_text(ns: int) -> str:
    text = f"{ns / 1e9:.9g}"
    return text if len(text) <= 30 else f"a number of {len(str(ns))} digits"


def _address(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def parse_address(text: str) -> Tuple[str, int]:
    """'IP:PORT' or '[IPv6]:PORT' as (host, port); ValueError otherwise."""
    host, colon, port = text.rpartition(":")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not colon or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"--device-addr {text!r}: expected IP:PORT or [IPv6]:PORT")
    return host, int(port)


@dataclasses.dataclass
class _Packet:
    number: int
    epoch_ns: int
    src: Tuple[str, int]
    dst: Tuple[str, int]
    syn: bool
    ack: bool
    fin: bool
    reset: bool
    payload_size: int
    seq: Optional[int] = None  # tshark's relative sequence number (TCP)
    acknowledged: Optional[int] = None  # relative acknowledgement number, when ACK is set


@dataclasses.dataclass(frozen=True)
class CaptureGap:
    """Bytes of one direction of a TCP stream that the capture lost."""

    direction: str  # "rx" (device to client) or "tx"
    offset: int  # the first lost byte, from the start of that direction
    length: int

    def describe(self, stream: str) -> str:
        side = "device to client (rx)" if self.direction == "rx" else "client to device (tx)"
        return (f"{stream}: {self.length} bytes missing from the {side} stream at offset "
                f"{self.offset}")


@dataclasses.dataclass
class Conversation:
    """One TCP conversation or UDP flow of a capture, as tshark numbers it."""

    protocol: str  # "tcp" or "udp"
    index: int  # tshark's tcp.stream / udp.stream
    packets: List[_Packet] = dataclasses.field(default_factory=list)

    @property
    def name(self) -> str:
        """What --stream takes to choose it: ``tcp:0``."""
        return f"{self.protocol}:{self.index}"

    @property
    def endpoints(self) -> Tuple[Tuple[str, int], Tuple[str, int]]:
        first = self.packets[0]
        return first.src, first.dst

    @property
    def payload_bytes(self) -> int:
        return sum(packet.payload_size for packet in self.packets)

    def has_endpoint(self, endpoint: Tuple[str, int]) -> bool:
        return endpoint in self.endpoints

    def device(self, device_addr: Optional[Tuple[str, int]] = None) -> Tuple[str, int]:
        """The device's endpoint (the module's text gives the rule)."""
        first_side, second_side = self.endpoints
        if device_addr is not None:
            return device_addr
        if self.protocol == "tcp":
            for packet in self.packets:
                if packet.syn and not packet.ack:
                    return packet.dst
            for packet in self.packets:
                if packet.syn and packet.ack:
                    return packet.src
        if first_side[1] != second_side[1]:
            return min((first_side, second_side), key=lambda side: side[1])
        return second_side

    def describe(self) -> str:
        (a_host, a_port), (b_host, b_port) = self.endpoints
        return (f"{self.name}  {_address(a_host, a_port)} <-> {_address(b_host, b_port)}  "
                f"{self.protocol.upper()}, {len(self.packets)} packets, "
                f"{self.payload_bytes} bytes of payload")


def _run_tshark(path: str, arguments: Sequence[str]) -> str:
    """tshark's standard output; CaptureError naming the file (and the
    packet, where tshark says) when tshark cannot read it."""
    # Relative sequence numbers whatever the user's preferences: the gap
    # check counts bytes from the start of each direction.
    command = [_tshark(), "-n", "-o", "tcp.relative_sequence_numbers:TRUE", "-r", path,
               *arguments]
    # Interrupted (SIGINT, SIGTERM), the block ends tshark: none is left behind.
    with Child(command, separate_stderr=True, text=True,
               env={**os.environ, "LC_ALL": "C"}) as child:
        outcome = child.run(_TIMEOUT_S)
    if outcome.timed_out:
        raise CaptureError(f"{path}: tshark took more than {_TIMEOUT_S} s to read it")
    stdout, stderr = str(outcome.stdout), str(outcome.stderr)
    if outcome.returncode != 0:
        raise _capture_problem(path, stdout, stderr)
    return stdout


def _problem_lines(stderr: str) -> List[str]:
    return [line.strip() for line in stderr.splitlines()
            if line.strip() and not line.startswith("Running as user")]


def _capture_problem(path: str, stdout: str, stderr: str) -> CaptureError:
    lines = _problem_lines(stderr)
    text = " ".join(lines) or "tshark could not read it"
    last_packet = 0
    for line in stdout.splitlines():
        number = line.split("\t", 1)[0]
        if number.isdigit():
            last_packet = int(number)
    if "cut short" in text or "truncated" in text.lower():
        where = (f"after packet {last_packet}" if last_packet else "in its first packet")
        return CaptureError(f"{path}: the capture is truncated {where} (packet "
                            f"{last_packet + 1} is cut short): {text}", 0)
    if "isn't a capture file" in text or "unknown file format" in text.lower() or \
            "understands" in text:
        return CaptureError(f"{path}: not a pcap or pcapng capture ({text})", 0)
    if "filter" in text.lower() or "expression" in text.lower():
        return CaptureError(f"{path}: --stream is neither tcp:N, udp:N, N nor a display "
                            f"filter tshark accepts: {text}", 0)
    return CaptureError(f"{path}: {text}", 0)


def _field(row: Dict[str, str], name: str) -> str:
    return row.get(name, "")


def _number(text: str) -> Optional[int]:
    return int(text) if text.isdigit() else None


def _packets(path: str) -> Iterator[Tuple[str, int, _Packet]]:
    """(protocol, stream index, packet) for every TCP or UDP packet."""
    arguments = ["-T", "fields", "-E", "separator=/t", "-E", "occurrence=f"]
    for name in _FIELDS:
        arguments += ["-e", name]
    for line in _run_tshark(path, arguments).splitlines():
        row = dict(zip(_FIELDS, line.split("\t")))
        if _field(row, "tcp.stream"):
            protocol, ports = "tcp", ("tcp.srcport", "tcp.dstport")
            payload = int(_field(row, "tcp.len") or 0)
        elif _field(row, "udp.stream"):
            protocol, ports = "udp", ("udp.srcport", "udp.dstport")
            payload = max(int(_field(row, "udp.length") or 8) - 8, 0)
        else:
            continue
        src_host = _field(row, "ip.src") or _field(row, "ipv6.src")
        dst_host = _field(row, "ip.dst") or _field(row, "ipv6.dst")
        if not src_host or not _field(row, ports[0]):
            continue

        def flag(name: str) -> bool:
            return _field(row, name) in ("1", "True")

        packet = _Packet(
            number=int(row["frame.number"]),
            epoch_ns=_epoch_ns(row["frame.time_epoch"]),
            src=(src_host, int(row[ports[0]])),
            dst=(dst_host, int(row[ports[1]])),
            syn=flag("tcp.flags.syn"), ack=flag("tcp.flags.ack"),
            fin=flag("tcp.flags.fin"), reset=flag("tcp.flags.reset"),
            payload_size=payload,
        )
        if protocol == "tcp":
            packet.seq = _number(_field(row, "tcp.seq"))
            packet.acknowledged = _number(_field(row, "tcp.ack")) if packet.ack else None
        yield protocol, int(row[f"{protocol}.stream"]), packet


def conversations(path: str) -> List[Conversation]:
    """The capture's TCP conversations and UDP flows, in order of their
    first packet."""
    found: Dict[Tuple[str, int], Conversation] = {}
    for protocol, index, packet in _packets(path):
        found.setdefault((protocol, index), Conversation(protocol, index)).packets.append(packet)
    return sorted(found.values(), key=lambda conversation: conversation.packets[0].number)


def _matching(path: str, display_filter: str) -> set:
    """(protocol, stream index) of the conversations with a packet that
    `display_filter` matches."""
    output = _run_tshark(path, ["-Y", display_filter, "-T", "fields", "-E", "separator=/t",
                                "-E", "occurrence=f",
                                "-e", "tcp.stream", "-e", "udp.stream"])
    found = set()
    for line in output.splitlines():
        tcp, _, udp = line.partition("\t")
        if tcp.strip().isdigit():
            found.add(("tcp", int(tcp)))
        elif udp.strip().split(",")[0].isdigit():
            found.add(("udp", int(udp.strip().split(",")[0])))
    return found


def _stream_filter(stream: str) -> Tuple[Optional[Tuple[str, int]], Optional[str]]:
    """--stream as (protocol, index) for ``tcp:N``, ``udp:N`` or ``N``
    (protocol None), or as a display filter."""
    text = stream.strip()
    protocol, colon, number = text.partition(":")
    if colon and protocol.lower() in ("tcp", "udp") and number.isdigit():
        return (protocol.lower(), int(number)), None
    if text.isdigit():
        return ("", int(text)), None
    return None, text


def _listing(all_of: Sequence[Conversation]) -> str:
    lines = [f"  {conversation.describe()}" for conversation in all_of]
    example = all_of[0].name if all_of else "tcp:0"
    return ("\n".join(lines) + f"\nchoose one with --stream {example} (or a tshark display "
            f"filter, e.g. --stream 'tcp.port == 502'), or narrow with --device-addr IP:PORT")


def choose(path: str, stream: Optional[str] = None,
           device_addr: Optional[str] = None, name: Optional[str] = None,
           every: Optional[List[Conversation]] = None
           ) -> Tuple[Conversation, Tuple[str, int]]:
    """The conversation to import and its device endpoint; CaptureError
    when none matches or several do. `name`: the channel the stream is
    for (``--stream NAME=FILTER``), named in the errors; `every`: the
    capture's conversations, when already listed."""
    flag = f"--stream {name}={stream}" if name is not None else f"--stream {stream}"
    device = parse_address(device_addr) if device_addr else None
    display_filter = None
    index = None
    if stream is not None:
        index, display_filter = _stream_filter(stream)
    if every is None:
        every = conversations(path)
    candidates = list(every)
    if display_filter:
        matching = _matching(path, display_filter)
        candidates = [c for c in candidates if (c.protocol, c.index) in matching]
    if index is not None:
        protocol, number = index
        candidates = [c for c in candidates
                      if c.index == number and (not protocol or c.protocol == protocol)]
    if device is not None:
        candidates = [c for c in candidates if c.has_endpoint(device)]
    if not candidates:
        asked = []
        if stream is not None:
            asked.append(flag)
        if device_addr:
            asked.append(f"--device-addr {device_addr}")
        what = f"matching {' and '.join(asked)}" if asked else "of TCP or UDP"
        message = f"{path}: no conversation {what} in the capture"
        if every:
            message += "; its conversations:\n" + "\n".join(f"  {c.describe()}" for c in every)
        raise CaptureError(message, 0)
    if len(candidates) > 1:
        matching = f" match {flag}" if stream is not None else " in the capture"
        raise CaptureError(f"{path}: {len(candidates)} conversations{matching}:\n"
                           + _listing(candidates), 0)
    conversation = candidates[0]
    return conversation, conversation.device(device)


def _follow_chunks(path: str, conversation: Conversation
                   ) -> Iterator[Tuple[Tuple[str, int], int, Optional[int], bytes]]:
    """(sender, epoch ns, packet number, bytes) per chunk of the reassembled stream, from
    ``tshark -z follow,PROTO,yaml,N``."""
    output = _run_tshark(path, ["-q", "-z", f"follow,{conversation.protocol},yaml,"
                                            f"{conversation.index}"])
    peers: Dict[int, Tuple[str, int]] = {}
    section = None
    item: Dict[str, str] = {}
    data_lines: List[str] = []
    in_data = False

    def finish():
        if "peer" in item:
            sender = peers[int(item["peer"])]
            data = base64.b64decode("".join(data_lines)) if data_lines else b""
            return sender, _epoch_ns(item["timestamp"]), _number(item.get("packet", "")), data
        return None

    for raw in output.splitlines():
        line = raw.rstrip()
        if line in ("peers:", "packets:"):
            section, item = line[:-1], {}
            continue
        stripped = line.strip()
        if section == "peers":
            if stripped.startswith("- "):
                item = {}
                stripped = stripped[2:]
            key, _, value = stripped.partition(": ")
            item[key] = value
            if {"peer", "host", "port"} <= item.keys():
                peers[int(item["peer"])] = (item["host"], int(item["port"]))
        elif section == "packets":
            if stripped.startswith("- "):
                chunk = finish()
                if chunk is not None:
                    yield chunk
                item, data_lines, in_data = {}, [], False
                stripped = stripped[2:]
            if in_data and raw.startswith("      "):
                data_lines.append(stripped)
                continue
            key, _, value = stripped.partition(": ")
            if key == "data":
                in_data = True
                continue
            item[key] = value
    if section == "packets":
        chunk = finish()
        if chunk is not None:
            yield chunk


@dataclasses.dataclass
class _Extent:
    """What the sequence numbers say of one direction of a TCP stream."""

    start: int  # the relative sequence number of its first byte
    length: int  # how far it is known to have reached, in bytes
    holes: List[CaptureGap]  # the bytes no captured segment claims


def _sequence_extents(conversation: Conversation, device: Tuple[str, int]) -> Dict[str, _Extent]:
    """Each direction of a TCP conversation from its sequence numbers:
    from the SYN (or the first segment seen) to the furthest byte the stream
    is known to have reached (a segment's end, its FIN, or what the other
    side acknowledged), and the bytes between that no segment claims."""
    extents: Dict[str, _Extent] = {}
    for direction in ("rx", "tx"):
        from_device = direction == "rx"
        # (sequence number, packet) of this direction's segments
        mine = [(p.seq, p) for p in conversation.packets
                if (p.src == device) == from_device and p.seq is not None]
        acknowledged = [p.acknowledged for p in conversation.packets
                        if (p.src == device) != from_device and p.acknowledged is not None]
        syn = any(p.syn for _, p in mine)
        covered = sorted((seq, seq + p.payload_size) for seq, p in mine if p.payload_size > 0)
        if not covered and not syn:
            continue
        start = 1 if syn else covered[0][0]
        fins = [seq for seq, p in mine if p.fin]
        if fins:
            end = min(fins)
        else:
            end = max([last for _, last in covered] +
                      [ack for ack in acknowledged if ack >= start] + [start])
        holes = []
        position = start
        for first, last in covered:
            if first > position and position < end:
                holes.append(CaptureGap(direction, position - start, min(first, end) - position))
            position = max(position, last)
        if position < end:
            holes.append(CaptureGap(direction, position - start, end - position))
        extents[direction] = _Extent(start, max(end - start, 0), holes)
    return extents


def _is_marker(data: bytes, epoch_ns: int, sender: Tuple[str, int],
               packets: Dict[int, _Packet], number: Optional[int]) -> Optional[int]:
    """The byte count tshark's "[N bytes missing in capture file]" stands
    for, when `data` is that marker and not bytes the packet carried."""
    match = _MISSING_MARKER.fullmatch(data)
    if match is None:
        return None
    packet = packets.get(number) if number is not None else None
    # tshark's follow prints times through a double: close, not equal.
    if packet is not None and packet.src == sender and abs(packet.epoch_ns - epoch_ns) < 1_000_000 \
            and packet.payload_size >= len(data):
        return None  # a segment really carried this text
    return int(match.group(1))


def read_capture(path: str, stream: Optional[str] = None,
                 device_addr: Optional[str] = None, allow_gaps: bool = False
                 ) -> Tuple[_core.SessionHeader, List[Tuple[str, int, bytes]]]:
    """The session of one conversation of the capture `path`: its header
    (as convert's other sources give it) and records (kind, t_ns, data) in
    time order.

    Bytes the capture lost (a TCP sequence hole, or tshark's "[N bytes
    missing in capture file]") are never payload: CaptureError names the
    stream, the direction and the offset, unless `allow_gaps`, which
    records a ``capture_gap`` event (direction, offset, length) there and
    no bytes."""
    with open(path, "rb"):  # missing, unreadable: an OSError naming the file (exit 3)
        pass
    conversation, device = choose(path, stream, device_addr)
    header, records = _import_conversation(path, conversation, device, allow_gaps,
                                           conversation.packets[0].epoch_ns)
    return header, [(kind, t_ns, data) for t_ns, _, kind, data in records]


def _start_utc(path: str, conversation: Conversation, start_ns: int) -> str:
    start_utc = _utc_text(start_ns)
    if start_utc is None:
        first = conversation.packets[0]
        raise CaptureError(f"{path}: packet {first.number}: timestamp {_seconds_text(start_ns)} s "
                           f"since 1970 is not a date (the capture's times are damaged)", 0)
    return start_utc


def _import_conversation(path: str, conversation: Conversation, device: Tuple[str, int],
                         allow_gaps: bool, start_ns: int, channel: Optional[str] = None
                         ) -> Tuple[_core.SessionHeader, List[Tuple[int, int, str, bytes]]]:
    """The header of one conversation's session and its records
    (t_ns, order, kind, data) in time order, on a clock whose zero is
    `start_ns` (epoch ns): its first packet's, or the first of several
    conversations imported into one session, the `channel` named in the
    errors."""
    first = conversation.packets[0]
    label = conversation.name if channel is None else f"{conversation.name} (channel {channel})"
    start_utc = _start_utc(path, conversation, start_ns)
    device_host, device_port = device
    header = _core.SessionHeader(
        port_type=conversation.protocol,
        port_options=f"type={conversation.protocol},"
                     f"host={_core.quote_option_value(device_host)},port={device_port}",
        capture="wire",
        start_utc=start_utc,
        source_format="pcap",
        source_files=[os.path.basename(path)],
        source_details={"stream": conversation.name},
        device_address=_address(device_host, device_port),
    )
    try:
        header.to_json()  # what the session writer would refuse, refused here
    except _core.OptionError as error:
        raise CaptureError(f"{path}: {label}: no session can start as its first "
                           f"packet ({first.number}) says: {error}", 0) from None
    records: List[Tuple[int, int, str, bytes]] = []  # (t_ns, order, kind, data)

    def add(epoch_ns: int, kind: str, data: bytes) -> None:
        t_ns = max(epoch_ns - start_ns, 0)
        if t_ns > _core.MAX_RECORD_T_NS:
            raise CaptureError(f"{path}: a packet {_seconds_text(t_ns)} s after the first: "
                               f"beyond the {_seconds_text(_core.MAX_RECORD_T_NS)} s a session "
                               f"can hold (the capture's times are damaged)", 0)
        records.append((t_ns, len(records), kind, data))

    client = next((side for side in conversation.endpoints if side != device),
                  conversation.endpoints[0])
    client_text = _address(*client)
    if conversation.protocol == "tcp":
        syn = next((p for p in conversation.packets if p.syn and not p.ack), None)
        if syn is not None:
            add(syn.epoch_ns, "client_connect",
                _core.event_payload("client_connect", {"peer": client_text, "role": "control"}))
    extents = (_sequence_extents(conversation, device) if conversation.protocol == "tcp"
               else {})
    holes = {direction: list(extents[direction].holes) if direction in extents else []
             for direction in ("rx", "tx")}
    packets = {packet.number: packet for packet in conversation.packets}
    offsets = {"rx": 0, "tx": 0}

    def gap(epoch_ns: int, found: CaptureGap) -> None:
        if not allow_gaps:
            raise CaptureError(f"{path}: {found.describe(label)}: the capture lost "
                               f"them, and an import never invents bytes; --allow-gaps imports "
                               f"the rest with a capture_gap event there", 0)
        add(epoch_ns, "capture_gap", _core.event_payload(
            "capture_gap", {"direction": found.direction, "offset": found.offset,
                            "length": found.length}))
        offsets[found.direction] = found.offset + found.length

    def holes_before(direction: str, epoch_ns: int, offset: int) -> None:
        """The sequence holes up to `offset` (tshark may pass over a lost
        segment without a marker)."""
        pending = holes[direction]
        while pending and pending[0].offset <= offset:
            hole = pending.pop(0)
            lost_from, lost_to = max(hole.offset, offsets[direction]), hole.offset + hole.length
            if lost_to > lost_from:
                gap(epoch_ns, CaptureGap(direction, lost_from, lost_to - lost_from))

    last_data_ns = start_ns
    for sender, epoch_ns, number, data in _follow_chunks(path, conversation):
        if not data:
            continue
        direction = "rx" if sender == device else "tx"
        missing = _is_marker(data, epoch_ns, sender, packets, number)
        if missing is not None:
            holes_before(direction, last_data_ns, offsets[direction] - 1)
            found = CaptureGap(direction, offsets[direction], missing)
            # The sequence hole it stands for is this gap.
            holes[direction] = [h for h in holes[direction]
                                if h.offset + h.length <= found.offset
                                or h.offset >= found.offset + found.length]
            gap(last_data_ns, found)
            continue
        # tshark gives the chunks in stream order, each with its packet's
        # time: bytes that came before a missing segment reach the receiver
        # only when it arrives, so a chunk is never earlier than the last.
        last_data_ns = max(last_data_ns, epoch_ns)
        holes_before(direction, last_data_ns, offsets[direction])
        packet = packets.get(number) if number is not None else None
        if direction in extents and packet is not None and packet.src == sender \
                and packet.seq is not None:
            # A segment cut short by the capture's snapshot length: tshark
            # gives what was captured, and the next segment starts later.
            expected = packet.seq - extents[direction].start
            if expected > offsets[direction]:
                gap(last_data_ns, CaptureGap(direction, offsets[direction],
                                             expected - offsets[direction]))
        add(last_data_ns, direction, data)
        offsets[direction] += len(data)
        if conversation.protocol == "udp" and packet is not None \
                and packet.payload_size > len(data):
            # A datagram cut short by the capture's snapshot length.
            gap(last_data_ns, CaptureGap(direction, offsets[direction],
                                         packet.payload_size - len(data)))
    for direction in ("rx", "tx"):
        holes_before(direction, last_data_ns, 1 << 64)
        if direction in extents and offsets[direction] < extents[direction].length:
            gap(last_data_ns, CaptureGap(direction, offsets[direction],
                                         extents[direction].length - offsets[direction]))
    if conversation.protocol == "tcp":
        ends = [p for p in conversation.packets if p.fin or p.reset]
        if ends:
            first_end, last_end = ends[0], ends[-1]
            by = "the client" if first_end.src == client else "the device"
            reason = f"{'reset' if first_end.reset else 'closed'} by {by}"
            add(max(last_end.epoch_ns, last_data_ns), "client_disconnect",
                _core.event_payload("client_disconnect", {"peer": client_text, "reason": reason}))
    records.sort()
    return header, records


# --- several conversations, one session of channels (DESIGN §19) ------------

_NAME_PREFIX = re.compile(r"([A-Za-z_][A-Za-z0-9_-]*)=(?!=)(.*)", re.DOTALL)


def split_name(text: str) -> Tuple[Optional[str], str]:
    """``NAME=VALUE`` as (NAME, VALUE); anything else (``tcp:0``, a display
    filter such as ``tcp.port == 502``, whose first ``=`` is part of
    ``==`` or follows a dotted field) as (None, text)."""
    match = _NAME_PREFIX.fullmatch(text)
    if match is None:
        return None, text
    return match.group(1), match.group(2)


def read_capture_channels(path: str, streams: Sequence[Tuple[str, str]],
                          device_addrs: Optional[Dict[str, str]] = None,
                          allow_gaps: bool = False
                          ) -> Tuple[_core.SessionHeader, List[Tuple[str, int, bytes, int]]]:
    """Several conversations of the capture `path` as one session: each
    (NAME, FILTER) of `streams` (``--stream NAME=FILTER``, in order) chooses
    one conversation, imported as read_capture does into the channel NAME
    (ids in the order given); `device_addrs` gives a channel's device side
    by name. One clock, the capture's: time 0 is the first packet of any
    chosen conversation. Returns the header (``channels``; its top-level
    port members are channel 0's) and records (kind, t_ns, data, channel
    id) in time order. CaptureError: a stream that matches no conversation
    or several (naming the flag and listing the capture's conversations),
    two names for one conversation, and what read_capture refuses."""
    with open(path, "rb"):  # missing, unreadable: an OSError naming the file (exit 3)
        pass
    device_addrs = dict(device_addrs or {})
    every = conversations(path)
    chosen: List[Tuple[str, str, Conversation, Tuple[str, int]]] = []
    for name, stream in streams:
        conversation, device = choose(path, stream, device_addrs.get(name), name=name,
                                      every=every)
        for other_name, other_stream, other, _ in chosen:
            if other is conversation:
                raise CaptureError(
                    f"{path}: --stream {other_name}={other_stream} and --stream "
                    f"{name}={stream} choose the same conversation ({conversation.name}): "
                    f"a conversation is imported into one channel", 0)
        chosen.append((name, stream, conversation, device))
    start_ns = min(conversation.packets[0].epoch_ns for _, _, conversation, _ in chosen)
    channels = []
    merged: List[Tuple[int, int, int, str, bytes]] = []  # (t_ns, channel, order, kind, data)
    for channel_id, (name, _, conversation, device) in enumerate(chosen):
        part, records = _import_conversation(path, conversation, device, allow_gaps, start_ns,
                                             channel=name)
        channels.append(_core.Channel(id=channel_id, name=name,
                                      port_options=part.port_options,
                                      port_type=part.port_type, capture=part.capture,
                                      device_address=part.device_address))
        merged.extend((t_ns, channel_id, order, kind, data)
                      for t_ns, order, kind, data in records)
    first = channels[0]
    header = _core.SessionHeader(
        port_type=first.port_type,
        port_options=first.port_options,
        capture=first.capture,
        start_utc=_utc_text(start_ns) or "",
        source_format="pcap",
        source_files=[os.path.basename(path)],
        source_details={"streams": ",".join(f"{name}={conversation.name}"
                                            for name, _, conversation, _ in chosen)},
        device_address=first.device_address,
    )
    header.channels = channels
    try:
        header.to_json()  # what the session writer would refuse, refused here
    except _core.OptionError as error:
        raise CaptureError(f"{path}: no session can hold these channels: {error}", 0) from None
    merged.sort()
    return header, [(kind, t_ns, data, channel) for t_ns, channel, _, kind, data in merged]
