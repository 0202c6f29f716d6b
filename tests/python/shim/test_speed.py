"""--speed K (DESIGN §22, docs/replay.md "Faster than real time"): CMD of
``replay ... -- CMD`` and of ``faults`` runs on a clock K times faster
(the preload shim _scaled_clock.so, wiretape.scaled_clock), and the
replay's timing with it.

Real time is read where the scaled clock cannot reach it: in this test
process (not preloaded), or in CMD from /proc/uptime (a file, not a clock
call)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape
from wiretape import faults, scaled_clock

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the scaled-clock shim is Linux only")

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
DEADLINE = 120.0
K = 10.0
DEVICE = "/dev/ttyWTSPEED"
EXCHANGES = 8


def run_cli(*args, env=None):
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True,
                          timeout=DEADLINE, env=env)


def make_session(path: Path) -> Path:
    """EXCHANGES line exchanges Qn\\n -> Rn\\n, recorded on DEVICE."""
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options=f"type=serial,device={DEVICE}") as writer:
        for n in range(EXCHANGES):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}\n".encode())
    return path


# A pyserial driver with argv[3] s read timeouts: it asks every question even when
# the device stops answering, so a silent device costs it EXCHANGES s. It
# prints the real seconds it ran (from /proc/uptime, which no clock call
# reads) and exits 3 when an answer was missing.
PYSERIAL_DRIVER = textwrap.dedent("""
    import sys, serial
    def real_now():
        with open("/proc/uptime") as uptime:
            return float(uptime.read().split()[0])
    started = real_now()
    port = serial.Serial(sys.argv[1], 9600, timeout=float(sys.argv[3]))
    answered = 0
    for n in range(int(sys.argv[2])):
        port.write(f"Q{n}\\n".encode())
        if port.readline() == f"R{n}\\n".encode():
            answered += 1
    print("answered", answered)
    print("real", real_now() - started)
    sys.exit(0 if answered == int(sys.argv[2]) else 3)
""")


@pytest.fixture()
def session(tmp_path: Path) -> Path:
    return make_session(tmp_path / "lines.wtape")


@pytest.fixture()
def pyserial_driver(tmp_path: Path) -> Path:
    pytest.importorskip("serial", reason="SKIPPED LOUDLY: pyserial is not installed")
    script = tmp_path / "driver.py"
    script.write_text(PYSERIAL_DRIVER)
    return script


def real_seconds_of(stdout: str) -> float:
    return float(next(line.split()[1] for line in stdout.splitlines()
                      if line.startswith("real ")))


def replay_driver(session: Path, driver: Path, speed: float, *extra: str, read_timeout=1.0):
    return run_cli("replay", str(session), "--speed", repr(speed), *extra, "--as", DEVICE,
                   "--", sys.executable, str(driver), DEVICE, str(EXCHANGES), str(read_timeout))


# --- a driver's timeouts ---------------------------------------------------------------


def test_a_driver_waiting_out_1s_timeouts_under_silence_finishes_5x_sooner_at_speed_10(
        session, pyserial_driver):
    slow = replay_driver(session, pyserial_driver, 1.0, "--fault", "silence@exchange:0")
    fast = replay_driver(session, pyserial_driver, K, "--fault", "silence@exchange:0")
    assert slow.returncode == 3, slow.stderr
    assert fast.returncode == slow.returncode, fast.stderr
    assert "answered 0" in slow.stdout and "answered 0" in fast.stdout
    slow_s, fast_s = real_seconds_of(slow.stdout), real_seconds_of(fast.stdout)
    # EXCHANGES s of timeouts at K=1; the driver's own run at K=10 is
    # ~EXCHANGES/10 s: 5x holds with room for a loaded machine.
    assert slow_s >= EXCHANGES * 0.95, slow.stdout
    assert slow_s / fast_s >= 5.0, (slow_s, fast_s)


def test_timing_session_replay_gives_the_same_answers_at_speed_10(session, pyserial_driver):
    # 3 s timeouts: 0.3 s of real slack at K=10 for a loaded machine.
    results = [replay_driver(session, pyserial_driver, speed, "--timing", "session",
                             read_timeout=3.0) for speed in (1.0, K)]
    for result in results:
        assert result.returncode == 0, result.stderr
        assert f"answered {EXCHANGES}" in result.stdout


# --- the clock calls, sleeps and waits of CMD ----------------------------------------

# Each wait is for WAIT_S on CMD's clock; CMD checks on its clock that it
# waited that long, and prints a line when done: this process times the
# lines on the real clock.
WAIT_S = 2.0

PYTHON_WAITS = textwrap.dedent("""
    import os, queue, select, selectors, sys, threading, time
    WAIT = float(sys.argv[1])
    def done(name, started):
        waited = time.monotonic() - started
        assert waited >= WAIT * 0.99, (name, waited)
        print(name, waited, flush=True)
    reader, writer = os.pipe()
    started = time.monotonic(); wall = time.time(); time.sleep(WAIT); done("time.sleep", started)
    assert time.time() - wall >= WAIT * 0.99
    started = time.monotonic(); threading.Event().wait(WAIT); done("Event.wait", started)
    lock = threading.Lock(); lock.acquire()
    started = time.monotonic(); assert not lock.acquire(timeout=WAIT); done("Lock.acquire", started)
    started = time.monotonic()
    try:
        queue.Queue().get(timeout=WAIT)
    except queue.Empty:
        pass
    done("queue.get", started)
    started = time.monotonic(); select.select([reader], [], [], WAIT); done("select", started)
    selector = selectors.DefaultSelector(); selector.register(reader, selectors.EVENT_READ)
    started = time.monotonic(); selector.select(WAIT); done("selectors", started)
    started = time.monotonic()
    child = float(__import__("subprocess").check_output(
        [sys.executable, "-c", "import time; print(time.monotonic())"]))
    after = time.monotonic()
    assert started <= child <= after, (started, child, after)
    print("child clock", child, flush=True)
