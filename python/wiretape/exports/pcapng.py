"""The pcapng export (Wireshark, ``tshark -r``); see the package's text for
the file's layout.

A session of a serial (or any non-IP) port is written with the user link
type: the payloads as they crossed. A TCP or UDP session (``port_type`` tcp
or udp) is written as IP packets (``LINKTYPE_RAW``) carrying the recorded
addresses and ports, so that Wireshark's own dissectors decode the protocol
(Modbus/TCP on port 502, or on any port set as its port preference): for TCP a handshake,
consistent sequence and acknowledgement numbers and a closing FIN exchange
are made up around the recorded bytes (network.py).
"""

from __future__ import annotations

import json
import struct
from typing import Any, Dict, Iterable, List, Optional, Tuple

from .._core import __version__
from ..session import (SessionPath, header_fields, open_session, raise_damage,
                       refuse_same_file, session_files)
from ._common import event_json, replacing, start_epoch_ns
from .network import LINKTYPE_RAW, NetworkSession

__all__ = ["write_pcapng", "LINKTYPE_USER0", "LINKTYPE_RAW"]

LINKTYPE_USER0 = 147

_PCAPNG_SHB = 0x0A0D0D0A
_PCAPNG_IDB = 0x00000001
_PCAPNG_EPB = 0x00000006
_BYTE_ORDER_MAGIC = 0x1A2B3C4D

_OPT_END = 0
_OPT_COMMENT = 1
_SHB_USERAPPL = 4
_IF_NAME = 2
_IF_DESCRIPTION = 3
_IF_TSRESOL = 9
_EPB_FLAGS = 2

_EPB_INBOUND = 0x1
_EPB_OUTBOUND = 0x2

# Interface numbers in the pcapng file.
_INTERFACES = (
    ("rx", "device to host (rx)"),
    ("tx", "host to device (tx)"),
    ("events", "port events: open, close, settings, modem lines, break"),
)
_RX_INTERFACE, _TX_INTERFACE, _EVENT_INTERFACE = 0, 1, 2




#: The longest value of one option: its length is 16 bits.
_OPTION_MAX = 0xFFFF


def _pad4(data: bytes) -> bytes:
    return data + b"\0" * (-len(data) % 4)


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + _pad4(value)


def _utf8_cut(data: bytes, limit: int) -> int:
    """Where to cut UTF-8 `data` at or before `limit`: at a character's start."""
    cut = min(limit, len(data))
    while 0 < cut < len(data) and data[cut] & 0xC0 == 0x80:
        cut -= 1
    return cut


def _text_options(code: int, text: str) -> List[Tuple[int, bytes]]:
    """A text longer than one option holds, as several options of `code` in
    order, each cut at a character's start (a comment, which pcapng lets
    repeat: the section's comments, joined, are the header JSON)."""
    data = text.encode("utf-8")
    pieces = []
    while True:
        cut = _utf8_cut(data, _OPTION_MAX)
        pieces.append((code, data[:cut]))
        data = data[cut:]
        if not data:
            return pieces


def _one_text_option(code: int, text: str) -> Tuple[int, bytes]:
    """A text option that cannot repeat (an interface's name, its
    description): cut to what one option holds, ending in an ellipsis
    (the header JSON in the section's comments holds it whole)."""
    data = text.encode("utf-8")
    if len(data) <= _OPTION_MAX:
        return code, data
    ellipsis = "\u2026".encode("utf-8")
    return code, data[:_utf8_cut(data, _OPTION_MAX - len(ellipsis))] + ellipsis


def _options(options: Iterable[Tuple[int, bytes]]) -> bytes:
    body = b"".join(_option(code, value) for code, value in options)
    return body + struct.pack("<HH", _OPT_END, 0) if body else b""


def _block(block_type: int, body: bytes) -> bytes:
    length = 12 + len(body)
    return struct.pack("<II", block_type, length) + body + struct.pack("<I", length)


def _section_header(comment: str) -> bytes:
    body = struct.pack("<IHHq", _BYTE_ORDER_MAGIC, 1, 0, -1)
    body += _options(_text_options(_OPT_COMMENT, comment)
                     + [(_SHB_USERAPPL, f"wiretape {__version__}".encode("utf-8"))])
    return _block(_PCAPNG_SHB, body)


def _interface(name: str, description: str, link_type: int = LINKTYPE_USER0) -> bytes:
    body = struct.pack("<HHI", link_type, 0, 0)  # snaplen 0: no limit
    body += _options([_one_text_option(_IF_NAME, name),
                      _one_text_option(_IF_DESCRIPTION, description),
                      (_IF_TSRESOL, bytes([9]))])
    return _block(_PCAPNG_IDB, body)


def _packet(interface: int, timestamp_ns: int, payload: bytes, flags: int,
            comment: Optional[str] = None) -> bytes:
    body = struct.pack(
        "<IIIII",
        interface,
        (timestamp_ns >> 32) & 0xFFFFFFFF,
        timestamp_ns & 0xFFFFFFFF,
        len(payload),
        len(payload),
    )
    body += _pad4(payload)
    options = []
    if flags:
        options.append((_EPB_FLAGS, struct.pack("<I", flags)))
    if comment:
        options.append((_OPT_COMMENT, comment.encode("utf-8")))
    body += _options(options)
    return _block(_PCAPNG_EPB, body)


