"""Running a campaign: a faulty virtual device per case, CMD run against
it with ``Child``, its outcome sorted, and a reproduction line for each
crash and hang."""

from __future__ import annotations

import contextlib
import math
import os
import re
import shlex
import signal
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, Iterator, List, Optional, Sequence, TextIO

from .. import _core, bridge, scaled_clock
from ..children import Child, sanitizer_report
from ..redirect import RedirectedCommand, recorded_identity
from .cases import (OUTCOMES, FaultCase, FaultInputError, Shard, _with_channel, all_cases,
                    session_channels)
from .report import Campaign, Run, session_digest

#: The longest --timeout a campaign takes (seconds, about 11.6 days): a
#: bound that no run needs, and that every clock and poll can count to.
MAX_TIMEOUT_S = 1e6
PORT_PLACEHOLDER = "{port}"
#: ``{port:NAME}``: the device of channel NAME of a session of several ports.
_CHANNEL_PLACEHOLDER = re.compile(r"\{port:([^{}]*)\}")


class _Stopped(Exception):
    """A run ended early because the campaign was interrupted."""


@contextlib.contextmanager
def faulty_device(session: str, case: Optional[FaultCase] = None, replay_options: str = "",
                  listen: bool = False, speed: float = 1.0) -> Iterator[str]:
    """A virtual device replaying ``session`` with ``case``'s fault: yields
    the path of a pty (a symbolic link in a private directory), or with
    ``listen`` a ``HOST:PORT``. Stopped on leaving. ``speed`` K: the
    replay's timing K times faster (the replay key ``speed``), for a
    client whose clock runs at K (wiretape.scaled_clock)."""
    pairs = _core.parse_options(replay_options) + (case.option_pairs if case else [])
    # Without a clock or an injected wait to scale, the speed is CMD's alone.
    if speed != 1.0 and _core.replay_speed_applies(_core.option_string(pairs)):
        pairs.append(("speed", speed))
    keys = _core.option_string(pairs)
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
    return replay_reproduction(session, ["--fault", case.spec, "--seed", str(case.seed)], argv,
                               replay_options, as_path, listen, timeout, speed)


def replay_reproduction(session: str, replay_arguments: Sequence[str], argv: Sequence[str],
                        replay_options: str, as_path: Optional[str], listen: bool = False,
                        timeout: Optional[float] = None, speed: float = 1.0) -> str:
    """reproduction() of a replay of `session` with `replay_arguments`
    (a fault and its seed; none for a session that is the finding itself,
    as `wiretape fuzz` writes them)."""
    channels = session_channels(session)
    replay = ["wiretape", "replay", session] + list(replay_arguments)
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
        _core.check_replay_options(_core.option_string(
            [("type", "replay"), ("file", "x")] + _core.parse_options(replay_options)))
        if speed != 1.0 and "speed" in dict(_core.parse_options(replay_options)):
            raise FaultInputError("--options holds speed= and --speed is given: give --speed "
                                  "only (it sets the replay's speed and CMD's clock)")
    everything = all_cases(session, kinds, budget, seed, None, None, replay_options)
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


