"""Faults seen from Python: a device that goes away while a read or a write is
blocked raises wiretape.PortClosed in that thread (never hangs, never kills
the interpreter with SIGPIPE), and a `wiretape record` proxy killed with
SIGKILL mid-stream leaves a file that verifies."""

import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

import pytest

import wiretape
from wiretape import _core

from devices import wait_until

DEADLINE = 10.0  # seconds: generous, for events that should happen at once
CHUNK = bytes(range(256)) * 16


class Blocked:
    """Runs `call` on a thread and keeps how it ended."""

    def __init__(self, call):
        self.started = threading.Event()
        self.error = None
        self.result = None

        def run():
            self.started.set()
            try:
                self.result = call()
            except BaseException as error:  # noqa: BLE001 - kept for the assertion
                self.error = error

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()
        assert self.started.wait(DEADLINE)

    def outcome(self):
        self.thread.join(DEADLINE)
        assert not self.thread.is_alive(), "the blocked call never woke up"
        return self.error


@pytest.fixture
def pty_device():
    master, terminal = os.openpty()
    tty.setraw(terminal)
    yield {"master": master, "path": os.ttyname(terminal)}
    for fd in (master, terminal):
        try:
            os.close(fd)
        except OSError:
            pass  # the test closed it: the device was unplugged


def test_serial_device_vanishing_mid_read_raises_port_closed(pty_device):
    port = wiretape.open_port(f"type=serial,device={pty_device['path']}")
    call = Blocked(lambda: port.read(1, timeout=None))
    os.close(pty_device["master"])  # unplugged, whether or not the read blocks yet
    assert isinstance(call.outcome(), wiretape.PortClosed), repr(call.error)
    port.close()


def test_serial_device_vanishing_mid_write_raises_port_closed(pty_device):
    port = wiretape.open_port(f"type=serial,device={pty_device['path']}")
    # Nobody reads the device: the write fills the terminal's buffer and
    # blocks (or has not started yet: the outcome must be the same).
    call = Blocked(lambda: port.write_all(b"w" * (16 << 20)))
    os.close(pty_device["master"])
    assert isinstance(call.outcome(), wiretape.PortClosed), repr(call.error)
    port.close()


def tcp_device():
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    return listener, listener.getsockname()[1]


def test_tcp_device_resetting_mid_write_raises_port_closed_not_sigpipe():
    listener, port_number = tcp_device()
    with listener:
        port = wiretape.open_port(f"type=tcp,host=127.0.0.1,port={port_number}")
        device, _ = listener.accept()
        call = Blocked(lambda: port.write_all(b"w" * (64 << 20)))
        device.close()  # unread data queued: the kernel sends a reset
        assert isinstance(call.outcome(), wiretape.PortClosed), repr(call.error)
        port.close()


def test_tcp_device_closing_mid_read_raises_port_closed_and_is_recorded(tmp_path):
    listener, port_number = tcp_device()
    log = tmp_path / "lost.wtape"
    with listener:
        port = wiretape.open_port(f"type=tcp,host=127.0.0.1,port={port_number},log={log}")
        device, _ = listener.accept()
        device.sendall(b"hello\n")
        assert port.read_until(b"\n", timeout=DEADLINE) == b"hello\n"
        call = Blocked(lambda: port.read_exactly(10, timeout=None))
        device.close()
        assert isinstance(call.outcome(), wiretape.PortClosed), repr(call.error)
        port.close()
    kinds = [record.kind for record in wiretape.SessionReader(str(log))]
    assert "rx" in kinds
    assert "device_lost" in kinds


def test_close_from_another_thread_wakes_a_blocked_read():
    port = wiretape.open_port("type=loopback")
    call = Blocked(lambda: port.read(1, timeout=None))
    port.close()
    assert isinstance(call.outcome(), wiretape.PortClosed), repr(call.error)


# --- the record proxy killed mid-stream ----------------------------------------------

RECORD_WITH_BRIDGE = """
import signal, sys, wiretape.bridge
device, link, output = sys.argv[1:4]
handle = wiretape.bridge.record(device, output, pty=link, quiet=True)
handle.wait()
"""


def recorder_command(device, link, output):
    """`wiretape record` when the CLI has it, else the same engine
    (wiretape.bridge.record) in a child interpreter."""
    script = Path(sys.executable).parent / "wiretape"
    cli = [str(script)] if script.exists() else [sys.executable, "-m", "wiretape.cli"]
    probe = subprocess.run(cli + ["record", "--help"], capture_output=True, text=True)
    if probe.returncode == 0 and "--pty" in probe.stdout:
        return cli + ["record", "--device", device, "--pty", link, "-o", output]
    return [sys.executable, "-c", RECORD_WITH_BRIDGE, device, link, output]


def file_ends_inside_record(path, offset):
    """True when the file ends inside the record that starts at `offset`."""
    data = path.read_bytes()
    if offset + _core.RECORD_HEADER_SIZE > len(data):
        return True
    length = int.from_bytes(data[offset:offset + 4], "little")
    return offset + _core.RECORD_OVERHEAD + length > len(data)


def test_record_proxy_killed_mid_stream_leaves_a_file_readable_to_its_end(tmp_path, pty_device):
    link = tmp_path / "proxy-pty"
    output = tmp_path / "killed.wtape"
    proxy = subprocess.Popen(recorder_command(pty_device["path"], str(link), str(output)),
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        def proxy_made_its_pty():
            if link.exists():
                return True
            # A proxy that ended will never make it: fail at once, with its errors.
            assert proxy.poll() is None, proxy.stderr.read().decode()
            return False

        wait_until(proxy_made_its_pty, DEADLINE, what="the proxy to make its pty")
        client = os.open(link, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(client)
        try:
            # Stream device -> client, chunk by chunk, for at least 1 MiB and
            # 0.6 s, noting when the client had seen how much; then kill the
            # proxy mid-stream.
            seen = 0
            progress = []  # (monotonic time, bytes the client had seen)
            started = time.monotonic()
            while seen < (1 << 20) or time.monotonic() - started < 0.6:
                os.write(pty_device["master"], CHUNK)
                target = seen + len(CHUNK)
                while seen < target:
                    ready, _, _ = select.select([client], [], [], DEADLINE)
                    assert ready, "the proxy stopped forwarding"
                    seen += len(os.read(client, 65536))
                progress.append((time.monotonic(), seen))
            os.write(pty_device["master"], CHUNK)  # in flight at the kill
            killed_at = time.monotonic()
            proxy.send_signal(signal.SIGKILL)
            proxy.wait(DEADLINE)
        finally:
            os.close(client)
    finally:
        if proxy.poll() is None:
            proxy.kill()
            proxy.wait()
        proxy.stderr.close()

    reader = wiretape.SessionReader(str(output))
    rx = b"".join(record.data for record in reader if record.kind == "rx")
    # Every record is whole but perhaps the last: the kernel stops a write
    # between pages when SIGKILL comes, so the write in flight may have
    # reached the file only in part.
    assert reader.damage is None or file_ends_inside_record(output, reader.damage.offset), (
        reader.damage)
    # What crossed more than flush_ms (100 ms) + 100 ms of slack before the
    # kill must be in the file.
    must_have = max((n for t, n in progress if t <= killed_at - 0.2), default=0)
    assert must_have > 0, "the stream was too short to test the flush bound"
    assert len(rx) >= must_have, (
        f"{len(rx)} bytes recorded; {must_have} had crossed over 200 ms before the kill")
    assert rx == (CHUNK * (len(rx) // len(CHUNK) + 1))[: len(rx)], "recorded bytes differ from the stream"
