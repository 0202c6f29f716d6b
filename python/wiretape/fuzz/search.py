"""``wiretape fuzz SESSION -- CMD ... {port}`` (DESIGN §27, unmodified
programs): plans run as replays to CMD, each through the fault campaign's
runner (faults.run.run_case) against a session the plan wrote; what breaks
CMD is minimized, re-run, deduplicated and written to the findings folder.
With coverage (a CMD built with AFL++'s compiler, coverage.py), a plan whose
run lit new edges joins the corpus, and later plans are mutations of it."""

from __future__ import annotations

import dataclasses
import os
import random
import shutil
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from .. import _core, scaled_clock
from ..faults.cases import FaultInputError, Shard
from ..faults.report import Run
from ..faults.run import (CleanRunFailed, _check_timeout, _quiet_stderr, check_command,
                          replay_reproduction, run_case)
from ..fuzzing import FuzzedRecording
from .coverage import AflMap, Coverage, CoverageError, instrumented, map_size
from .findings import (Finding, debugger_command, debugger_stack, finding_kind, run_signal,
                       signature, stack, write_index)

#: Steps of a plan the search makes (four bytes a step, docs/fuzzing.md).
MAX_STEPS = 4
#: The runs of one search when neither --runs nor --time is given.
DEFAULT_RUNS = 100
#: Real seconds a finding's run under gdb may take (its symbols load first).
DEBUGGER_TIMEOUT_S = 30.0
#: Reproductions tried while minimizing one finding, at most.
MAX_MINIMIZE_RUNS = 32
#: Steps a mutation of a corpus plan grows to, at most.
MAX_CORPUS_STEPS = 16
#: What --coverage takes: auto (AFL++ when CMD's program holds its runtime),
#: afl (always: an error when CMD writes nothing into the map), none.
COVERAGE_MODES = ("auto", "afl", "none")
#: The corpus a search with coverage writes, under the findings folder.
CORPUS_DIR = "corpus"


@dataclasses.dataclass
class Search:
    """The result: the findings kept, and what the search counted."""
    findings: List[Finding]
    runs: List[Run]
    flaky: int = 0
    duplicates: int = 0
    seconds: float = 0.0
    #: "afl" when AFL++'s coverage guided the search, else "".
    coverage: str = ""
    #: With coverage: the recording unchanged (b""), then every plan whose
    #: run lit new edges, in the order found.
    corpus: List[bytes] = dataclasses.field(default_factory=list)
    #: With coverage: the edges the runs lit.
    edges: int = 0

    @property
    def found(self) -> bool:
        return bool(self.findings)


@dataclasses.dataclass
class Target:
    """CMD and how each run is made: what run_case takes besides the session."""
    argv: Sequence[str]
    timeout: float
    replay_options: str = ""
    listen: bool = False
    as_path: Optional[str] = None
    speed: float = 1.0
    coverage: str = "auto"


def random_plan(seed: int, index: int, units: int) -> bytes:
    """The plan of run `index` of a search with `seed`: the same on every
    machine, in every shard and job."""
    rng = random.Random(f"wiretape-fuzz:{seed}:{index}")
    plan = bytearray()
    for _ in range(rng.randint(1, MAX_STEPS)):
        plan += bytes([rng.randrange(256), rng.randrange(max(units, 1)) % 256,
                       rng.randrange(256), rng.randrange(256)])
    return bytes(plan)


def _random_step(rng: random.Random, units: int) -> bytes:
    return bytes([rng.randrange(256), rng.randrange(max(units, 1)) % 256,
                  rng.randrange(256), rng.randrange(256)])


