"""wiretape serve under pressure: what a server holds for clients that never
read is bounded (RFC 2217 answers, monitors' data, the number of monitors),
running out of file descriptors does not make it spin, pyserial's RFC 2217
client works as a monitor, and a device loss never turns into a client that
is accepted and then cut off.

The memory and CPU figures are measured on a server in a child process
(`python -m wiretape.cli serve`), from /proc."""

import os
import re
import resource
import select
import socket
import struct
import subprocess
import sys
import threading
import time

import pytest
import serial

from wiretape import bridge, cli

from devices import TcpDevice, read_exactly, read_to_end, wait_until

DEADLINE = 10.0
MIB = 1 << 20

# pyserial's rfc2217 client uses threading names deprecated in Python 3.10.
pytestmark = pytest.mark.filterwarnings("ignore:set.*is deprecated:DeprecationWarning")

# A SET-BAUDRATE request (IAC SB COM-PORT-OPTION 1 <baud> IAC SE) and the
# start of the server's answer to it (command + 100).
SET_BAUDRATE_115200 = b"\xff\xfa\x2c\x01" + struct.pack("!I", 115200) + b"\xff\xf0"
BAUDRATE_ANSWER = b"\xff\xfa\x2c\x65"


class ServeProcess:
    """`wiretape serve ARGS` in a child process; its stderr lines are kept
    (`lines`) and can be awaited (`wait_for_line`)."""

    def __init__(self, *args):
        self.child = subprocess.Popen(
            [sys.executable, "-m", "wiretape.cli", "serve", *args],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self.lines = []
        self._changed = threading.Condition()
        self._reader = threading.Thread(target=self._read_stderr, daemon=True)
        self._reader.start()
        match = self.wait_for_line(r"clients use tcp (\S+):(\d+)")
        self.address = (match.group(1), int(match.group(2)))

    def _read_stderr(self):
        for line in self.child.stderr:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self.lines.append(None)  # the end
            self._changed.notify_all()

    def count(self, pattern):
        with self._changed:
            return sum(1 for line in self.lines if line and re.search(pattern, line))

    def wait_for_line(self, pattern, times=1, deadline=DEADLINE):
        """The last of `times` lines that match `pattern`."""
        end = time.monotonic() + deadline
        with self._changed:
            while True:
                found = [m for m in (re.search(pattern, line) for line in self.lines if line) if m]
                if len(found) >= times:
                    return found[times - 1]
                left = end - time.monotonic()
                if left <= 0 or None in self.lines:
                    raise AssertionError(
                        f"no {times} line(s) matching {pattern!r} from the server: "
                        + "\n".join(str(line) for line in self.lines))
                self._changed.wait(left)

    def rss(self):
        with open(f"/proc/{self.child.pid}/status") as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
        raise AssertionError("no VmRSS in /proc status")

    def cpu_seconds(self):
        with open(f"/proc/{self.child.pid}/stat") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
        # utime and stime are fields 14 and 15 of stat(5); fields[0] is 3.
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def open_descriptors(self):
        return len(os.listdir(f"/proc/{self.child.pid}/fd"))

    def connect(self, receive_buffer=None):
        sock = socket.socket()
        if receive_buffer:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
        sock.settimeout(DEADLINE)
        sock.connect(self.address)
        return sock

    def stop(self):
        if self.child.poll() is None:
            self.child.send_signal(2)  # SIGINT: the CLI's Ctrl-C
        try:
            self.child.wait(DEADLINE)
        except subprocess.TimeoutExpired:
            self.child.kill()
            self.child.wait()
        self._reader.join(DEADLINE)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def send_until_stalled(sock, block, total, stall_s=2.0):
    """Sends `block` repeatedly, up to `total` bytes, until the peer stops
    taking data for `stall_s`; returns the bytes sent."""
    sock.setblocking(False)
    sent = 0
    view = memoryview(block)
    offset = 0
    while sent < total:
        _, writable, _ = select.select([], [sock], [], stall_s)
        if not writable:
            break
        try:
            n = sock.send(view[offset:])
        except BlockingIOError:
            continue
        sent += n
        offset = (offset + n) % len(block)
    sock.settimeout(DEADLINE)
    return sent


def address_of(handle):
    host, port = handle.address.rsplit(":", 1)
    return host, int(port)


# --- what the server holds for clients that do not read ---------------------------------


def test_rfc2217_answers_for_a_client_that_never_reads_are_bounded():
    """A client that sends setting requests and never reads the answers is
    held back (the server stops reading it once 1 MiB of answers waits),
    and gets every answer once it reads: backpressure, not loss."""
    with ServeProcess("--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "--protocol", "rfc2217") as server:
        before = server.rss()
        with server.connect(receive_buffer=4096) as client:
            block = SET_BAUDRATE_115200 * 6000
            total = 16 * MIB
            sent = send_until_stalled(client, block, total=total)
            growth = server.rss() - before
            # Unbounded, the answers (as many bytes as the requests) pile up.
            assert growth < 4 * MIB, (f"the server grew by {growth / MIB:.1f} MiB "
                                      f"for {sent / MIB:.1f} MiB of requests")
            assert sent < total, "the server kept reading a client that never reads"
            requests = sent // len(SET_BAUDRATE_115200)
            greeting = b"\xff\xfb\x00\xff\xfd\x00"  # WILL BINARY, DO BINARY
            answers = read_exactly(client, len(greeting) + requests * 10)
        assert answers.startswith(greeting)
        assert answers.count(BAUDRATE_ANSWER) == requests


def test_monitors_beyond_the_limit_are_refused_with_a_message():
    with TcpDevice() as device:
        handle = bridge.serve(device.options, "127.0.0.1:0", shared=True, max_monitors=2,
                              quiet=True)
        try:
            address = address_of(handle)
            control = socket.create_connection(address, timeout=DEADLINE)
            monitors = [socket.create_connection(address, timeout=DEADLINE) for _ in range(2)]
            wait_until(lambda: handle.stats().clients_accepted == 3, DEADLINE,
                       what="the controller and two monitors to be accepted")
            with socket.create_connection(address, timeout=DEADLINE) as extra:
                refusal = read_to_end(extra)
            assert b"2 monitors are connected" in refusal
            assert b"--max-monitors" in refusal
            # The server counts and logs the refusal after it has ended the
            # connection, so the client can see the end first.
            wait_until(lambda: handle.stats().clients_refused == 1, DEADLINE,
                       what="the refusal to be counted")
            wait_until(lambda: any(m.startswith("refused client") and "monitors" in m
                                   for m in handle.messages()),
                       DEADLINE, what="the refusal to be logged")
            # A monitor that leaves makes room for another.
            monitors.pop().close()
            wait_until(lambda: sum("disconnected" in m for m in handle.messages()) == 1,
                       DEADLINE, what="the monitor's departure to be logged")
            monitors.append(socket.create_connection(address, timeout=DEADLINE))
            wait_until(lambda: handle.stats().clients_accepted == 4, DEADLINE,
                       what="a new monitor to be accepted")
            control.sendall(b"hi")
            assert read_exactly(control, 2) == b"HI"
            assert all(read_exactly(m, 2) == b"HI" for m in monitors)
            for sock in [control, *monitors]:
                sock.close()
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)


def test_max_monitors_needs_a_positive_count(capsys):
    with pytest.raises(ValueError, match="max_monitors"):
        bridge.serve("type=loopback", "127.0.0.1:0", shared=True, max_monitors=0, quiet=True)
    for argv, words in ((["--max-monitors", "4"], "give --shared too"),
                        (["--shared", "--max-monitors", "0"], "at least 1")):
        code = cli.main(["serve", "--device", "type=loopback", "--listen", "0", *argv])
        assert code == 2
        assert words in capsys.readouterr().err


def test_monitors_that_never_read_cost_a_bounded_amount():
    """40 monitors that never read, while the controller moves 8 MiB: at most
    16 (the default limit) are accepted, and each holds at most its 1 MiB
    queue."""
    connect_count = 40
    with ServeProcess("--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "--shared") as server:
        before = server.rss()
        control = server.connect()
        server.wait_for_line(r"client \S+ connected$")
        monitors = []
        for _ in range(connect_count):
            monitors.append(server.connect(receive_buffer=4096))
        server.wait_for_line(r"client \S+ connected \(read-only monitor\)|refused client",
                             times=connect_count)
        accepted = server.count(r"read-only monitor")
        assert accepted <= 16
        assert server.count(r"refused client .*monitors") == connect_count - accepted
        chunk = bytes(range(256)) * 256
        total = 8 * MIB
        sender = threading.Thread(target=lambda: [control.sendall(chunk)
                                                  for _ in range(total // len(chunk))])
        sender.start()
        assert len(read_exactly(control, total)) == total
        sender.join(DEADLINE)
        growth = server.rss() - before
        bound = (accepted + 2) * MIB * 1.25 + 4 * MIB
        assert growth < bound, (f"{accepted} monitors cost {growth / MIB:.1f} MiB "
                                f"(bound {bound / MIB:.1f} MiB)")
        for sock in [control, *monitors]:
            sock.close()


# --- out of file descriptors --------------------------------------------------------------


def test_out_of_file_descriptors_the_server_waits_instead_of_spinning():
    with ServeProcess("--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "--shared") as server:
        # Room for exactly three more descriptors: a controller and two
        # monitors; the next connections cannot be accepted.
        spare = 3
        limit = server.open_descriptors() + spare
        _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
        resource.prlimit(server.child.pid, resource.RLIMIT_NOFILE, (limit, hard))
        clients = [server.connect() for _ in range(spare)]
        server.wait_for_line(r"client \S+ connected", times=spare)
        waiting = [server.connect() for _ in range(2)]  # in the listen queue
        server.wait_for_line(r"cannot accept clients")
        start = server.cpu_seconds()
        window = 2.0
        select.select([], [], [], window)  # the measurement window
        used = server.cpu_seconds() - start
        # A spin takes a whole core (a share of one on a loaded machine); a
        # waiting server takes next to nothing.
        assert used < 0.1 * window, f"the server used {used:.2f} s of CPU in {window} s"
        assert server.count(r"cannot accept clients") == 1
        # A client that leaves frees a descriptor: the next one is served.
        clients.pop().close()
        server.wait_for_line(r"accepting clients again")
        server.wait_for_line(r"client \S+ connected", times=spare + 1)
        for sock in clients + waiting:
            sock.close()


# --- pyserial's rfc2217 client on a shared server -----------------------------------------


def test_pyserial_rfc2217_clients_control_and_monitor_a_shared_device():
    """The controller sets 115200; a monitor opens with pyserial's defaults
    (9600): its requests are acknowledged, not applied, so it opens and
    watches."""
    with TcpDevice() as device:
        handle = bridge.serve(device.options, "127.0.0.1:0", protocol="rfc2217", shared=True,
                              quiet=True)
        url = "rfc2217://" + handle.address
        try:
            with serial.serial_for_url(url, baudrate=115200, timeout=DEADLINE) as control:
                with serial.serial_for_url(url, timeout=DEADLINE) as monitor:
                    assert monitor.baudrate == 9600
                    monitor.dtr = False
                    monitor.reset_input_buffer()
                    control.write(b"hello\n")
                    assert control.read_until(b"\n") == b"HELLO\n"
                    assert monitor.read_until(b"\n") == b"HELLO\n"
                    monitor.write(b"ignored\n")
                control.baudrate = 57600
                control.write(b"again\n")
                assert control.read_until(b"\n") == b"AGAIN\n"
            assert bytes(device.received) == b"hello\nagain\n"
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)
        result = handle.result()
        assert result.ok, result
        # Only the controller's settings are applied.
        assert result.stats.settings_changes == 2


# --- device loss ----------------------------------------------------------------------------


def test_a_client_that_arrives_while_the_device_is_away_is_served_once_it_is_back():
    with TcpDevice() as device:
        handle = bridge.serve(device.options, "127.0.0.1:0", reopen=True, quiet=True)
        try:
            address = address_of(handle)
            with socket.create_connection(address, timeout=DEADLINE) as first:
                first.sendall(b"one")
                assert read_exactly(first, 3) == b"ONE"
                device.accepting.clear()
                device.drop()
                assert read_to_end(first) == b""
            wait_until(lambda: handle.stats().device_losses == 1, DEADLINE,
                       what="the device loss to be counted")
            # A driver connects and talks at once, while the device is away.
            with socket.create_connection(address, timeout=DEADLINE) as second:
                second.sendall(b"two")
                device.accepting.set()
                assert read_exactly(second, 3) == b"TWO"
            assert handle.stats().clients_refused == 0
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)


def test_a_device_lost_while_no_client_is_connected_is_noticed_at_once():
    """The loss is seen without a client, so the next client is not
    accepted only to be cut off when the server finds the device gone."""
    with TcpDevice() as device:
        handle = bridge.serve(device.options, "127.0.0.1:0", reopen=True, quiet=True)
        try:
            wait_until(lambda: device.connections == 1, DEADLINE,
                       what="the server to open the device")
            device.accepting.clear()
            device.drop()
            wait_until(lambda: handle.stats().device_losses == 1, DEADLINE,
                       what="the device loss to be noticed without a client")
            with socket.create_connection(address_of(handle), timeout=DEADLINE) as client:
                client.sendall(b"hello")
                device.accepting.set()
                assert read_exactly(client, 5) == b"HELLO"
            assert handle.stats().clients_refused == 0
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)
