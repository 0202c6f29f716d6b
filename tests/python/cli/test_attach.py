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


def test_kill_9_of_wiretape_keeps_what_was_flushed_and_the_program_running(traced_program,
                                                                          tmp_path):
    program, master, path = traced_program
    output = tmp_path / "killed.wtape"
    recorder = attach(str(program.pid), "-o", str(output))
    assert exchange(master, b"kept\n") == b"ok:kept\n"
    # flush_ms (100 ms) bounds what a crash loses: the records reach the file.
    wait_until(lambda: directions(output) == (b"kept\n", b"ok:kept\n"),
               what="the records flushed to the file")
    recorder.kill()
    recorder.wait()
    assert exchange(master, b"free\n") == b"ok:free\n"
    assert_unharmed(program)


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
    fresh = subprocess.Popen(["gpsd", "-N", "-n", "-b", "-S", str(port),
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

def replay_to_fresh_program(recording, argv_for, listen=None, pty_link=None):
    """Serves `recording` and runs a fresh traced_program against it
    (argv_for(address)); once the program wrote all the recorded tx, the
    replay is stopped: its verdict."""
    expected_tx = len(directions(recording)[1])
    handle = bridge.serve_replay(str(recording), pty=pty_link, listen=listen, quiet=True)
    program = None
    try:
        address = pty_link if pty_link else listen
        program = subprocess.Popen([str(TRACED_PROGRAM), *argv_for(address)],
                                   stdout=subprocess.PIPE, stdin=subprocess.DEVNULL)
        assert program.stdout.readline().startswith(b"ready")
        wait_until(lambda: handle.stats().bytes_to_device >= expected_tx,
                   what="the fresh program's answers")
    finally:
        if program is not None:
            program.kill()
            program.wait()
        handle.stop()
        handle.wait()
    result = handle.result()
    assert result.ok, result.message
    assert handle.stats().bytes_to_device == expected_tx


def test_a_tty_programs_recording_replays_to_a_fresh_instance(traced_program, tmp_path):
    program, master, path = traced_program
    assert exchange(master, b"early\n") == b"ok:early\n"
    output = tmp_path / "tty.wtape"
    attachment = wiretape.attach(program.pid, str(output))
    for request in (b"one\n", b"baud 57600\n", b"two\n"):
        assert exchange(master, request) == b"ok:" + request
    attachment.stop()
    replay_to_fresh_program(output, lambda link: ["tty", link],
                            pty_link=str(tmp_path / "ttyReplay"))


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
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        free = probe.getsockname()[1]
    replay_to_fresh_program(output, lambda address: ["tcp", "127.0.0.1", str(free)],
                            listen=f"127.0.0.1:{free}")