def mutated_plan(seed: int, index: int, corpus: Sequence[bytes], units: int) -> bytes:
    """The plan of run `index` of a search with coverage: a third of the
    time a random plan as without coverage (the corpus fills with plans
    that lit edges by breaking the exchange, whose mutations rarely get
    further), else a mutation of a corpus plan, the newest (what lit edges
    last) a third of the time: 1 to 4
    random steps added; a step of its own copied with its record, offset
    or amount changed (the same change elsewhere: what a plan that got
    past one check most often needs next); one step replaced; a byte of one
    changed; or one step removed (what else it changed may be what stops
    the driver short of the next check). Of the recording unchanged, a
    random plan."""
    rng = random.Random(f"wiretape-fuzz-afl:{seed}:{index}")
    if not corpus or rng.randrange(3) == 0:
        return random_plan(seed, index, units)
    parent = corpus[-1] if rng.randrange(3) == 0 else corpus[rng.randrange(len(corpus))]
    steps = steps_of(parent)
    if not steps:
        return random_plan(seed, index, units)
    how = rng.randrange(5)
    if how == 4 and len(steps) > 1:
        del steps[rng.randrange(len(steps))]
    elif how == 2 or len(steps) >= MAX_CORPUS_STEPS:
        steps[rng.randrange(len(steps))] = _random_step(rng, units)
    elif how == 0:
        for _ in range(min(rng.randint(1, MAX_STEPS), MAX_CORPUS_STEPS - len(steps))):
            steps.insert(rng.randrange(len(steps) + 1), _random_step(rng, units))
    else:
        at = rng.randrange(len(steps))
        step = bytearray(steps[at])
        step[rng.randrange(1, 4)] = rng.randrange(256)
        if how == 1:
            steps.insert(rng.randrange(len(steps) + 1), bytes(step))
        else:
            steps[at] = bytes(step)
    return b"".join(steps)


def _written_options(replay_options: str) -> str:
    """The replay keys the plans' sessions are made with: CMD's own (the
    tolerance that makes a delay inert), on the clock CMD's replays keep
    (causal unless timing= is given), not in-process fuzzing's timing=none."""
    pairs = _core.parse_options(replay_options)
    if not any(key == "timing" for key, _ in pairs):
        pairs.append(("timing", "causal"))
    return _core.option_string(pairs)


def steps_of(plan: bytes) -> List[bytes]:
    return [plan[at:at + 4] for at in range(0, len(plan) - len(plan) % 4, 4)]


class _Runner:
    """Runs plans against CMD, each from a session written in a scratch
    folder; with coverage, each job (thread) with an AFL++ map of its own."""

    def __init__(self, recording: FuzzedRecording, target: Target, scratch: str,
                 stop: threading.Event, coverage_map_size: Optional[int] = None):
        self.recording = recording
        self.target = target
        self.scratch = scratch
        self.stop = stop
        self._count = 0
        self._lock = threading.Lock()
        self._map_size = coverage_map_size
        self._maps: List[AflMap] = []
        self._local = threading.local()

    def _map(self) -> Optional[AflMap]:
        if self._map_size is None:
            return None
        coverage_map = getattr(self._local, "map", None)
        if coverage_map is None:
            coverage_map = self._local.map = AflMap(self._map_size)
            with self._lock:
                self._maps.append(coverage_map)
        return coverage_map

    def close(self) -> None:
        for coverage_map in self._maps:
            coverage_map.close()

    def run(self, plan: bytes) -> Run:
        return self.run_traced(plan)[0]

    def run_traced(self, plan: bytes) -> Tuple[Run, Optional[bytes]]:
        """The run, and with coverage its bucketed AFL++ trace."""
        with self._lock:
            self._count += 1
            path = os.path.join(self.scratch, f"plan-{self._count}.wtape")
        self.recording.write(path, plan)
        coverage_map = self._map()
        target = self.target
        argv = list(target.argv)
        if coverage_map is not None:
            coverage_map.clear()
            argv = ["env", *coverage_map.environment(), *argv]
        try:
            run = run_case(path, None, argv, target.timeout, target.replay_options,
                           target.listen, target.as_path, self.stop, target.speed)
        finally:
            os.unlink(path)
        return run, coverage_map.trace() if coverage_map is not None else None

    def verdict(self, plan: bytes) -> Tuple[Run, Optional[str], str]:
        run = self.run(plan)
        kind = finding_kind(run, self.recording.inert(plan))
        return run, kind, signature(kind, run) if kind else ""

    def debugger_stack(self, plan: bytes) -> List[str]:
        """The plan run once more with CMD under gdb (when it is installed):
        the symbolized stack of a crash CMD printed none for. Generous
        time: gdb loads CMD's symbols before it runs."""
        if shutil.which("gdb") is None:
            return []
        with self._lock:
            self._count += 1
            path = os.path.join(self.scratch, f"plan-{self._count}.wtape")
        self.recording.write(path, plan)
        target = self.target
        try:
            run = run_case(path, None, debugger_command(list(target.argv)),
                           max(target.timeout, DEBUGGER_TIMEOUT_S * target.speed),
                           target.replay_options, target.listen, target.as_path, self.stop,
                           target.speed)
        except OSError:
            return []
        finally:
            os.unlink(path)
        return debugger_stack(run.output or "")

    def minimize(self, plan: bytes, kind: str, sign: str) -> bytes:
        """The plan with every step it does not need to give the same
        finding removed: the fewest changed fields that still reproduce it."""
        steps = steps_of(plan)
        tries = 0
        at = len(steps) - 1
        while at >= 0 and len(steps) > 1 and tries < MAX_MINIMIZE_RUNS:
            candidate = b"".join(steps[:at] + steps[at + 1:])
            if self.recording.edits(candidate) == self.recording.edits(b"".join(steps)):
                steps.pop(at)  # the step changed nothing: no run needed
            else:
                tries += 1
                _, got_kind, got_sign = self.verdict(candidate)
                if got_kind == kind and got_sign == sign:
                    steps.pop(at)
            at = min(at - 1, len(steps) - 1)
        return b"".join(steps)


