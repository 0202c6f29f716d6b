"""wiretape record: the transparent proxy between a device and a program that
opens a pty (pyserial) or connects over TCP, recording every byte both ways."""

import json
import os
import random
import select
import socket
import time

import pytest
import serial

from wiretape import _core, bridge

from devices import TcpDevice, skip_unless_serial_opens_on_a_pty, wait_until

DEADLINE = 10.0


@pytest.fixture
def device():
    with TcpDevice() as dev:
        yield dev


def read_records(path):
    with _core.SessionReader(str(path)) as reader:
        records = list(reader)
        assert reader.damage is None, reader.damage
        return reader.header, records


def joined(records, kind):
    return b"".join(r.data for r in records if r.kind == kind)


def read_exactly(port, count):
    data = bytearray()
    deadline = time.monotonic() + DEADLINE
    while len(data) < count and time.monotonic() < deadline:
        data += port.read(count - len(data))
    return bytes(data)


def finish(handle):
    handle.stop()
    assert handle.wait(DEADLINE)
    return handle.result()


def test_pty_proxy_forwards_and_records_every_byte_in_order(device, tmp_path):
    out = tmp_path / "run.wtape"
    link = tmp_path / "ttyV0"
    handle = bridge.record(device.options, out, pty=str(link), meta={"robot": "r2"}, quiet=True)
    rng = random.Random(7)
    sent = bytearray()
    answers = bytearray()
    with serial.Serial(str(link), 115200, timeout=DEADLINE) as client:
        for _ in range(50):
            chunk = bytes(rng.randrange(ord("a"), ord("z") + 1) for _ in range(rng.randrange(1, 2000)))
            client.write(chunk)
            sent += chunk
            answers += read_exactly(client, len(chunk))
    result = finish(handle)
    assert result.ok and result.outcome == "stopped"
    assert bytes(answers) == bytes(sent).upper()
    assert bytes(device.received) == bytes(sent)

    header, records = read_records(out)
    assert header.capture == "wire"
    assert header.port_type == "tcp"
    assert header.metadata == {"robot": "r2"}
    assert records[0].kind == "open" and records[0].t_ns == 0
    assert records[-1].kind == "close"
    assert joined(records, "tx") == bytes(sent)
    assert joined(records, "rx") == bytes(sent).upper()
    times = [r.t_ns for r in records]
    assert times == sorted(times)
    assert result.stats.bytes_to_device == len(sent)
    assert result.stats.bytes_from_device == len(sent)


def test_tcp_proxy_forwards_and_records(device, tmp_path):
    out = tmp_path / "tcp.wtape"
    handle = bridge.record(device.options, out, listen="127.0.0.1:0", quiet=True)
    host, port = handle.address.rsplit(":", 1)
    assert host == "127.0.0.1"
    payload = bytes(range(256)) * 400  # every byte value, 100 KiB
    with socket.create_connection((host, int(port)), timeout=DEADLINE) as client:
        client.sendall(payload)
        got = bytearray()
        while len(got) < len(payload):
            data = client.recv(65536)
            assert data, "the proxy closed the connection early"
            got += data
    assert bytes(got) == payload.upper()
    # The client's disconnect is recorded before stop.
    wait_until(lambda: any("disconnected" in m for m in handle.messages()), DEADLINE,
               what=lambda: f"the client's disconnect to be logged (messages: {handle.messages()})")
    finish(handle)
    _, records = read_records(out)
    kinds = [r.kind for r in records]
    assert kinds[0] == "open"
    assert "client_connect" in kinds and "client_disconnect" in kinds
    assert kinds.index("client_connect") < kinds.index("tx")
    assert joined(records, "tx") == payload
    assert joined(records, "rx") == payload.upper()


def test_terminal_settings_the_client_sets_are_recorded(device, tmp_path):
    out = tmp_path / "settings.wtape"
    handle = bridge.record(device.options, out, pty=True, quiet=True)
    with serial.Serial(handle.pty_path, 9600, timeout=DEADLINE) as client:
        client.write(b"a")
        assert read_exactly(client, 1) == b"A"
        client.baudrate = 57600
        client.write(b"b")
        assert read_exactly(client, 1) == b"B"
    finish(handle)
    _, records = read_records(out)
    settings = [json.loads(r.data) for r in records if r.kind == "settings"]
    assert 57600 in [s["baud"] for s in settings]
    # A tcp device has no line settings: the change is recorded as not applied.
    assert all(s["applied"] is False for s in settings)
    # The baud change was seen before the byte written after it crossed.
    index_57600 = next(i for i, r in enumerate(records)
                       if r.kind == "settings" and json.loads(r.data)["baud"] == 57600)
    assert joined(records[index_57600:], "tx") == b"b"


def test_settings_mirrored_onto_a_serial_device(tmp_path):
    skip_unless_serial_opens_on_a_pty()
    import termios
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    device_path = os.ttyname(slave)
    out = tmp_path / "serial.wtape"
    handle = bridge.record(f"type=serial,device={device_path},baud=9600,exclusive=false",
                           out, pty=True, quiet=True)
    try:
        with serial.Serial(handle.pty_path, 9600, timeout=DEADLINE) as client:
            client.baudrate = 115200
            client.write(b"x")
            ready, _, _ = select.select([master], [], [], DEADLINE)
            assert ready and os.read(master, 10) == b"x"
            speed = termios.tcgetattr(slave)[5]
            assert speed == termios.B115200
    finally:
        finish(handle)
        os.close(master)
        os.close(slave)
    _, records = read_records(out)
    assert any(r.kind == "settings" and b'"baud":115200' in r.data and b'"applied":true' in r.data
               for r in records)


def test_stop_mid_stream_leaves_a_complete_file(tmp_path):
    out = tmp_path / "stream.wtape"
    with TcpDevice(stream=True) as streaming:
        handle = bridge.record(streaming.options, out, listen="127.0.0.1:0", quiet=True)
        host, port = handle.address.rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=DEADLINE) as client:
            got = bytearray()
            while len(got) < 200_000:
                got += client.recv(65536)
            result = finish(handle)
    assert result.ok
    _, records = read_records(out)
    assert records[-1].kind == "close"
    rx = joined(records, "rx")
    assert len(rx) >= 200_000
    # Lines in order, none lost or repeated.
    lines = rx.split(b"\n")[:-1]
    assert lines == [b"line %08d" % i for i in range(len(lines))]


def test_duration_ends_the_recording(device, tmp_path):
    out = tmp_path / "short.wtape"
    started = time.monotonic()
    handle = bridge.record(device.options, out, pty=True, duration=0.3, quiet=True)
    assert handle.wait(DEADLINE)
    assert time.monotonic() - started >= 0.3
    assert handle.result().outcome == "finished"
    _, records = read_records(out)
    assert [r.kind for r in records] == ["open", "close"]


def test_unreachable_device_is_a_clear_error(tmp_path):
    out = tmp_path / "x.wtape"
    with pytest.raises(_core.PortError, match="connect"):
        bridge.record("type=tcp,port=1,timeout=2", out, pty=True, quiet=True)
    # Nothing was recorded: no file that looks like a session is left.
    assert not out.exists()


def test_exactly_one_client_side(device, tmp_path):
    with pytest.raises(ValueError, match="exactly one"):
        bridge.record(device.options, tmp_path / "x.wtape")
    with pytest.raises(ValueError, match="port"):
        bridge.record(device.options, tmp_path / "x.wtape", listen="localhost:http")
