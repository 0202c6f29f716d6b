"""A campaign's cases: the fault kinds, the places a session has for them
(counted and checked in C++: ``_core.session_shape``,
``FaultPlan.check_against``), and the cases made of both, sampled and
sharded."""

from __future__ import annotations

import dataclasses
import random
from typing import List, Optional, Sequence, Tuple

from .. import _core
from ..session import open_session
from .shard import FaultInputError, Shard

#: Every fault kind, as a campaign injects it (docs/faults.md says why these
#: amounts): the replay's own table of kinds.
KINDS = tuple(kind.campaign for kind in _core.fault_kinds())
KIND_NAMES = tuple(kind.name for kind in _core.fault_kinds())
OUTCOMES = ("ok", "error", "crash", "hang")

#: Where faults can fire in what a replay serves (``session_shape()``).
SessionShape = _core.SessionShape


@dataclasses.dataclass(frozen=True)
class FaultCase:
    """One fault at one place: ``options`` is the replay keys that inject it
    (``faults=...,seed=S``), ``id`` a name for pytest."""

    kind: str
    where: str
    seed: int = 0

    @property
    def spec(self) -> str:
        return f"{self.kind}@{self.where}"

    @property
    def option_pairs(self) -> List[Tuple[str, object]]:
        return [("faults", self.spec), ("seed", self.seed)]

    @property
    def options(self) -> str:
        return _core.option_string(self.option_pairs)

    @property
    def id(self) -> str:
        return self.spec


def session_channels(session: str) -> List[str]:
    """The channels of a session of several ports, by name; empty for a
    session of one port (named or not): its exchanges are numbered as one."""
    channels = open_session(session).header.channel_list()
    return [channel.name for channel in channels] if len(channels) > 1 else []


def _with_channel(options: str, channel: Optional[str]) -> str:
    """The replay keys `options` with ``channel=`` (none: as they are)."""
    if not channel:
        return options
    return _core.option_string(_core.parse_options(options) + [("channel", channel)])


def session_shape(session: str, profile: Optional[str] = None, match: Optional[str] = None,
                  options: str = "", channel: Optional[str] = None) -> SessionShape:
    """Where faults can fire in what a replay with ``profile``, ``match``
    (and further replay keys ``options``) serves: its exchanges (numbered
    per file, ``first_exchange`` up to ``exchanges``, one past the last with
    rx), rx bytes, and ``seconds``, the session time of its last rx. A
    proxy recording counts every client session, as its replay serves each
    client its own. ``channel``: the channel of a session of several ports. All
    of it measured by the one segmentation in C++."""
    return _core.session_shape(session, profile=profile, match=match, options=options,
                               channel=channel)


def _kind_spec(text: str) -> str:
    """A --kinds item as a campaign injects it: a bare name takes the
    campaign's amount (delay -> delay:500)."""
    text = text.strip()
    if text in KIND_NAMES:
        return KINDS[KIND_NAMES.index(text)]
    try:
        return _core.normal_fault_kind(text)
    except _core.OptionError as error:
        raise FaultInputError(str(error)) from None


def check_where(session: str, spec: str, profile: Optional[str] = None,
                match: Optional[str] = None, options: str = "") -> None:
    """Raises FaultInputError for a plan (KIND@WHERE[;...]) that the replay
    refuses, that names a channel the session lacks, or whose WHERE lies
    past the end of what the replay serves (exchange:N, rx:N, t:SECONDS),
    counted as a replay with ``profile``, ``match`` and ``options`` counts
    them (``FaultPlan.check_against``)."""
    try:
        _core.parse_faults(spec).check_against(session, profile=profile, match=match,
                                               options=options)
    except _core.OptionError as error:
        raise FaultInputError(str(error)) from None


def cases(session: str, kinds: Optional[Sequence[str]] = None, budget: Optional[int] = None,
          seed: int = 0, profile: Optional[str] = None, match: Optional[str] = None,
          options: str = "", shard: Optional[Shard] = None) -> List[FaultCase]:
    """The campaign's cases: every kind (``kinds``, default all) at every
    exchange of ``session`` (numbered as a replay with ``profile``, ``match``
    and further replay keys ``options`` numbers them); with ``budget``, that
    many of them sampled by ``seed``, in the same order. Items of ``kinds``
    may name a place themselves (``drop@rx:100``). With ``shard``, only the
    cases of that shard (``Shard.owns``), in the same order. In a session
    of several ports, every channel's exchanges, channel by channel
    (``drop@exchange:3@channel:gps``)."""
    everything = all_cases(session, kinds, budget, seed, profile, match, options)
    if shard is None:
        return everything
    return [case for index, case in enumerate(everything) if shard.owns(index)]


def all_cases(session: str, kinds: Optional[Sequence[str]], budget: Optional[int], seed: int,
              profile: Optional[str], match: Optional[str], options: str) -> List[FaultCase]:
    """cases() of every shard."""
    fixed: List[FaultCase] = []
    spread: List[str] = []
    for text in (kinds or KINDS):
        text = text.strip()
        if "@" in text:
            check_where(session, text, profile=profile, match=match, options=options)
            fixed.extend(FaultCase(fault.kind_text, fault.where_text, seed)
                         for fault in _core.parse_faults(text))
        else:
            spread.append(_kind_spec(text))
    places: List[str] = []
    for channel in session_channels(session) or [None]:
        own = session_shape(session, profile=profile, match=match, options=options,
                            channel=channel)
        suffix = f"@channel:{channel}" if channel else ""
        places += [f"exchange:{n}{suffix}" for n in range(own.first_exchange, own.exchanges)]
    everything = fixed + [FaultCase(kind, place, seed) for kind in spread for place in places]
    if budget is not None and budget < len(everything):
        chosen = sorted(random.Random(seed).sample(range(len(everything)), budget))
        everything = [everything[i] for i in chosen]
    return everything
