"""A TCP or UDP session's records as the IP packets that carried them, for
the pcapng export: Wireshark dissects these as it would a capture.

Addresses: the device's from the header's ``device_address`` when there is
one, else the ``host`` and ``port`` of ``port_options`` (``bind_port`` for
a UDP port without ``port``); the client's from each ``client_connect``
event's ``peer``. What is not known, or is a name rather than an address,
is replaced by a placeholder from the documentation ranges:
device 192.0.2.2 (port 10001), client 192.0.2.1 (port 49152).

TCP: each client connection (a ``client_connect`` event, or the first bytes
when there is none) starts with a handshake, its bytes follow with sequence
and acknowledgement numbers that add up, and a ``client_disconnect`` ends it
with FIN, FIN, ACK; a payload larger than one packet holds is split.
"""

from __future__ import annotations

import ipaddress
import json
import struct
from typing import Any, Dict, Iterator, List, Optional, Tuple

from .. import _core
from .._core import OptionError
from ..options import default_of, option_values

__all__ = ["LINKTYPE_RAW", "NetworkSession", "PLACEHOLDER_DEVICE", "PLACEHOLDER_CLIENT"]

#: Raw IP (v4 or v6, told by the packet's first nibble).
LINKTYPE_RAW = 101

PLACEHOLDER_DEVICE = ("192.0.2.2", 10001)
PLACEHOLDER_CLIENT = ("192.0.2.1", 49152)

_MAX_SEGMENT = 65000  # payload per packet: an IPv4 packet is at most 65535 bytes
_CLIENT_ISN = 1_000
_DEVICE_ISN = 2_000_000
_SYN, _ACK, _FIN, _PSH = 0x02, 0x10, 0x01, 0x08
_TCP, _UDP = 6, 17

Endpoint = Tuple[Any, int]  # (ipaddress.IPv4Address | IPv6Address, port)


def _address(host: Optional[str], fallback: str):
    try:
        return ipaddress.ip_address((host or "").strip("[]"))
    except ValueError:
        return ipaddress.ip_address(fallback)


def _port(text: Optional[str], fallback: int) -> int:
    if text is not None and str(text).isdigit() and 0 < int(text) <= 65535:
        return int(text)
    return fallback


def parse_endpoint(text: Optional[str], placeholder: Tuple[str, int]) -> Endpoint:
    """'IP:PORT' or '[IPv6]:PORT' as an endpoint; the placeholder's parts
    for what is missing or not an address."""
    host, _, port = (text or "").rpartition(":")
    return _address(host, placeholder[0]), _port(port, placeholder[1])


def _checksum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def _ip_packet(src: Endpoint, dst: Endpoint, protocol: int, segment: bytes) -> bytes:
    """`segment` (a TCP or UDP header and payload, checksum field zero) in
    an IPv4 or IPv6 packet, checksums filled in."""
    source, destination = src[0], dst[0]
    if source.version != destination.version:  # one side unknown: both placeholders' kind
        source = ipaddress.ip_address(PLACEHOLDER_CLIENT[0])
        destination = ipaddress.ip_address(PLACEHOLDER_DEVICE[0])
    checksum_at = 16 if protocol == _TCP else 6
    if source.version == 4:
        pseudo = source.packed + destination.packed + struct.pack("!BBH", 0, protocol,
                                                                  len(segment))
    else:
        pseudo = source.packed + destination.packed + struct.pack("!I3xB", len(segment),
                                                                  protocol)
    checksum = _checksum(pseudo + segment) or (0xFFFF if protocol == _UDP else 0)
    segment = segment[:checksum_at] + struct.pack("!H", checksum) + segment[checksum_at + 2:]
    if source.version == 4:
        header = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(segment), 0, 0x4000, 64,
                             protocol, 0, source.packed, destination.packed)
        header = header[:10] + struct.pack("!H", _checksum(header)) + header[12:]
        return header + segment
    return struct.pack("!IHBB16s16s", 6 << 28, len(segment), protocol, 64, source.packed,
                       destination.packed) + segment


