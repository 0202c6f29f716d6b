"""The RFC 2217 client port (type=rfc2217, --device rfc2217://HOST:PORT)
against the servers a lab runs: wiretape's own `serve --protocol rfc2217`
(over a pty device, and over a replay of a device with modem lines),
ser2net (Debian's, exporting a pty) and pyserial's server side
(PortManager). What it records is a serial port's
session, which a replay checks as it would a local port's."""

import json
import os
import shutil
import socket
import subprocess
import termios
import threading

import pytest

import wiretape
from wiretape import _core, bridge

from devices import (announced_address, interrupt, skip_unless_serial_opens_on_a_pty,
                     start_cli, wait_until)
from line_devices import AFTER, BEFORE, line_device_session
from pty_device import PtyDevice

DEADLINE = 10.0
SER2NET = shutil.which("ser2net") or ("/usr/sbin/ser2net"
                                      if os.path.exists("/usr/sbin/ser2net") else None)


@pytest.fixture
def pty_device():
    skip_unless_serial_opens_on_a_pty()
    device = PtyDevice()
    yield device
    device.close()


@pytest.fixture
def served_pty(pty_device):
    """`serve --protocol rfc2217` in front of the pty device."""
    handle = bridge.serve(f"type=serial,device={pty_device.path},exclusive=false",
                          "127.0.0.1:0", protocol="rfc2217", quiet=True)
    yield pty_device, handle.address
    handle.stop()
    assert handle.wait(DEADLINE)


def rfc2217_options(address, **keys):
    host, port = address.rsplit(":", 1)
    return _core.option_string([("type", "rfc2217"), ("host", host), ("port", int(port)),
                                *keys.items()])


def records_of(path):
    with wiretape.SessionReader(str(path)) as reader:
        return reader.header, list(reader)


def test_the_port_through_wiretape_serve_sets_the_line_and_moves_bytes(served_pty, tmp_path):
    device, address = served_pty
    out = tmp_path / "lab.wtape"
    with wiretape.open_port(rfc2217_options(address, baud=115200, timeout=DEADLINE,
                                            log=str(out))) as port:
        assert device.speed() == termios.B115200
        payload = bytes(range(256)) * 4  # the Telnet escape byte, both ways
        assert port.write_all(payload) == len(payload)
        assert device.read(len(payload)) == payload
        device.write(payload[::-1])
        assert port.read_exactly(len(payload)) == payload[::-1]
        port.set_baud(57600)
        assert device.speed() == termios.B57600
        assert port.serial_settings()["baud"] == 57600
    header, records = records_of(out)
    assert header.port_type == "rfc2217"
    settings = [json.loads(r.data) for r in records if r.kind == "settings"]
    assert settings[-1]["baud"] == 57600
    assert b"".join(r.data for r in records if r.kind == "tx") == payload
    assert b"".join(r.data for r in records if r.kind == "rx") == payload[::-1]


@pytest.fixture
def line_device(tmp_path):
    """`serve --protocol rfc2217` in front of a replayed device whose modem
    lines change among the bytes (a pty has none)."""
    device = line_device_session(tmp_path / "device.wtape", answer_ms=7, close_ms=10)
    handle = bridge.serve(f"type=replay,file={device},timing=none,check=off", "127.0.0.1:0",
                          protocol="rfc2217", quiet=True)
    yield handle.address
    handle.stop()
    assert handle.wait(DEADLINE)


def lines(port):
    return {"cts": port.cts, "dsr": port.dsr, "ri": port.ri, "cd": port.cd}


def board_session(port):
    """A board programmer's session: reset by DTR, then PING; returns the
    lines before, the answer and the lines after."""
    before = lines(port)
    port.set_dtr(False)
    port.set_dtr(True)
    port.write(b"PING\n")
    answer = port.read_exactly(5)
    wait_until(lambda: lines(port) == AFTER, DEADLINE,
               what=lambda: f"the device's lines after its answer (now {lines(port)})")
    return before, answer, lines(port)


def record_board(address, out):
    with wiretape.open_port(rfc2217_options(address, timeout=DEADLINE, log=str(out))) as port:
        assert board_session(port) == (BEFORE, b"PONG\n", AFTER)


