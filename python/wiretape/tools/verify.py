"""``wiretape verify``: checks every record of a session (length and CRC)
and, in a session of several ports, that each record names a channel the
header lists."""

from __future__ import annotations

import dataclasses
import os
import stat
import struct
from typing import Any, Dict, List, Optional, Tuple

from .. import _core
from ..session import SessionPath, open_session
from .channels import channel_label, channel_names

__all__ = ["verify", "VerifyResult"]


@dataclasses.dataclass(frozen=True)
class VerifyResult:
    """The outcome of verify(); ``to_json()`` is what ``verify --json`` prints."""

    ok: bool
    path: str
    records: int  # the good records before the damage (all of them when ok)
    offset: Optional[int]  # where reading stopped, or the first bad record (None when ok)
    message: Optional[str]  # why (None when ok)
    # the records of each channel by name (a channel the header does not
    # list as #N), in a session of several channels; empty otherwise
    channel_records: Dict[str, int] = dataclasses.field(default_factory=dict)
    # the channel of the first record that names one the header does not list
    unlisted_channel: Optional[int] = None

    def to_json(self) -> Dict[str, Any]:
        return dataclasses.asdict(self)


def verify(path: SessionPath) -> VerifyResult:
    """Checks every record's CRC and length, and that it names a channel
    the header lists. Never raises for a bad file: the result says where
    and why reading stopped, or which record names no channel."""
    name = os.fspath(path)
    try:
        reader = open_session(path)
    except _core.SessionError as error:
        return VerifyResult(ok=False, path=name, records=0, offset=error.offset,
                            message=str(error))
    names = channel_names(reader.header)
    counts: Dict[int, int] = {}
    records = 0
    for record in reader:
        counts[record.channel] = counts.get(record.channel, 0) + 1
        records += 1
    damage = reader.damage
    # A reader passes over the records of channels the header does not
    # list, as over kinds it does not know: their record headers say them.
    strays = _unlisted(name, set(names), damage.offset if damage is not None else None)
    for _, channel in strays:
        counts[channel] = counts.get(channel, 0) + 1
    per_channel = ({channel_label(names, channel): counts.get(channel, 0)
                    for channel in sorted(set(names) | set(counts))}
                   if len(names) > 1 or set(counts) - set(names) else {})
    if strays:
        offset, channel = strays[0]
        listed = ", ".join(channel_label(names, id) for id in sorted(names)) or "none"
        more = f" ({len(strays)} such records)" if len(strays) > 1 else ""
        message = (f"record at byte {offset} names channel {channel}, which the header does "
                   f"not list (its channels: {listed}){more}")
        if damage is not None:
            message += f"; and damaged at byte {damage.offset}: {damage.message}"
        return VerifyResult(ok=False, path=name, records=records + len(strays), offset=offset,
                            message=message, channel_records=per_channel,
                            unlisted_channel=channel)
    if damage is not None:
        return VerifyResult(ok=False, path=name, records=records, offset=damage.offset,
                            message=damage.message, channel_records=per_channel)
    return VerifyResult(ok=True, path=name, records=records, offset=None, message=None,
                        channel_records=per_channel)


def _unlisted(path: str, listed: set, end: Optional[int]) -> List[Tuple[int, int]]:
    """(offset, channel) of every record, up to `end` (the damage), whose
    channel is not `listed`, read from the record headers (the records'
    lengths and channels: the layout's constants are the library's). A
    file that cannot be read twice (a pipe) or is not one file (a
    flexiport log) is not walked."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return []
    except OSError:
        return []
    found: List[Tuple[int, int]] = []
    with open(path, "rb") as file:
        fixed = file.read(_core.FILE_HEADER_FIXED_SIZE)
        if len(fixed) < _core.FILE_HEADER_FIXED_SIZE:
            return []
        (json_length,) = struct.unpack_from("<I", fixed, 12)
        offset = _core.FILE_HEADER_OVERHEAD + json_length
        while end is None or offset < end:
            file.seek(offset)
            head = file.read(_core.RECORD_HEADER_SIZE)
            if len(head) < _core.RECORD_HEADER_SIZE:
                break
            length, _, _, channel = struct.unpack_from("<IBBH", head, 0)
            if channel not in listed:
                found.append((offset, channel))
            offset += _core.RECORD_OVERHEAD + length
    return found
