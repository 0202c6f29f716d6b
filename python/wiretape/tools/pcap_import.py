"""``convert --from pcap``: one TCP conversation or UDP flow of a packet
capture (pcap or pcapng, as tcpdump, dumpcap or Wireshark write them)
becomes a session.

Reading the capture and putting a TCP stream back together (retransmissions
dropped, segments received out of order put back in order, overlapping
segments cut) is Wireshark's work, done by ``tshark`` (pcap_capture); this
module makes the session of the conversation chosen: its header, its
records, the bytes the capture lost.

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

import dataclasses
import os
import re
from typing import Dict, List, Optional, Sequence, Tuple

from .. import _core
from .pcap_capture import (MISSING_MARKER, CaptureError, CaptureGap, Conversation, Packet,
                           address_text, choose, conversations, follow_chunks, is_capture,
                           parse_address, seconds_text)

__all__ = ["CaptureError", "CaptureGap", "Conversation", "conversations", "read_capture",
           "read_capture_channels", "split_name", "is_capture", "parse_address"]


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
               packets: Dict[int, Packet], number: Optional[int]) -> Optional[int]:
    """The byte count tshark's "[N bytes missing in capture file]" stands
    for, when `data` is that marker and not bytes the packet carried."""
    match = MISSING_MARKER.fullmatch(data)
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
    """The header's start_utc of `start_ns`, by the session model's rule
    (``_core.format_start_utc``): a time no header can hold is damage."""
    try:
        return _core.format_start_utc(start_ns)
    except (ValueError, OverflowError, TypeError):  # TypeError: past the int64 clock
        first = conversation.packets[0]
        raise CaptureError(f"{path}: packet {first.number}: timestamp {seconds_text(start_ns)} s "
                           f"since 1970 is not a date a session can start at (the capture's "
                           f"times are damaged)", 0) from None


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
        port_options=_core.option_string([("type", conversation.protocol),
                                          ("host", device_host), ("port", device_port)]),
        capture="wire",
        start_utc=start_utc,
        source_format="pcap",
        source_files=[os.path.basename(path)],
        source_details={"stream": conversation.name},
        device_address=address_text(device_host, device_port),
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
            raise CaptureError(f"{path}: a packet {seconds_text(t_ns)} s after the first: "
                               f"beyond the {seconds_text(_core.MAX_RECORD_T_NS)} s a session "
                               f"can hold (the capture's times are damaged)", 0)
        records.append((t_ns, len(records), kind, data))

    client = next((side for side in conversation.endpoints if side != device),
                  conversation.endpoints[0])
    client_text = address_text(*client)
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
    for sender, epoch_ns, number, data in follow_chunks(path, conversation):
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
        start_utc=_core.format_start_utc(start_ns),
        source_format="pcap",
        source_files=[os.path.basename(path)],
        source_details={"streams": _core.option_string(
            [(name, conversation.name) for name, _, conversation, _ in chosen])},
        device_address=first.device_address,
    )
    header.channels = channels
    try:
        header.to_json()  # what the session writer would refuse, refused here
    except _core.OptionError as error:
        raise CaptureError(f"{path}: no session can hold these channels: {error}", 0) from None
    merged.sort()
    return header, [(kind, t_ns, data, channel) for t_ns, channel, _, kind, data in merged]
