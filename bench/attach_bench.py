#!/usr/bin/env python3
"""What attaching costs (bench/run.py, group "attach"; docs/benchmarks.md,
"Attach"): prints one JSON line. Usage: attach_bench.py BUILD WORKDIR

- syscall_ns, syscall_attached_ns, syscall_strace_ns: a program's time per
  read/write system call (a byte through a pipe; build/bin/traced_program's
  bench mode times itself), untraced, while wiretape.attach records it (its
  writes, by --fd), and under strace -o /dev/null, the anchor: both stop the
  program twice per call, and on a loaded machine that is scheduling;
- attach_ms, detach_ms: wiretape.attach() until every thread is traced, and
  stop() until every thread is detached (median of ATTACHES);
- relay_p99_ms, relay_attached_p99_ms, relay_attached_vs_untraced_ratio:
  socat relaying RATE bytes/s between two ptys, each CHUNK stamped when
  written and when read at the far end: the 99th percentile of how late it
  arrived, untraced and while attached (the median of RELAY_ROUNDS runs of
  each, interleaved), and their ratio;
- relay_lost_runs: relay runs taken again because their chunks did not all
  arrive in order (socat lost bytes; seen when the machine is loaded);
- load_average: the machine's (1 min) at the end, which the relay figures
  depend on.
"""

import json
import os
import shutil
import statistics
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import wiretape

ROUNDS = 200_000
ROUNDS_TRACED = 20_000  # every call stops twice: ten times fewer, same figure
ATTACHES = 9
RATE = 1_000_000  # bytes/s
CHUNK = 1000  # one every ms
RELAY_S = 2.0
RELAY_ROUNDS = 3  # of each, interleaved: the median p99 of each
RELAY_TRIES = 3  # runs in which socat lost bytes are taken again


def traced_program(build: Path) -> Path:
    program = build / "bin" / "traced_program"
    if not program.exists():
        sys.exit(f"{program} not built (cmake --build {build} --target traced_program)")
    return program


def per_call_ns(build: Path, work: Path, attached: bool = False, strace: bool = False) -> float:
    rounds = ROUNDS_TRACED if attached or strace else ROUNDS
    command = [str(traced_program(build)), "bench", str(rounds)]
    if strace:
        command = ["strace", "-o", "/dev/null", *command]
    program = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        fd = int(program.stdout.readline().split()[1])
        attachment = (wiretape.attach(program.pid, str(work / "attach_calls.wtape"), fd=fd)
                      if attached else None)
        program.stdin.write("go\n")
        program.stdin.flush()
        ns = float(program.stdout.readline())
        if attachment is not None:
            attachment.stop()
        return ns
    finally:
        program.kill()
        program.wait()


