"""``wiretape record --attach PID`` (DESIGN §26) on real programs attached in
the middle of their work: a pyserial script on a pty talking to a simulator,
and gpsd reading NMEA from a pty. The recording holds exactly the bytes that
crossed while attached (a tee of the traffic: the simulator's own log), and
replays to a fresh instance of the program. Then the unharmed cases of the
command line (SIGTERM, --duration, kill -9) and its refusals (exit 2,
nothing written)."""

import json
import os
import pathlib
import pty
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import tty

import pytest

import wiretape
from wiretape import bridge

from devices import DEADLINE_S, interrupt, start_cli, wait_until

pytestmark = [
    pytest.mark.skipif(not sys.platform.startswith("linux") or os.uname().machine != "x86_64",
                       reason="attaching is Linux x86_64 only"),
]

REPO = pathlib.Path(__file__).resolve().parents[3]
TRACED_PROGRAM = REPO / "build" / "bin" / "traced_program"

# A pyserial client: one request per line on its stdin, each answer printed;
# its requests are numbered from its second argument (1).
CLIENT = """
import sys, serial
port = serial.Serial(sys.argv[1], 115200, timeout=10)
print("ready", flush=True)
for n, _ in enumerate(sys.stdin, int(sys.argv[2]) if len(sys.argv) > 2 else 1):
    port.write(b"REQ %d\\n" % n)
    print(port.readline().decode().strip(), flush=True)
"""


class Simulator:
    """The device side of a pty: answers each "REQ n" line with "RSP n"
    and keeps its own log of both directions (the tee)."""

    def __init__(self):
        # The terminal side stays open here: without it the master reads EIO
        # until the client opens it.
        self.master, self.slave = pty.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.received = bytearray()
        self.sent = bytearray()
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        pending = b""
        while True:
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            if not data:
                return
            pending += data
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                answer = b"RSP" + line[3:] + b"\n"
                with self.lock:
                    self.received += line + b"\n"
                    self.sent += answer
                os.write(self.master, answer)

    def mark(self):
        with self.lock:
            return len(self.received), len(self.sent)


def directions(path):
    rx = tx = b""
    for record in wiretape.SessionReader(str(path)):
        if record.kind == "rx":
            rx += record.data
        elif record.kind == "tx":
            tx += record.data
    return rx, tx


