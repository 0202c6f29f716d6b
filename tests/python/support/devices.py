"""Helpers for the Python tests: ``wait_until``, the one way a test waits
for an event, and a device on TCP for the tests of the programs that sit
between a device and its driver (record, serve): a small server on
127.0.0.1 that the program under test connects to as it would to a real
device."""

import os
import re
import select
import signal
import socket
import struct
import subprocess
import sys
import threading
import time

# Generous: a loaded CI machine must not fail a test that waits for an event.
DEADLINE_S = 5.0
# How long wait_until pauses between two looks at its condition.
_WAIT_POLL_S = 0.005

# How long the device's loop waits in select before looking at its events
# (stop, drop, accepting) again: bounds how soon it reacts to them.
_POLL_S = 0.05
# How long close() waits for the device's thread to end.
_JOIN_S = 10.0
# SO_LINGER on, 0 s: closing sends a reset, as a device that vanished would.
_RESET_ON_CLOSE = struct.pack("ii", 1, 0)


def wait_until(condition, deadline_s=DEADLINE_S, what="the condition"):
    """Polls `condition` until it is true; raises AssertionError naming
    `what` if `deadline_s` passes first.

    Between checks it selects on nothing for a short while (never a blind
    sleep of the whole deadline). `what` says what is awaited ("the client's
    disconnect to be logged"); it may be a callable returning that text,
    called only on failure, so the message can show the state at the
    deadline (e.g. the messages logged so far). The condition may itself
    raise (an assert) to give up early when the awaited event can no
    longer happen."""
    end = time.monotonic() + deadline_s
    while not condition():
        if time.monotonic() > end:
            awaited = what() if callable(what) else what
            raise AssertionError(f"timed out after {deadline_s}s waiting for {awaited}")
        select.select([], [], [], _WAIT_POLL_S)


class TcpDevice:
    """A device on TCP, one connection at a time.

    By default it answers each chunk it receives with ``respond(chunk)``
    (upper case unless told otherwise; ``respond=None`` answers nothing).
    With ``stream=True`` it sends numbered lines (``b"line 00000000\\n"``, ...)
    without stopping and answers nothing.

    ``received`` holds every byte it received, ``connections`` counts the
    connections it accepted. ``drop()`` resets the current connection (the
    device goes away). While the ``accepting`` event is clear it takes no
    new connection (they wait in the listen backlog). ``options`` is the
    wiretape option string that reaches it. Use it as a context manager, or
    call ``close()``."""

    def __init__(self, respond=bytes.upper, stream=False):
        self.server = socket.socket()
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(4)
        self.port = self.server.getsockname()[1]
        self.options = f"type=tcp,port={self.port}"
        self.respond = respond
        self.stream = stream
        self.received = bytearray()
        self.connections = 0
        self.accepting = threading.Event()
        self.accepting.set()
        self._drop = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    def drop(self):
        """Resets the current connection (or the next one, if none is open)."""
        self._drop.set()

    def close(self):
        self._stop.set()
        self._thread.join(_JOIN_S)
        self.server.close()

    def _run(self):
        while not self._stop.is_set():
            ready, _, _ = select.select([self.server], [], [], _POLL_S)
            if not ready or not self.accepting.is_set():
                continue
            conn, _ = self.server.accept()
            self.connections += 1
            with conn:
                self._serve(conn)
                if self._drop.is_set():
                    conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, _RESET_ON_CLOSE)
                    self._drop.clear()

    def _serve(self, conn):
        line = 0
        unsent = b""  # of the current line: a send may take only part of it
        conn.setblocking(False)
        while not self._stop.is_set() and not self._drop.is_set():
            if self.stream:
                if not unsent:
                    unsent = b"line %08d\n" % line
                    line += 1
                try:
                    unsent = unsent[conn.send(unsent):]
                except BlockingIOError:
                    select.select([], [conn], [], _POLL_S)
                except OSError:
                    return
            ready, _, _ = select.select([conn], [], [], 0 if self.stream else _POLL_S)
            if not ready:
                continue
            try:
                data = conn.recv(65536)
            except OSError:
                return
            if not data:
                return
            self.received += data
            if self.respond and not self.stream:
                conn.setblocking(True)
                try:
                    conn.sendall(self.respond(data))
                except OSError:
                    return
                conn.setblocking(False)


def read_exactly(sock, count):
    """`count` bytes from socket `sock`, or fewer if it closes first (its
    own timeout bounds each wait)."""
    data = bytearray()
    while len(data) < count:
        chunk = sock.recv(min(count - len(data), 1 << 20))
        if not chunk:
            break
        data += chunk
    return bytes(data)


def read_to_end(sock):
    """Everything socket `sock` receives until the peer closes it."""
    data = bytearray()
    while True:
        chunk = sock.recv(4096)
        if not chunk:
            return bytes(data)
        data += chunk


def skip_unless_serial_opens_on_a_pty():
    """Skips the calling test, saying why, when a serial port cannot be
    opened on a pseudo-terminal here."""
    import pytest

    from wiretape import _core

    master, terminal = os.openpty()
    try:
        _core.open_port(f"type=serial,device={os.ttyname(terminal)},exclusive=false").close()
    except Exception as error:  # noqa: BLE001 - any failure means "not usable here"
        pytest.skip(f"serial ports cannot be opened here: {error}")
    finally:
        os.close(master)
        os.close(terminal)


# --- the command line as a child process ----------------------------------------------

def start_cli(*argv) -> subprocess.Popen:
    """`wiretape ARGV...` as a child process, its output piped."""
    return subprocess.Popen([sys.executable, "-m", "wiretape.cli", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def announced_address(child: subprocess.Popen, transport: str):
    """(host, port) that a bridge command announces on stderr for its
    clients ("clients use tcp HOST:PORT"); the child is killed if it never
    says."""
    lines = []
    for _ in range(20):
        line = child.stderr.readline()
        if not line:
            break
        lines.append(line)
        match = re.search(rf"clients use {transport} (\S+):(\d+)", line)
        if match:
            return match.group(1), int(match.group(2))
    child.kill()
    raise AssertionError("no address announced: " + "".join(lines) + child.stderr.read())


def interrupt(child: subprocess.Popen, deadline: float = 15.0):
    """Ctrl-C, then (exit status, stdout, stderr); a child still running
    after `deadline` is killed (its status is then -SIGKILL)."""
    if child.poll() is None:
        child.send_signal(signal.SIGINT)
    try:
        out, err = child.communicate(timeout=deadline)
    except subprocess.TimeoutExpired:
        child.kill()
        out, err = child.communicate()
    return child.returncode, out, err
