"""Fault campaigns (DESIGN.md section 14, docs/faults.md).

``wiretape faults SESSION -- CMD ... {port} ...`` runs CMD once against a
clean replay of SESSION (it must pass), then once per fault case (a fault
kind at an exchange), each against a fresh virtual device, and sorts each run
into ``ok``, ``error``, ``crash`` or ``hang``.

The same cases are there for pytest::

    from wiretape import faults

    @pytest.mark.parametrize("case", faults.cases("scan.wtape", budget=20),
                             ids=lambda case: case.id)
    def test_driver_survives(case):
        with faults.faulty_device("scan.wtape", case) as path:
            ...  # run the driver against path; assert it fails cleanly

A session of several ports (DESIGN §19) has exchanges numbered per
channel: its cases are every channel's (``drop@exchange:3@channel:gps``),
CMD names each channel's device ``{port:NAME}``, and every channel is
replayed, on the session's one clock, with the case's fault (which names
the channel it applies to).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import math
import os
import random
import re
import shlex
import signal
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, Iterator, List, Optional, Sequence, TextIO

from . import _core, bridge, scaled_clock
from .children import Child, sanitizer_report
from .session import open_session, session_files

#: Every fault kind, as a campaign injects it (docs/faults.md says why these
#: amounts): the replay's own table of kinds.
KINDS = tuple(kind.campaign for kind in _core.fault_kinds())
KIND_NAMES = tuple(kind.name for kind in _core.fault_kinds())
OUTCOMES = ("ok", "error", "crash", "hang")
#: The longest --timeout a campaign takes (seconds, about 11.6 days): a
#: bound that no run needs, and that every clock and poll can count to.
MAX_TIMEOUT_S = 1e6
PORT_PLACEHOLDER = "{port}"
#: ``{port:NAME}``: the device of channel NAME of a session of several ports.
_CHANNEL_PLACEHOLDER = re.compile(r"\{port:([^{}]*)\}")


class FaultInputError(ValueError):
    """Bad input to a campaign (exit 2): names the problem."""


class _Stopped(Exception):
    """A run ended early because the campaign was interrupted."""


@dataclasses.dataclass(frozen=True)
class Shard:
    """Shard ``number`` of ``count`` (``--shard K/N``, K from 1): the cases
    whose index is K-1 modulo N. Every shard makes its own clean run."""

    number: int
    count: int

    def __post_init__(self) -> None:
        if self.count < 1 or not 1 <= self.number <= self.count:
            raise FaultInputError(f"--shard {self.number}/{self.count}: K must be from 1 to N "
                                  "(e.g. 1/3, 2/3, 3/3)")

    @classmethod
    def parse(cls, text: str) -> "Shard":
        """``K/N`` as the command line gives it."""
        number, slash, count = text.strip().partition("/")
        if not slash or not number.strip().isdigit() or not count.strip().isdigit():
            raise FaultInputError(f"--shard {text!r}: give K/N, e.g. 2/3 for the second of "
                                  "three shards")
        return cls(int(number), int(count))

    def owns(self, index: int) -> bool:
        return index % self.count == self.number - 1

    def __str__(self) -> str:
        return f"{self.number}/{self.count}"


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
    def options(self) -> str:
        return f"faults={_core.quote_option_value(self.spec)},seed={self.seed}"

    @property
    def id(self) -> str:
        return self.spec


@dataclasses.dataclass
class SessionShape:
    """What a campaign needs to know of a session: its exchanges (numbered
    as replay numbers them), its served rx bytes and its length."""

    exchanges: int  # one past the last exchange with rx
    rx_bytes: int
    seconds: float
    first_exchange: int = 0  # of the client session a replay serves (numbered per file)


def session_channels(session: str) -> List[str]:
    """The channels of a session of several ports, by name; empty for a
    session of one port (named or not): its exchanges are numbered as one."""
    channels = open_session(session).header.channel_list()
    return [channel.name for channel in channels] if len(channels) > 1 else []


def _with_channel(options: str, channel: Optional[str]) -> str:
    if not channel:
        return options
    key = f"channel={_core.quote_option_value(channel)}"
    return f"{options},{key}" if options.strip() else key


def session_shape(session: str, profile: Optional[str] = None, match: Optional[str] = None,
                  options: str = "", channel: Optional[str] = None) -> SessionShape:
    """The exchanges that hold rx as a replay with ``profile`` and ``match``
    (and further replay keys ``options``) numbers them: counted by the one
    segmentation in C++ (``_core.session_exchanges``). A proxy recording
    counts its first client session, as its replay serves a client (the
    exchanges numbered per file, from ``first_exchange``). ``channel``: the
    channel of a session of several ports whose exchanges are counted."""
    if channel:
        return _channel_shape(session, profile, match, options, channel)
    exchanges = _core.session_exchanges(session, profile=profile, match=match, options=options)
    sessions = _core.session_client_sessions(session)
    first_record, end_record = 0, None
    if sessions:
        # A replay serves a client the records after its connect, numbered afresh.
        first_record, end_record = sessions[0].first_record + 1, sessions[0].end_record
        exchanges = [exchange for exchange in exchanges if exchange.client_session == 0]
    with_rx = [exchange for exchange in exchanges if exchange.response_bytes]
    first = exchanges[0].index if exchanges else 0
    end = with_rx[-1].index + 1 if with_rx else 0
    rx_bytes = sum(exchange.response_bytes for exchange in exchanges)
    first_t = last_t = None
    for index, record in enumerate(open_session(session)):
        if index < first_record or (end_record is not None and index >= end_record):
            continue
        first_t = record.t_ns if first_t is None else first_t
        last_t = record.t_ns
    return SessionShape(end, rx_bytes, ((last_t or 0) - (first_t or 0)) / 1e9, first)


def _channel_shape(session: str, profile: Optional[str], match: Optional[str], options: str,
                   channel: str) -> SessionShape:
    """session_shape() of one channel: its exchanges as a replay of it
    (``channel=NAME``) numbers them, from its first client session."""
    exchanges = _core.session_exchanges(session, profile=profile, match=match,
                                        options=_with_channel(options, channel))
    served = [exchange.client_session for exchange in exchanges
              if exchange.client_session is not None]
    if served:
        exchanges = [exchange for exchange in exchanges
                     if exchange.client_session == min(served)]
    with_rx = [exchange for exchange in exchanges if exchange.response_bytes]
    first = exchanges[0].index if exchanges else 0
    end = with_rx[-1].index + 1 if with_rx else 0
    rx_bytes = sum(exchange.response_bytes for exchange in exchanges)
    found = open_session(session).header.find_channel(channel)
    first_t = last_t = None
    if found is not None:
        for record in _core.SessionReader(session, channel=found.id):
            first_t = record.t_ns if first_t is None else first_t
            last_t = record.t_ns
    return SessionShape(end, rx_bytes, ((last_t or 0) - (first_t or 0)) / 1e9, first)


def fault_channel(fault) -> Optional[str]:
    """The channel a parsed fault names (``@channel:NAME``), or None."""
    name = getattr(fault, "channel", None)
    if name is None:
        # (a FaultPlan item that does not bind it: the text says it)
        found = re.search(r"@channel:([^@;]+)", getattr(fault, "text", "") or "")
        name = found.group(1) if found else None
    return name or None


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


def check_where(session: str, spec: str, shape: Optional[SessionShape] = None,
                profile: Optional[str] = None, match: Optional[str] = None,
                options: str = "") -> None:
    """Raises FaultInputError for a plan (KIND@WHERE[;...]) that the replay
    refuses, or whose WHERE lies past the session's end (exchange:N, rx:N,
    t:SECONDS), exchanges counted as a replay with ``profile``, ``match``
    and ``options`` counts them."""
    try:
        plan = _core.parse_faults(spec)
    except _core.OptionError as error:
        raise FaultInputError(str(error)) from None
    channels = session_channels(session)
    shapes: Dict[Optional[str], SessionShape] = {}
    for fault in plan:
        channel = fault_channel(fault)
        if channel is not None and channel not in channels:
            known = (", ".join(channels) if channels
                     else "none: the session has one port (leave @channel out)")
            raise FaultInputError(f"{fault.text}: the session has no channel {channel!r} "
                                  f"(its channels: {known})")
        if channel not in shapes:
            if channel is None and channels:
                # A fault without @channel applies to every channel: past
                # the end only when past every channel's.
                each = [session_shape(session, profile=profile, match=match, options=options,
                                      channel=name) for name in channels]
                shapes[channel] = SessionShape(max(one.exchanges for one in each),
                                               max(one.rx_bytes for one in each),
                                               max(one.seconds for one in each))
            else:
                shapes[channel] = (shape if shape is not None and channel is None else
                                   session_shape(session, profile=profile, match=match,
                                                 options=options, channel=channel))
        fault_shape = shapes[channel]
        number, value = fault.number, fault.value
        whose = (f"channel {channel}" if channel else
                 "every channel" if channels else "the session")
        if (fault.where == "exchange" and number is not None
                and number >= fault_shape.exchanges):
            raise FaultInputError(
                f"{fault.text}: {whose} has {fault_shape.exchanges} exchanges with rx "
                f"(0..{fault_shape.exchanges - 1}); exchange {number} is past its end")
        if fault.where == "rx" and number is not None and number >= fault_shape.rx_bytes:
            raise FaultInputError(f"{fault.text}: {whose} has {fault_shape.rx_bytes} rx "
                                  f"bytes; rx byte {number} is past its end")
        if fault.where == "t" and value is not None and value > fault_shape.seconds:
            raise FaultInputError(f"{fault.text}: {whose} lasts {fault_shape.seconds:.3f} s; "
                                  f"t:{value:g} is past its end")


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
    everything = _all_cases(session, kinds, budget, seed, profile, match, options)
    if shard is None:
        return everything
    return [case for index, case in enumerate(everything) if shard.owns(index)]


def _all_cases(session: str, kinds: Optional[Sequence[str]], budget: Optional[int], seed: int,
               profile: Optional[str], match: Optional[str], options: str) -> List[FaultCase]:
    channels = session_channels(session)
    shape = (session_shape(session, profile=profile, match=match, options=options)
             if not channels else None)
    fixed: List[FaultCase] = []
    spread: List[str] = []
    for text in (kinds or KINDS):
        text = text.strip()
        if "@" in text:
            check_where(session, text, shape, profile=profile, match=match, options=options)
            fixed.extend(FaultCase(fault.kind_text, fault.where_text, seed)
                         for fault in _core.parse_faults(text))
        else:
            spread.append(_kind_spec(text))
    if not channels:
        places = [f"exchange:{n}" for n in range(shape.first_exchange, shape.exchanges)]
    else:
        places = []
        for channel in channels:
            own = session_shape(session, profile=profile, match=match, options=options,
                                channel=channel)
            places += [f"exchange:{n}@channel:{channel}"
                       for n in range(own.first_exchange, own.exchanges)]
    everything = fixed + [FaultCase(kind, place, seed) for kind in spread for place in places]
    if budget is not None and budget < len(everything):
        chosen = sorted(random.Random(seed).sample(range(len(everything)), budget))
        everything = [everything[i] for i in chosen]
    return everything


@contextlib.contextmanager
def faulty_device(session: str, case: Optional[FaultCase] = None, replay_options: str = "",
                  listen: bool = False, speed: float = 1.0) -> Iterator[str]:
    """A virtual device replaying ``session`` with ``case``'s fault: yields
    the path of a pty (a symbolic link in a private directory), or with
    ``listen`` a ``HOST:PORT``. Stopped on leaving. ``speed`` K: the
    replay's timing K times faster (the replay key ``speed``), for a
    client whose clock runs at K (wiretape.scaled_clock)."""
    speed_key = f"speed={speed!r}" if speed != 1.0 else ""
    keys = ",".join(part for part in (replay_options.strip(), speed_key,
                                      case.options if case else "") if part)
    with tempfile.TemporaryDirectory(prefix="wiretape-faults-") as directory:
        link = os.path.join(directory, "port")
        handle = bridge.serve_replay(session, pty=None if listen else link,
                                     listen="127.0.0.1:0" if listen else None,
                                     replay_options=keys, quiet=True)
        try:
            yield handle.address if listen else link
        finally:
            handle.stop()
            handle.wait()


@contextlib.contextmanager
def faulty_devices(session: str, case: Optional[FaultCase] = None, replay_options: str = "",
                   listen: bool = False, speed: float = 1.0) -> Iterator[Dict[str, str]]:
    """faulty_device() for a session of several ports: every channel
    replayed (``channel=NAME``) on the session's one clock, each with
    ``case``'s fault (a fault naming a channel applies to it alone); yields
    each channel's device (a pty path, or with ``listen`` a ``HOST:PORT``)
    by name."""
    channels = session_channels(session)
    if not channels:
        raise FaultInputError(f"{session}: a session of one port: use faulty_device()")
    with contextlib.ExitStack() as stack:
        devices = {}
        for channel in channels:
            devices[channel] = stack.enter_context(faulty_device(
                session, case, _with_channel(replay_options, channel), listen, speed))
        yield devices


def _substituted(argv: Sequence[str], devices: Dict[str, str]) -> List[str]:
    """CMD with each ``{port:NAME}`` (and ``{port}``, a session of one
    port's) replaced by the device."""
    def one(arg: str) -> str:
        arg = _CHANNEL_PLACEHOLDER.sub(lambda found: devices[found.group(1)], arg)
        return arg.replace(PORT_PLACEHOLDER, devices[""]) if "" in devices else arg
    return [one(arg) for arg in argv]


# --------------------------------------------------------------------------
# the campaign


@dataclasses.dataclass
class Run:
    kind: str
    where: str
    outcome: str
    exit: Optional[int]
    seconds: float
    repro: str = ""
    output: str = ""
    #: The case's index among the campaign's cases (all shards).
    case: int = 0

    @property
    def spec(self) -> str:
        return f"{self.kind}@{self.where}"

    def as_json(self) -> Dict[str, object]:
        return {"case": self.case, "kind": self.kind, "where": self.where,
                "outcome": self.outcome, "exit": self.exit, "seconds": round(self.seconds, 3),
                "repro": self.repro}


@dataclasses.dataclass
class Campaign:
    session: str
    seed: int
    runs: List[Run]
    #: SIGINT or SIGTERM ended it early: ``runs`` are those that ended by
    #: themselves before (the run it stopped has no outcome).
    interrupted: bool = False
    #: How many cases were to run (in this shard).
    planned: int = 0
    #: What makes the cases: shards of one campaign agree on all of these
    #: (``merge`` checks it).
    kinds: Optional[List[str]] = None
    budget: Optional[int] = None
    options: str = ""
    session_sha256: str = ""
    #: The campaign's cases in all shards, and this one's shard (None: all).
    cases: int = 0
    shard: Optional[Shard] = None
    #: --speed: CMD's clock ran this many times faster than real time.
    speed: float = 1.0

    @property
    def summary(self) -> Dict[str, int]:
        counts = {outcome: 0 for outcome in OUTCOMES}
        for run in self.runs:
            counts[run.outcome] += 1
        return counts

    @property
    def failed(self) -> bool:
        summary = self.summary
        return summary["crash"] > 0 or summary["hang"] > 0

    def as_json(self) -> Dict[str, object]:
        return {"session": self.session, "session_sha256": self.session_sha256,
                "seed": self.seed, "kinds": self.kinds, "budget": self.budget,
                "options": self.options, "cases": self.cases,
                "shard": str(self.shard) if self.shard else None, "speed": self.speed,
                "runs": [run.as_json() for run in self.runs], "summary": self.summary,
                "interrupted": self.interrupted}


class CampaignInterrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM (``signum``) stopped a campaign: the running case's
    CMD and replay were ended, and ``campaign`` holds the runs so far. A
    KeyboardInterrupt, so that it ends a caller as Ctrl-C does."""

    def __init__(self, campaign: Campaign, signum: int):
        super().__init__(signum)
        self.campaign = campaign
        self.signum = signum


class CleanRunFailed(Exception):
    """The command fails without any fault (exit 1)."""

    def __init__(self, run: Run):
        super().__init__(f"the command fails on the clean replay, without any fault "
                         f"({run.outcome}, exit {run.exit}):\n{run.output}")
        self.run = run


def check_command(argv: Sequence[str], as_path: Optional[str],
                  channels: Sequence[str] = ()) -> None:
    """Refuses a CMD without a device to run against; `channels`: those of
    a session of several ports, whose devices CMD names ``{port:NAME}``."""
    if not argv:
        raise FaultInputError("no command after --: give the program to run, with {port} "
                              "where the device's path goes")
    if channels:
        if as_path is not None:
            raise FaultInputError("--as redirects one device path: a session of several "
                                  "ports needs {port:NAME} in the command for each channel")
        named = [found.group(1) for arg in argv for found in _CHANNEL_PLACEHOLDER.finditer(arg)]
        if any(PORT_PLACEHOLDER in arg for arg in argv) or not named:
            raise FaultInputError("the session has several ports (channels "
                                  + ", ".join(channels) + "): put {port:NAME} where each "
                                  "channel's device path goes (e.g. -- ./driver --gps "
                                  "{port:" + channels[0] + "})")
        for name in named:
            if name not in channels:
                raise FaultInputError("{port:" + name + "}: the session has no channel "
                                      f"{name!r} (its channels: {', '.join(channels)})")
        return
    if as_path is None and not any(PORT_PLACEHOLDER in arg for arg in argv):
        raise FaultInputError("the command has no {port}: put {port} where the device's path "
                              "goes (e.g. -- ./driver --device {port}), or give --as PATH for "
                              "a program with a fixed device path")


def _classify(returncode: Optional[int], output: str, timed_out: bool) -> str:
    if timed_out:
        return "hang"
    if returncode is not None and returncode < 0:
        return "crash"
    if sanitizer_report(output) is not None:
        return "crash"
    return "ok" if returncode == 0 else "error"


def run_case(session: str, case: Optional[FaultCase], argv: Sequence[str], timeout: float,
             replay_options: str = "", listen: bool = False,
             as_path: Optional[str] = None, stop: Optional[threading.Event] = None,
             speed: float = 1.0) -> Run:
    """Runs CMD once against a fresh virtual device with ``case``'s fault
    (None: clean); a CMD past `timeout` is ended with everything it
    started (its process group), and so is one running when `stop` is set
    (then this raises _Stopped: the run has no outcome). The outcome is
    decided by CMD's own exit, not by the end of its output: a daemon it
    left holding the output is not waited for. At `speed` K, CMD's clock
    and the replay run K times faster, and `timeout` is on CMD's clock."""
    started = time.monotonic()
    real_timeout = min(scaled_clock.real_seconds(timeout, speed), MAX_TIMEOUT_S)
    several = session_channels(session)
    with (faulty_devices(session, case, replay_options, listen, speed) if several else
          faulty_device(session, case, replay_options, listen, speed)) as port:
        devices = port if several else {"": port}
        command = _substituted(argv, devices)
        if as_path is not None:
            from .redirect import RedirectedCommand, recorded_identity

            redirected = RedirectedCommand(command, as_path, os.path.realpath(port),
                                           identity=recorded_identity(session), speed=speed)
            try:
                outcome = redirected.child.run(real_timeout, stop)
            finally:
                redirected.close()
        else:
            outcome = Child(command, env=scaled_clock.environment(speed)).run(real_timeout, stop)
    if outcome.stopped:
        raise _Stopped()
    text = outcome.text
    returncode = None if outcome.timed_out else outcome.returncode
    return Run(case.kind if case else "", case.where if case else "",
               _classify(returncode, text, outcome.timed_out), returncode,
               time.monotonic() - started, output=text)


#: Where a reproduction line puts the virtual device (a pty link, or with
#: --listen a TCP address).
REPRO_PORT = "/tmp/wiretape-fault-port"
REPRO_ADDRESS = "127.0.0.1:5020"


def reproduction(session: str, case: FaultCase, argv: Sequence[str], replay_options: str,
                 as_path: Optional[str], listen: bool = False,
                 timeout: Optional[float] = None, speed: float = 1.0) -> str:
    """One line for a shell that replays the fault, runs the command
    against it and exits with the command's status, as the campaign's run
    did (with `timeout`, a hang ends as `timeout` ends it: status 124; at
    `speed` K, the replay runs with --speed K and CMD on the scaled clock)."""
    channels = session_channels(session)
    replay = ["wiretape", "replay", session, "--fault", case.spec, "--seed", str(case.seed)]
    if speed != 1.0:
        replay += ["--speed", _seconds_text(speed)]
    if replay_options:
        replay += ["--options", replay_options]
    limit = [] if timeout is None else ["timeout", "-k", "5",
                                        _seconds_text(scaled_clock.real_seconds(timeout, speed))]
    if as_path is not None:
        # replay -- CMD keeps CMD running under an injected loss, and exits
        # with CMD's status when CMD failed: the run's own.
        return shlex.join(limit + replay + ["-q", "--as", as_path, "--"] + list(argv))
    port = REPRO_ADDRESS if listen else REPRO_PORT
    if channels:
        # each channel's device at its own place; replay NAME=PLACE (DESIGN §19)
        host, _, first_port = REPRO_ADDRESS.rpartition(":")
        devices = {name: (f"{host}:{int(first_port) + number}" if listen
                          else f"{REPRO_PORT}-{name}")
                   for number, name in enumerate(channels)}
    else:
        devices = {"": port}
    command = _substituted(argv, devices)
    if speed != 1.0:
        # CMD on the scaled clock, as replay --speed K -- CMD would run it.
        command = (["env", "LD_PRELOAD=" + scaled_clock.shim_path(),
                    f"{scaled_clock.ENV_SPEED}={speed!r}"] + command)
    for name, place in devices.items():
        replay += ["--listen" if listen else "--pty", f"{name}={place}" if name else place]
    # CMD starts once the device is there: its link appears (a TCP
    # listener is given a second: a probe would be a client of the replay).
    ready = "sleep 1" if listen else "; ".join(
        f"until [ -e {shlex.quote(place)} ]; do sleep 0.1; done" for place in devices.values())
    return (f"({shlex.join(replay + ['-q'])} & {ready}; {shlex.join(limit + command)}; "
            "status=$?; kill $!; wait $!; exit $status)")


def _seconds_text(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(value)


@contextlib.contextmanager
def _quiet_stderr(enabled: bool) -> Iterator[Optional[int]]:
    """The replays' own fault reports (one line each on stderr) would bury
    the table: they go to /dev/null while the runs go on. Yields a
    descriptor of the real stderr (None when not quieted)."""
    if not enabled:
        yield None
        return
    sys.stderr.flush()
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 2)
    os.close(null)
    try:
        yield saved
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _check_timeout(timeout: float) -> None:
    if not math.isfinite(timeout) or timeout <= 0 or timeout > MAX_TIMEOUT_S:
        raise FaultInputError(f"--timeout {timeout:g}: give a finite number of seconds above 0 "
                              f"and at most {MAX_TIMEOUT_S:g}")


def _end_pool(pool: ThreadPoolExecutor) -> None:
    """Waits for the running cases to end (they were told to stop), a further
    interruption notwithstanding: none of them is left behind."""
    while True:
        try:
            pool.shutdown(wait=True, cancel_futures=True)
            return
        except KeyboardInterrupt:
            continue


def campaign(session: str, argv: Sequence[str], kinds: Optional[Sequence[str]] = None,
             budget: Optional[int] = None, seed: int = 0, timeout: float = 10.0, jobs: int = 1,
             replay_options: str = "", listen: bool = False, as_path: Optional[str] = None,
             progress: Optional[TextIO] = None, quiet_replays: bool = True,
             shard: Optional[Shard] = None, speed: float = 1.0,
             progress_every: Optional[float] = None) -> Campaign:
    """Runs the campaign (with ``shard``, that shard's cases and a clean
    run; at ``speed`` K, CMD's clock and the replays K times faster, and
    ``timeout`` on CMD's clock); raises FaultInputError (bad input),
    CleanRunFailed, or CampaignInterrupted (SIGINT/SIGTERM as a
    KeyboardInterrupt: the runs so far are in it). Progress goes to
    ``progress``: one line rewritten in place (a terminal), or with
    ``progress_every`` a line every that many seconds and one at the end (a
    log)."""
    check_command(argv, as_path, session_channels(session))
    if jobs < 1:
        raise FaultInputError(f"--jobs {jobs}: give 1 or more")
    _check_timeout(timeout)
    try:
        speed = scaled_clock.check_speed(speed)
    except ValueError as error:
        raise FaultInputError(str(error)) from None
    if replay_options:
        _core.check_replay_options("type=replay,file=x," + replay_options)
        if speed != 1.0 and "speed" in dict(_core.parse_options(replay_options)):
            raise FaultInputError("--options holds speed= and --speed is given: give --speed "
                                  "only (it sets the replay's speed and CMD's clock)")
    everything = _all_cases(session, kinds, budget, seed, None, None, replay_options)
    indices = [index for index in range(len(everything)) if shard is None or shard.owns(index)]
    selected = [everything[index] for index in indices]
    runs: List[Optional[Run]] = [None] * len(selected)

    def finished(interrupted: bool) -> Campaign:
        return Campaign(session, seed, [run for run in runs if run is not None],
                        interrupted=interrupted, planned=len(selected),
                        kinds=[kind.strip() for kind in kinds] if kinds else None,
                        budget=budget, options=replay_options,
                        session_sha256=session_digest(session), cases=len(everything),
                        shard=shard, speed=speed)
    # Set when the campaign must end: each running case ends its CMD.
    stop = threading.Event()
    with _quiet_stderr(quiet_replays) as real_stderr:
        def note(text: str) -> None:
            if progress is None:
                return
            if real_stderr is not None and progress is sys.stderr:
                os.write(real_stderr, text.encode())
            else:
                progress.write(text)
                progress.flush()

        done = [0]
        lock = threading.Lock()
        started = time.monotonic()
        counted = {outcome: 0 for outcome in OUTCOMES}
        last_line = [started]

        def report() -> None:
            elapsed = time.monotonic() - started
            problems = ", ".join(f"{counted[o]} {o}" for o in OUTCOMES if o != "ok" and counted[o])
            text = (f"wiretape faults: {done[0]}/{len(selected)} runs"
                    + (f" ({problems})" if problems else "") + f", {elapsed:.0f} s")
            if progress_every is None:
                note(f"\r{text}\x1b[K")
            elif done[0] == len(selected) or time.monotonic() - last_line[0] >= progress_every:
                last_line[0] = time.monotonic()
                note(text + "\n")

        def one(index: int) -> None:
            if stop.is_set():
                return
            case = selected[index]
            try:
                run = run_case(session, case, argv, timeout, replay_options, listen, as_path,
                               stop, speed)
            except _Stopped:
                return
            if run.outcome in ("crash", "hang"):
                run.repro = reproduction(session, case, argv, replay_options, as_path, listen,
                                         timeout if run.outcome == "hang" else None, speed)
            run.case = indices[index]
            runs[index] = run
            with lock:
                done[0] += 1
                counted[run.outcome] = counted.get(run.outcome, 0) + 1
                report()

        # The runs go on in worker threads (the clean one too): the main
        # thread only waits, so SIGINT/SIGTERM reach it there, and it tells
        # the workers to stop.
        pool = ThreadPoolExecutor(max_workers=jobs)
        if progress_every is not None:
            note(f"wiretape faults: a clean run, then {len(selected)} runs with faults\n")
        try:
            clean = pool.submit(run_case, session, None, argv, timeout, replay_options,
                                listen, as_path, stop, speed).result()
            if clean.outcome != "ok":
                raise CleanRunFailed(clean)
            for future in [pool.submit(one, i) for i in range(len(selected))]:
                future.result()
        except KeyboardInterrupt as interruption:
            stop.set()
            _end_pool(pool)
            if selected and progress_every is None:
                note("\n")
            result = finished(interrupted=True)
            signum = getattr(interruption, "signum", signal.SIGINT)
            raise CampaignInterrupted(result, signum) from None
        except BaseException:
            stop.set()
            raise
        finally:
            _end_pool(pool)
        if selected and progress_every is None:
            note("\n")
    return finished(interrupted=False)


def session_digest(session: str) -> str:
    """SHA-256 of the session's bytes (every file of a flexiport pair): what
    tells shards run on other machines, under other paths, that they
    replayed the same recording."""
    digest = hashlib.sha256()
    for path in session_files(session):
        with open(path, "rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


_LETTERS = {"ok": ".", "error": "E", "crash": "C", "hang": "H"}


def table(result: Campaign) -> str:
    """A line per kind, a column per exchange: . ok, E error, C crash,
    H hang (blank: not run); then other places and the totals."""
    by_kind: Dict[str, Dict[int, str]] = {}
    others: List[Run] = []
    width = 0
    for run in result.runs:
        place = _core.parse_faults(run.spec)[0]
        if place.where == "exchange" and place.number is not None:
            exchange = place.number
            # a session of several ports: a line per channel and kind
            channel = fault_channel(place)
            row = f"{channel} {run.kind}" if channel else run.kind
            by_kind.setdefault(row, {})[exchange] = run.outcome
            width = max(width, exchange + 1)
        else:
            others.append(run)
    lines = []
    if by_kind:
        channelled = any(fault_channel(_core.parse_faults(run.spec)[0]) for run in result.runs
                         if "@channel:" in run.where)
        corner = "channel kind \\ exchange" if channelled else "kind \\ exchange"
        name_width = max(len(corner), *(len(kind) for kind in by_kind))
        header = "".join(str(n % 10) for n in range(width))
        lines.append(f"{corner:<{name_width}}  {header}")
        for kind, outcomes in by_kind.items():
            cells = "".join(_LETTERS[outcomes[n]] if n in outcomes else " " for n in range(width))
            counts = {outcome: list(outcomes.values()).count(outcome) for outcome in OUTCOMES}
            figures = " ".join(f"{outcome} {count}" for outcome, count in counts.items() if count)
            lines.append(f"{kind:<{name_width}}  {cells}  {figures}")
    for run in others:
        lines.append(f"{run.kind}@{run.where}: {run.outcome}")
    summary = result.summary
    blank = any(n not in outcomes for outcomes in by_kind.values() for n in range(width))
    lines.append(f"{len(result.runs)} runs: " + ", ".join(f"{summary[o]} {o}" for o in OUTCOMES)
                 + "  (. ok  E error  C crash  H hang" + (f"  blank: {_not_run(result)}"
                                                          if blank else "") + ")")
    return "\n".join(lines)


def _not_run(result: Campaign) -> str:
    """Why a cell of the table is blank: the case was not run, because..."""
    reasons = []
    if result.interrupted:
        reasons.append("the campaign was interrupted")
    if result.shard is not None:
        reasons.append(f"another shard's (this is {result.shard})")
    if result.budget is not None and result.budget < result.cases:
        reasons.append(f"left out by --budget {result.budget} (sampled by --seed {result.seed})")
    return "not run: " + ("; or ".join(reasons) if reasons else "no such fault there")


def write_json(result: Campaign, path: str) -> None:
    """Writes the campaign's JSON whole or not at all (a file beside it,
    renamed over `path`); to a FIFO, a device or /dev/stdout, directly."""
    import stat

    try:
        special = not stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        special = False
    if special:
        with open(path, "w", encoding="utf-8") as output:
            json.dump(result.as_json(), output, indent=1)
            output.write("\n")
        return
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(prefix=".wiretape-faults-", suffix=".json",
                                         dir=folder)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as output:
            json.dump(result.as_json(), output, indent=1)
            output.write("\n")
        umask = os.umask(0o022)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)  # as open() would have made it
        os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise


# --------------------------------------------------------------------------
# shards of one campaign, merged


def _member(document: Dict[str, object], name: str, types, where: str):
    if name not in document:
        raise FaultInputError(f"{where}: no {name!r}: not the --json of a wiretape faults run "
                              "with --shard (run it again with this wiretape)")
    value = document[name]
    allowed = types if isinstance(types, tuple) else (types,)
    # A JSON true is a Python bool, which is an int too: not a count.
    if not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed):
        raise FaultInputError(f"{where}: {name!r} is {json.dumps(value)[:60]}: not what a "
                              "campaign writes")
    return value


