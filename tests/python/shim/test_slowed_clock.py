"""A slowed clock never turns waits into busy loops (issue 37): under
``--speed 1e-06`` two drivers spun at 92 % CPU. CMD's code runs as fast as
ever against a clock a million times slower, so a wait of zero that finds
nothing (a timeout a driver rounded down to 0 ms while less than 1 ms was
left, a zero sleep until a deadline) returned at once a million times more
often than at K = 1. The shim now makes such a wait last 1 us of CMD's
clock, at most 1 ms of real time (src/shim/scaled_clock.c,
docs/replay.md "Faster than real time").

Each CMD below waits in a loop towards a deadline half a millisecond away on
its clock (500 s of real time at K = 1e-6), for a few real seconds, and
says how many waits it made, the CPU time it used and the real time that
passed (read where the scaled clock cannot reach: /proc/uptime, the raw
system call)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape
from wiretape import scaled_clock

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the scaled-clock shim is Linux only")

SLOWED = 1e-06
REAL_S = 2.0
DEADLINE_S = 120.0
DEVICE = "/dev/ttyWTSLOWED"

PYTHON_LOOP = textwrap.dedent("""
    import os, select, sys, time
    def real_now():
        with open("/proc/uptime") as uptime:
            return float(uptime.read().split()[0])
    reader, writer = os.pipe()
    poller = select.poll()
    poller.register(reader, select.POLLIN)
    epoll = select.epoll()
    epoll.register(reader, select.EPOLLIN)
    deadline = time.monotonic() + 0.5e-3
    started, cpu, waits = real_now(), time.process_time(), 0
    while real_now() - started < float(sys.argv[1]):
        left_ms = int((deadline - time.monotonic()) * 1000)  # truncated, as drivers do
        poller.poll(left_ms)
        epoll.poll(left_ms / 1000)
        select.select([reader], [], [], left_ms / 1000)
        time.sleep(left_ms / 1000)
        waits += 4
    print("waits", waits, time.process_time() - cpu, real_now() - started, flush=True)
""")

C_LOOP = textwrap.dedent(r"""
    #define _GNU_SOURCE
    #include <poll.h>
    #include <pthread.h>
    #include <stdio.h>
    #include <stdlib.h>
    #include <sys/epoll.h>
    #include <sys/select.h>
    #include <sys/syscall.h>
    #include <time.h>
    #include <unistd.h>
    static double seconds(const struct timespec *ts) { return ts->tv_sec + ts->tv_nsec / 1e9; }
    static double real_now(void) {  /* the system call itself: no shim between */
      struct timespec ts; syscall(SYS_clock_gettime, CLOCK_MONOTONIC, &ts); return seconds(&ts);
    }
    static double cpu_now(void) {
      struct timespec ts; clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts); return seconds(&ts);
    }
    static long long ns_now(void) {
      struct timespec ts; clock_gettime(CLOCK_MONOTONIC, &ts);
      return ts.tv_sec * 1000000000LL + ts.tv_nsec;
    }
    int main(int argc, char **argv) {
      int pipe_fds[2]; if (pipe(pipe_fds) != 0) return 2;
      int epoll = epoll_create1(0);
      struct epoll_event event = {EPOLLIN, {0}}; epoll_ctl(epoll, EPOLL_CTL_ADD, pipe_fds[0], &event);
      pthread_mutex_t mutex = PTHREAD_MUTEX_INITIALIZER; pthread_cond_t cond = PTHREAD_COND_INITIALIZER;
      long long deadline = ns_now() + 500000;
      double started = real_now(), cpu = cpu_now();
      long waits = 0;
      while (real_now() - started < atof(argv[1])) {
        int left_ms = (int)((deadline - ns_now()) / 1000000);  /* truncated: 0 */
        struct pollfd fd = {pipe_fds[0], POLLIN, 0};
        poll(&fd, 1, left_ms);
        epoll_wait(epoll, &event, 1, left_ms);
        fd_set readable; FD_ZERO(&readable); FD_SET(pipe_fds[0], &readable);
        struct timeval none = {0, left_ms * 1000};
        select(pipe_fds[0] + 1, &readable, NULL, NULL, &none);
        usleep(left_ms * 1000);
        struct timespec now; clock_gettime(CLOCK_REALTIME, &now);
        pthread_mutex_lock(&mutex); pthread_cond_timedwait(&cond, &mutex, &now);
        pthread_mutex_unlock(&mutex);
        waits += 5;
      }
      printf("waits %ld %f %f\n", waits, cpu_now() - cpu, real_now() - started);
      return 0;
    }
