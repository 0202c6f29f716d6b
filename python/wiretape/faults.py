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
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import random
import shlex
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, Iterator, List, Optional, Sequence, TextIO

from . import _core, bridge
from .children import Child
from .session import open_session

#: Every fault kind, as a campaign injects it (docs/faults.md says why these
#: amounts): the replay's own table of kinds.
KINDS = tuple(kind.campaign for kind in _core.fault_kinds())
KIND_NAMES = tuple(kind.name for kind in _core.fault_kinds())
OUTCOMES = ("ok", "error", "crash", "hang")
PORT_PLACEHOLDER = "{port}"
# What sanitizers print when they find something: a crash even if the
# program then exits with a plain error code.
_SANITIZER_MARKERS = ("ERROR: AddressSanitizer", "ERROR: LeakSanitizer",
                      "ERROR: MemorySanitizer", "WARNING: ThreadSanitizer",
                      "runtime error:", "ERROR: UndefinedBehaviorSanitizer")


class FaultInputError(ValueError):
    """Bad input to a campaign (exit 2): names the problem."""


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


def session_shape(session: str, profile: Optional[str] = None, match: Optional[str] = None,
                  options: str = "") -> SessionShape:
    """The exchanges that hold rx as a replay with ``profile`` and ``match``
    (and further replay keys ``options``) numbers them: counted by the one
    segmentation in C++ (``_core.session_exchanges``). A proxy recording
    counts its first client session, as its replay serves a client (the
    exchanges numbered per file, from ``first_exchange``)."""
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
    shape = shape or session_shape(session, profile=profile, match=match, options=options)
    for fault in plan:
        number, value = fault.number, fault.value
        if fault.where == "exchange" and number is not None and number >= shape.exchanges:
            raise FaultInputError(
                f"{fault.text}: the session has {shape.exchanges} exchanges with rx "
                f"(0..{shape.exchanges - 1}); exchange {number} is past its end")
        if fault.where == "rx" and number is not None and number >= shape.rx_bytes:
            raise FaultInputError(f"{fault.text}: the session has {shape.rx_bytes} rx bytes; "
                                  f"rx byte {number} is past its end")
        if fault.where == "t" and value is not None and value > shape.seconds:
            raise FaultInputError(f"{fault.text}: the session lasts {shape.seconds:.3f} s; "
                                  f"t:{value:g} is past its end")


def cases(session: str, kinds: Optional[Sequence[str]] = None, budget: Optional[int] = None,
          seed: int = 0, profile: Optional[str] = None, match: Optional[str] = None,
          options: str = "") -> List[FaultCase]:
    """The campaign's cases: every kind (``kinds``, default all) at every
    exchange of ``session`` (numbered as a replay with ``profile``, ``match``
    and further replay keys ``options`` numbers them); with ``budget``, that
    many of them sampled by ``seed``, in the same order. Items of ``kinds``
    may name a place themselves (``drop@rx:100``)."""
    shape = session_shape(session, profile=profile, match=match, options=options)
    fixed: List[FaultCase] = []
    spread: List[str] = []
    for text in (kinds or KINDS):
        text = text.strip()
        if "@" in text:
            check_where(session, text, shape)
            fixed.extend(FaultCase(fault.kind_text, fault.where_text, seed)
                         for fault in _core.parse_faults(text))
        else:
            spread.append(_kind_spec(text))
    everything = fixed + [FaultCase(kind, f"exchange:{n}", seed)
                          for kind in spread
                          for n in range(shape.first_exchange, shape.exchanges)]
    if budget is not None and budget < len(everything):
        chosen = sorted(random.Random(seed).sample(range(len(everything)), budget))
        everything = [everything[i] for i in chosen]
    return everything


@contextlib.contextmanager
def faulty_device(session: str, case: Optional[FaultCase] = None, replay_options: str = "",
                  listen: bool = False) -> Iterator[str]:
    """A virtual device replaying ``session`` with ``case``'s fault: yields
    the path of a pty (a symbolic link in a private directory), or with
    ``listen`` a ``HOST:PORT``. Stopped on leaving."""
    keys = ",".join(part for part in (replay_options.strip(), case.options if case else "")
                    if part)
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

    @property
    def spec(self) -> str:
        return f"{self.kind}@{self.where}"

    def as_json(self) -> Dict[str, object]:
        return {"kind": self.kind, "where": self.where, "outcome": self.outcome,
                "exit": self.exit, "seconds": round(self.seconds, 3), "repro": self.repro}


@dataclasses.dataclass
class Campaign:
    session: str
    seed: int
    runs: List[Run]

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
        return {"session": self.session, "seed": self.seed,
                "runs": [run.as_json() for run in self.runs], "summary": self.summary}


class CleanRunFailed(Exception):
    """The command fails without any fault (exit 1)."""

    def __init__(self, run: Run):
        super().__init__(f"the command fails on the clean replay, without any fault "
                         f"({run.outcome}, exit {run.exit}):\n{run.output}")
        self.run = run