def read_json(path: str) -> Campaign:
    """A campaign's ``--json`` file read back (for ``merge``); FaultInputError
    names the file and what is wrong in it."""
    try:
        with open(path, encoding="utf-8") as stream:
            document = json.load(stream)
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise FaultInputError(f"{path}: not a campaign's JSON: {error}") from None
    if not isinstance(document, dict):
        raise FaultInputError(f"{path}: not a campaign's JSON: not an object")
    shard_text = _member(document, "shard", (str, type(None)), path)
    kinds = _member(document, "kinds", (list, type(None)), path)
    if kinds is not None and not all(isinstance(kind, str) for kind in kinds):
        raise FaultInputError(f"{path}: 'kinds' holds something that is not a kind")
    runs = []
    for number, item in enumerate(_member(document, "runs", list, path)):
        where = f"{path}: runs[{number}]"
        if not isinstance(item, dict):
            raise FaultInputError(f"{where}: not an object")
        outcome = _member(item, "outcome", str, where)
        if outcome not in OUTCOMES:
            raise FaultInputError(f"{where}: outcome {outcome!r} is not one of "
                                  + ", ".join(OUTCOMES))
        runs.append(Run(_member(item, "kind", str, where), _member(item, "where", str, where),
                        outcome, _member(item, "exit", (int, type(None)), where),
                        float(_member(item, "seconds", (int, float), where)),
                        repro=_member(item, "repro", str, where),
                        case=_member(item, "case", int, where)))
    try:
        shard = Shard.parse(shard_text) if shard_text is not None else None
    except FaultInputError as error:
        raise FaultInputError(f"{path}: {error}") from None
    return Campaign(_member(document, "session", str, path), _member(document, "seed", int, path),
                    runs, interrupted=_member(document, "interrupted", bool, path),
                    kinds=kinds, budget=_member(document, "budget", (int, type(None)), path),
                    options=_member(document, "options", str, path),
                    session_sha256=_member(document, "session_sha256", str, path),
                    cases=_member(document, "cases", int, path), shard=shard,
                    planned=len(runs), speed=_speed_member(document, path))