class _TcpConnection:
    def __init__(self, client: Endpoint, device: Endpoint):
        self.client = client
        self.device = device
        self.client_seq = _CLIENT_ISN
        self.device_seq = _DEVICE_ISN

    def _segment(self, to_device: bool, flags: int, payload: bytes = b"") -> Tuple[bool, bytes]:
        src, dst = (self.client, self.device) if to_device else (self.device, self.client)
        seq, ack = ((self.client_seq, self.device_seq) if to_device
                    else (self.device_seq, self.client_seq))
        header = struct.pack("!HHIIBBHHH", src[1], dst[1], seq & 0xFFFFFFFF,
                             ack & 0xFFFFFFFF if flags & _ACK else 0, 5 << 4, flags, 65535, 0, 0)
        return to_device, _ip_packet(src, dst, _TCP, header + payload)

    def open(self) -> List[Tuple[bool, bytes]]:
        packets = [self._segment(True, _SYN)]
        self.client_seq += 1
        packets.append(self._segment(False, _SYN | _ACK))
        self.device_seq += 1
        packets.append(self._segment(True, _ACK))
        return packets

    def data(self, to_device: bool, payload: bytes) -> List[Tuple[bool, bytes]]:
        packets = []
        for start in range(0, len(payload), _MAX_SEGMENT):
            piece = payload[start:start + _MAX_SEGMENT]
            packets.append(self._segment(to_device, _PSH | _ACK, piece))
            if to_device:
                self.client_seq += len(piece)
            else:
                self.device_seq += len(piece)
        return packets

    def close(self) -> List[Tuple[bool, bytes]]:
        packets = [self._segment(True, _FIN | _ACK)]
        self.client_seq += 1
        packets.append(self._segment(False, _FIN | _ACK))
        self.device_seq += 1
        packets.append(self._segment(True, _ACK))
        return packets


class NetworkSession:
    """Turns a TCP or UDP session's records, in order, into IP packets."""

    def __init__(self, protocol: str, device: Endpoint):
        self.protocol = protocol
        self.device = device
        self.client = parse_endpoint(None, PLACEHOLDER_CLIENT)
        self._connection: Optional[_TcpConnection] = None
        # Client sessions by the bridge's rule, kept in C++: a monitor's
        # connect or disconnect is no connection of the client's.
        self._sessions = _core.ClientSessionTracker()

    @classmethod
    def of_header(cls, header: Dict[str, Any]) -> Optional["NetworkSession"]:
        """The session's packet maker, or None when it is not TCP or UDP."""
        protocol = header.get("port_type")
        if protocol not in ("tcp", "udp"):
            return None
        device = parse_endpoint(None, PLACEHOLDER_DEVICE)
        try:
            options: Optional[Dict[str, str]] = option_values(
                header.get("port_options") or "", protocol)
        except OptionError:  # not an option string (an import's header): unknown
            options = None
        if options is not None:
            port = options.get("port")
            if protocol == "udp" and _port(port, 0) == 0:
                port = options.get("bind_port")
            device = (_address(options.get("host") or default_of("host", protocol),
                               PLACEHOLDER_DEVICE[0]),
                      _port(port, PLACEHOLDER_DEVICE[1]))
        if header.get("device_address"):
            device = parse_endpoint(header["device_address"], PLACEHOLDER_DEVICE)
        return cls(protocol, device)

    def packets(self, kind: str, data: bytes) -> Iterator[Tuple[bool, bytes]]:
        """(to the device?, IP packet) for one record; nothing for events
        that are not about the connection."""
        change = self._sessions.feed(kind, data) if kind.startswith("client_") else ""
        if change == "began":
            peer = _peer(data)
            if peer is not None:
                self.client = parse_endpoint(peer, PLACEHOLDER_CLIENT)
            if self.protocol == "tcp":
                if self._connection is not None:
                    yield from self._connection.close()
                self._connection = _TcpConnection(self.client, self.device)
                yield from self._connection.open()
        elif change == "ended" and self._connection is not None:
            yield from self._connection.close()
            self._connection = None
        elif kind in ("rx", "tx"):
            to_device = kind == "tx"
            if self.protocol == "udp":
                src, dst = (self.client, self.device) if to_device else (self.device, self.client)
                for start in range(0, max(len(data), 1), _MAX_SEGMENT):
                    piece = data[start:start + _MAX_SEGMENT]
                    header = struct.pack("!HHHH", src[1], dst[1], 8 + len(piece), 0)
                    yield to_device, _ip_packet(src, dst, _UDP, header + piece)
                return
            if self._connection is None:
                self._connection = _TcpConnection(self.client, self.device)
                yield from self._connection.open()
            yield from self._connection.data(to_device, data)


def _peer(data: bytes) -> Optional[str]:
    try:
        event = json.loads(data.decode("utf-8")) if data else {}
    except (UnicodeDecodeError, ValueError):
        return None
    peer = event.get("peer") if isinstance(event, dict) else None
    return peer if isinstance(peer, str) else None
