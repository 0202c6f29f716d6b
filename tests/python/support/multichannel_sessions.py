"""A session of several named channels (format 1.2, DESIGN §19) written
with SessionWriter, for the tests of what reads, converts and exports such
files: a GPS on a serial line (``gps``) and an RTK correction stream over
TCP (``rtk``), their records interleaved on one clock."""

from __future__ import annotations

import wiretape
from wiretape import _core

RTK_CLIENT = "127.0.0.1:40100"
RTK_DEVICE = "127.0.0.1:2101"

CHANNELS = [
    dict(id=0, name="gps", port_options="type=serial,device=/dev/ttyUSB0,baud=9600",
         port_type="serial", capture="wire"),
    dict(id=1, name="rtk", port_options="type=tcp,host=127.0.0.1,port=2101",
         port_type="tcp", capture="wire", device_address=RTK_DEVICE),
]

# (t_ns, kind, data, channel id)
RECORDS = [
    (0, "open", b"", 0),
    (1_000, "client_connect",
     _core.event_payload("client_connect", {"peer": RTK_CLIENT, "role": "control"}), 1),
    (2_000, "tx", b"GET /RTCM3 HTTP/1.0\r\n\r\n", 1),
    (3_000_000, "rx", b"$GPGGA,123519,4807.038,N,01131.000,E*47\r\n", 0),
    (3_500_000, "rx", b"ICY 200 OK\r\n\r\n\xd3\x00\x13>\xd0", 1),
    (4_000_000, "settings", b'{"baud": 115200}', 0),
    (5_000_000, "tx", b"\xb5b\x06\x01\x03\x00\xf0\x05\x00\xff\x19", 0),
    (5_000_000, "rx", b"\xd3\x00\x04\x4c\xe0\x00\x80\xed\xed\xd6", 1),
    (6_000_000, "rx", b"$GPRMC,123519,A*6A\r\n", 0),
    (7_000_000, "client_disconnect",
     _core.event_payload("client_disconnect", {"peer": RTK_CLIENT, "reason": "closed by the client"}),
     1),
    (8_000_000, "close", b"", 0),
]


def channels_header(channels=CHANNELS, **members) -> _core.SessionHeader:
    """A header listing `channels` (dicts of Channel's members); its
    top-level port members are channel 0's, as the format says."""
    first = channels[0]
    header = _core.SessionHeader(
        port_options=first["port_options"], port_type=first["port_type"],
        capture=first.get("capture", "client"),
        device_address=first.get("device_address", ""),
        start_utc="2026-11-26T10:00:00.000000000Z", host="robot", **members)
    header.channels = [_core.Channel(**channel) for channel in channels]
    return header


def write_channels_session(path, records=RECORDS, channels=CHANNELS, **members):
    """Writes a session of `channels` holding `records` (t_ns, kind, data,
    channel id) to `path`; returns `path`."""
    with wiretape.SessionWriter(str(path), channels_header(channels, **members)) as writer:
        for t_ns, kind, data, channel in records:
            writer.write(kind, t_ns, data, channel=channel)
    return path


def records_with_channels(path, channel=None):
    """(t_ns, kind, data, channel id) of every record of the session at
    `path` (of one channel, when given); raises its damage, if any."""
    with wiretape.SessionReader(str(path), channel) as reader:
        records = [(r.t_ns, r.kind, bytes(r.data), r.channel) for r in reader]
        if reader.damage is not None:
            raise reader.damage
    return records


def channel_list(path):
    """The session's channels as dicts of their members."""
    header = wiretape.SessionReader(str(path)).header
    return [channel_members(channel) for channel in header.channel_list()]


def channel_members(channel) -> dict:
    identity = channel.device_identity
    return {"id": channel.id, "name": channel.name, "port_options": channel.port_options,
            "port_type": channel.port_type, "capture": channel.capture,
            "device_address": channel.device_address,
            "device_identity": None if identity is None else repr(identity)}