""")

C_WAITS = textwrap.dedent(r"""
    #define _GNU_SOURCE
    #include <pthread.h>
    #include <semaphore.h>
    #include <stdio.h>
    #include <stdlib.h>
    #include <time.h>
    static double now(clockid_t clock) {
      struct timespec ts; clock_gettime(clock, &ts); return ts.tv_sec + ts.tv_nsec / 1e9;
    }
    static struct timespec in(clockid_t clock, double seconds) {
      double at = now(clock) + seconds;
      struct timespec ts = {(time_t)at, (long)((at - (time_t)at) * 1e9)}; return ts;
    }
    static void done(const char *name, double started, double wait) {
      double waited = now(CLOCK_MONOTONIC) - started;
      if (waited < wait * 0.99) { printf("%s too short %f\n", name, waited); exit(1); }
      printf("%s %f\n", name, waited); fflush(stdout);
    }
    int main(int argc, char **argv) {
      double wait = atof(argv[1]);
      sem_t sem; sem_init(&sem, 0, 0);
      double started = now(CLOCK_MONOTONIC);
      struct timespec deadline = in(CLOCK_REALTIME, wait);
      sem_timedwait(&sem, &deadline); done("sem_timedwait", started, wait);
      started = now(CLOCK_MONOTONIC);
      struct timespec span = {(time_t)wait, (long)((wait - (time_t)wait) * 1e9)};
      nanosleep(&span, NULL); done("nanosleep", started, wait);
      started = now(CLOCK_MONOTONIC); deadline = in(CLOCK_MONOTONIC, wait);
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, NULL);
      done("clock_nanosleep", started, wait);
      pthread_mutex_t mutex = PTHREAD_MUTEX_INITIALIZER; pthread_cond_t cond = PTHREAD_COND_INITIALIZER;
      pthread_mutex_lock(&mutex);
      started = now(CLOCK_MONOTONIC); deadline = in(CLOCK_REALTIME, wait);
      while (pthread_cond_timedwait(&cond, &mutex, &deadline) == 0) {}
      done("pthread_cond_timedwait", started, wait);
      pthread_condattr_t attributes; pthread_condattr_init(&attributes);
      pthread_condattr_setclock(&attributes, CLOCK_MONOTONIC);
      pthread_cond_t monotonic; pthread_cond_init(&monotonic, &attributes);
      started = now(CLOCK_MONOTONIC); deadline = in(CLOCK_MONOTONIC, wait);
      while (pthread_cond_timedwait(&monotonic, &mutex, &deadline) == 0) {}
      done("pthread_cond_timedwait(monotonic)", started, wait);
      return 0;
    }
