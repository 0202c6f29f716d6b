"""wiretape replay --pty/--listen: a recording becomes a virtual device that
any program opens (pyserial on the pty, a socket over TCP). A client that
reconnects continues the session (restart starts it over); a client that
diverges gets the mismatch report as the result."""

import socket

import pytest
import serial

from wiretape import _core, bridge

from devices import wait_until

DEADLINE = 10.0
EXCHANGES = [(b"PING\n", b"PONG\n"), (b"ID?\n", b"DEV-1\n"), (b"T?\n", b"+21.5C\n")]


@pytest.fixture
def session(tmp_path):
    path = tmp_path / "device.wtape"
    writer = _core.SessionWriter(str(path), capture="wire",
                                 port_options="type=serial,device=/dev/ttyX", port_type="serial")
    writer.write("open", 0, b"{}")
    t = 1_000_000
    for request, answer in EXCHANGES:
        writer.write("tx", t, request)
        writer.write("rx", t + 500_000, answer)
        t += 1_000_000
    writer.close()
    return path


def read_line(port):
    line = port.read_until(b"\n")
    return line


def recv_line(sock):
    data = bytearray()
    while not data.endswith(b"\n"):
        chunk = sock.recv(1)
        if not chunk:
            break
        data += chunk
    return bytes(data)


def connect(handle):
    host, port = handle.address.rsplit(":", 1)
    return socket.create_connection((host, int(port)), timeout=DEADLINE)


def finish(handle):
    handle.stop()
    assert handle.wait(DEADLINE)
    return handle.result()


def test_virtual_device_on_a_pty_with_pyserial(session, tmp_path):
    link = tmp_path / "ttyReplay"
    handle = bridge.serve_replay(session, pty=str(link), replay_options="timing=none", quiet=True)
    try:
        with serial.Serial(str(link), 115200, timeout=DEADLINE) as client:
            for request, answer in EXCHANGES:
                client.write(request)
                assert read_line(client) == answer
    finally:
        result = finish(handle)
    assert result.ok, result
    assert result.outcome == "stopped"


def test_reopening_the_pty_continues_the_session(session):
    handle = bridge.serve_replay(session, pty=True, replay_options="timing=none", quiet=True)
    try:
        for request, answer in EXCHANGES:
            with serial.Serial(handle.pty_path, 9600, timeout=DEADLINE) as client:
                client.write(request)
                assert read_line(client) == answer
    finally:
        assert finish(handle).ok


def client_left(handle):
    """The last message the server logged is a client's disconnect."""
    return any("disconnected" in m for m in handle.messages()[-1:])


def test_virtual_device_over_tcp_continues_across_reconnects(session):
    handle = bridge.serve_replay(session, listen="127.0.0.1:0",
                                 replay_options="timing=causal", quiet=True)
    try:
        for request, answer in EXCHANGES:
            with connect(handle) as client:
                client.sendall(request)
                assert recv_line(client) == answer
            # The next client may only come once this one is seen to leave.
            wait_until(lambda: client_left(handle), DEADLINE,
                       what=lambda: f"the client's disconnect to be logged "
                                    f"(messages: {handle.messages()})")
    finally:
        result = finish(handle)
    assert result.ok, result


def test_restart_on_a_pty_starts_the_session_over_for_each_client(session, tmp_path):
    # The bridge sees a pty client leave when the last opener closes the
    # terminal (Linux); without restart the second PING would be a mismatch.
    out = tmp_path / "clients.wtape"
    handle = bridge.serve_replay(session, pty=True, restart=True, output=out,
                                 replay_options="timing=none,unused=ignore", quiet=True)
    try:
        for round_ in range(3):
            with serial.Serial(handle.pty_path, 9600, timeout=DEADLINE) as client:
                client.write(b"PING\n")
                assert read_line(client) == b"PONG\n"
            wait_until(lambda: sum("client closed" in m for m in handle.messages()) > round_,
                       DEADLINE, what=lambda: f"the pty client's close to be seen "
                                              f"(messages: {handle.messages()})")
    finally:
        result = finish(handle)
    assert result.ok, result
    assert handle.stats().clients_accepted == 3
    with _core.SessionReader(str(out)) as reader:
        events = [(r.kind, r.data) for r in reader if r.kind.startswith("client_")]
    assert [kind for kind, _ in events] == ["client_connect", "client_disconnect"] * 3
    assert all(b'"peer":"pty"' in data.replace(b" ", b"") for _, data in events)


def test_restart_starts_the_session_over_for_each_client(session):
    handle = bridge.serve_replay(session, listen="127.0.0.1:0", restart=True,
                                 replay_options="timing=none,unused=ignore", quiet=True)
    try:
        for _ in range(3):
            with connect(handle) as client:
                client.sendall(b"PING\n")
                assert recv_line(client) == b"PONG\n"
            wait_until(lambda: client_left(handle), DEADLINE,
                       what=lambda: f"the client's disconnect to be logged "
                                    f"(messages: {handle.messages()})")
    finally:
        result = finish(handle)
    assert result.ok, result


def test_a_diverging_client_gets_the_mismatch_report(session):
    handle = bridge.serve_replay(session, listen="127.0.0.1:0",
                                 replay_options="timing=none,unused=ignore", quiet=True)
    with connect(handle) as client:
        client.sendall(b"PING\n")
        assert recv_line(client) == b"PONG\n"
        client.sendall(b"IDX\n")
        # The bridge ends by itself and closes the connection.
        assert handle.wait(DEADLINE)
        assert client.recv(100) == b""
    result = handle.result()
    assert result.outcome == "mismatch"
    assert not result.ok
    assert "tx byte offset 7" in result.message
    assert "expected: 3f 0a" in result.message


def test_missing_recording_is_a_clear_error(tmp_path):
    with pytest.raises(Exception, match="missing.wtape"):
        bridge.serve_replay(tmp_path / "missing.wtape", pty=True, quiet=True)


def test_unused_error_turns_leftover_data_into_a_mismatch(session):
    handle = bridge.serve_replay(session, listen="127.0.0.1:0",
                                 replay_options="timing=none,unused=error", quiet=True)
    with connect(handle) as client:
        client.sendall(b"PING\n")
        assert recv_line(client) == b"PONG\n"
    result = finish(handle)
    assert result.outcome == "mismatch"
    assert "unused=error" in result.message


def test_a_recorded_device_loss_ends_the_virtual_device(tmp_path):
    path = tmp_path / "lost.wtape"
    writer = _core.SessionWriter(str(path), capture="wire", port_type="serial")
    writer.write("open", 0, b"{}")
    writer.write("tx", 1000, b"PING\n")
    writer.write("rx", 2000, b"PONG\n")
    writer.write("device_lost", 3000, b'{"error":"unplugged"}')
    writer.close()
    handle = bridge.serve_replay(path, listen="127.0.0.1:0", replay_options="timing=none",
                                 quiet=True)
    with connect(handle) as client:
        client.sendall(b"PING\n")
        assert recv_line(client) == b"PONG\n"
        assert handle.wait(DEADLINE)
        assert client.recv(10) == b""
    result = handle.result()
    assert result.outcome == "device_closed"
    assert result.ok
