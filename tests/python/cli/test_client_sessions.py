"""wiretape replay --pty/--listen serves client sessions (DESIGN §12): a
client's session starts when it connects, at the recording's
client_connect; what the device said before it, or between two clients,
is not served."""

import os
import select
import socket
import sys
import threading
import time

import pytest

from wiretape import _core, bridge

from devices import wait_until

DEADLINE = 10.0
BOOT = b"boot banner before anyone listened\n"
GREETING = b"hello client\n"
LATER = b"still here\n"

linux_only = pytest.mark.skipif(
    not sys.platform.startswith("linux"),
    reason="only Linux shows a pty's clients coming and going (inotify)")


class GreetingDevice:
    """A device on TCP that says BOOT as soon as it is connected, and
    GREETING then LATER (a pause apart) once `client_here` is set."""

    def __init__(self, pause_s=0.2):
        self.server = socket.socket()
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(1)
        self.options = f"type=tcp,port={self.server.getsockname()[1]}"
        self.client_here = threading.Event()
        self.done = threading.Event()
        self.pause_s = pause_s
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        connection, _ = self.server.accept()
        with connection:
            connection.sendall(BOOT)
            self.client_here.wait(DEADLINE)
            connection.sendall(GREETING)
            # The device's own pace, which the replay keeps.
            select.select([], [], [], self.pause_s)
            connection.sendall(LATER)
            self.done.set()
            # Until the proxy goes away.
            while connection.recv(4096):
                pass

    def close(self):
        self.server.close()
        self.thread.join(DEADLINE)


def read_records(path):
    with _core.SessionReader(str(path)) as reader:
        return list(reader)


def read_until(fd, count, deadline_s=DEADLINE):
    data = bytearray()
    end = time.monotonic() + deadline_s
    while len(data) < count:
        left = end - time.monotonic()
        if left <= 0:
            break
        ready, _, _ = select.select([fd], [], [], left)
        if ready:
            data += os.read(fd, 4096)
    return bytes(data)


def record_greeting_session(tmp_path):
    """A proxy recording: BOOT before the client connected, GREETING and
    LATER after."""
    out = tmp_path / "greeting.wtape"
    link = tmp_path / "ttyRec"
    device = GreetingDevice()
    handle = bridge.record(device.options, out, pty=str(link), quiet=True)
    try:
        wait_until(lambda: handle.stats().bytes_from_device >= len(BOOT), DEADLINE,
                   "the device's boot banner to reach the proxy")
        fd = os.open(str(link), os.O_RDWR | os.O_NOCTTY)
        try:
            wait_until(lambda: handle.stats().clients_accepted >= 1, DEADLINE,
                       "the proxy to see its client")
            device.client_here.set()
            # A live device's proxy passes on what it said before, too.
            got = read_until(fd, len(BOOT + GREETING + LATER))
            assert got.endswith(GREETING + LATER)
        finally:
            os.close(fd)
        wait_until(lambda: any(m.startswith("client closed") for m in handle.messages()),
                   DEADLINE, "the client's close to be seen")
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
        device.close()
    kinds = [(r.kind, bytes(r.data)) for r in read_records(out) if r.kind != "open"]
    connect = [k for k, _ in kinds].index("client_connect")
    rx_before = b"".join(d for k, d in kinds[:connect] if k == "rx")
    rx_after = b"".join(d for k, d in kinds[connect:] if k == "rx")
    assert rx_before == BOOT and rx_after == GREETING + LATER
    return out


@linux_only
def test_a_late_pty_client_gets_what_followed_client_connect_timed_from_its_connect(tmp_path):
    recording = record_greeting_session(tmp_path)
    link = tmp_path / "ttyReplay"
    handle = bridge.serve_replay(recording, pty=str(link),
                                 replay_options="timing=session", quiet=True)
    try:
        # Late: the replay has been running for a while, longer than the
        # recording's whole span after its client_connect would take.
        replay_started = time.monotonic()
        wait_until(lambda: time.monotonic() - replay_started > 0.5, DEADLINE,
                   "the replay to run a while without a client")
        connected = time.monotonic()
        fd = os.open(str(link), os.O_RDWR | os.O_NOCTTY)
        try:
            greeting = read_until(fd, len(GREETING))
            got_greeting = time.monotonic()
            later = read_until(fd, len(LATER))
            got_later = time.monotonic()
        finally:
            os.close(fd)
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert greeting == GREETING, "the client got what the device said to nobody"
    assert later == LATER
    # Timed from the client's connect: LATER came the recorded pause after
    # GREETING, not at once (as it would if the clock had started with the
    # replay).
    assert got_later - connected >= 0.15
    assert got_greeting <= got_later
    result = handle.result()
    assert result.ok and not result.nothing_served, result


def test_a_tcp_client_of_a_proxy_recording_is_not_served_what_came_before_it(tmp_path):
    recording = record_greeting_session(tmp_path) if sys.platform.startswith("linux") else None
    if recording is None:
        pytest.skip("the recording needs a pty proxy (Linux)")
    handle = bridge.serve_replay(recording, listen="127.0.0.1:0",
                                 replay_options="timing=none", quiet=True)
    try:
        host, port = handle.address.rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=DEADLINE) as client:
            got = read_until(client.fileno(), len(GREETING + LATER))
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert got == GREETING + LATER


def write_two_client_recording(path):
    writer = _core.SessionWriter(str(path), capture="wire",
                                 port_options="type=serial,device=/dev/ttyX", port_type="serial")
    writer.write("open", 0, b"{}")
    writer.write("rx", 1_000, b"to nobody\n")
    writer.write("client_connect", 2_000, b'{"peer":"pty","role":"control"}')
    writer.write("rx", 3_000, b"one\n")
    writer.write("client_disconnect", 4_000, b'{"peer":"pty","reason":"closed"}')
    writer.write("rx", 5_000, b"between clients\n")
    writer.write("client_connect", 6_000, b'{"peer":"pty","role":"control"}')
    writer.write("rx", 7_000, b"two\n")
    writer.close()
    return path


@linux_only
def test_a_pty_clients_second_connection_continues_at_the_second_client_connect(tmp_path):
    recording = write_two_client_recording(tmp_path / "two.wtape")
    link = str(tmp_path / "tty")
    handle = bridge.serve_replay(recording, pty=link, replay_options="timing=none",
                                 quiet=True)
    try:
        for number, expected in enumerate([b"one\n", b"two\n"], start=1):
            fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
            try:
                assert read_until(fd, len(expected)) == expected
            finally:
                os.close(fd)
            wait_until(lambda: sum(m.startswith("client closed") for m in handle.messages())
                       >= number, DEADLINE, f"client {number}'s close to be seen")
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert handle.result().ok, handle.result()


def test_a_tcp_clients_second_connection_continues_at_the_second_client_connect(tmp_path):
    recording = write_two_client_recording(tmp_path / "two.wtape")
    handle = bridge.serve_replay(recording, listen="127.0.0.1:0",
                                 replay_options="timing=none", quiet=True)
    try:
        host, port = handle.address.rsplit(":", 1)
        for number, expected in enumerate([b"one\n", b"two\n"], start=1):
            with socket.create_connection((host, int(port)), timeout=DEADLINE) as client:
                assert read_until(client.fileno(), len(expected)) == expected
            wait_until(lambda: sum("disconnected" in m for m in handle.messages()) >= number,
                       DEADLINE, f"client {number}'s disconnect to be seen")
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
