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

def wiretape_cli():
    script = Path(sys.executable).parent / "wiretape"
    command = [str(script)] if script.exists() else [sys.executable, "-m", "wiretape.cli"]
    probe = subprocess.run(command + ["record", "--help"], capture_output=True, text=True)
    if probe.returncode != 0 or "--pty" not in probe.stdout:
        pytest.skip("SKIPPED LOUDLY: `wiretape record` is not available in this build: "
                    + (probe.stderr or probe.stdout).strip()[-200:])
    return command


def test_record_proxy_killed_mid_stream_leaves_a_file_that_verifies(tmp_path, pty_device):
    command = wiretape_cli()
    link = tmp_path / "proxy-pty"
    output = tmp_path / "killed.wtape"
    proxy = subprocess.Popen(command + ["record", "--device", pty_device["path"], "--pty", str(link),
                                        "-o", str(output)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + DEADLINE
        while not link.exists():
            assert proxy.poll() is None, proxy.stderr.read().decode()
            assert time.monotonic() < deadline, "the proxy never made its pty"
            time.sleep(0.01)  # waiting for another process's file to appear
        client = os.open(link, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(client)
        try:
            # Stream device -> client, chunk by chunk, until the client has
            # seen 1 MiB through the proxy; then kill it mid-stream.
            seen = 0
            while seen < (1 << 20):
                os.write(pty_device["master"], CHUNK)
                target = seen + len(CHUNK)
                while seen < target:
                    ready, _, _ = select.select([client], [], [], DEADLINE)
                    assert ready, "the proxy stopped forwarding"
                    seen += len(os.read(client, 65536))
            os.write(pty_device["master"], CHUNK)  # in flight at the kill
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
    assert reader.damage is None, reader.damage
    assert len(rx) >= 512 * 1024, f"only {len(rx)} bytes of the 1 MiB forwarded reached the file"
    assert rx == (CHUNK * (len(rx) // len(CHUNK) + 1))[: len(rx)], "recorded bytes differ from the stream"
    verify = subprocess.run(command + ["verify", str(output)], capture_output=True, text=True)
    assert verify.returncode == 0, verify.stdout + verify.stderr