def attach_detach_ms(build: Path, work: Path) -> tuple:
    program = subprocess.Popen([str(traced_program(build)), "bench", "1"],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    attach, detach = [], []
    try:
        fd = int(program.stdout.readline().split()[1])
        for n in range(ATTACHES):
            start = time.perf_counter()
            attachment = wiretape.attach(program.pid, str(work / f"attach_{n}.wtape"), fd=fd)
            traced = time.perf_counter()
            attachment.stop()
            attach.append((traced - start) * 1e3)
            detach.append((time.perf_counter() - traced) * 1e3)
    finally:
        program.kill()
        program.wait()
    return statistics.median(attach), statistics.median(detach)


def relay_p99_ms(work: Path, attached: bool) -> float:
    link_in, link_out = work / "relay_in", work / "relay_out"
    for link in (link_in, link_out):
        link.unlink(missing_ok=True)
    socat = subprocess.Popen(["socat", f"PTY,link={link_in},raw,echo=0",
                              f"PTY,link={link_out},raw,echo=0"], stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 10
    while not (link_in.exists() and link_out.exists()) and time.monotonic() < deadline:
        time.sleep(0.01)  # socat makes its ptys; no event to wait on
    attachment = None
    writer = reader = None
    try:
        writer = os.open(link_in, os.O_WRONLY | os.O_NOCTTY)
        reader = os.open(link_out, os.O_RDONLY | os.O_NOCTTY)
        if attached:
            held = sorted(int(fd) for fd in os.listdir(f"/proc/{socat.pid}/fd")
                          if os.readlink(f"/proc/{socat.pid}/fd/{fd}") == "/dev/ptmx")
            attachment = wiretape.attach(socat.pid, str(work / "attach_relay.wtape"),
                                         fd=held[0])
        sent = {}
        late = []
        lost = []
        count = int(RELAY_S * RATE / CHUNK)

        def read_all():
            buffered = b""
            got = 0
            while got < count:
                try:
                    data = os.read(reader, 65536)
                except OSError:
                    return  # socat killed: the run is over
                if not data:
                    return
                if lost:
                    continue  # drained, so that the writer is never blocked
                buffered += data
                now = time.perf_counter()
                while len(buffered) >= CHUNK:
                    (sequence,) = struct.unpack_from("<I", buffered)
                    if sequence != got:
                        lost.append(f"chunk {got} arrived as {sequence}")
                        break
                    late.append(now - sent[sequence])
                    buffered = buffered[CHUNK:]
                    got += 1

        thread = threading.Thread(target=read_all, daemon=True)
        thread.start()
        start = time.perf_counter()
        for sequence in range(count):
            # Paced at RATE by sleeping to each chunk's due time (late chunks
            # go at once): a busy pacer would hold the GIL from the reader
            # thread for Python's switch interval (5 ms) at a time, and take
            # a core of two from socat and the tracer.
            wait = start + sequence * CHUNK / RATE - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            sent[sequence] = time.perf_counter()
            os.write(writer, struct.pack("<I", sequence) + b"x" * (CHUNK - 4))
        if not lost:
            thread.join(30)
        if lost or len(late) < count:
            # Bytes lost by socat (seen on a loaded machine, the far reader
            # late by more than a pty's 4 KiB of buffer): that run says
            # nothing of the relay's lateness.
            return None
        late.sort()
        return late[int(len(late) * 0.99) - 1] * 1e3
    finally:
        if attachment is not None:
            attachment.stop()
        socat.kill()
        socat.wait()
        for fd in (writer, reader):
            if fd is not None:
                os.close(fd)


def main() -> None:
    build, work = Path(sys.argv[1]), Path(sys.argv[2])
    work.mkdir(parents=True, exist_ok=True)
    figures = {
        "syscall_ns": min(per_call_ns(build, work) for _ in range(3)),
        "syscall_attached_ns": min(per_call_ns(build, work, attached=True) for _ in range(3)),
    }
    if shutil.which("strace"):
        figures["syscall_strace_ns"] = min(per_call_ns(build, work, strace=True)
                                           for _ in range(3))
        figures["attached_vs_strace_ratio"] = (figures["syscall_attached_ns"] /
                                               figures["syscall_strace_ns"])
    figures["attach_ms"], figures["detach_ms"] = attach_detach_ms(build, work)
    # Interleaved, so that both see the same machine: on a shared one the
    # load changes from second to second, more than the attach does.
    untraced, attached = [], []
    figures["relay_lost_runs"] = 0
    for _ in range(RELAY_ROUNDS):
        for runs, traced in ((untraced, False), (attached, True)):
            for _ in range(RELAY_TRIES):
                p99 = relay_p99_ms(work, traced)
                if p99 is not None:
                    runs.append(p99)
                    break
                figures["relay_lost_runs"] += 1
    if not untraced or not attached:
        sys.exit("relay: socat lost bytes in every run (a reader late by more than a pty's buffer)")
    figures["relay_p99_ms"] = statistics.median(untraced)
    figures["relay_attached_p99_ms"] = statistics.median(attached)
    figures["relay_attached_vs_untraced_ratio"] = (figures["relay_attached_p99_ms"] /
                                                   figures["relay_p99_ms"])
    figures["load_average"] = os.getloadavg()[0]
    print(json.dumps({key: round(value, 3) for key, value in figures.items()}))


if __name__ == "__main__":
    main()
