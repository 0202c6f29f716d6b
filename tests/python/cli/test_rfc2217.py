"""wiretape serve --protocol rfc2217 against pyserial's rfc2217:// client: the
client sets baud, data bits, parity, stop bits, modem lines and purges
buffers on a device; settings reach the device and are recorded."""

import json
import socket
import termios
import time

import pytest
import serial

from wiretape import _core, bridge

from devices import skip_unless_serial_opens_on_a_pty, wait_until
from pty_device import PtyDevice

DEADLINE = 10.0

# pyserial's rfc2217 client uses threading names deprecated in Python 3.10.
pytestmark = pytest.mark.filterwarnings("ignore:set.*is deprecated:DeprecationWarning")


@pytest.fixture
def pty_device():
    skip_unless_serial_opens_on_a_pty()
    device = PtyDevice()
    yield device
    device.close()


def finish(handle):
    handle.stop()
    assert handle.wait(DEADLINE)
    return handle.result()


def read_exactly(port, count):
    data = bytearray()
    deadline = time.monotonic() + DEADLINE
    while len(data) < count and time.monotonic() < deadline:
        data += port.read(count - len(data))
    return bytes(data)


def test_pyserial_rfc2217_client_sets_the_line_and_moves_bytes(pty_device, tmp_path):
    out = tmp_path / "rfc2217.wtape"
    handle = bridge.serve(pty_device.options, "127.0.0.1:0", protocol="rfc2217",
                          output=out, quiet=True)
    try:
        url = "rfc2217://" + handle.address
        with serial.serial_for_url(url, baudrate=9600, timeout=DEADLINE) as client:
            assert pty_device.speed() == termios.B9600
            # Bytes both ways, the Telnet escape byte (0xff) included.
            payload = bytes(range(256)) * 8
            client.write(payload)
            assert pty_device.read(len(payload)) == payload
            pty_device.write(payload[::-1])
            assert read_exactly(client, len(payload)) == payload[::-1]

            client.baudrate = 115200
            assert pty_device.speed() == termios.B115200
            client.stopbits = serial.STOPBITS_TWO
            assert pty_device.stop_bits() == 2
            client.bytesize = serial.SEVENBITS   # a pty shows 8N whatever is
            client.parity = serial.PARITY_EVEN   # set: checked in the file
            client.dtr = False                   # a pty has no modem lines:
            client.rts = True                    # acknowledged, noted
            assert client.cts is False
            pty_device.write(b"stale")
            wait_until(lambda: client.in_waiting >= 5, DEADLINE,
                       what="the 5 stale bytes to reach the client")
            client.reset_input_buffer()
            client.write(b"after")
            assert pty_device.read(5) == b"after"
    finally:
        result = finish(handle)
    assert result.ok, result
    with _core.SessionReader(str(out)) as reader:
        records = list(reader)
    kinds = [r.kind for r in records]
    assert kinds[0] == "open" and "client_connect" in kinds and "client_disconnect" in kinds
    settings = [json.loads(r.data) for r in records if r.kind == "settings"]
    assert settings[0]["baud"] == 115200 and settings[0]["source"] == "rfc2217"
    assert all(s["applied"] for s in settings)
    assert any(s["stopbits"] == 2 for s in settings)
    assert any(s["databits"] == 7 and s["parity"] == "even" for s in settings)
    lines = [json.loads(r.data) for r in records if r.kind == "modem_lines"]
    assert {"dtr": False, "applied": False} in lines
    assert "flush_input" in kinds
    assert b"".join(r.data for r in records if r.kind == "tx") == payload + b"after"


def test_rfc2217_over_a_device_without_line_settings(tmp_path):
    """A TCP device has no baud rate: the server keeps the client's view of
    the line and acknowledges it, so pyserial opens and works."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    handle = bridge.serve(f"type=tcp,port={server.getsockname()[1]}", "127.0.0.1:0",
                          protocol="rfc2217", quiet=True)
    try:
        conn, _ = server.accept()
        with conn, serial.serial_for_url("rfc2217://" + handle.address, baudrate=38400,
                                         timeout=DEADLINE) as client:
            client.baudrate = 19200
            client.write(b"\xff\xfe data")
            got = b""
            while len(got) < 7:
                got += conn.recv(16)
            assert got == b"\xff\xfe data"
            conn.sendall(b"\xff\xff\x00")
            assert read_exactly(client, 3) == b"\xff\xff\x00"
    finally:
        finish(handle)
        server.close()


def test_malformed_telnet_never_stops_the_server(tmp_path):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    handle = bridge.serve(f"type=tcp,port={server.getsockname()[1]}", "127.0.0.1:0",
                          protocol="rfc2217", quiet=True)
    try:
        conn, _ = server.accept()
        host, port = handle.address.rsplit(":", 1)
        garbage = [
            b"\xff",                                   # IAC at the end
            b"\xff\xfa" + b"\x2c\x01" + b"A" * 5000,   # endless subnegotiation
            b"\xff\xfa\x2c\x01\xff\xf0",               # baud without a value
            b"\xff\xfb\x99\xff\xfd\x99\xff\xfe\x00",   # unknown options
            b"\xff\xfa\xff\xf0\xff\xf0\xff\x01",       # empty SB, stray SE, bad command
            bytes(range(256)) * 4,
        ]
        for chunk in garbage:
            with socket.create_connection((host, int(port)), timeout=DEADLINE) as raw:
                raw.sendall(chunk)
            wait_until(lambda: handle.stats().clients_accepted != 0, DEADLINE,
                       what="the first client to be accepted")
        assert handle.running
        # Each garbage client is either served then gone (closed or reset),
        # or refused while the server had not yet seen the previous one leave.
        ends = ("disconnected", "refused", "connection failed")
        wait_until(lambda: sum(any(e in m for e in ends) for m in handle.messages())
                   >= len(garbage), DEADLINE,
                   what=lambda: f"every garbage client's end to be logged "
                                f"(messages: {handle.messages()})")
        with serial.serial_for_url("rfc2217://" + handle.address, timeout=DEADLINE) as client:
            client.write(b"still here")
            conn.settimeout(DEADLINE)
            got = b""
            while not got.endswith(b"still here"):
                got += conn.recv(65536)
    finally:
        result = finish(handle)
        server.close()
    assert result.ok


def test_rfc2217_in_front_of_a_replay(tmp_path):
    path = tmp_path / "device.wtape"
    writer = _core.SessionWriter(str(path), capture="wire", port_type="serial")
    writer.write("open", 0, b"{}")
    writer.write("tx", 1000, b"PING\n")
    writer.write("rx", 2000, b"PONG\xff\n")
    writer.close()
    handle = bridge.serve(f"type=replay,file={path},timing=none", "127.0.0.1:0",
                          protocol="rfc2217", output=tmp_path / "served.wtape", quiet=True)
    try:
        with serial.serial_for_url("rfc2217://" + handle.address, baudrate=115200,
                                   timeout=DEADLINE) as client:
            client.write(b"PING\n")
            assert client.read_until(b"\n") == b"PONG\xff\n"
    finally:
        result = finish(handle)
    assert result.ok, result
    with _core.SessionReader(str(tmp_path / "served.wtape")) as reader:
        records = list(reader)
    settings = [json.loads(r.data) for r in records if r.kind == "settings"]
    # Only the change from the replay's default line is recorded.
    assert [s["baud"] for s in settings] == [115200]
