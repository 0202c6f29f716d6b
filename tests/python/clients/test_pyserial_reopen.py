"""pyserial against virtual devices (DESIGN §12): a client that closes and
reopens at once is two client sessions, when recording and when replaying
(the issue's repro: `s=serial.Serial(p); s.close(); s=serial.Serial(p);
s.write(b"PING\\n")`); and rx gated on recorded flushes is served to a
client that flushed fewer times than recorded, within flush_wait, and at
once when it writes past the recorded flushes (issue 37)."""

import socket
import sys
import threading

import pytest

from wiretape import _core, bridge

from devices import wait_until

serial = pytest.importorskip("serial", reason="pyserial not installed (make installs it)")

DEADLINE = 10.0
RUNS = 10

linux_only = pytest.mark.skipif(
    not sys.platform.startswith("linux"),
    reason="only Linux shows a pty's clients coming and going (inotify)")


class PongDevice:
    """A device on TCP that answers every PING line with PONG."""

    def __init__(self):
        self.server = socket.socket()
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(1)
        self.options = f"type=tcp,host=127.0.0.1,port={self.server.getsockname()[1]}"
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        connection, _ = self.server.accept()
        with connection:
            pending = b""
            while True:
                chunk = connection.recv(4096)
                if not chunk:
                    return
                pending += chunk
                while b"\n" in pending:
                    line, pending = pending.split(b"\n", 1)
                    if line == b"PING":
                        connection.sendall(b"PONG\n")

    def close(self):
        self.server.close()
        self.thread.join(DEADLINE)


def reopen_and_ping(path):
    port = serial.Serial(path, timeout=DEADLINE)
    port.close()
    port = serial.Serial(path, timeout=DEADLINE)
    try:
        port.write(b"PING\n")
        return port.read(5)
    finally:
        port.close()


def client_events(path):
    letters = {"client_connect": "C", "client_disconnect": "D", "tx": "T"}
    with _core.SessionReader(str(path)) as reader:
        return "".join(letters.get(record.kind, "") for record in reader)


@linux_only
def test_recording_a_client_that_reopens_at_once_records_two_sessions(tmp_path):
    device = PongDevice()
    out = tmp_path / "reopen.wtape"
    link = str(tmp_path / "ttyRec")
    handle = bridge.record(device.options, out, pty=link, quiet=True)
    try:
        for run in range(RUNS):
            assert reopen_and_ping(link) == b"PONG\n", run
        wait_until(lambda: sum(m.startswith("client closed") for m in handle.messages())
                   >= 2 * RUNS, DEADLINE, "the last close to be seen")
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
        device.close()
    assert client_events(out) == "CDCTD" * RUNS


def write_recording(path, records):
    writer = _core.SessionWriter(str(path), capture="wire",
                                 port_options="type=serial,device=/dev/ttyUSB0",
                                 port_type="serial")
    writer.write("open", 0, b"{}")
    for t_ms, (kind, data) in enumerate(records, start=1):
        writer.write(kind, t_ms * 1_000_000, data)
    writer.close()
    return path


PTY_CLIENT = b'{"peer":"pty","role":"control"}'


@linux_only
def test_replaying_a_client_that_reopens_at_once_serves_the_second_session(tmp_path):
    recording = write_recording(tmp_path / "reopen.wtape", [
        ("client_connect", PTY_CLIENT), ("client_disconnect", PTY_CLIENT),
        ("client_connect", PTY_CLIENT), ("tx", b"PING\n"), ("rx", b"PONG\n"),
        ("client_disconnect", PTY_CLIENT)])
    for run in range(RUNS):
        link = str(tmp_path / f"ttyReplay{run}")
        handle = bridge.serve_replay(recording, pty=link, replay_options="timing=none",
                                     quiet=True)
        try:
            assert reopen_and_ping(link) == b"PONG\n", run
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)
        assert handle.result().ok, (run, handle.result())


@linux_only
def test_a_client_that_flushed_fewer_times_than_recorded_is_served_everything(tmp_path):
    # The repro: Serial() and reset_input_buffer() flush back to
    # back, and the pty may show the two as one.
    recording = write_recording(tmp_path / "flushes.wtape", [
        ("client_connect", PTY_CLIENT), ("flush_input", b"{}"), ("rx", b"$A"),
        ("flush_input", b"{}"), ("rx", b"$B"), ("rx", b"$C")])
    link = str(tmp_path / "ttyFlush")
    handle = bridge.serve_replay(recording, pty=link, replay_options="timing=none",
                                 quiet=True)
    try:
        port = serial.Serial(link, timeout=DEADLINE)
        try:
            port.reset_input_buffer()
            got = b""
            while len(got) < 6:
                chunk = port.read(6 - len(got))
                if not chunk:
                    break
                got += chunk
        finally:
            port.close()
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert got == b"$A$B$C"
    assert handle.result().ok, handle.result()


# A motor-controller SDK's status request (Dynamixel protocol 2.0 ping: 10 bytes).
SDK_PING = bytes.fromhex("fffffd0001030001194e")
SDK_STATUS = bytes.fromhex("fffffd0001070055000604265d")


def open_set_baud_and_ping(path, read_timeout):
    """openPort() then setBaudRate() (which closes and reopens the port: the
    reopen flushes once), then one ping and its status packet."""
    port = serial.Serial(path, timeout=read_timeout)
    port.close()
    port = serial.Serial(path, 57600, timeout=read_timeout)
    try:
        port.write(SDK_PING)
        return port.read(len(SDK_STATUS))
    finally:
        port.close()


@linux_only
@pytest.mark.parametrize("flush_wait", [None, 600_000], ids=["default", "ten_minutes"])
def test_an_sdk_that_flushed_once_of_two_recorded_flushes_is_answered_at_its_ping(
        tmp_path, flush_wait):
    # Issue 37: the recording shows two flushes before the ping (the SDK's
    # number of flushes depends on timing); the client makes one. Once it
    # has written the ping, past the place of the recorded flushes, they can
    # no longer come, and the status packet they held is due at once: not
    # flush_wait later, so a flush_wait of ten minutes still answers it
    # within the client's read timeout.
    recording = write_recording(tmp_path / "sdk.wtape", [
        ("client_connect", PTY_CLIENT), ("flush_input", b"{}"),
        ("client_disconnect", PTY_CLIENT),
        ("client_connect", PTY_CLIENT), ("flush_input", b"{}"), ("flush_input", b"{}"),
        ("tx", SDK_PING), ("rx", SDK_STATUS), ("client_disconnect", PTY_CLIENT)])
    options = [("timing", "none")]
    if flush_wait is not None:
        options.append(("flush_wait", flush_wait))
    link = str(tmp_path / "ttySdk")
    handle = bridge.serve_replay(recording, pty=link,
                                 replay_options=_core.option_string(options), quiet=True)
    try:
        assert open_set_baud_and_ping(link, read_timeout=DEADLINE) == SDK_STATUS
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    result = handle.result()
    assert result.ok, result
    assert not result.nothing_served, result