def test_a_recording_through_rfc2217_replays_as_a_serial_ports(line_device, tmp_path):
    out = tmp_path / "board.wtape"
    record_board(line_device, out)
    _, records = records_of(out)
    events = [json.loads(r.data) for r in records if r.kind == "modem_lines"]
    assert {"dtr": False} in events and {"dtr": True} in events, events
    assert {k: v for k, v in events[0].items()} == BEFORE, events

    # Replayed, the same session passes: the recorded lines are presented.
    with wiretape.open_port(f"type=replay,file={out},timing=none") as replay:
        assert board_session(replay) == (BEFORE, b"PONG\n", AFTER)
    # A session without the reset pulse is a mismatch, as for a local port.
    with pytest.raises(wiretape.ReplayMismatch, match="DTR low"):
        with wiretape.open_port(f"type=replay,file={out},timing=none") as replay:
            replay.write(b"PING\n")
            replay.read_exactly(5)


def test_the_port_on_replay_listen_protocol_rfc2217(line_device, tmp_path):
    """Recorded through the port, served by `replay --listen --protocol
    rfc2217`, played by the port again: the same session passes (exit 0),
    one without the reset pulse is exit 1 naming it."""
    out = tmp_path / "board.wtape"
    record_board(line_device, out)

    def replay_with(session, may_drop=False):
        child = start_cli("replay", str(out), "--listen", "127.0.0.1:0", "--protocol",
                          "rfc2217", "--timing", "none")
        host, port = announced_address(child, "tcp")
        try:
            with wiretape.open_port(rfc2217_options(f"{host}:{port}",
                                                    timeout=DEADLINE)) as client:
                wait_until(lambda: lines(client) == BEFORE, DEADLINE,
                           what=lambda: f"the recorded lines (now {lines(client)})")
                session(client)
        except wiretape.PortError:
            if not may_drop:  # the replay may end the connection at its mismatch
                raise
        finally:
            if may_drop:
                # A mismatch ends the replay by itself: no Ctrl-C racing its
                # report.
                try:
                    child.wait(DEADLINE)
                except subprocess.TimeoutExpired:
                    pass
            code, _, err = interrupt(child)
        return code, err

    code, err = replay_with(board_session)
    assert code == 0, err

    def no_pulse(client):
        client.write(b"PING\n")
        client.read_exactly(5)
    code, err = replay_with(no_pulse, may_drop=True)
    assert code == 1, (code, err)
    assert "replay mismatch" in err and "DTR low" in err, err


def test_record_from_an_rfc2217_device_url(served_pty, tmp_path):
    device, address = served_pty
    out = tmp_path / "desk.wtape"
    child = start_cli("record", "--device", "rfc2217://" + address, "--listen", "127.0.0.1:0",
                      "-o", str(out))
    try:
        host, port = announced_address(child, "tcp")
        with socket.create_connection((host, port), timeout=DEADLINE) as client:
            client.sendall(b"PING\n")
            assert device.read(5) == b"PING\n"
            device.write(b"PONG\n")
            got = b""
            while len(got) < 5:
                got += client.recv(16)
            assert got == b"PONG\n"
    finally:
        code, _, err = interrupt(child)
    assert code == 0, err
    header, records = records_of(out)
    assert header.port_type == "rfc2217"
    assert "port=" in header.port_options and "type=rfc2217" in header.port_options
    assert b"".join(r.data for r in records if r.kind == "rx") == b"PONG\n"


def test_record_on_a_pty_carries_the_drivers_rate_to_the_exported_line(served_pty, tmp_path):
    """The driver programs 115200 on the proxy's pty: the proxy sends it to
    the exporter as SET-BAUDRATE, which sets the far device, and records it."""
    serial = pytest.importorskip("serial", reason="pyserial is not installed")
    device, address = served_pty
    link = tmp_path / "ttyBoard"
    out = tmp_path / "desk.wtape"
    child = start_cli("record", "--device", "rfc2217://" + address, "--pty", str(link),
                      "-o", str(out))
    try:
        seen = []
        while not any("clients use pty" in line for line in seen):
            line = child.stderr.readline()
            assert line, "no pty announced: " + "".join(seen)
            seen.append(line)
        with serial.Serial(str(link), 115200, timeout=DEADLINE) as driver:
            wait_until(lambda: device.speed() == termios.B115200, DEADLINE,
                       what="the exported line to be set to 115200")
            driver.write(b"PING\n")
            assert device.read(5) == b"PING\n"
            device.write(b"PONG\n")
            assert driver.read(5) == b"PONG\n"
    finally:
        code, _, err = interrupt(child)
    assert code == 0, err
    _, records = records_of(out)
    settings = [json.loads(r.data) for r in records if r.kind == "settings"]
    assert {"baud": 115200, "applied": True}.items() <= settings[-1].items(), settings


def test_a_bad_rfc2217_url_is_a_usage_error_naming_it(tmp_path):
    child = start_cli("record", "--device", "rfc2217://lab-pi", "--listen", "127.0.0.1:0",
                      "-o", str(tmp_path / "x.wtape"))
    out, err = child.communicate(timeout=30)
    assert child.returncode == 2, err
    assert "rfc2217://lab-pi" in err and "HOST:PORT" in err, err


