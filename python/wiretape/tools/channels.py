"""The channels of a session (DESIGN §19, format 1.2) as the tools use
them: names by id, a ``--channel NAME`` choice checked against the file, and
one record stream per channel.

The rules of channels (names, ids, the header member) live in the C++
session model (``SessionHeader.channel_list()``, ``find_channel()``,
``channel_name_problem()``); this module only looks them up.
"""

from __future__ import annotations

import difflib
import os
from typing import Dict, FrozenSet, Iterable, Optional

from .. import _core
from ..session import SessionPath, header_text

__all__ = ["channel_names", "several_channels", "choose_channels", "channel_label",
           "open_channel", "capture_text", "UnknownChannel"]


class UnknownChannel(ValueError):
    """A channel name (``--channel NAME``) the session does not have."""


def channel_names(header: _core.SessionHeader) -> Dict[int, str]:
    """Every channel's name by id; a file without ``channels`` has one,
    id 0, named "" (unnamed)."""
    return {channel.id: channel.name for channel in header.channel_list()}


def several_channels(header: _core.SessionHeader) -> bool:
    """Whether the file holds more than one channel: then the tools name
    the channel of each record."""
    return len(header.channel_list()) > 1


def capture_text(capture) -> str:
    """A capture kind as the header's JSON names it (``client``, ``wire``),
    whether it comes as that text or as the enum."""
    return capture if isinstance(capture, str) else str(getattr(capture, "name", capture))


def channel_label(names: Dict[int, str], channel: int) -> str:
    """A record's channel for people: its name, or ``#N`` for an id the
    header does not list (a damaged or hand-made file)."""
    name = names.get(channel)
    return header_text(name) if name else f"#{channel}"


def choose_channels(header: _core.SessionHeader, chosen: Optional[Iterable[str]],
                    path: SessionPath = "") -> Optional[FrozenSet[int]]:
    """The ids of the channels named in `chosen` (``--channel NAME``,
    repeatable); None when none is chosen (every channel). An unknown name
    raises UnknownChannel (a ValueError) naming it, the closest name and the file's channels."""
    if not chosen:
        return None
    known = [channel.name for channel in header.channel_list() if channel.name]
    where = f"{os.fspath(path)}: " if path else ""
    ids = set()
    for name in chosen:
        channel = header.find_channel(name) if name else None
        if channel is None:
            if not known:
                raise UnknownChannel(f"{where}no channel {name!r}: the session has one unnamed "
                                 "channel (no --channel needed)")
            close = difflib.get_close_matches(name, known, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise UnknownChannel(f"{where}no channel {name!r}{hint}: the session's channels are "
                             + ", ".join(known))
        ids.add(channel.id)
    return frozenset(ids)


def open_channel(path: SessionPath, channel: Optional[int] = None) -> _core.SessionReader:
    """A reader of one channel's records (None: every channel's)."""
    return _core.SessionReader(os.fspath(path), channel=channel)
