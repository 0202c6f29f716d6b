"""wiretape's exceptions from Python (classes, bases, attributes) and the
Port across threads: close() wakes a blocked read, the GIL is released while
a call blocks, Ctrl-C interrupts a blocked read or write."""

import errno
import os
import pickle
import select
import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest

import wiretape


# --- the classes ---------------------------------------------------------------


def test_exception_classes_derive_from_the_builtins_python_users_catch():
    assert issubclass(wiretape.OptionError, ValueError)
    assert issubclass(wiretape.PortError, OSError)
    assert issubclass(wiretape.PortClosed, wiretape.PortError)
    assert issubclass(wiretape.ReplayMismatch, AssertionError)
    assert issubclass(wiretape.SessionError, ValueError)
    for cls in (wiretape.OptionError, wiretape.PortError, wiretape.PortClosed,
                wiretape.ReplayMismatch, wiretape.SessionError):
        assert cls.__module__ == "wiretape"
        assert cls.__doc__


def test_option_error_names_the_key():
    with pytest.raises(wiretape.OptionError) as raised:
        wiretape.open_port("type=loopback,bogus_key=1")
    assert raised.value.key == "bogus_key"
    assert "bogus_key" in str(raised.value)


def test_option_error_for_a_bad_value_lists_what_is_valid():
    with pytest.raises(wiretape.OptionError) as raised:
        wiretape.open_port("type=teleport")
    assert raised.value.key == "type"
    assert "loopback" in str(raised.value)


def test_port_error_carries_errno_and_a_message_without_noise(loopback):
    with pytest.raises(wiretape.PortError) as raised:
        loopback.set_baud(9600)
    error = raised.value
    assert error.errno == errno.ENOTSUP
    assert str(error).startswith("set_baud is not supported by loopback")
    assert not isinstance(error, wiretape.PortClosed)


def test_port_closed_has_no_misleading_errno(loopback):
    loopback.close()
    with pytest.raises(wiretape.PortClosed) as raised:
        loopback.read(1)
    assert raised.value.errno is None
    assert "closed" in str(raised.value)
    assert not str(raised.value).endswith("Success")


def test_a_device_that_goes_away_raises_port_closed(tmp_path):
    import socket

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = wiretape.open_port(f"type=tcp,port={server.getsockname()[1]},timeout=5")
    peer, _ = server.accept()
    server.close()
    peer.close()
    with pytest.raises(wiretape.PortClosed):
        port.read(1)
    port.close()


def test_replay_mismatch_carries_offset_time_and_exchange(session_file):
    path = session_file([("tx", 1_000_000, b"PING\n"), ("rx", 2_000_000, b"PONG\n")])
    with wiretape.open_port(f"type=replay,file={path},timing=none,timeout=2,unused=ignore") as port:
        with pytest.raises(wiretape.ReplayMismatch) as raised:
            port.write(b"PANG\n")
            port.read(5)
    error = raised.value
    assert isinstance(error, AssertionError)
    assert error.tx_offset == 1
    assert isinstance(error.session_time_ns, int)
    assert error.exchange == 0  # the mismatch is in the first exchange
    assert "|ANG.|" in str(error) and "|ING.|" in str(error)  # actual and expected


def test_replay_mismatch_in_request_mode_names_the_exchange(session_file):
    path = session_file([("tx", 1_000_000, b"A?\n"), ("rx", 2_000_000, b"a\n"),
                         ("tx", 3_000_000, b"B?\n"), ("rx", 4_000_000, b"b\n")])
    options = f"type=replay,file={path},timing=none,match=request,timeout=2,unused=ignore"
    with wiretape.open_port(options) as port:
        port.write(b"A?\n")
        assert port.read_exactly(2) == b"a\n"
        with pytest.raises(wiretape.ReplayMismatch) as raised:
            port.write(b"Z?\n")
            port.read(2)
    assert isinstance(raised.value.exchange, int)


def test_session_error_carries_the_offset(tmp_path):
    path = tmp_path / "not-a-session.wtape"
    path.write_bytes(b"this is not a session file")
    with pytest.raises(wiretape.SessionError) as raised:
        wiretape.SessionReader(str(path))
    assert raised.value.offset == 0
    assert str(path) in str(raised.value)


def test_exceptions_survive_pickling_with_their_attributes():
    cases = [
        wiretape.OptionError("bad", "baud"),
        wiretape.PortError(errno.EIO, "dev: Input/output error"),
        wiretape.PortClosed(None, "dev: gone"),
        wiretape.ReplayMismatch("report", 12, 3400, 2),
        wiretape.SessionError("broken", 99),
    ]
    for error in cases:
        copy = pickle.loads(pickle.dumps(error))
        assert type(copy) is type(error)
        assert str(copy) == str(error)
        for name in ("key", "errno", "tx_offset", "session_time_ns", "exchange", "offset"):
            if hasattr(error, name):
                assert getattr(copy, name) == getattr(error, name)


# --- threads -----------------------------------------------------------------------


def _blocked_reader(port, outcome, started, **kwargs):
    started.set()
    try:
        outcome["data"] = port.read(1, **kwargs)
    except BaseException as error:  # noqa: B902 - the test inspects it
        outcome["error"] = error