""")


def assert_waits_waited(output: str) -> None:
    """Every zero wait lasted its nap (1 ms of real time at K = 1e-6): at
    most one per millisecond that passed; and the loop used a fraction of
    the real time in CPU (spinning, all of it; a loaded machine's share of a
    core for a spinner is still far above this bound's waits)."""
    line = [line for line in output.splitlines() if line.startswith("waits ")]
    assert line, output
    _, waits, cpu_s, real_s = line[0].split()
    waits, cpu_s, real_s = int(waits), float(cpu_s), float(real_s)
    assert real_s >= REAL_S * 0.99, line
    # /proc/uptime counts in hundredths: a hundredth more at most.
    assert waits <= (real_s + 0.01) * 1000 + 5, f"{waits} waits in {real_s} s: a busy loop"
    assert cpu_s < real_s / 4, f"{cpu_s} s of CPU in {real_s} s: a busy loop"


def test_a_python_driver_waiting_towards_a_deadline_waits(tmp_path):
    script = tmp_path / "loop.py"
    script.write_text(PYTHON_LOOP)
    done = subprocess.run([sys.executable, str(script), str(REAL_S)], capture_output=True,
                          text=True, timeout=DEADLINE_S,
                          env=scaled_clock.environment(SLOWED))
    assert done.returncode == 0, done.stderr
    assert_waits_waited(done.stdout)


def test_a_c_driver_waiting_towards_a_deadline_waits(tmp_path):
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("SKIPPED LOUDLY: no C compiler (cc) to build the waiting program")
    source, program = tmp_path / "loop.c", tmp_path / "loop"
    source.write_text(C_LOOP)
    subprocess.run([compiler, "-O1", "-pthread", "-o", str(program), str(source)], check=True)
    done = subprocess.run([str(program), str(REAL_S)], capture_output=True, text=True,
                          timeout=DEADLINE_S, env=scaled_clock.environment(SLOWED))
    assert done.returncode == 0, done.stderr
    assert_waits_waited(done.stdout)


def test_cmd_of_a_replay_at_speed_1e06_waits(tmp_path):
    """The same Python driver as CMD of ``wiretape replay --speed 1e-06``;
    its own line is relayed whatever the replay's verdict."""
    session = tmp_path / "s.wtape"
    with wiretape.SessionWriter(str(session), port_type="serial",
                                port_options=f"type=serial,device={DEVICE}") as writer:
        writer.write("tx", 1_000_000, b"Q\n")
    script = tmp_path / "loop.py"
    script.write_text(PYTHON_LOOP)
    done = subprocess.run([sys.executable, "-m", "wiretape.cli", "replay", str(session),
                           "--as", DEVICE, "--speed", str(SLOWED), "--",
                           sys.executable, str(script), str(REAL_S)],
                          capture_output=True, text=True, timeout=DEADLINE_S)
    assert "waits " in done.stdout, done.stderr
    assert_waits_waited(done.stdout)


def test_a_slowed_zero_wait_still_returns_as_soon_as_a_descriptor_is_ready(tmp_path):
    """The nap is a wait on what the caller waits for, not a blind sleep:
    a zero poll of a ready descriptor returns it, at once."""
    script = tmp_path / "ready.py"
    script.write_text(textwrap.dedent("""
        import os, select
        reader, writer = os.pipe()
        os.write(writer, b"x")
        poller = select.poll()
        poller.register(reader, select.POLLIN)
        print(len(poller.poll(0)), select.select([reader], [], [], 0)[0] == [reader])
    """))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=DEADLINE_S, env=scaled_clock.environment(SLOWED))
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["1", "True"]