""")


def timed_lines(argv, env):
    """Runs argv; returns (its lines, real seconds between consecutive lines,
    the first counted from the start)."""
    import time

    started = time.monotonic()
    child = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=env)
    lines, spans, last = [], [], started
    try:
        for line in child.stdout:
            now = time.monotonic()
            lines.append(line.strip())
            spans.append(now - last)
            last = now
        assert child.wait(DEADLINE) == 0, child.stderr.read()
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    return lines, spans


def assert_scaled(lines, spans, names):
    assert [line.split()[0] for line in lines[:len(names)]] == names, lines
    # Each wait is WAIT_S/K = 0.2 s of real time: well under half of WAIT_S
    # even on a loaded machine (unscaled, each would take WAIT_S).
    for line, span in zip(lines[1:len(names)], spans[1:len(names)]):
        assert span < WAIT_S / 2, (line, span)
    assert sum(spans[1:len(names)]) < (len(names) - 1) * WAIT_S / 3, spans


def test_python_clocks_sleeps_and_timed_waits_run_k_times_faster(tmp_path):
    script = tmp_path / "waits.py"
    script.write_text(PYTHON_WAITS)
    names = ["time.sleep", "Event.wait", "Lock.acquire", "queue.get", "select", "selectors"]
    lines, spans = timed_lines([sys.executable, str(script), str(WAIT_S)],
                               scaled_clock.environment(K))
    assert_scaled(lines, spans, names)
    # A child's monotonic clock goes on from its parent's (one anchor).
    assert lines[-1].startswith("child clock"), lines


def test_c_sleeps_and_futex_deadlines_run_k_times_faster(tmp_path):
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("SKIPPED LOUDLY: no C compiler (cc) to build the waiting program")
    source, program = tmp_path / "waits.c", tmp_path / "waits"
    source.write_text(C_WAITS)
    subprocess.run([compiler, "-O1", "-pthread", "-o", str(program), str(source)], check=True)
    names = ["sem_timedwait", "nanosleep", "clock_nanosleep", "pthread_cond_timedwait",
             "pthread_cond_timedwait(monotonic)"]
    # The first wait is timed from the start: the program's start counts.
    lines, spans = timed_lines([str(program), str(WAIT_S)], scaled_clock.environment(K))
    assert_scaled(lines, spans, names)
    assert spans[0] < WAIT_S / 2, spans


def test_speed_1_loads_nothing():
    env = dict(os.environ, LD_PRELOAD="")
    assert scaled_clock.environment(1.0, env) == env


def test_the_shim_goes_before_a_preload_already_there():
    env = scaled_clock.environment(K, {"LD_PRELOAD": "/lib/other.so"})
    assert env["LD_PRELOAD"] == scaled_clock.shim_path() + " /lib/other.so"
    assert env[scaled_clock.ENV_SPEED] == "10.0"
    # A command started by a scaled one keeps the anchor it was given.
    assert scaled_clock.environment(K, env)[scaled_clock.ENV_ANCHOR] == env[scaled_clock.ENV_ANCHOR]


# --- campaigns -------------------------------------------------------------------------

# The driver of tests/python/cli/test_faults_campaign.py, reduced: waits
# of argv[3] s on select, a clean error (3) on a missing or wrong answer.
CAMPAIGN_DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    for n in range(int(sys.argv[2])):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            if not select.select([fd], [], [], float(sys.argv[3]))[0]:
                sys.exit(3)
            try:
                chunk = os.read(fd, 1)
            except OSError:
                sys.exit(3)
            if not chunk:
                sys.exit(3)
            line += chunk
        if line != f"R{n}\\n".encode():
            sys.exit(3)
""")


def campaign_driver(tmp_path: Path, wait_s: float) -> list:
    script = tmp_path / "campaign_driver.py"
    script.write_text(CAMPAIGN_DRIVER)
    return [sys.executable, str(script), "{port}", str(EXCHANGES), str(wait_s)]


