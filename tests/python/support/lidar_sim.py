"""A simulated LiDAR of two ports, as many are (issue 25): a TCP command
port, and a UDP data stream that starts only after the command ``START\\n``
and goes to a set destination (where the driver listens, or a proxy in
between). ``LidarDriver`` is its client: it records when it sent START and
when each datagram came, so a test asserts on those events."""

import select
import socket
import threading
import time

# How often the LiDAR sends a data datagram once started (seconds).
DATA_PERIOD_S = 0.02


class Lidar:
    """The device: TCP command port at ``command_port`` (``options``), data
    datagrams ``SCAN n`` to `destination` (host, port) after START."""

    def __init__(self, destination):
        self.destination = destination
        self._server = socket.socket()
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._server.bind(("127.0.0.1", 0))
        self._server.listen(1)
        self.command_port = self._server.getsockname()[1]
        self.options = f"type=tcp,host=127.0.0.1,port={self.command_port}"
        self.started = threading.Event()
        self._stop = threading.Event()
        self._data = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._threads = [threading.Thread(target=self._serve, daemon=True),
                         threading.Thread(target=self._stream, daemon=True)]

    def _serve(self):
        while not self._stop.is_set():
            if not select.select([self._server], [], [], 0.05)[0]:
                continue
            connection, _ = self._server.accept()
            with connection:
                received = b""
                while not self._stop.is_set():
                    if not select.select([connection], [], [], 0.05)[0]:
                        continue
                    chunk = connection.recv(256)
                    if not chunk:
                        break
                    received += chunk
                    while b"\n" in received:
                        line, received = received.split(b"\n", 1)
                        if line == b"START":
                            self.started.set()
                            connection.sendall(b"OK\n")

    def _stream(self):
        if not self._wait_started():
            return
        count = 0
        while not self._stop.wait(DATA_PERIOD_S):
            self._data.sendto(b"SCAN %d" % count, self.destination)
            count += 1

    def _wait_started(self):
        while not self._stop.is_set():
            if self.started.wait(0.05):
                return True
        return False

    def __enter__(self):
        for thread in self._threads:
            thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        for thread in self._threads:
            thread.join(10.0)
        self._server.close()
        self._data.close()


class LidarDriver:
    """The client: binds its data port (``data_port``), connects to the
    command port, watches the data port for `quiet_s` (a datagram then came
    before START: it is kept in ``early``), sends START and reads `count`
    datagrams. ``start_sent`` and each of ``data`` (time, datagram) are
    time.monotonic() stamps."""

    def __init__(self):
        self._data = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._data.bind(("127.0.0.1", 0))
        self.data_port = self._data.getsockname()[1]
        self.early = []
        self.data = []
        self.start_sent = None
        self.answer = b""

    def run(self, command_address, count, quiet_s, deadline_s):
        with socket.create_connection(command_address, timeout=deadline_s) as command:
            end = time.monotonic() + quiet_s
            while time.monotonic() < end:
                if select.select([self._data], [], [], end - time.monotonic())[0]:
                    self.early.append((time.monotonic(), self._data.recv(65535)))
            self.start_sent = time.monotonic()
            command.sendall(b"START\n")
            while not self.answer.endswith(b"\n"):
                chunk = command.recv(64)
                if not chunk:
                    break
                self.answer += chunk
            self._data.settimeout(deadline_s)
            while len(self.data) < count:
                datagram = self._data.recv(65535)
                self.data.append((time.monotonic(), datagram))

    def close(self):
        self._data.close()
