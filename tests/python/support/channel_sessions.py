"""Sessions of several ports (format 1.2, DESIGN §19) written from Python,
with the records kept as the oracle the tools' results are checked against."""

from __future__ import annotations

import dataclasses
from typing import Dict, List, Sequence, Tuple

import wiretape
from wiretape import _core


@dataclasses.dataclass
class ChannelSession:
    """A written session: its path, channel names by id, and every record
    (channel id, kind, t_ns, data) in the order written."""

    path: str
    names: Dict[int, str]
    records: List[Tuple[int, str, int, bytes]]

    def of(self, name: str) -> List[Tuple[str, int, bytes]]:
        """The records of channel `name`: (kind, t_ns, data)."""
        wanted = {id for id, known in self.names.items() if known == name}
        return [(kind, t, data) for channel, kind, t, data in self.records if channel in wanted]


def write_channel_session(path, channels: Sequence[Tuple[str, str]],
                          records: Sequence[Tuple[str, str, int, bytes]],
                          stray: Sequence[Tuple[int, str, int, bytes]] = ()) -> ChannelSession:
    """Writes a session of `channels` ((name, port_type), ids in order) and
    `records` ((channel name, kind, t_ns, data), written in order); `stray`
    records ((channel id, ...)) are written after them under ids the
    header may not list."""
    header = _core.SessionHeader()
    header.capture = "wire"
    header.channels = [_core.Channel(id=number, name=name, port_type=port_type,
                                     port_options=f"type={port_type},name={name}",
                                     capture="wire")
                       for number, (name, port_type) in enumerate(channels)]
    ids = {name: number for number, (name, _) in enumerate(channels)}
    written: List[Tuple[int, str, int, bytes]] = []
    with wiretape.SessionWriter(str(path), header) as writer:
        for name, kind, t_ns, data in records:
            writer.write(kind, t_ns, data, channel=ids[name])
            written.append((ids[name], kind, t_ns, data))
        for channel, kind, t_ns, data in stray:
            writer.write(kind, t_ns, data, channel=channel)
            written.append((channel, kind, t_ns, data))
    return ChannelSession(str(path), {number: name for name, number in ids.items()}, written)


def gnss_records(fixes: int = 3, corrections: int = 2) -> List[Tuple[str, str, int, bytes]]:
    """A GNSS driver's session: `gps` answers each poll 4 ms later, in two
    records; `rtk` (a caster) answers each request 20 ms later; the
    channels' records interleave on the one clock (a poll of gps is
    followed by rtk's traffic before gps answers), so that anything
    mixing them up shows."""
    records: List[Tuple[str, str, int, bytes]] = [("gps", "open", 0, b"{}"),
                                                  ("rtk", "open", 100_000, b"{}")]
    t = 1_000_000
    for n in range(max(fixes, corrections)):
        if n < fixes:
            records.append(("gps", "tx", t, b"POLL%d\r\n" % n))
        if n < corrections:
            records.append(("rtk", "tx", t + 1_000_000, b"GET /MOUNT%d\r\n" % n))
            records.append(("rtk", "rx", t + 21_000_000, b"RTCM%d" % n + b"\xd3" * 8))
        if n < fixes:
            records.append(("gps", "rx", t + 4_000_000, b"$GPGGA,%d," % n))
            records.append(("gps", "rx", t + 4_500_000, b"FIX*00\r\n"))
        t += 50_000_000
    records.sort(key=lambda record: record[2])
    return records
