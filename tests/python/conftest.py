"""Fixtures shared by the Python tests: ports with a "device side" the test
controls, and helpers that wait on events with generous deadlines. The
real recordings under tests/data/flexiport are found by real_recordings.py,
which the Hokuyo example's tests use too."""

import os
import pathlib
import select
import signal
import socket
import sys
import time

import pytest

import wiretape

# The tests' helpers (support/) are importable from every folder of tests.
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent / "support"))

from devices import DEADLINE_S, wait_until

# The tests play a terminal's Ctrl-C on the commands they start. A suite run
# as a shell's background job (`make test &`) inherits SIGINT ignored, its
# children too, and wiretape keeps an ignored SIGINT ignored (as a background
# job should): Ctrl-C tests would then wait out their deadlines and fail.
# Handled here, the children start with the default action instead.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


class Endpoint:
    """A port under test and the device side the test drives.

    ``feed(data)`` makes `data` arrive at the port (the device sends it);
    ``collect(n)`` returns what the port wrote to the device (n bytes, or
    what came before the deadline)."""

    def __init__(self, kind, port, feed, collect, cleanup=()):
        self.kind = kind
        self.port = port
        self._feed = feed
        self._collect = collect
        self._cleanup = list(cleanup)

    def feed(self, data):
        self._feed(data)

    def collect(self, count, deadline_s=DEADLINE_S):
        return self._collect(count, deadline_s)

    def wait_in_waiting(self, count):
        """Waits until the port has `count` bytes ready (the device's bytes
        may cross a pty or socket in pieces)."""
        wait_until(lambda: self.port.in_waiting >= count, what=f"{count} bytes at the port")

    def close(self):
        if self.port.is_open:
            self.port.close()
        cleanup, self._cleanup = self._cleanup, []
        for action in cleanup:
            action()


def _read_fd(fd, count, deadline_s):
    data = b""
    end = time.monotonic() + deadline_s
    while len(data) < count:
        left = end - time.monotonic()
        if left <= 0:
            break
        ready, _, _ = select.select([fd], [], [], left)
        if ready:
            chunk = os.read(fd, count - len(data))
            if not chunk:
                break
            data += chunk
    return data


def _recv_socket(sock, count, deadline_s):
    data = b""
    end = time.monotonic() + deadline_s
    while len(data) < count:
        left = end - time.monotonic()
        if left <= 0:
            break
        ready, _, _ = select.select([sock], [], [], left)
        if ready:
            chunk = sock.recv(count - len(data))
            if not chunk:
                break
            data += chunk
    return data


def make_loopback(timeout="1"):
    port = wiretape.open_port(f"type=loopback,timeout={timeout}")
    # What a loopback is written comes back: the device side is the port.
    return Endpoint("loopback", port, feed=port.write_all,
                    collect=lambda n, d: port.read_exactly(n, timeout=d))


def make_pty(tmp_path, timeout="1"):
    link = tmp_path / "tty"
    port = wiretape.open_port(f"type=pty,link={link},timeout={timeout}")
    client = os.open(str(link), os.O_RDWR | os.O_NOCTTY)
    try:  # raw: no echo, no line discipline between the test and the port
        import termios
        import tty

        tty.setraw(client, termios.TCSANOW)
    except ImportError:  # pragma: no cover - POSIX only
        pass
    return Endpoint("pty", port, feed=lambda data: os.write(client, data),
                    collect=lambda n, d: _read_fd(client, n, d),
                    cleanup=[lambda: os.close(client)])


def make_tcp(timeout="1"):
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    number = server.getsockname()[1]
    port = wiretape.open_port(f"type=tcp,host=127.0.0.1,port={number},timeout={timeout}")
    server.settimeout(DEADLINE_S)
    peer, _ = server.accept()
    server.close()
    return Endpoint("tcp", port, feed=peer.sendall,
                    collect=lambda n, d: _recv_socket(peer, n, d),
                    cleanup=[peer.close])


STREAM_KINDS = ["loopback", "pty", "tcp"]


@pytest.fixture(params=STREAM_KINDS)
def endpoint(request, tmp_path):
    """A byte-stream port of each kind (timeout 1 s) with its device side."""
    if request.param == "loopback":
        made = make_loopback()
    elif request.param == "pty":
        made = make_pty(tmp_path)
    else:
        made = make_tcp()
    yield made
    made.close()


@pytest.fixture
def loopback():
    """A loopback port with a 1 s timeout, closed after the test."""
    port = wiretape.open_port("type=loopback,timeout=1")
    yield port
    if port.is_open:
        port.close()


def write_session(path, records, port_type="serial", capture="client", port_options=None):
    """Writes a session file of (kind, t_ns, data) records."""
    with wiretape.SessionWriter(str(path), port_type=port_type, capture=capture,
                                port_options=port_options or f"type={port_type}") as writer:
        for kind, t_ns, data in records:
            writer.write(kind, t_ns, data)
    return path


@pytest.fixture
def session_file(tmp_path):
    """``session_file(records, name="s.wtape", **header)``: writes a session
    of (kind, t_ns, data) records into tmp_path and returns its path."""

    def make(records, name="s.wtape", **header):
        return write_session(tmp_path / name, records, **header)

    return make


@pytest.fixture
def device_recording(session_file):
    """``device_recording(records, name)``: a proxy's recording of a serial
    device (capture=wire) that starts with its open event, as a virtual
    device replays it."""

    def make(records, name="recording.wtape"):
        return session_file([("open", 0, b"{}"), *records], name=name, capture="wire",
                            port_options="type=serial,device=/dev/ttyX")

    return make


@pytest.fixture
def endpoint_factory(tmp_path):
    """``endpoint_factory(kind)``: an Endpoint of that kind ("loopback",
    "pty", "tcp"), closed after the test."""
    made = []

    def make(kind, timeout="1"):
        if kind == "loopback":
            endpoint = make_loopback(timeout)
        elif kind == "pty":
            endpoint = make_pty(tmp_path, timeout)
        elif kind == "tcp":
            endpoint = make_tcp(timeout)
        else:
            raise ValueError(f"unknown endpoint kind {kind!r}")
        made.append(endpoint)
        return endpoint

    yield make
    for endpoint in made:
        endpoint.close()


# The lab tools' plugins that pyproject's addopts turn off (pytest-embedded,
# which the test extra installs; labgrid): the runs of pytester have their
# own config, so they would load them, with pytest-embedded's multiprocessing
# lock in this very process. Off there too (pytester clears PYTEST_ADDOPTS
# when it starts, hence after it).
LAB_PLUGINS_OFF = "-p no:pytest_embedded -p no:labgrid"


@pytest.fixture
def pytester(pytester, monkeypatch):
    monkeypatch.setenv("PYTEST_ADDOPTS", LAB_PLUGINS_OFF)
    return pytester