def _channel_fields(header: Dict[str, Any], channel: Dict[str, Any]) -> Dict[str, Any]:
    """The header as one channel's own: its port members in place of the
    top-level ones (which are channel 0's), for NetworkSession.of_header."""
    fields = dict(header)
    for key in ("port_options", "port_type", "capture", "device_address"):
        fields[key] = channel.get(key, "")
    return fields


def _write_records_by_direction(out, reader, header: Dict[str, Any], start_ns: int,
                                counts: Dict[str, int]) -> None:
    """A session without named channels: interfaces rx, tx and events."""
    network = NetworkSession.of_header(header)
    for name, description in _INTERFACES:
        link_type = LINKTYPE_USER0
        if network is not None and name in ("rx", "tx"):
            link_type = LINKTYPE_RAW
            description += f", {network.protocol.upper()} over IP"
        out.write(_interface(name, description, link_type))
    for record in reader:
        t_ns, kind, data = record.t_ns, record.kind, record.data
        stamp = start_ns + t_ns
        if network is not None:
            for to_device, packet in network.packets(kind, data):
                interface, flags = ((_TX_INTERFACE, _EPB_OUTBOUND) if to_device
                                    else (_RX_INTERFACE, _EPB_INBOUND))
                out.write(_packet(interface, stamp, packet, flags))
        if kind in ("rx", "tx"):
            if network is None:
                interface, flags = ((_RX_INTERFACE, _EPB_INBOUND) if kind == "rx"
                                    else (_TX_INTERFACE, _EPB_OUTBOUND))
                out.write(_packet(interface, stamp, data, flags))
            counts[kind] += 1
        else:
            out.write(_event_packet(_EVENT_INTERFACE, stamp, kind, data))
            counts["events"] += 1


def _event_packet(interface: int, stamp: int, kind: str, data: bytes) -> bytes:
    event = json.dumps(event_json(data), sort_keys=True)
    return _packet(interface, stamp, f"{kind} {event}".encode("utf-8"), 0,
                   comment=f"wiretape event: {kind}")


def _write_records_by_channel(out, reader, header: Dict[str, Any], start_ns: int,
                              counts: Dict[str, int]) -> None:
    """A session of named channels (DESIGN §19): one interface per channel,
    named after it, carrying its rx (inbound) and tx (outbound) and its
    events; a TCP or UDP channel's interface carries IP packets, which an
    event is not, so its events have an interface of their own,
    ``NAME events``."""
    interface_of: Dict[int, Tuple[int, Optional[NetworkSession], int]] = {}
    number = 0
    for channel in header["channels"]:
        name = channel["name"]
        network = NetworkSession.of_header(_channel_fields(header, channel))
        description = (f"wiretape channel {name}: {channel.get('port_type') or 'port'} "
                       f"{channel.get('port_options') or ''}").rstrip()
        if network is None:
            out.write(_interface(name, description, LINKTYPE_USER0))
            interface_of[channel["id"]] = (number, None, number)
            number += 1
        else:
            out.write(_interface(name, description + f", {network.protocol.upper()} over IP",
                                 LINKTYPE_RAW))
            out.write(_interface(f"{name} events", f"wiretape channel {name}: port events"))
            interface_of[channel["id"]] = (number, network, number + 1)
            number += 2
    for record in reader:
        t_ns, kind, data = record.t_ns, record.kind, record.data
        stamp = start_ns + t_ns
        interface, network, event_interface = interface_of[record.channel]
        if network is not None:
            for to_device, packet in network.packets(kind, data):
                flags = _EPB_OUTBOUND if to_device else _EPB_INBOUND
                out.write(_packet(interface, stamp, packet, flags))
        if kind in ("rx", "tx"):
            if network is None:
                flags = _EPB_INBOUND if kind == "rx" else _EPB_OUTBOUND
                out.write(_packet(interface, stamp, data, flags))
            counts[kind] += 1
        else:
            out.write(_event_packet(event_interface, stamp, kind, data))
            counts["events"] += 1


def write_pcapng(src: SessionPath, dst: SessionPath) -> Dict[str, int]:
    """Writes the session `src` (a .wtape, or a flexiport ``name.log``) to
    `dst` as pcapng; returns counts of what was written
    (``{"rx": n, "tx": n, "events": n}``). A session of named channels has
    an interface per channel (wiretape.exports has the layout). A damaged
    session is written up to the damage, then its SessionError is raised."""
    refuse_same_file(session_files(src), [dst])
    reader = open_session(src)
    header = header_fields(reader)
    start_ns = start_epoch_ns(header)
    counts = {"rx": 0, "tx": 0, "events": 0}
    with replacing(dst) as out:
        out.write(_section_header(json.dumps(header, sort_keys=True, default=str)))
        if header.get("channels"):
            _write_records_by_channel(out, reader, header, start_ns, counts)
        else:
            _write_records_by_direction(out, reader, header, start_ns, counts)
    raise_damage(reader)  # after the rename: the export keeps what came before
    return counts
