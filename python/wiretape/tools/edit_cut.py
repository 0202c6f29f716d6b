"""The ``--cut`` of ``wiretape edit``: the window it keeps, in exchanges
numbered as a replay with the same profile numbers them (the one
segmentation, ``_core.session_exchanges``), and the cutter that keeps the
greeting and the state in force at the cut before the part kept."""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple

from .. import _core
from ..options import join_options
from ..session import event_payload, is_stream
from .edit_specs import Cut

__all__ = ["cut_window", "exchange_starts", "Cutter"]


def exchange_starts(path: str, channel: str = "", profile=None) -> List[int]:
    """The time each exchange begins (its first tx byte; for one with no
    request, its first rx), exchanges as a replay with `profile` (a
    ``_core.Profile``, or None) numbers them (``_core.session_exchanges``;
    per channel in a session of several)."""
    options = join_options(_core.option_string([("channel", channel)] if channel else []),
                           profile.options if profile is not None else "")
    starts: List[int] = []
    for exchange in _core.session_exchanges(path, options=options):
        first = exchange.request_first_t_ns
        starts.append(first if first is not None else exchange.response_first_t_ns)
    return starts


def cut_window(path: str, cut: Cut, channel: str = "", profile=None
               ) -> Tuple[Optional[int], Optional[int]]:
    """[start, end) of the cut in the session's nanoseconds; exchanges are
    `channel`'s (named in a session of several channels), numbered as a
    replay with `profile` numbers them."""
    if not cut.exchanges:
        to_ns = (lambda s: None if s is None else int(round(s * 1e9)))
        return to_ns(cut.start), to_ns(cut.end)
    if is_stream(path):
        raise ValueError(f"--cut {cut.spec}: counting exchanges reads {path} twice; "
                         "give a regular file, not a pipe or FIFO")
    starts = exchange_starts(path, channel, profile)

    def at(index: Optional[float], side: str) -> Optional[int]:
        if index is None:
            return None
        if index >= len(starts):
            if side == "TO" and index == len(starts):
                return None
            whose = f"channel {channel} of the session" if channel else "the session"
            raise ValueError(f"--cut {cut.spec}: {whose} has {len(starts)} "
                             f"exchanges (0 to {len(starts) - 1}), no exchange {int(index)}")
        return starts[int(index)]

    return at(cut.start, "FROM"), at(cut.end, "TO")


_STATE_EVENTS = ("settings", "modem_lines")
# The lines the host sets (a modem_lines event's dtr, rts); the device's
# inputs (cts, dsr, ri, cd) are served, and held over a cut.
_HOST_LINES = {"dtr", "rts"}


class Cutter:
    """Keeps the greeting, the state in force at the cut and the cut part,
    moved back in time; feeds what it keeps on (``keep(channel, kind,
    t_ns, data)``).

    The channels of a session share its one clock: the cut part of every
    channel resumes where the session's client first wrote (on any
    channel), moved back by one shift. Each channel has its own greeting
    (the records before its client's first write), settings, modem lines
    and client: a greeting that ends after the session's first write but
    before the cut is held over the cut, as the state is. With `move`
    false the part kept stays at its time (a cut of some channels only)."""

    def __init__(self, start: Optional[int], end: Optional[int], keep, move: bool = True):
        self.start, self.end, self.keep = start, end, keep
        self.move = move
        self.greeting_channels: Dict[int, bool] = {}  # channel: still in its greeting
        self.first_write: Optional[int] = None  # when a client first wrote: where the cut part resumes
        self.state: Dict[Tuple[int, str], Tuple[int, str, int, bytes]] = {}
        self.greetings: List[Tuple[int, str, int, bytes]] = []  # held over the cut
        self.clients: Dict[int, Tuple[int, str, int, bytes]] = {}
        # Client sessions by the bridge's rule (C++): a monitor's connect or
        # disconnect does not change the client in force.
        self.sessions: Dict[int, _core.ClientSessionTracker] = {}
        self.shift = 0
        self.started = start is None or start == 0
        self.closing: Dict[int, Tuple[str, int, bytes]] = {}

    def add(self, kind: str, t_ns: int, data: bytes, channel: int = 0) -> None:
        in_greeting = self.greeting_channels.setdefault(channel, True)
        if in_greeting and not (kind == "tx" and data):
            if self.first_write is None:
                self.keep(channel, kind, t_ns, data)
                return
            if not self.started:
                if t_ns < self.start:
                    if self.move:
                        # after the session's first write, before the cut: held over it
                        self.greetings.append((channel, kind, t_ns, data))
                    else:
                        self.keep(channel, kind, t_ns, data)
                    return
                self._begin(t_ns)
            if self.end is None or t_ns < self.end:
                self.keep(channel, kind, t_ns - self.shift, data)
            return
        if in_greeting:
            self.greeting_channels[channel] = False
            if self.first_write is None:
                self.first_write = t_ns
        if self.end is not None and t_ns >= self.end:
            if kind in ("close", "device_lost") and channel not in self.closing:
                self.closing[channel] = (kind, t_ns, data)
            return
        if not self.started:
            if t_ns < self.start:
                self._remember(channel, kind, t_ns, data)
                return
            self._begin(t_ns)
        self.keep(channel, kind, t_ns - self.shift, data)

    def _remember(self, channel: int, kind: str, t_ns: int, data: bytes) -> None:
        if kind in _STATE_EVENTS:
            key = kind
            if kind == "modem_lines":
                members = sorted((event_payload(data) or {}).keys())
                if set(members) & _HOST_LINES:
                    # The client's own line changes are checked on replay:
                    # held over the cut they would be changes it never made.
                    return
                key += ":" + ",".join(members)
            self.state[(channel, key)] = (channel, kind, t_ns, data)
        elif kind in ("client_connect", "client_disconnect"):
            sessions = self.sessions.get(channel)
            if sessions is None:
                sessions = self.sessions[channel] = _core.ClientSessionTracker()
            change = sessions.feed(kind, data)
            if change == "began":
                self.clients[channel] = (channel, kind, t_ns, data)
            elif change == "ended":
                self.clients.pop(channel, None)

    def _begin(self, t_ns: int) -> None:
        self.started = True
        resume = self.first_write if self.first_write is not None else 0
        if not self.move:
            # the held state goes just before the cut part, which stays where it was
            resume = self.start
        self.shift = max(0, self.start - resume) if self.move else 0
        held = sorted(self.greetings + list(self.state.values()) + list(self.clients.values()),
                      key=lambda item: item[2])
        for channel, kind, _, data in held:
            self.keep(channel, kind, resume, data)

    def finish(self) -> None:
        if not self.started and self.start is not None:
            self._begin(self.start)
        for channel, (kind, t_ns, data) in sorted(self.closing.items(),
                                                  key=lambda item: item[1][1]):
            self.keep(channel, kind, (self.end if self.end is not None else t_ns) - self.shift,
                      data)
