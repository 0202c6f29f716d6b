"""Packet captures made in memory for the import tests: classic pcap or
pcapng bytes holding one TCP conversation or UDP flow over IPv4 on Ethernet,
with the segments (and their sequence numbers) the test asks for, so a
capture that lost a segment, reordered one or carries a strange timestamp
needs no capture permission and no file checked in.

tshark checks no checksum by default, so none is computed."""

from __future__ import annotations

import struct
from typing import Iterable, List, Optional, Sequence, Tuple

CLIENT = ("10.0.0.1", 40000)
DEVICE = ("10.0.0.2", 502)

SYN, ACK, PSH, FIN = 0x02, 0x10, 0x08, 0x01


def _ip(address: str) -> bytes:
    return bytes(int(part) for part in address.split("."))


def _ethernet_ipv4(src: str, dst: str, protocol: int, transport: bytes) -> bytes:
    ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(transport), 0, 0x4000, 64, protocol,
                     0, _ip(src), _ip(dst))
    return b"\x00\x00\x00\x00\x00\x02" + b"\x00\x00\x00\x00\x00\x01" + b"\x08\x00" + ip + transport


def tcp_frame(src: Tuple[str, int], dst: Tuple[str, int], seq: int, ack: int, flags: int,
              payload: bytes = b"") -> bytes:
    """An Ethernet frame of one TCP segment."""
    tcp = struct.pack(">HHIIBBHHH", src[1], dst[1], seq & 0xFFFFFFFF, ack & 0xFFFFFFFF,
                      5 << 4, flags, 65535, 0, 0) + payload
    return _ethernet_ipv4(src[0], dst[0], 6, tcp)


def udp_frame(src: Tuple[str, int], dst: Tuple[str, int], payload: bytes) -> bytes:
    """An Ethernet frame of one UDP datagram."""
    udp = struct.pack(">HHHH", src[1], dst[1], 8 + len(payload), 0) + payload
    return _ethernet_ipv4(src[0], dst[0], 17, udp)


def tcp_conversation(exchanges: Sequence[Tuple[str, bytes]], lose: Iterable[int] = (),
                     handshake: bool = True, close: bool = True) -> List[bytes]:
    """The frames of a TCP conversation: the handshake, one segment per
    (side, payload) of `exchanges` (side "tx" from the client, "rx" from the
    device), the FINs. The segments whose indexes are in `lose` are left out
    of the capture (the sequence numbers still count their bytes), as a
    capture that dropped them."""
    lost = set(lose)
    client_seq, device_seq = 1000, 5000
    frames = []
    if handshake:
        frames.append(tcp_frame(CLIENT, DEVICE, client_seq, 0, SYN))
        frames.append(tcp_frame(DEVICE, CLIENT, device_seq, client_seq + 1, SYN | ACK))
        frames.append(tcp_frame(CLIENT, DEVICE, client_seq + 1, device_seq + 1, ACK))
    client_seq += 1
    device_seq += 1
    for index, (side, payload) in enumerate(exchanges):
        if side == "tx":
            frame = tcp_frame(CLIENT, DEVICE, client_seq, device_seq, PSH | ACK, payload)
            client_seq += len(payload)
        else:
            frame = tcp_frame(DEVICE, CLIENT, device_seq, client_seq, PSH | ACK, payload)
            device_seq += len(payload)
        if index not in lost:
            frames.append(frame)
    if close:
        frames.append(tcp_frame(CLIENT, DEVICE, client_seq, device_seq, FIN | ACK))
        frames.append(tcp_frame(DEVICE, CLIENT, device_seq, client_seq + 1, FIN | ACK))
        frames.append(tcp_frame(CLIENT, DEVICE, client_seq + 1, device_seq + 1, ACK))
    return frames


def pcap(frames: Sequence[bytes], start_s: int = 1_700_000_000,
         step_us: int = 1000, cut: Optional[dict] = None) -> bytes:
    """A classic pcap (microseconds, Ethernet) of `frames`, `step_us` apart;
    `cut` {frame index: bytes}: those frames captured without their last
    bytes, as a snapshot length shorter than the frame does."""
    out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1)]
    for index, frame in enumerate(frames):
        seconds, micros = divmod(start_s * 1_000_000 + index * step_us, 1_000_000)
        captured = frame[:len(frame) - (cut or {}).get(index, 0)]
        out.append(struct.pack("<IIII", seconds, micros, len(captured), len(frame)) + captured)
    return b"".join(out)


def _block(kind: int, body: bytes) -> bytes:
    body += b"\x00" * (-len(body) % 4)
    length = 12 + len(body)
    return struct.pack("<II", kind, length) + body + struct.pack("<I", length)


def pcapng(frames: Sequence[bytes], timestamps: Optional[Sequence[int]] = None) -> bytes:
    """A pcapng (one section, one Ethernet interface in microseconds) of
    `frames`; `timestamps` are the raw 64-bit timestamp fields (default:
    1 ms apart from 2023)."""
    if timestamps is None:
        timestamps = [1_700_000_000_000_000 + 1000 * index for index in range(len(frames))]
    out = [_block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1)),
           _block(1, struct.pack("<HHI", 1, 0, 65535))]
    for frame, stamp in zip(frames, timestamps):
        out.append(_block(6, struct.pack("<IIIII", 0, stamp >> 32, stamp & 0xFFFFFFFF,
                                         len(frame), len(frame)) + frame))
    return b"".join(out)
