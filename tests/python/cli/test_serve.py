"""wiretape serve, raw protocol: one controlling client at a time, refused or
read-only (--shared) extra clients, a device that stays open across clients,
device loss reported and survived with --reopen, server-side recording."""

import json
import select
import socket
import threading

import pytest

from wiretape import _core, bridge

from devices import (TcpDevice, read_exactly, read_to_end, skip_unless_serial_opens_on_a_pty,
                     wait_until)

DEADLINE = 10.0


@pytest.fixture
def device():
    with TcpDevice() as dev:
        yield dev


def connect(handle):
    host, port = handle.address.rsplit(":", 1)
    return socket.create_connection((host, int(port)), timeout=DEADLINE)


def finish(handle):
    handle.stop()
    assert handle.wait(DEADLINE)
    return handle.result()


def test_one_client_talks_to_the_device(device):
    handle = bridge.serve(device.options, "0", quiet=True)
    try:
        assert handle.address.startswith("127.0.0.1:")
        assert any("this machine only" in m for m in handle.messages())
        with connect(handle) as client:
            client.sendall(b"ping\xff\x00")
            assert read_exactly(client, 6) == b"PING\xff\x00"
    finally:
        assert finish(handle).ok


def test_second_client_is_refused_with_a_message(device):
    handle = bridge.serve(device.options, "127.0.0.1:0", quiet=True)
    try:
        with connect(handle) as first:
            first.sendall(b"a")
            assert read_exactly(first, 1) == b"A"
            with connect(handle) as second:
                refusal = read_to_end(second)
            assert b"in use by another client" in refusal
            assert b"--shared" in refusal
            # The first client is unaffected.
            first.sendall(b"b")
            assert read_exactly(first, 1) == b"B"
        assert handle.stats().clients_refused == 1
    finally:
        finish(handle)


def test_shared_clients_watch_read_only(device):
    handle = bridge.serve(device.options, "127.0.0.1:0", shared=True, quiet=True)
    try:
        with connect(handle) as control, connect(handle) as monitor:
            wait_until(lambda: handle.stats().clients_accepted == 2, DEADLINE,
                       what="both clients to be accepted")
            monitor.sendall(b"ignored")
            control.sendall(b"hello")
            assert read_exactly(control, 5) == b"HELLO"
            assert read_exactly(monitor, 5) == b"HELLO"
        assert bytes(device.received) == b"hello"
    finally:
        finish(handle)


def test_device_stays_open_when_a_client_leaves(device):
    handle = bridge.serve(device.options, "127.0.0.1:0", quiet=True)
    try:
        for word in (b"one", b"two", b"three"):
            with connect(handle) as client:
                client.sendall(word)
                assert read_exactly(client, len(word)) == word.upper()
            wait_until(lambda: bridge_has_no_client(handle), DEADLINE,
                       what="the client's disconnect to be logged")
        assert device.connections == 1
    finally:
        finish(handle)


def bridge_has_no_client(handle):
    return sum("disconnected" in m for m in handle.messages()) >= \
        sum("connected" in m and "disconnected" not in m for m in handle.messages())


def test_device_loss_without_reopen_ends_the_server(device):
    handle = bridge.serve(device.options, "127.0.0.1:0", quiet=True)
    with connect(handle) as client:
        client.sendall(b"x")
        assert read_exactly(client, 1) == b"X"
        device.drop()
        # The device is gone: the client sees its connection end, as a reset
        # when the server closed it with the client's "y" still unread.
        try:
            client.sendall(b"y")
            ended_with = read_to_end(client)
        except (ConnectionResetError, BrokenPipeError):
            ended_with = b""
        assert ended_with in (b"", b"Y")
    assert handle.wait(DEADLINE)
    result = handle.result()
    assert result.outcome == "device_closed"
    assert "went away" in result.message


