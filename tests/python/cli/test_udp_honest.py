"""Honest outcomes over UDP (DESIGN.md section 23): the record proxy's device
side takes datagrams from the device alone, and ``replay --udp --peer``
counts as served only what the peer took, starting its client session when
the peer first takes a datagram."""

import re
import select
import signal
import socket
import subprocess
import threading
import time

import pytest

from wiretape import _core, bridge

from devices import start_cli

DEADLINE = 10.0


def udp_socket(port=0):
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", port))
    return sock


def free_udp_port():
    """A port nobody listens on (bound, then closed)."""
    with udp_socket() as sock:
        return sock.getsockname()[1]


def address_of(text):
    host, port = text.rsplit(":", 1)
    return host, int(port)


def receive(sock, count):
    sock.settimeout(DEADLINE)
    return [sock.recv(65535) for _ in range(count)]


def nothing_waiting(sock):
    ready, _, _ = select.select([sock], [], [], 0)
    return not ready


def read_records(path):
    with _core.SessionReader(str(path)) as reader:
        records = list(reader)
        assert reader.damage is None, reader.damage
        return records


class StderrLines:
    """A child's stderr, line by line (read by a thread), awaited with a
    deadline; `rest()` is all of it once the child has ended."""

    def __init__(self, child):
        self.lines = []
        self._changed = threading.Condition()
        self._ended = False
        self._reader = threading.Thread(target=self._read, args=(child.stderr,), daemon=True)
        self._reader.start()

    def _read(self, stream):
        for line in stream:
            with self._changed:
                self.lines.append(line)
                self._changed.notify_all()
        with self._changed:
            self._ended = True
            self._changed.notify_all()

    def wait_for(self, pattern, deadline=DEADLINE):
        end = time.monotonic() + deadline
        with self._changed:
            while True:
                for line in self.lines:
                    if re.search(pattern, line):
                        return line
                left = end - time.monotonic()
                if left <= 0 or self._ended:
                    raise AssertionError(f"no line matching {pattern!r} on stderr: "
                                         + "".join(self.lines))
                self._changed.wait(left)

    def text(self):
        self._reader.join(DEADLINE)
        return "".join(self.lines)


def stop(child, stderr):
    """Ctrl-C; (exit status, all of stderr)."""
    child.send_signal(signal.SIGINT)
    try:
        child.wait(DEADLINE)
    except subprocess.TimeoutExpired:
        child.kill()
        child.wait()
    return child.returncode, stderr.text()


# --- record --udp: the device side is the device's alone ----------------------------------


class EchoDevice:
    """A device on UDP that answers each datagram with it in upper case, in
    the test's own thread (`answer_one`), and knows the proxy's address."""

    def __init__(self):
        self.socket = udp_socket()
        self.options = "type=udp,host=127.0.0.1,port=%d" % self.socket.getsockname()[1]
        self.proxy = None

    def answer_one(self):
        self.socket.settimeout(DEADLINE)
        data, self.proxy = self.socket.recvfrom(65535)
        self.socket.sendto(data.upper(), self.proxy)
        return data


def test_record_drops_a_datagram_another_sender_sends_to_the_device_side(tmp_path):
    out = tmp_path / "udp.wtape"
    device = EchoDevice()
    with device.socket, udp_socket() as driver, udp_socket() as spoofer:
        handle = bridge.record(device.options, out, udp="127.0.0.1:0", quiet=True)
        where = address_of(handle.address)
        driver.sendto(b"first", where)
        assert device.answer_one() == b"first"
        assert receive(driver, 1) == [b"FIRST"]
        # Someone else than the device, at the proxy's device side: on
        # loopback the kernel delivers (or refuses) it before sendto returns.
        spoofer.sendto(b"SPOOFED", device.proxy)
        driver.sendto(b"second", where)
        assert device.answer_one() == b"second"
        # The device's answer is the next datagram the driver gets, and the
        # last: the spoofed one never reaches it.
        assert receive(driver, 1) == [b"SECOND"]
        handle.stop()
        assert handle.wait(DEADLINE)
        result = handle.result()
        assert nothing_waiting(driver)
    assert result.ok, result.message
    records = read_records(out)
    assert [r.data for r in records if r.kind == "rx"] == [b"FIRST", b"SECOND"]
    assert [r.data for r in records if r.kind == "tx"] == [b"first", b"second"]