def check_command(argv: Sequence[str], as_path: Optional[str]) -> None:
    if not argv:
        raise FaultInputError("no command after --: give the program to run, with {port} "
                              "where the device's path goes")
    if as_path is None and not any(PORT_PLACEHOLDER in arg for arg in argv):
        raise FaultInputError("the command has no {port}: put {port} where the device's path "
                              "goes (e.g. -- ./driver --device {port}), or give --as PATH for "
                              "a program with a fixed device path")


def _classify(returncode: Optional[int], output: str, timed_out: bool) -> str:
    if timed_out:
        return "hang"
    if returncode is not None and returncode < 0:
        return "crash"
    if any(marker in output for marker in _SANITIZER_MARKERS):
        return "crash"
    return "ok" if returncode == 0 else "error"


def run_case(session: str, case: Optional[FaultCase], argv: Sequence[str], timeout: float,
             replay_options: str = "", listen: bool = False,
             as_path: Optional[str] = None) -> Run:
    """Runs CMD once against a fresh virtual device with ``case``'s fault
    (None: clean); a CMD past `timeout` is ended with everything it
    started (its process group)."""
    started = time.monotonic()
    with faulty_device(session, case, replay_options, listen) as port:
        command = [arg.replace(PORT_PLACEHOLDER, port) for arg in argv]
        if as_path is not None:
            from .redirect import RedirectedCommand

            redirected = RedirectedCommand(command, as_path, os.path.realpath(port),
                                           capture=True)
            try:
                outcome = redirected.child.run(timeout)
            finally:
                redirected.close()
        else:
            outcome = Child(command).run(timeout)
    text = outcome.text
    returncode = None if outcome.timed_out else outcome.returncode
    return Run(case.kind if case else "", case.where if case else "",
               _classify(returncode, text, outcome.timed_out), returncode,
               time.monotonic() - started, output=text)


def reproduction(session: str, case: FaultCase, argv: Sequence[str], replay_options: str,
                 as_path: Optional[str]) -> str:
    """One line that replays the fault and runs the command against it."""
    port = "/tmp/wiretape-fault-port"
    replay = ["wiretape", "replay", session, "--pty", port, "--fault", case.spec,
              "--seed", str(case.seed)]
    if replay_options:
        replay += ["--options", replay_options]
    if as_path is not None:
        return shlex.join(replay + ["--as", as_path, "--"] + list(argv))
    command = [arg.replace(PORT_PLACEHOLDER, port) for arg in argv]
    return (shlex.join(replay) + " & sleep 0.5; " + shlex.join(command) + "; kill %1")


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


def campaign(session: str, argv: Sequence[str], kinds: Optional[Sequence[str]] = None,
             budget: Optional[int] = None, seed: int = 0, timeout: float = 10.0, jobs: int = 1,
             replay_options: str = "", listen: bool = False, as_path: Optional[str] = None,
             progress: Optional[TextIO] = None, quiet_replays: bool = True) -> Campaign:
    """Runs the campaign; raises FaultInputError (bad input) or
    CleanRunFailed."""
    check_command(argv, as_path)
    if jobs < 1:
        raise FaultInputError(f"--jobs {jobs}: give 1 or more")
    if timeout <= 0:
        raise FaultInputError(f"--timeout {timeout}: give a number of seconds above 0")
    if replay_options:
        _core.check_replay_options("type=replay,file=x," + replay_options)
    selected = cases(session, kinds, budget, seed, options=replay_options)
    with _quiet_stderr(quiet_replays) as real_stderr:
        def note(text: str) -> None:
            if progress is None:
                return
            if real_stderr is not None and progress is sys.stderr:
                os.write(real_stderr, text.encode())
            else:
                progress.write(text)
                progress.flush()

        clean = run_case(session, None, argv, timeout, replay_options, listen, as_path)
        if clean.outcome != "ok":
            raise CleanRunFailed(clean)
        runs: List[Optional[Run]] = [None] * len(selected)
        done = [0]
        lock = threading.Lock()

        def one(index: int) -> None:
            case = selected[index]
            run = run_case(session, case, argv, timeout, replay_options, listen, as_path)
            if run.outcome in ("crash", "hang"):
                run.repro = reproduction(session, case, argv, replay_options, as_path)
            runs[index] = run
            with lock:
                done[0] += 1
                note(f"\r{done[0]}/{len(selected)} runs")

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            for future in [pool.submit(one, i) for i in range(len(selected))]:
                future.result()
        if selected:
            note("\n")
    return Campaign(session, seed, [run for run in runs if run is not None])


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
            by_kind.setdefault(run.kind, {})[exchange] = run.outcome
            width = max(width, exchange + 1)
        else:
            others.append(run)
    lines = []
    if by_kind:
        corner = "kind \\ exchange"
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
    lines.append(f"{len(result.runs)} runs: " + ", ".join(f"{summary[o]} {o}" for o in OUTCOMES)
                 + "  (. ok  E error  C crash  H hang)")
    return "\n".join(lines)


def write_json(result: Campaign, path: str) -> None:
    with open(path, "w", encoding="utf-8") as output:
        json.dump(result.as_json(), output, indent=1)
        output.write("\n")