def test_reopen_after_device_loss(device, tmp_path):
    out = tmp_path / "served.wtape"
    handle = bridge.serve(device.options, "127.0.0.1:0", output=out, reopen=True, quiet=True)
    try:
        with connect(handle) as client:
            client.sendall(b"before")
            assert read_exactly(client, 6) == b"BEFORE"
            device.accepting.clear()
            device.drop()
            wait_until(lambda: handle.stats().device_losses == 1, DEADLINE,
                       what="the device loss to be counted")
            # The loss reaches the client as the end of its connection.
            assert read_to_end(client) == b""
        assert handle.running
        # While the device is away, a new client waits in the listen queue
        # and is served once the device is back.
        with connect(handle) as early:
            early.sendall(b"early")
            device.accepting.set()
            assert read_exactly(early, 5) == b"EARLY"
        assert handle.stats().device_reopens == 1
        with connect(handle) as client:
            client.sendall(b"after")
            assert read_exactly(client, 5) == b"AFTER"
        assert device.connections == 2
    finally:
        result = finish(handle)
    assert result.ok
    with _core.SessionReader(str(out)) as reader:
        records = list(reader)
    kinds = [r.kind for r in records]
    assert kinds.count("open") == 2
    assert "device_lost" in kinds
    assert kinds.index("device_lost") < len(kinds) - 1 - kinds[::-1].index("open")
    connects = [json.loads(r.data) for r in records if r.kind == "client_connect"]
    assert all(c["peer"].startswith("127.0.0.1:") for c in connects)
    assert kinds.count("client_disconnect") == kinds.count("client_connect")
    assert b"".join(r.data for r in records if r.kind == "tx").startswith(b"before")
    assert b"".join(r.data for r in records if r.kind == "rx") == b"BEFOREEARLYAFTER"


def test_bad_listen_address_is_a_clear_error(device):
    with pytest.raises(ValueError, match="out of range"):
        bridge.serve(device.options, "127.0.0.1:70000")
    with pytest.raises(_core.PortError, match="resolve|bind"):
        bridge.serve(device.options, "no.such.host.invalid:0", quiet=True)


def test_pty_device_closed_then_back_under_the_same_link(tmp_path):
    """The device is a serial port on a pty reached through a symlink (as
    /dev/serial/by-id/... is): its pty closes (unplugged), a new one appears
    under the same link (plugged back), and the server carries on."""
    import os
    import tty

    skip_unless_serial_opens_on_a_pty()

    def plug():
        master, slave = os.openpty()
        tty.setraw(slave)
        if os.path.lexists(link):
            os.unlink(link)
        os.symlink(os.ttyname(slave), link)
        return master, slave

    link = str(tmp_path / "ttyDevice")
    master, slave = plug()
    handle = bridge.serve(f"type=serial,device={link},exclusive=false", "127.0.0.1:0",
                          reopen=True, quiet=True)
    try:
        with connect(handle) as client:
            client.sendall(b"one")
            ready, _, _ = select.select([master], [], [], DEADLINE)
            assert ready and os.read(master, 10) == b"one"
            os.unlink(link)
            os.close(slave)
            os.close(master)  # unplugged: the server's reads fail
            wait_until(lambda: handle.stats().device_losses == 1, DEADLINE,
                       what="the device loss to be counted")
            assert read_to_end(client) == b""
        assert any("went away" in m for m in handle.messages())
        master, slave = plug()
        wait_until(lambda: handle.stats().device_reopens == 1, DEADLINE,
                   what="the replugged device to be reopened")
        with connect(handle) as client:
            client.sendall(b"two")
            ready, _, _ = select.select([master], [], [], DEADLINE)
            assert ready and os.read(master, 10) == b"two"
            os.write(master, b"back")
            assert read_exactly(client, 4) == b"back"
    finally:
        result = finish(handle)
        os.close(master)
        os.close(slave)
    assert result.ok


def test_a_monitor_that_does_not_read_never_holds_the_controller_back():
    handle = bridge.serve("type=loopback", "127.0.0.1:0", shared=True, quiet=True)
    total = 32 << 20
    try:
        with connect(handle) as control, connect(handle) as monitor:
            monitor.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            wait_until(lambda: handle.stats().clients_accepted == 2, DEADLINE,
                       what="both clients to be accepted")
            chunk = bytes(range(256)) * 256
            sender = threading.Thread(
                target=lambda: [control.sendall(chunk) for _ in range(total // len(chunk))])
            sender.start()
            got = 0
            while got < total:
                data = control.recv(1 << 20)
                assert data
                got += len(data)
            sender.join(DEADLINE)
        stats = handle.stats()
        assert stats.bytes_from_device == total
        # The monitor's share beyond its bound was dropped, not queued.
        assert stats.bytes_dropped > 0
    finally:
        finish(handle)