def search(session: str, target: Target, findings_dir: str, profile: Optional[str] = None,
           seed: int = 0, runs: Optional[int] = None, seconds: Optional[float] = None,
           jobs: int = 1, shard: Optional[Shard] = None, plans: Sequence[bytes] = (),
           progress: Optional[Callable[[str], None]] = None) -> Search:
    """Runs the search and writes its findings (FaultInputError: bad input;
    CleanRunFailed: CMD fails on the recording unchanged)."""
    check_command(target.argv, target.as_path, ())
    _check_timeout(target.timeout)
    if jobs < 1:
        raise FaultInputError(f"--jobs {jobs}: give 1 or more")
    if target.coverage not in COVERAGE_MODES:
        raise FaultInputError(f"--coverage {target.coverage}: give one of "
                              f"{', '.join(COVERAGE_MODES)}")
    try:
        target.speed = scaled_clock.check_speed(target.speed)
        recording = FuzzedRecording(session, profile, _written_options(target.replay_options))
    except (ValueError, _core.OptionError, _core.SessionError) as error:
        raise FaultInputError(str(error)) from None
    guided = target.coverage == "afl" or (target.coverage == "auto"
                                          and instrumented(target.argv))
    budget = runs if runs is not None else (None if seconds is not None else DEFAULT_RUNS)
    started = time.monotonic()
    stop = threading.Event()
    scratch = tempfile.mkdtemp(prefix="wiretape-fuzz-")
    runner = _Runner(recording, target, scratch, stop,
                     map_size(target.argv) if guided else None)
    coverage = Coverage()
    corpus: List[bytes] = [b""]
    done: List[Run] = []
    found: Dict[Tuple[str, str], Tuple[bytes, Run]] = {}
    lock = threading.Lock()
    next_index = [0]
    counted = {"duplicates": 0}

    def take_index() -> Optional[int]:
        with lock:
            while True:
                index = next_index[0]
                if budget is not None and index >= budget:
                    return None
                if seconds is not None and time.monotonic() - started >= seconds:
                    return None
                next_index[0] += 1
                if shard is None or shard.owns(index):
                    return index

    def worker() -> None:
        while not stop.is_set():
            index = take_index()
            if index is None:
                return
            if index < len(plans):
                plan = plans[index]
            elif guided:
                with lock:
                    plan = mutated_plan(seed, index, corpus, recording.units)
            else:
                plan = random_plan(seed, index, recording.units)
            run, trace = runner.run_traced(plan)
            kind = finding_kind(run, recording.inert(plan))
            sign = signature(kind, run) if kind else ""
            run.kind, run.where, run.case = "fuzz", plan.hex(), index
            with lock:
                done.append(run)
                # A plan that lit new edges (and broke nothing) is mutated further.
                if trace is not None and not kind and coverage.add(trace):
                    corpus.append(plan)
                if kind and (kind, sign) in found:
                    counted["duplicates"] += 1
                elif kind:
                    found[(kind, sign)] = (plan, run)
                    if progress:
                        progress(f"wiretape fuzz: run {index}: {kind} ({sign})")

    try:
        with _quiet_stderr(True) as real_stderr:
            if progress is None and real_stderr is not None:
                def progress(text: str, descriptor: int = real_stderr) -> None:
                    os.write(descriptor, (text + "\n").encode())
            clean, trace = runner.run_traced(b"")
            if clean.outcome != "ok":
                raise CleanRunFailed(clean)
            if trace is not None and not coverage.add(trace):
                raise FaultInputError(
                    f"--coverage afl: {target.argv[0]} wrote nothing into AFL++'s coverage map: "
                    "build it with afl-clang-fast (or afl-cc), or leave --coverage out")
            pool = ThreadPoolExecutor(max_workers=jobs)
            try:
                for future in [pool.submit(worker) for _ in range(jobs)]:
                    future.result()
            except BaseException:
                stop.set()  # before waiting for the workers: each ends its CMD now
                raise
            finally:
                pool.shutdown(wait=True)
            result = _keep_findings(runner, found, findings_dir, session)
            if guided:
                _write_corpus(os.path.join(findings_dir, CORPUS_DIR), corpus)
    except CoverageError as error:
        stop.set()
        raise FaultInputError(str(error)) from None
    except BaseException:
        stop.set()
        raise
    finally:
        runner.close()
        shutil.rmtree(scratch, ignore_errors=True)
    findings, flaky, duplicates = result
    return Search(findings, sorted(done, key=lambda run: run.case), flaky,
                  duplicates + counted["duplicates"],
                  time.monotonic() - started, "afl" if guided else "",
                  list(corpus) if guided else [], coverage.edges if guided else 0)