# --- pyserial's server side ---------------------------------------------------------

@pytest.fixture
def pyserial_server(pty_device):
    """pyserial's RFC 2217 server side (serial.rfc2217.PortManager) over a
    pyserial Serial on the pty, one client, as pyserial's example server."""
    serial = pytest.importorskip("serial.rfc2217", reason="pyserial is not installed")
    import serial as pyserial
    listener = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def serve():
        connection, _ = listener.accept()

        class PtySerial(pyserial.Serial):
            """A pty has no modem lines, which PortManager reads."""
            cts = dsr = ri = cd = property(lambda self: False)

            def _update_dtr_state(self):
                pass

            def _update_rts_state(self):
                pass
        device = PtySerial(pty_device.path, 9600, timeout=0.05)

        class Connection:
            def write(self, data):
                connection.sendall(data)
        manager = serial.PortManager(device, Connection())

        def device_to_client():
            while not stop.is_set():
                data = device.read(device.in_waiting or 1)
                if data:
                    connection.sendall(b"".join(manager.escape(data)))
        relay = threading.Thread(target=device_to_client, daemon=True)
        relay.start()
        try:
            while True:
                data = connection.recv(4096)
                if not data:
                    break
                device.write(b"".join(manager.filter(data)))
        finally:
            stop.set()
            relay.join(DEADLINE)
            device.close()
            connection.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield pty_device, "127.0.0.1:%d" % listener.getsockname()[1]
    stop.set()
    thread.join(DEADLINE)
    listener.close()


@pytest.mark.filterwarnings("ignore:set.*is deprecated:DeprecationWarning")
def test_the_port_against_pyserials_server_side(pyserial_server):
    device, address = pyserial_server
    with wiretape.open_port(rfc2217_options(address, baud=115200, timeout=DEADLINE)) as port:
        assert device.speed() == termios.B115200
        payload = bytes(range(256)) * 2
        port.write_all(payload)
        assert device.read(len(payload)) == payload
        device.write(payload[::-1])
        assert port.read_exactly(len(payload)) == payload[::-1]
        port.flush_output()
        port.configure(baud=19200, stopbits=2)
        assert device.speed() == termios.B19200
        assert port.serial_settings()["stopbits"] == 2


# --- ser2net ----------------------------------------------------------------------------

@pytest.fixture
def ser2net(pty_device, tmp_path):
    """ser2net exporting the pty device over RFC 2217 (telnet(rfc2217)
    accepter), as a lab's exporter does."""
    if SER2NET is None:
        pytest.skip("ser2net is not installed (Debian package ser2net)")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        tcp_port = probe.getsockname()[1]
    config = tmp_path / "ser2net.yaml"
    config.write_text(f"""connection: &lab
  accepter: telnet(rfc2217),tcp,127.0.0.1,{tcp_port}
  connector: serialdev,{pty_device.path},9600n81,local
  options:
    kickolduser: true
""")
    child = subprocess.Popen([SER2NET, "-n", "-u", "-c", str(config),
                              "-P", str(tmp_path / "ser2net.pid")],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT)

    def listening():
        assert child.poll() is None, child.stdout.read()
        with socket.socket() as s:
            return s.connect_ex(("127.0.0.1", tcp_port)) == 0
    wait_until(listening, DEADLINE, what="ser2net to listen")
    yield pty_device, f"127.0.0.1:{tcp_port}"
    child.terminate()
    child.wait(DEADLINE)


def test_the_port_through_ser2net(ser2net, tmp_path):
    device, address = ser2net
    out = tmp_path / "ser2net.wtape"
    # kickolduser: the probe's connection may still be closing.
    with wiretape.open_port(rfc2217_options(address, baud=115200, timeout=DEADLINE,
                                            log=str(out))) as port:
        wait_until(lambda: device.speed() == termios.B115200, DEADLINE,
                   what="ser2net to set the pty to 115200")
        payload = b"AT\r\n\xff\x00" + bytes(range(256))
        port.write_all(payload)
        assert device.read(len(payload)) == payload
        device.write(payload[::-1])
        assert port.read_exactly(len(payload)) == payload[::-1]
        port.flush_input()
        port.set_baud(19200)
        wait_until(lambda: device.speed() == termios.B19200, DEADLINE,
                   what="ser2net to set the pty to 19200")
    _, records = records_of(out)
    assert [json.loads(r.data)["baud"] for r in records if r.kind == "settings"][-1] == 19200
    assert "flush_input" in [r.kind for r in records]
