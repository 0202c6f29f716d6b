"""Reading a packet capture for ``convert --from pcap``, all of it
through Wireshark's ``tshark``: a first pass lists the packets of every
conversation (``-T fields``), a second follows the one chosen (``-z
follow,tcp,yaml,N``), which gives each reassembled chunk with its side, its
packet number and its time. Nothing here reassembles; pcap_import makes
the session of what this reads.

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
import os
import re
import shutil
from typing import Dict, Iterator, List, Optional, Sequence, Tuple

from .. import _core
from ..children import Child

__all__ = ["CaptureError", "CaptureGap", "Conversation", "conversations", "choose",
           "follow_chunks", "is_capture", "parse_address", "parse_epoch_ns", "seconds_text",
           "address_text", "Packet", "MISSING_MARKER"]

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
MISSING_MARKER = re.compile(rb"\[([0-9]{1,20}) bytes missing in capture file\]\x00?")

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


def parse_epoch_ns(text: str) -> int:
    """'1795482638.583698988' as an exact count of nanoseconds."""
    whole, _, fraction = text.strip().partition(".")
    return int(whole) * 1_000_000_000 + int((fraction + "000000000")[:9])


def seconds_text(ns: int) -> str:
    text = f"{ns / 1e9:.9g}"
    return text if len(text) <= 30 else f"a number of {len(str(ns))} digits"


def address_text(host: str, port: int) -> str:
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
class Packet:
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
    packets: List[Packet] = dataclasses.field(default_factory=list)

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
        return (f"{self.name}  {address_text(a_host, a_port)} <-> {address_text(b_host, b_port)}  "
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


def _packets(path: str) -> Iterator[Tuple[str, int, Packet]]:
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

        packet = Packet(
            number=int(row["frame.number"]),
            epoch_ns=parse_epoch_ns(row["frame.time_epoch"]),
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


def follow_chunks(path: str, conversation: Conversation
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
            number = _number(item.get("packet", ""))
            return sender, parse_epoch_ns(item["timestamp"]), number, data
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
