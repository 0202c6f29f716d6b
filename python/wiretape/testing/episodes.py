"""The pytest record mode ``new_episodes`` for a cassette of several ports
(DESIGN §11, §19): the episode is a port. The channels a cassette holds are
replayed; the ports it lacks are recorded by a ``wiretape.Recorder`` into a
file of their own, which `append_channels` merges into the cassette when the
test passes.

Inside one port's session there is no honest episode (a device that never saw
the replayed part is in another state than the recording assumes), so a
cassette of one port under new_episodes is recorded as under ``once``.

The merge runs in Python: a 12 MB cassette of 100 000 records of 100 bytes
takes 0.09 s, a 14 MB one of 600 000 records of 4 bytes 0.4 s (the reader
and writer do the work, this module only picks the next record)."""

from __future__ import annotations

import copy
import heapq
import os
from pathlib import Path
from typing import Iterator, List, Tuple

from wiretape import _core

from ..session import raise_damage

# What a merged record is: (t_ns, kind code, data, channel id).
_Entry = Tuple[int, int, bytes, int]


def _entries(reader: _core.SessionReader, offset_ns: int = 0,
             channel_ids=None) -> Iterator[_Entry]:
    for record in reader:
        channel = record.channel if channel_ids is None else channel_ids[record.channel]
        yield max(0, record.t_ns + offset_ns), record.kind_code, record.data, channel


def append_channels(cassette: Path, recording: Path, offset_ns: int, note: str) -> List[str]:
    """Rewrites `cassette` (a session of named channels) with the channels of
    `recording` (a Recorder's file) appended: their ids continue the
    cassette's, their header entries are the recording's; every record of
    the cassette is kept as it was (same time, kind, data, channel), the
    recording's records are moved by `offset_ns` onto the cassette's clock
    (never before its time 0), and both are merged in time order (at equal
    times the cassette's first). `note` ends the header's edits list. The
    new file replaces the cassette atomically (publish_recording); on any
    error the cassette is left as it was. Returns the appended channels'
    names."""
    cassette, recording = Path(cassette), Path(recording)
    merged = cassette.with_name(f"{cassette.name}.appending-{os.getpid()}")
    with _core.SessionReader(str(cassette)) as old, \
            _core.SessionReader(str(recording)) as new:
        header = copy.copy(old.header)
        channels = header.channels
        if not channels:
            raise ValueError(f"{cassette} is a session of one port: channels can be "
                             "appended only to a session of named channels")
        ids = {}
        for channel in new.header.channel_list():
            if header.find_channel(channel.name) is not None:
                raise ValueError(f"{recording}: channel {channel.name!r} is already in "
                                 f"{cassette}: it is replayed, not appended")
            added = copy.copy(channel)
            added.id = len(channels)
            ids[channel.id] = added.id
            channels.append(added)
        header.channels = channels
        header.edits = list(header.edits) + [note]
        try:
            with _core.SessionWriter(str(merged), header, flush_ms=1000) as writer:
                for t_ns, kind, data, channel in heapq.merge(
                        _entries(old), _entries(new, offset_ns, ids), key=lambda e: e[0]):
                    writer.write(kind, t_ns, data, channel)
            # A damaged input would lose what follows the damage: keep the cassette.
            raise_damage(old)
            raise_damage(new)
            _core.publish_recording(str(merged), str(cassette))
        except BaseException:
            if merged.exists():
                merged.unlink()
            raise
    return [channel.name for channel in channels[len(channels) - len(ids):]]
