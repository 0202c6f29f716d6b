"""wiretape replay: no silent success (DESIGN §12). A replay whose recording
has rx exits 1 when no client was served any of it (no client connected,
nothing it sent matched, or the greeting was lost), saying which; a client
served the recording exits 0, and a recording without rx never fails for
this. The clients are pyserial on the pty, as a real driver would be."""

import signal
import subprocess
import sys
import threading

import pytest
import serial

from devices import wait_until

DEADLINE = 10.0


@pytest.fixture
def greeting(device_recording):
    """The device speaks first: a greeting at t=0, then one exchange."""
    return device_recording(name="greeting.wtape", records=[
        ("rx", 0, b"HELLO\n"), ("tx", 2_000_000, b"PING\n"), ("rx", 2_500_000, b"PONG\n")])


@pytest.fixture
def exchange(device_recording):
    return device_recording(name="exchange.wtape", records=[
        ("tx", 1_000_000, b"PING\n"), ("rx", 1_500_000, b"PONG\n")])


@pytest.fixture
def no_rx(device_recording):
    """A device that only listens."""
    return device_recording(name="listener.wtape", records=[("tx", 1_000_000, b"GO\n")])


class Replay:
    """`wiretape replay FILE --pty LINK --timing none` as a child process,
    its diagnostics collected as they come."""

    def __init__(self, recording, link, *options):
        self.link = str(link)
        self.lines = []
        self._child = subprocess.Popen(
            [sys.executable, "-m", "wiretape.cli", "replay", str(recording), "--pty", self.link,
             "--timing", "none", *options],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self._reader = threading.Thread(target=self._collect, daemon=True)
        self._reader.start()
        self.wait_for("clients use pty")

    def _collect(self):
        for line in self._child.stderr:
            self.lines.append(line)

    def wait_for(self, text):
        wait_until(lambda: any(text in line for line in self.lines) or
                   self._child.poll() is not None, DEADLINE, f"{text!r} from the replay")
        assert any(text in line for line in self.lines), "".join(self.lines)

    def stop(self):
        """Ctrl-C, as a user ends it: (exit code, everything it said)."""
        if self._child.poll() is None:
            self._child.send_signal(signal.SIGINT)
        try:
            code = self._child.wait(timeout=DEADLINE)
        except subprocess.TimeoutExpired:
            self._child.kill()
            code = self._child.wait()
        self._reader.join(DEADLINE)
        return code, "".join(self.lines)


def test_a_client_that_closes_without_reading_the_greeting_exits_1(greeting, tmp_path):
    replay = Replay(greeting, tmp_path / "tty")
    try:
        client = serial.Serial(replay.link, 115200, timeout=DEADLINE)
        client.close()
        replay.wait_for("client closed")
    finally:
        code, said = replay.stop()
    assert code == 1, said
    assert "no client was served any of the recording's rx" in said
    assert "the client read none" in said and "greeting was lost" in said


def test_no_client_before_the_end_exits_1(greeting, tmp_path):
    code, said = Replay(greeting, tmp_path / "tty").stop()
    assert code == 1, said
    assert "no client connected before the end" in said


def test_a_client_that_sends_nothing_the_recording_answers_exits_1(exchange, tmp_path):
    replay = Replay(exchange, tmp_path / "tty")
    try:
        serial.Serial(replay.link, 115200, timeout=DEADLINE).close()
        replay.wait_for("client closed")
    finally:
        code, said = replay.stop()
    assert code == 1, said
    assert "nothing the client sent matched" in said


def test_a_client_served_the_recording_exits_0(exchange, tmp_path):
    replay = Replay(exchange, tmp_path / "tty")
    try:
        with serial.Serial(replay.link, 115200, timeout=DEADLINE) as client:
            client.write(b"PING\n")
            assert client.read_until(b"\n") == b"PONG\n"
        replay.wait_for("client closed")
    finally:
        code, said = replay.stop()
    assert code == 0, said
    assert "no client was served" not in said


def test_a_recording_without_rx_and_a_silent_client_exits_0(no_rx, tmp_path):
    replay = Replay(no_rx, tmp_path / "tty")
    try:
        serial.Serial(replay.link, 115200, timeout=DEADLINE).close()
        replay.wait_for("client closed")
    finally:
        code, said = replay.stop()
    assert code == 0, said


@pytest.fixture
def flushed_greeting(device_recording):
    """A proxy recording whose client flushed five times before the device
    greeted it and answered its PING."""
    client = b'{"peer":"pty","role":"control"}'
    return device_recording(name="flushed.wtape", records=[
        ("client_connect", 1_000_000, client),
        *[("flush_input", 2_000_000 + i, b"{}") for i in range(5)],
        ("rx", 3_000_000, b"HELLO\n"), ("tx", 4_000_000, b"PING\n"),
        ("rx", 4_500_000, b"PONG\n")])


def test_a_client_that_flushed_fewer_times_and_wrote_past_the_flushes_is_served_and_exits_0(
        flushed_greeting, tmp_path):
    # Issue 37: once the client wrote past the recorded flushes they can no
    # longer come: the greeting they held is due at its write, not
    # flush_wait later (here ten minutes: the client's reads would time out).
    replay = Replay(flushed_greeting, tmp_path / "tty", "--flush-wait", "600000")
    try:
        with serial.Serial(replay.link, 115200, timeout=DEADLINE) as client:
            client.write(b"PING\n")
            assert client.read_until(b"\n") == b"HELLO\n"
            assert client.read_until(b"\n") == b"PONG\n"
        replay.wait_for("client closed")
    finally:
        code, said = replay.stop()
    assert code == 0, said


def test_a_client_that_flushed_fewer_times_is_served_after_flush_wait_and_exits_0(
        flushed_greeting, tmp_path):
    replay = Replay(flushed_greeting, tmp_path / "tty", "--flush-wait", "100")
    try:
        with serial.Serial(replay.link, 115200, timeout=DEADLINE) as client:
            assert client.read_until(b"\n") == b"HELLO\n"
            client.write(b"PING\n")
            assert client.read_until(b"\n") == b"PONG\n"
        replay.wait_for("client closed")
    finally:
        code, said = replay.stop()
    assert code == 0, said