def _speed_member(document: Dict[str, object], path: str) -> float:
    """``speed`` (written since --speed: 1 when absent)."""
    value = document.get("speed", 1.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value > 0):
        raise FaultInputError(f"{path}: 'speed' is {json.dumps(value)[:60]}: not what a "
                              "campaign writes")
    return float(value)


# What shards of one campaign agree on, and the flag that sets each.
_CAMPAIGN_IDENTITY = (("session_sha256", "SESSION (its bytes differ)"), ("seed", "--seed"),
                      ("kinds", "--kinds"), ("budget", "--budget"), ("options", "--options"),
                      ("speed", "--speed"), ("cases", "the cases (a different wiretape?)"))


def merge(paths: Sequence[str]) -> Campaign:
    """One campaign from the ``--json`` of its shards (``--shard K/N``, every
    K once): the runs in the cases' order, as one unsharded run gives them.
    Refuses (FaultInputError) files of different sessions, seeds, kinds,
    budgets or replay keys, a shard missing or given twice, and an
    interrupted shard."""
    if not paths:
        raise FaultInputError("give the --json files of every shard")
    shards = [(path, read_json(path)) for path in paths]
    first_path, first = shards[0]
    by_number: Dict[int, str] = {}
    for path, part in shards:
        if part.shard is None:
            raise FaultInputError(f"{path}: a whole campaign (run without --shard): nothing to "
                                  "merge")
        if part.interrupted:
            raise FaultInputError(f"{path}: shard {part.shard} was interrupted after "
                                  f"{len(part.runs)} runs: run it again")
        for member, flag in _CAMPAIGN_IDENTITY:
            if getattr(part, member) != getattr(first, member):
                raise FaultInputError(
                    f"{path}: {member} {json.dumps(getattr(part, member))} but {first_path}: "
                    f"{json.dumps(getattr(first, member))}: shards of one campaign share {flag}")
        if part.shard.count != first.shard.count:
            raise FaultInputError(f"{path}: --shard {part.shard} but {first_path}: --shard "
                                  f"{first.shard}: shards of one campaign share N")
        if part.shard.number in by_number:
            raise FaultInputError(f"{path}: shard {part.shard} is also {by_number[part.shard.number]}")
        by_number[part.shard.number] = path
        expected = [index for index in range(part.cases) if part.shard.owns(index)]
        if sorted(run.case for run in part.runs) != expected:
            raise FaultInputError(f"{path}: its runs are not the cases of shard {part.shard} "
                                  f"({len(part.runs)} runs, {len(expected)} cases)")
    missing = [f"{number}/{first.shard.count}" for number in range(1, first.shard.count + 1)
               if number not in by_number]
    if missing:
        raise FaultInputError("missing shard " + ", ".join(missing) + " of the campaign")
    runs = sorted((run for _, part in shards for run in part.runs), key=lambda run: run.case)
    return dataclasses.replace(first, runs=runs, planned=first.cases, shard=None)