def _write_corpus(directory: str, corpus: Sequence[bytes]) -> None:
    """The corpus as plan files (hex, as --plan reads them), the recording
    unchanged first: plan-0.hex is empty."""
    os.makedirs(directory, exist_ok=True)
    for number, plan in enumerate(corpus):
        with open(os.path.join(directory, f"plan-{number}.hex"), "w") as file:
            file.write(plan.hex() + "\n")


def _keep_findings(runner: _Runner, found: Dict[Tuple[str, str], Tuple[bytes, Run]],
                   directory: str, session: str) -> Tuple[List[Finding], int, int]:
    """Each finding minimized, re-run (a flaky one dropped), deduplicated
    again (two plans minimized to one cause are one), written as a session
    with index.json listing them all."""
    kept: Dict[Tuple[str, str], Tuple[bytes, Run]] = {}
    flaky = duplicates = 0
    for (kind, sign), (plan, run) in found.items():
        small = runner.minimize(plan, kind, sign)
        again, again_kind, again_sign = runner.verdict(small)
        if again_kind != kind or again_sign != sign:
            flaky += 1
            continue
        if (kind, sign) in kept:
            duplicates += 1
            continue
        kept[(kind, sign)] = (small, again)
    os.makedirs(directory, exist_ok=True)
    findings = []
    target = runner.target
    for number, ((kind, sign), (plan, run)) in enumerate(sorted(kept.items()), start=1):
        name = f"{kind}-{number}.wtape"
        path = os.path.join(directory, name)
        changed = runner.recording.write(path, plan)
        repro = replay_reproduction(path, [], target.argv, target.replay_options,
                                    target.as_path, target.listen,
                                    target.timeout if kind == "hang" else None, target.speed)
        frames = stack(run)
        if not frames and kind == "crash" and run_signal(run) is not None:
            frames = runner.debugger_stack(plan)
        findings.append(Finding(kind, run_signal(run), sign, name, changed, repro, plan.hex(),
                                frames))
    write_index(directory, findings)
    return findings, flaky, duplicates


def replay_findings(directory: str, target: Target) -> List[Tuple[Finding, Run, bool]]:
    """Every finding of `directory` replayed to CMD: (finding, run, whether
    it still reproduces: the same kind of finding)."""
    from .findings import read_index

    check_command(target.argv, target.as_path, ())
    _check_timeout(target.timeout)
    results = []
    with _quiet_stderr(True):
        for finding in read_index(directory):
            path = os.path.join(directory, finding.session)
            run = run_case(path, None, target.argv, target.timeout, target.replay_options,
                           target.listen, target.as_path, None, target.speed)
            still = run.outcome in ("crash", "hang") or (finding.kind == "error"
                                                          and run.outcome == "error")
            results.append((finding, run, still))
    return results

