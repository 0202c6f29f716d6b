"""``wiretape verify``: checks every record of a session (length and CRC)
and, in a session of several ports, that each record names a channel the
header lists."""

from __future__ import annotations

import dataclasses
import os
from typing import Any, Dict, Optional

from .. import _core
from ..session import SessionPath
from .channels import channel_label, channel_names

__all__ = ["verify", "repair_index", "VerifyResult"]


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
    # the per-channel index (format 1.3) of a session of several channels:
    # "not needed" (one channel), "current", "absent", "stale", "unchecked"
    index: str = "not needed"
    index_detail: str = ""
    # why the records ended early in a file still being written (a recorder
    # has it open), which is not damage: ok stays True
    unfinished: Optional[str] = None
    unfinished_offset: Optional[int] = None

    def to_json(self) -> Dict[str, Any]:
        return dataclasses.asdict(self)


def verify(path: SessionPath) -> VerifyResult:
    """Checks every record's CRC and length, and that it names a channel
    the header lists. Never raises for a bad file: the result says where
    and why reading stopped, or which record names no channel. The records
    are read by the session reader (``_core.check_session_records``), which
    also reports those of channels the header does not list: it passes over
    them, as over kinds it does not know."""
    name = os.fspath(path)
    try:
        check = _core.check_session_records(name)
    except _core.SessionError as error:
        return VerifyResult(ok=False, path=name, records=0, offset=error.offset,
                            message=str(error))
    index = {"index": check.index_state, "index_detail": check.index_detail}
    names = channel_names(check.header)
    counts = dict(check.channel_records)
    records = check.records
    damage = check.damage
    per_channel = ({channel_label(names, channel): counts.get(channel, 0)
                    for channel in sorted(set(names) | set(counts))}
                   if len(names) > 1 or set(counts) - set(names) else {})
    if check.unlisted_records:
        offset, channel = check.first_unlisted_offset, check.first_unlisted_channel
        listed = ", ".join(channel_label(names, id) for id in sorted(names)) or "none"
        strays = check.unlisted_records
        more = f" ({strays} such records)" if strays > 1 else ""
        message = (f"record at byte {offset} names channel {channel}, which the header does "
                   f"not list (its channels: {listed}){more}")
        if damage is not None:
            message += f"; and damaged at byte {damage.offset}: {damage.message}"
        return VerifyResult(ok=False, path=name, records=records + strays, offset=offset,
                            message=message, channel_records=per_channel,
                            unlisted_channel=channel, **index)
    if damage is not None:
        return VerifyResult(ok=False, path=name, records=records, offset=damage.offset,
                            message=damage.message, channel_records=per_channel, **index)
    return VerifyResult(ok=True, path=name, records=records, offset=None, message=None,
                        channel_records=per_channel, unfinished=check.unfinished,
                        unfinished_offset=check.unfinished_offset, **index)


def repair_index(path: SessionPath) -> str:
    """``verify --repair``: appends the per-channel index to a session of
    several channels whose index is absent or stale (the reader's scan, in
    C++, finds the records). Returns where it was appended, or "" when the
    index was current or is not needed. Raises ``_core.SessionError`` for a
    damaged file."""
    state, detail = _core.repair_session_index(os.fspath(path))
    return detail if detail.startswith("appended") else ""