@pytest.mark.parametrize("kind", ["loopback", "pty", "tcp"])
def test_close_from_another_thread_wakes_a_blocked_read(kind, endpoint_factory):
    endpoint = endpoint_factory(kind)
    port = endpoint.port
    outcome, started = {}, threading.Event()
    thread = threading.Thread(target=_blocked_reader, args=(port, outcome, started),
                              kwargs={"timeout": None})
    thread.start()
    assert started.wait(5)
    port.close()
    thread.join(5)
    assert not thread.is_alive(), "close() did not wake the blocked read"
    assert isinstance(outcome.get("error"), wiretape.PortClosed), outcome
    endpoint.close()


def test_a_blocked_read_releases_the_gil(loopback):
    """If read() held the GIL, the main thread could not write until the
    reader's 5 s timeout expired, and the reader would get b""."""
    outcome, started = {}, threading.Event()
    thread = threading.Thread(target=_blocked_reader, args=(loopback, outcome, started),
                              kwargs={"timeout": 5})
    thread.start()
    assert started.wait(5)
    began = time.monotonic()
    loopback.write(b"!")
    thread.join(5)
    assert outcome.get("data") == b"!"
    assert time.monotonic() - began < 4


def test_one_reader_and_one_writer_at_once(loopback):
    payload = bytes(range(256)) * 200
    received = []

    def reader():
        received.append(loopback.read_exactly(len(payload), timeout=10))

    thread = threading.Thread(target=reader)
    thread.start()
    for offset in range(0, len(payload), 1000):
        loopback.write_all(payload[offset:offset + 1000])
    thread.join(10)
    assert received == [payload]


def interrupt_each_call(setup, calls):
    """Runs `calls` (Python expressions over `port`, made by `setup`) one by
    one in a child interpreter; each must end in KeyboardInterrupt.

    A SIGINT can land before a call blocks, or between calls, so the parent
    keeps sending SIGINT until the child reports that the call was
    interrupted, and the child turns SIGINT into KeyboardInterrupt only while
    a call is under test (once per call): a signal that lands elsewhere is
    ignored, and the next one interrupts."""
    script = textwrap.dedent(setup) + textwrap.dedent(f"""
        import signal, sys
        armed = False

        def on_sigint(signum, frame):
            global armed
            if armed:
                armed = False
                raise KeyboardInterrupt

        signal.signal(signal.SIGINT, on_sigint)
        for call in [{", ".join(f"lambda: {call}" for call in calls)}]:
            print("ready", flush=True)
            try:
                armed = True
                call()
                sys.exit(1)
            except KeyboardInterrupt:
                pass
            print("interrupted", flush=True)
        print("done", flush=True)
    """)
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE)
    lines = _LineReader(child.stdout.fileno())
    deadline = time.monotonic() + 60
    try:
        for _ in calls:
            assert lines.next(deadline) == "ready"
            # Each SIGINT either interrupts the call or is ignored; the
            # child's report is the event waited for, a resend every 0.1 s.
            line = None
            while line is None and time.monotonic() < deadline:
                child.send_signal(signal.SIGINT)
                line = lines.next(min(deadline, time.monotonic() + 0.1), or_none=True)
            assert line == "interrupted"
        assert lines.next(deadline) == "done"
        child.wait(timeout=max(1.0, deadline - time.monotonic()))
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        err = child.stderr.read().decode(errors="replace")
        child.stdout.close()
        child.stderr.close()
    assert child.returncode == 0, err


class _LineReader:
    """Lines from a pipe, each awaited until a deadline (select, no sleep)."""

    def __init__(self, fd):
        self._fd = fd
        self._pending = b""

    def next(self, deadline, or_none=False):
        while b"\n" not in self._pending:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([self._fd], [], [], max(0.0, left))
            if not ready:
                if or_none:
                    return None
                raise AssertionError(f"no line from the child in time; got {self._pending!r}")
            chunk = os.read(self._fd, 4096)
            if not chunk:
                raise AssertionError(f"the child ended early; got {self._pending!r}")
            self._pending += chunk
        line, self._pending = self._pending.split(b"\n", 1)
        return line.decode().strip()


def test_ctrl_c_interrupts_blocked_reads():
    interrupt_each_call("""
        import wiretape
        port = wiretape.open_port("type=loopback")
    """, ["port.read(1, timeout=None)",
          "port.read_until(b'\\n', timeout=None)",
          "port.read_line(timeout=None)",
          "port.skip_until(b'\\n', timeout=None)",
          "port.skip(5, timeout=None)",
          "port.wait_readable(None)",
          "port.read_exactly(5, timeout=60)"])


def test_ctrl_c_interrupts_a_write_to_a_device_that_does_not_drain():
    # A pty whose other side nobody reads: once its buffer is full, writes
    # block for as long as the port's timeout (None: forever).
    interrupt_each_call("""
        import os, wiretape
        master, terminal = os.openpty()
        port = wiretape.open_port("type=serial,device=" + os.ttyname(terminal))
        port.timeout = None
    """, ["port.write_all(b'x' * (16 << 20))", "port.write(b'y')"])