def start_client(tmp_path, device, first=1):
    script = tmp_path / "client.py"
    script.write_text(CLIENT)
    client = subprocess.Popen([sys.executable, str(script), device, str(first)],
                              stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    assert client.stdout.readline().strip() == "ready"
    return client


def ask(client, n):
    client.stdin.write("go\n")
    client.stdin.flush()
    assert client.stdout.readline().strip() == f"RSP {n}"


def attach(*argv):
    """`wiretape record --attach ...` once it says it is attached."""
    child = start_cli("record", "--attach", *argv)
    line = child.stderr.readline()
    if "attached to process" not in line:
        child.kill()
        raise AssertionError(line + child.stderr.read())
    return child


def test_a_pyserial_client_attached_mid_work_records_the_tee_and_replays(tmp_path):
    simulator = Simulator()
    client = start_client(tmp_path, simulator.path)
    output = tmp_path / "client.wtape"
    try:
        ask(client, 1)
        ask(client, 2)
        received_before, sent_before = simulator.mark()
        recorder = attach(str(client.pid), "--path", simulator.path, "-o", str(output))
        for n in (3, 4, 5):
            ask(client, n)
        received_during, sent_during = simulator.mark()
        status, _, err = interrupt(recorder)
        assert status == 0, err
        ask(client, 6)  # unharmed: it goes on untraced
        assert "detached" in err
    finally:
        client.stdin.close()
        assert client.wait(DEADLINE_S) == 0
    rx, tx = directions(output)
    assert tx == bytes(simulator.received[received_before:received_during])
    assert rx == bytes(simulator.sent[sent_before:sent_during])
    header = wiretape.SessionReader(str(output)).header
    assert header.capture == "client"
    assert header.attached["pid"] == client.pid
    assert header.attached["device"] == simulator.path

    # A fresh instance of the client against the recording.
    link = str(tmp_path / "ttyReplay")
    handle = bridge.serve_replay(str(output), pty=link, replay_options="match=request",
                                 quiet=True)
    try:
        # It does what the recorded one did while attached: requests 3 to 5.
        fresh = start_client(tmp_path, link, first=3)
        for n in (3, 4, 5):
            fresh.stdin.write("go\n")
            fresh.stdin.flush()
            assert fresh.stdout.readline().strip() == f"RSP {n}"
        fresh.stdin.close()
        assert fresh.wait(DEADLINE_S) == 0
    finally:
        handle.stop()
        handle.wait()
    assert handle.result().ok, handle.result().message


@pytest.fixture
def traced_program():
    if not TRACED_PROGRAM.exists():
        pytest.skip("SKIPPED LOUDLY: build/bin/traced_program is not built (make)")
    master, slave = pty.openpty()
    path = os.ttyname(slave)
    program = subprocess.Popen([str(TRACED_PROGRAM), "tty", path], stdout=subprocess.PIPE,
                               stdin=subprocess.DEVNULL)
    assert program.stdout.readline() == b"ready\n"
    yield program, master, path
    program.kill()
    program.wait()
    os.close(master)
    os.close(slave)


def exchange(master, request):
    os.write(master, request)
    answer = b""
    deadline = time.monotonic() + DEADLINE_S
    while len(answer) < len(request) + 3 and time.monotonic() < deadline:
        answer += os.read(master, 100)
    return answer


def status_of(pid, member):
    for line in pathlib.Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(member + ":"):
            return line.split(":", 1)[1].strip()
    return ""


def assert_unharmed(program):
    assert program.poll() is None
    assert status_of(program.pid, "TracerPid") == "0"
    assert not status_of(program.pid, "State").startswith("t")


def test_sigterm_and_duration_end_the_recording_and_the_program_goes_on(traced_program,
                                                                          tmp_path):
    program, master, path = traced_program
    recorder = attach(str(program.pid), "-o", str(tmp_path / "term.wtape"))
    assert exchange(master, b"one\n") == b"ok:one\n"
    recorder.send_signal(signal.SIGTERM)
    assert recorder.wait(DEADLINE_S) == 0
    assert exchange(master, b"two\n") == b"ok:two\n"
    assert_unharmed(program)
    timed = attach(str(program.pid), "--fd", "3", "--duration", "0.5",
                   "-o", str(tmp_path / "timed.wtape"))
    assert exchange(master, b"three\n") == b"ok:three\n"
    assert timed.wait(DEADLINE_S) == 0  # ends by itself
    assert exchange(master, b"four\n") == b"ok:four\n"
    assert_unharmed(program)
    assert directions(tmp_path / "term.wtape") == (b"one\n", b"ok:one\n")
    assert directions(tmp_path / "timed.wtape") == (b"three\n", b"ok:three\n")
    shown = subprocess.run([sys.executable, "-m", "wiretape.cli", "show",
                            str(tmp_path / "term.wtape")], capture_output=True, text=True)
    assert f"attached     to process {program.pid} (traced_program)" in shown.stdout


FLUSH_MS = 100  # a recording's default flush_ms
# What the issue allows a crash to lose beyond flush_ms: the flusher may run late.
CRASH_SLACK_MS = 50


def test_kill_9_of_wiretape_loses_at_most_flush_ms_and_the_program_runs_on(traced_program,
                                                                          tmp_path):
    program, master, path = traced_program
    output = tmp_path / "killed.wtape"
    recorder = attach(str(program.pid), "-o", str(output))
    # A stream of requests, each stamped with its send time (CLOCK_MONOTONIC,
    # one clock for every process), each written once the last was answered,
    # until the kill.
    sent = []  # (stamp_ns, request)
    failures = []
    stop = threading.Event()

    def stream():
        while not stop.is_set():
            stamp = time.monotonic_ns()
            request = b"t%d\n" % stamp
            sent.append((stamp, request))
            if exchange(master, request) != b"ok:" + request:
                failures.append(request)
                return

    streamer = threading.Thread(target=stream, daemon=True)
    streamer.start()
    wait_until(lambda: failures or directions(output)[0], what="the first records flushed")
    # The stream runs several flush intervals before the kill (its length,
    # not a synchronisation: any moment of it would do).
    streamed_from = time.monotonic_ns()
    wait_until(lambda: failures or time.monotonic_ns() - streamed_from > 5 * FLUSH_MS * 1_000_000,
               what="half a second of stream while attached")
    killed_ns = time.monotonic_ns()
    recorder.kill()
    recorder.wait()
    stop.set()
    streamer.join(DEADLINE_S)
    assert not failures, f"the program's answer to {failures[0]!r} was wrong"
    assert exchange(master, b"free\n") == b"ok:free\n"
    assert_unharmed(program)

    reader = wiretape.SessionReader(str(output))
    rx = b"".join(bytes(record.data) for record in reader if record.kind == "rx")
    damage = reader.damage
    assert damage is None or "truncated" in str(damage), damage  # only a record cut by the kill
    everything = b"".join(request for _, request in sent)
    assert everything.startswith(rx), "the recorded reads are not what the program was sent"
    bound_ns = (FLUSH_MS + CRASH_SLACK_MS) * 1_000_000
    must_have = [request for stamp, request in sent if stamp <= killed_ns - bound_ns]
    assert must_have, "nothing was sent long enough before the kill"
    newest = b"".join(must_have)
    last = rx.rstrip(b"\n").rsplit(b"\n", 1)[-1]
    lost_ms = (killed_ns - int(last[1:])) / 1e6 if last.startswith(b"t") else float("inf")
    assert len(rx) >= len(newest), (
        f"every request sent up to flush_ms + {CRASH_SLACK_MS} ms before the kill must be in "
        f"the file: its last read was sent {lost_ms:.1f} ms before the kill")


def test_refusals_exit_2_and_write_nothing(traced_program, tmp_path):
    program, master, path = traced_program
    output = tmp_path / "refused.wtape"
    gone = subprocess.Popen(["true"])
    gone.wait()
    cases = [
        (["record", "--attach", str(gone.pid), "-o", str(output)], "there is no process"),
        (["record", "--attach", str(program.pid), "--fd", "9", "-o", str(output)],
         "holds no descriptor 9"),
        (["record", "--attach", str(program.pid), "--path", "/dev/zero", "-o", str(output)],
         "does not hold /dev/zero"),
        (["record", "--fd", "3", "--device", "/dev/null", "-o", str(output)],
         "give --attach too"),
        (["record", "--attach", str(program.pid), "--device", "/dev/null", "-o", str(output)],
         "--device cannot be given with --attach"),
    ]
    for argv, said in cases:
        child = start_cli(*argv)
        _, err = child.communicate(timeout=DEADLINE_S * 4)
        assert child.returncode == 2, (argv, err)
        assert said in err, err
        assert not output.exists()
    assert exchange(master, b"fine\n") == b"ok:fine\n"


@pytest.mark.skipif(shutil.which("setpriv") is None or os.geteuid() != 0,
                    reason="SKIPPED LOUDLY: needs root and setpriv to be another user")
def test_another_users_process_is_refused_without_cap_sys_ptrace(traced_program, tmp_path):
    program, master, path = traced_program
    os.chmod(tmp_path, 0o777)
    output = tmp_path / "nobody.wtape"
    child = subprocess.run(["setpriv", "--reuid", "nobody", "--regid", "nogroup",
                            "--clear-groups", sys.executable, "-m", "wiretape.cli", "record",
                            "--attach", str(program.pid), "-o", str(output)],
                           capture_output=True, text=True, timeout=DEADLINE_S * 4)
    assert child.returncode == 2, child.stderr
    assert "CAP_SYS_PTRACE" in child.stderr
    assert not output.exists()
    assert_unharmed(program)


# --- gpsd ----------------------------------------------------------------------------------

def sentence(body):
    checksum = 0
    for byte in body.encode():
        checksum ^= byte
    return f"${body}*{checksum:02X}\r\n".encode()


def nmea_fix(second):
    hhmmss = f"1235{second % 60:02d}"
    return (sentence(f"GPGGA,{hhmmss}.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,") +
            sentence(f"GPRMC,{hhmmss}.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W"))


class Fixes:
    """gpspipe -w's complete fixes (TPV with a position), counted as they come."""

    def __init__(self, port):
        self.count = 0
        self.lock = threading.Lock()
        self.pipe = subprocess.Popen(["gpspipe", "-w", f"127.0.0.1:{port}"],
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        threading.Thread(target=self._run, daemon=True).start()

    def _run(self):
        for line in self.pipe.stdout:
            try:
                message = json.loads(line)
            except ValueError:
                continue
            if message.get("class") == "TPV" and "lat" in message and "lon" in message:
                with self.lock:
                    self.count += 1

    def more_than(self, count):
        wait_until(lambda: self.count > count, deadline_s=20.0, what="a complete gpsd fix")
        return self.count


@pytest.mark.skipif(shutil.which("gpsd") is None or shutil.which("gpspipe") is None,
                    reason="SKIPPED LOUDLY: gpsd/gpspipe not installed "
                           "(apt-get install gpsd gpsd-clients)")
def test_gpsd_keeps_its_fixes_before_during_and_after_an_attach(tmp_path):
    master, slave = pty.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    fed = bytearray()
    stop = threading.Event()

    def feed():
        second = 0
        while not stop.is_set():
            data = nmea_fix(second)
            try:
                os.write(master, data)
            except OSError:
                return
            fed.extend(data)
            second += 1
            stop.wait(0.2)  # a 5 Hz receiver: its pace, not a synchronisation

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    gpsd = subprocess.Popen(["gpsd", "-N", "-n", "-b", "-S", str(port),
                             "-F", str(tmp_path / "gpsd.sock"), path],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    output = tmp_path / "gpsd.wtape"
    try:
        wait_until(lambda: _listening(port), deadline_s=20.0, what="gpsd listening")
        fixes = Fixes(port)
        before = fixes.more_than(0)
        recorder = attach(str(gpsd.pid), "--path", path, "-o", str(output))
        # A fix gpsd read while attached: one counted after its bytes are in
        # the file (flushed within flush_ms).
        wait_until(lambda: directions(output)[0], deadline_s=20.0, what="gpsd's reads recorded")
        during = fixes.more_than(fixes.count)
        status, _, err = interrupt(recorder)
        assert status == 0, err
        fixes.more_than(during)
        assert gpsd.poll() is None
        assert status_of(gpsd.pid, "TracerPid") == "0"
        fixes.pipe.kill()
    finally:
        stop.set()
        gpsd.terminate()
        gpsd.wait(DEADLINE_S)
        os.close(master)
        os.close(slave)
    rx, tx = directions(output)
    assert rx and bytes(rx) in bytes(fed)  # what gpsd read while attached, byte for byte

    # A fresh gpsd reads the recorded fixes from the recording played back.
    link = str(tmp_path / "ttyReplay")
    handle = bridge.serve_replay(str(output), pty=link,
                                 replay_options="timing=session,check=off,unused=ignore",
                                 quiet=True)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    # Without -n gpsd opens the device at its first client's watch: the
    # recording's few fixes are not all read before gpspipe is there to
    # see them (on a loaded machine they were).
    fresh = subprocess.Popen(["gpsd", "-N", "-b", "-S", str(port),
                              "-F", str(tmp_path / "fresh.sock"), handle.pty_path],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_until(lambda: _listening(port), deadline_s=20.0, what="the fresh gpsd listening")
        replayed = Fixes(port)
        replayed.more_than(0)
        replayed.pipe.kill()
    finally:
        fresh.terminate()
        fresh.wait(DEADLINE_S)
        handle.stop()
        handle.wait()


def _listening(port):
    try:
        socket.create_connection(("127.0.0.1", port), timeout=1).close()
        return True
    except OSError:
        return False


# --- the C program's recordings replay to a fresh instance of it ---------------------------

def records_of(path):
    """The recording's rx and tx records, in order: (kind, bytes) each."""
    return [(record.kind, bytes(record.data)) for record in wiretape.SessionReader(str(path))
            if record.kind in ("rx", "tx")]


def replay_to_fresh_program(recording, tmp_path, run, **serve):
    """Serves `recording` as a virtual device under match=request (the
    documented choice for an attached recording: its first exchange may be
    cut) and lets `run(handle)` start a fresh traced_program against it and
    drive it (it returns the program). Once the fresh program wrote every
    recorded tx byte the replay is stopped; its verdict must be ok, and what
    the fresh program was sent and wrote (the replay's own recording of it)
    must be the attached program's records, record for record."""
    expected = records_of(recording)
    expected_tx = sum(len(data) for kind, data in expected if kind == "tx")
    assert expected_tx, "nothing recorded to replay"
    fresh_output = tmp_path / ("fresh-" + pathlib.Path(recording).name)
    handle = bridge.serve_replay(str(recording), replay_options="match=request",
                                 output=str(fresh_output), quiet=True, **serve)
    program = None
    try:
        program = run(handle)
        wait_until(lambda: handle.stats().bytes_to_device >= expected_tx,
                   what="the fresh program's writes")
    finally:
        if program is not None:
            program.kill()
            program.wait()
        handle.stop()
        handle.wait()
    result = handle.result()
    assert result.ok, result.message
    assert handle.stats().bytes_to_device == expected_tx
    assert records_of(fresh_output) == expected


def start_fresh(*argv):
    program = subprocess.Popen([str(TRACED_PROGRAM), *argv], stdout=subprocess.PIPE,
                               stdin=subprocess.PIPE)
    ready = program.stdout.readline()
    assert ready.startswith(b"ready"), ready
    program.port = int(ready.split()[1]) if len(ready.split()) > 1 else None  # its local port
    return program


def test_a_tty_programs_recording_replays_to_a_fresh_instance(traced_program, tmp_path):
    # The baud/DTR program: a custom rate (TCSETS2) and a DTR pulse
    # (TIOCMBIC, TIOCMBIS) while attached.
    program, master, path = traced_program
    assert exchange(master, b"early\n") == b"ok:early\n"
    output = tmp_path / "tty.wtape"
    attachment = wiretape.attach(program.pid, str(output))
    for request in (b"one\n", b"baud 57600\n", b"dtr\n", b"two\n"):
        assert exchange(master, request) == b"ok:" + request
    attachment.stop()
    link = str(tmp_path / "ttyReplay")
    replay_to_fresh_program(output, tmp_path, lambda handle: start_fresh("tty", link),
                            pty=link)


def test_a_reader_and_writer_threads_recording_replays_to_a_fresh_instance(tmp_path):
    if not TRACED_PROGRAM.exists():
        pytest.skip("SKIPPED LOUDLY: build/bin/traced_program is not built (make)")
    master, slave = pty.openpty()
    program = subprocess.Popen([str(TRACED_PROGRAM), "threads", os.ttyname(slave)],
                               stdout=subprocess.PIPE, stdin=subprocess.PIPE)
    output = tmp_path / "threads.wtape"
    chunks = [b"chunk-%d" % n for n in range(1, 5)]
    try:
        assert program.stdout.readline() == b"ready\n"
        os.write(master, b"early")  # mid-work: the reader thread read before the attach
        assert program.stdout.readline() == b"read 5\n"
        attachment = wiretape.attach(program.pid, str(output))
        for n, chunk in enumerate(chunks, 1):
            os.write(master, chunk)
            assert program.stdout.readline() == b"read %d\n" % len(chunk)
            program.stdin.write(b"x")
            program.stdin.flush()
            line = b"line %d from the writer\n" % n
            got = b""
            while len(got) < len(line):
                got += os.read(master, 100)
            assert got == line
        attachment.stop()
    finally:
        program.kill()
        program.wait()
        os.close(master)
        os.close(slave)
    assert [data for kind, data in records_of(output) if kind == "rx"] == chunks
    link = str(tmp_path / "ttyThreads")

    def run(handle):
        # The reader thread is sent each recorded chunk (the first at once,
        # each next one as the answer to the writer thread's line before it).
        # The reader thread may print its first read before the main
        # thread prints "ready".
        fresh = subprocess.Popen([str(TRACED_PROGRAM), "threads", link],
                                 stdout=subprocess.PIPE, stdin=subprocess.PIPE)
        lines = (line for line in iter(fresh.stdout.readline, b"") if line != b"ready\n")
        for chunk in chunks:
            assert next(lines, b"(its end)") == b"read %d\n" % len(chunk)
            fresh.stdin.write(b"x")
            fresh.stdin.flush()
        return fresh

    replay_to_fresh_program(output, tmp_path, run, pty=link)


def test_a_tcp_programs_recording_replays_to_a_fresh_instance(tmp_path):
    if not TRACED_PROGRAM.exists():
        pytest.skip("SKIPPED LOUDLY: build/bin/traced_program is not built (make)")
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(1)
        port = listener.getsockname()[1]
        program = subprocess.Popen([str(TRACED_PROGRAM), "tcp", "127.0.0.1", str(port)],
                                   stdout=subprocess.PIPE, stdin=subprocess.DEVNULL)
        peer, _ = listener.accept()
    output = tmp_path / "tcp.wtape"
    try:
        assert program.stdout.readline().startswith(b"ready")
        peer.sendall(b"early")
        assert peer.recv(100) == b"ok:early"
        attachment = wiretape.attach(program.pid, str(output))
        for request in (b"hello", b"world"):
            peer.sendall(request)
            assert peer.recv(100) == b"ok:" + request
        attachment.stop()
    finally:
        peer.close()
        program.kill()
        program.wait()
    assert wiretape.SessionReader(str(output)).header.port_type == "tcp"
    free = free_port()
    replay_to_fresh_program(output, tmp_path,
                            lambda handle: start_fresh("tcp", "127.0.0.1", str(free)),
                            listen=f"127.0.0.1:{free}")


def free_port(kind=socket.SOCK_STREAM):
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_a_udp_programs_recording_replays_to_a_fresh_instance(tmp_path):
    if not TRACED_PROGRAM.exists():
        pytest.skip("SKIPPED LOUDLY: build/bin/traced_program is not built (make)")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as peer:
        peer.bind(("127.0.0.1", 0))
        peer.settimeout(DEADLINE_S)
        program = start_fresh("udp", "127.0.0.1", str(peer.getsockname()[1]))
        output = tmp_path / "udp.wtape"
        try:
            peer.connect(("127.0.0.1", program.port))
            peer.send(b"early")
            assert peer.recv(100) == b"ok:early"
            attachment = wiretape.attach(program.pid, str(output))
            for request in (b"ping", b"pong", b"last"):
                peer.send(request)
                assert peer.recv(100) == b"ok:" + request
            attachment.stop()
        finally:
            program.kill()
            program.wait()
    header = wiretape.SessionReader(str(output)).header
    assert header.port_type == "udp"
    assert [data for kind, data in records_of(output) if kind == "rx"] == [b"ping", b"pong",
                                                                           b"last"]
    # The fresh client connects to the replay's port before the replay is
    # there (a UDP connect needs no peer), so that the replay, which speaks
    # first here, knows where to send its first datagram.
    replay_port = free_port(socket.SOCK_DGRAM)
    fresh = start_fresh("udp", "127.0.0.1", str(replay_port))
    try:
        replay_to_fresh_program(output, tmp_path, lambda handle: fresh,
                                udp=f"127.0.0.1:{replay_port}", peer=f"127.0.0.1:{fresh.port}")
    finally:
        fresh.kill()
        fresh.wait()