def campaign(session, tmp_path, name, kinds, budget, timeout, wait_s, *extra):
    out = tmp_path / f"{name}.json"
    result = run_cli("faults", str(session), "--kinds", kinds, "--budget", str(budget),
                     "--timeout", str(timeout), "--json", str(out), *extra, "--",
                     *campaign_driver(tmp_path, wait_s))
    assert out.exists(), result.stderr
    return result, json.loads(out.read_text())


def test_a_campaign_at_speed_10_has_the_outcomes_of_speed_1(session, tmp_path):
    # The driver's 2 s timeouts end the faulty runs (an error) at K=1 in
    # 2 s, at K=10 in 0.2 s (real slack enough for the clean run on a
    # loaded machine); the same outcomes.
    arguments = ("silence,drop", 4, 10, 2.0)
    slow, slow_json = campaign(session, tmp_path, "slow", *arguments)
    fast, fast_json = campaign(session, tmp_path, "fast", *arguments, "--speed", "10")
    assert slow.returncode == fast.returncode == 0, (slow.stderr, fast.stderr)
    outcomes = lambda doc: [(run["kind"], run["where"], run["outcome"], run["exit"])
                            for run in doc["runs"]]
    assert outcomes(fast_json) == outcomes(slow_json)
    assert "error" in {run["outcome"] for run in slow_json["runs"]}
    assert slow_json["speed"] == 1.0 and fast_json["speed"] == 10.0
    slow_errors = [run["seconds"] for run in slow_json["runs"] if run["outcome"] == "error"]
    fast_errors = [run["seconds"] for run in fast_json["runs"] if run["outcome"] == "error"]
    assert min(slow_errors) >= 2.0
    assert sum(fast_errors) < sum(slow_errors) / 2


def test_a_campaigns_timeout_is_on_the_commands_clock(session, tmp_path):
    # --timeout 20 on CMD's clock is 2 s of real time at K=10: a driver
    # waiting 100 s for an answer that a silence withholds is a hang then,
    # and the reproduction line runs it as the campaign did.
    result, document = campaign(session, tmp_path, "hang", "silence", 1, 20, 100,
                                "--speed", "10")
    assert result.returncode == 1, result.stderr
    [hang] = document["runs"]
    assert hang["outcome"] == "hang"
    assert 2.0 <= hang["seconds"] < 20.0
    assert "--speed 10" in hang["repro"] and "timeout -k 5 2 " in hang["repro"]
    assert scaled_clock.ENV_SPEED + "=10.0" in hang["repro"]


def test_merge_refuses_shards_of_different_speeds(session, tmp_path):
    arguments = ("silence", 2, 10, 2.0)
    one, _ = campaign(session, tmp_path, "one", *arguments, "--shard", "1/2")
    two, _ = campaign(session, tmp_path, "two", *arguments, "--shard", "2/2", "--speed", "10")
    assert one.returncode == two.returncode == 0, (one.stderr, two.stderr)
    merged = run_cli("faults", "merge", str(tmp_path / "one.json"), str(tmp_path / "two.json"))
    assert merged.returncode == 2
    assert "--speed" in merged.stderr and "two.json" in merged.stderr


# --- bad input -------------------------------------------------------------------------


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "ten"])
@pytest.mark.parametrize("command", ["replay", "faults"])
def test_a_bad_speed_is_a_usage_error_naming_the_flag(session, value, command):
    result = run_cli(command, str(session), f"--speed={value}", "--", "true", "{port}")
    assert result.returncode == 2, result.stderr
    assert "--speed" in result.stderr and value in result.stderr


def test_the_python_campaign_refuses_a_bad_speed(session):
    with pytest.raises(faults.FaultInputError, match="--speed"):
        faults.campaign(str(session), ["true", "{port}"], speed=float("nan"))


def test_speed_in_options_and_the_flag_is_refused(session):
    result = run_cli("faults", str(session), "--speed", "10", "--options", "speed=2", "--",
                     "true", "{port}")
    assert result.returncode == 2
    assert "--speed" in result.stderr