def test_a_udp_port_with_a_destination_reads_the_destination_alone():
    with udp_socket() as device, udp_socket() as stranger:
        port = _core.open_port("type=udp,host=127.0.0.1,port=%d" % device.getsockname()[1])
        try:
            port.write(b"ping")
            device.settimeout(DEADLINE)
            _, mine = device.recvfrom(100)
            stranger.sendto(b"not the device", mine)
            device.sendto(b"pong", mine)
            assert port.read(100, timeout=DEADLINE) == b"pong"
            assert port.read(100, timeout=0) == b""
        finally:
            port.close()


def test_record_forwards_and_records_empty_datagrams_both_ways(tmp_path):
    out = tmp_path / "udp.wtape"
    device = EchoDevice()
    with device.socket, udp_socket() as driver:
        handle = bridge.record(device.options, out, udp="127.0.0.1:0", quiet=True)
        where = address_of(handle.address)
        driver.sendto(b"", where)
        assert device.answer_one() == b""
        assert receive(driver, 1) == [b""]
        driver.sendto(b"after", where)
        assert device.answer_one() == b"after"
        assert receive(driver, 1) == [b"AFTER"]
        handle.stop()
        assert handle.wait(DEADLINE)
        assert handle.result().ok
    records = read_records(out)
    assert [r.data for r in records if r.kind == "tx"] == [b"", b"after"]
    assert [r.data for r in records if r.kind == "rx"] == [b"", b"AFTER"]


# --- replay --udp --peer: served is what the peer took -------------------------------------


STREAM = [
    ("open", 0, b"{}"),
    ("rx", 1_000_000, b"scan 0"),
    ("rx", 2_000_000, b"scan 1"),
    ("rx", 3_000_000, b"scan 2"),
    ("close", 4_000_000, b""),
]
SCANS = [data for kind, _, data in STREAM if kind == "rx"]


def test_replay_to_a_peer_nobody_listens_at_exits_1_naming_the_peer(session_file):
    path = session_file(STREAM, port_type="udp")
    port = free_udp_port()
    child = start_cli("replay", str(path), "--udp", "127.0.0.1:0",
                      "--peer", "127.0.0.1:%d" % port, "--timing", "none")
    stderr = StderrLines(child)
    stderr.wait_for(r"refused a datagram")
    status, err = stop(child, stderr)
    assert status == 1, err
    assert re.search(r"the peer 127\.0\.0\.1:%d refused every datagram" % port, err), err
    assert re.search(r"\b[1-9]\d* datagrams? refused by the peer", err), err  # the summary


def ipv6_loopback_works():
    try:
        with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as sock:
            sock.bind(("::1", 0))
        return True
    except OSError:
        return False


@pytest.mark.skipif(not ipv6_loopback_works(), reason="no IPv6 loopback")
def test_an_ipv6_peer_that_binds_late_gets_the_recording_from_its_start(session_file):
    path = session_file(STREAM, port_type="udp")
    with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as sock:
        sock.bind(("::1", 0))
        port = sock.getsockname()[1]
    child = start_cli("replay", str(path), "--udp", "[::1]:0",
                      "--peer", "[::1]:%d" % port, "--timing", "none")
    stderr = StderrLines(child)
    try:
        stderr.wait_for(r"refused a datagram")
        with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as late:
            late.bind(("::1", port))
            got = receive(late, len(SCANS))
    finally:
        status, err = stop(child, stderr)
    assert got == SCANS
    assert status == 0, err


def test_a_peer_that_binds_late_gets_the_recording_from_its_start(session_file):
    path = session_file(STREAM, port_type="udp")
    port = free_udp_port()
    child = start_cli("replay", str(path), "--udp", "127.0.0.1:0",
                      "--peer", "127.0.0.1:%d" % port, "--timing", "none")
    stderr = StderrLines(child)
    try:
        stderr.wait_for(r"refused a datagram")
        with udp_socket(port) as late:
            got = receive(late, len(SCANS))
            stderr.wait_for(r"took a datagram")
    finally:
        status, err = stop(child, stderr)
    assert got == SCANS
    assert status == 0, err
