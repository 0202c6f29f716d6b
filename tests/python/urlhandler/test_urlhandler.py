"""pyserial URL handlers: a small pyserial-based driver records a session with
a (fake, pty-backed) device through wiretape+record://, then runs unchanged
against the recording through wiretape://."""

import json
import os
import select
import subprocess
import sys
import textwrap
import threading
import tty

import pytest
import serial

import wiretape
from wiretape import urlhandler


class FakeThermometer:
    """A device on a pseudo-terminal: answers ``ID?`` and ``T?`` lines."""

    ANSWERS = {b"ID?": b"THERMO-1 v2.0", b"T?": b"+21.50C", b"H?": b"45%"}

    def __init__(self):
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self.requests = []
        self._stop_reader, self._stop_writer = os.pipe()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        pending = b""
        while True:
            ready, _, _ = select.select([self.master, self._stop_reader], [], [], 10)
            if self._stop_reader in ready:
                return
            if not ready:
                continue
            try:
                chunk = os.read(self.master, 1024)
            except OSError:  # the other side closed
                return
            pending += chunk
            while b"\r" in pending:
                line, pending = pending.split(b"\r", 1)
                self.requests.append(line)
                answer = self.ANSWERS.get(line, b"ERR")
                os.write(self.master, answer + b"\r\n")

    def close(self):
        os.write(self._stop_writer, b"x")
        self._thread.join(10)
        for fd in (self.master, self._slave, self._stop_reader, self._stop_writer):
            os.close(fd)


@pytest.fixture
def thermometer():
    device = FakeThermometer()
    yield device
    device.close()


def read_thermometer(port):
    """The driver under test: plain pyserial calls."""
    port.reset_input_buffer()
    port.write(b"ID?\r")
    ident = port.read_until(b"\r\n").strip().decode()
    port.write(b"T")
    port.write(b"?\r")  # split writes: replay must not care
    line = b""
    while not line.endswith(b"\r\n"):
        chunk = port.read(1)
        if not chunk:
            raise TimeoutError(f"no answer to T?: got {line!r}")
        line += chunk
    return {"id": ident, "celsius": float(line.strip()[:-1].decode())}


def test_import_wiretape_registers_the_schemes():
    # In a fresh interpreter: inside pytest the plugin registers them too.
    program = textwrap.dedent("""
        import serial, wiretape
        for url in ("wiretape:///nonexistent/x.wtape", "wiretape+record:///tmp/x.wtape"):
            try:
                serial.serial_for_url(url)
            except serial.SerialException as error:
                print("handled:", error)
    """)
    result = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 2, result.stdout
    assert "x.wtape" in lines[0]
    assert "device=" in lines[1]


def test_register_is_idempotent():
    assert urlhandler.register() is True
    assert urlhandler.register() is True
    assert serial.protocol_handler_packages.count("wiretape.urlhandler") == 1


def test_driver_records_through_pyserial_then_replays(thermometer, tmp_path):
    cassette = tmp_path / "thermo.wtape"
    recording_url = f"wiretape+record://{cassette}?device={thermometer.path}&baud=115200" \
                    "&meta_bench=desk"
    with serial.serial_for_url(recording_url, timeout=5) as port:
        recorded = read_thermometer(port)
        port.baudrate = 57600  # recorded as a settings event
    assert recorded == {"id": "THERMO-1 v2.0", "celsius": 21.5}
    assert thermometer.requests == [b"ID?", b"T?"]

    reader = wiretape.SessionReader(str(cassette))
    kinds = [record.kind for record in reader]
    tx = b"".join(r.data for r in wiretape.SessionReader(str(cassette)) if r.kind == "tx")
    rx = b"".join(r.data for r in wiretape.SessionReader(str(cassette)) if r.kind == "rx")
    assert tx == b"ID?\rT?\r"
    assert rx == b"THERMO-1 v2.0\r\n+21.50C\r\n"
    assert kinds[0] == "open" and kinds[-1] == "close"
    # read_until is one read for the driver, so one record
    assert b"THERMO-1 v2.0\r\n" in [bytes(r.data) for r in wiretape.SessionReader(str(cassette))]
    assert "flush_input" in kinds
    settings = [json.loads(bytes(r.data)) for r in wiretape.SessionReader(str(cassette))
                if r.kind == "settings"]
    assert [event["baud"] for event in settings] == [57600]
    opened = next(iter(wiretape.SessionReader(str(cassette))))
    assert "@ 115200" in json.loads(bytes(opened.data))["description"]
    header = wiretape.SessionReader(str(cassette)).header
    assert "desk" in str(header)

    replay_url = f"wiretape://{cassette}?timing=none&unused=error"
    with serial.serial_for_url(replay_url, timeout=5) as port:
        assert read_thermometer(port) == recorded
    assert thermometer.requests == [b"ID?", b"T?"]  # the device was not asked again


def test_replay_in_request_mode_serves_repeated_commands(thermometer, tmp_path):
    cassette = tmp_path / "thermo.wtape"
    with serial.serial_for_url(f"wiretape+record://{cassette}?device={thermometer.path}",
                               timeout=5) as port:
        read_thermometer(port)

    # This driver asks for the identity twice: the recording has it once.
    with serial.serial_for_url(f"wiretape://{cassette}?timing=none&match=request&repeat=last",
                               timeout=5) as port:
        for _ in range(2):
            port.write(b"ID?\r")
            assert port.read_until(b"\r\n") == b"THERMO-1 v2.0\r\n"
        port.write(b"T?\r")
        assert port.read_until(b"\r\n") == b"+21.50C\r\n"


def test_replay_mismatch_reaches_the_driver_with_the_report(thermometer, tmp_path):
    cassette = tmp_path / "thermo.wtape"
    with serial.serial_for_url(f"wiretape+record://{cassette}?device={thermometer.path}",
                               timeout=5) as port:
        read_thermometer(port)

    port = serial.serial_for_url(f"wiretape://{cassette}?timing=none&unused=ignore", timeout=5)
    try:
        with pytest.raises(wiretape.ReplayMismatch) as mismatch:
            port.write(b"XX?\r")
            port.read_until(b"\r\n")
        assert "ID?" in str(mismatch.value) or "49 44 3f" in str(mismatch.value).lower()
    finally:
        try:
            port.close()
        except wiretape.ReplayMismatch:
            pass


def test_replay_timeouts_follow_pyserial(tmp_path):
    cassette = tmp_path / "greeting.wtape"
    with wiretape.SessionWriter(str(cassette), port_type="serial") as writer:
        writer.write("rx", 0, b"hello")
    with serial.serial_for_url(f"wiretape://{cassette}?timing=none&unused=ignore",
                               timeout=0.2) as port:
        assert port.read(3) == b"hel"
        assert port.in_waiting == 2
        assert port.read(10) == b"lo"  # partial on timeout, as pyserial does
        port.timeout = 0
        assert port.read(1) == b""


def test_bad_urls_name_the_problem(tmp_path):
    missing = tmp_path / "missing.wtape"
    with pytest.raises(serial.SerialException, match="missing.wtape"):
        serial.serial_for_url(f"wiretape://{missing}?timing=none")
    existing = tmp_path / "x.wtape"
    with wiretape.SessionWriter(str(existing), port_type="serial") as writer:
        writer.write("rx", 0, b"x")
    with pytest.raises(serial.SerialException, match="bogus"):
        serial.serial_for_url(f"wiretape://{existing}?bogus=1")
    with pytest.raises(serial.SerialException, match="no session file path"):
        serial.serial_for_url("wiretape://?timing=none")
    with pytest.raises(serial.SerialException, match="twice"):
        serial.serial_for_url(f"wiretape://{existing}?timing=none&timing=session")
    with pytest.raises(serial.SerialException, match="unknown key 'speed'"):
        serial.serial_for_url(f"wiretape+record://{existing}?device=loop://&speed=2")
    with pytest.raises(serial.SerialException, match="pyserial URL"):
        serial.serial_for_url(f"wiretape+record://{existing}?device=loop://")
    with pytest.raises(serial.SerialException, match="empty"):
        serial.serial_for_url(f"wiretape+record://{existing}?device=")
    with pytest.raises(serial.SerialException, match="exactly one"):
        serial.serial_for_url(f"wiretape+record://{existing}?device=/dev/x&options=type=loopback")


def test_record_through_a_wiretape_option_string(tmp_path):
    cassette = tmp_path / "loop.wtape"
    with serial.serial_for_url(f"wiretape+record://{cassette}?options=type=loopback",
                               timeout=5) as port:
        port.write(b"ping\n")
        assert port.read_until(b"\n") == b"ping\n"
    tx = b"".join(r.data for r in wiretape.SessionReader(str(cassette)) if r.kind == "tx")
    rx = b"".join(r.data for r in wiretape.SessionReader(str(cassette)) if r.kind == "rx")
    assert (tx, rx) == (b"ping\n", b"ping\n")
    with serial.serial_for_url(f"wiretape://{cassette}?timing=none&unused=error",
                               timeout=5) as port:
        port.write(b"ping\n")
        assert port.read_until(b"\n") == b"ping\n"


def _kinds_and_payload_keys(path):
    """(kind, sorted keys of an event's JSON payload) per record; rx/tx bytes
    stand for themselves."""
    shape = []
    for record in wiretape.SessionReader(str(path)):
        if record.kind in ("rx", "tx"):
            shape.append((record.kind, bytes(record.data)))
        else:
            payload = bytes(record.data)
            shape.append((record.kind, tuple(sorted(json.loads(payload))) if payload else ()))
    return shape


def test_the_url_handler_records_as_the_library_does(thermometer, tmp_path):
    """The same exchange recorded through wiretape+record:// and through a
    port opened with log= reads back with the same records and payloads."""
    through_url = tmp_path / "url.wtape"
    with serial.serial_for_url(f"wiretape+record://{through_url}?device={thermometer.path}"
                               "&baud=115200", timeout=5) as port:
        port.reset_input_buffer()
        port.write(b"ID?\r")
        assert port.read_until(b"\r\n") == b"THERMO-1 v2.0\r\n"
        port.dtr = False
        port.baudrate = 57600

    through_library = tmp_path / "library.wtape"
    with wiretape.open_port(f"type=serial,device={thermometer.path},baud=115200,timeout=5,"
                            f"log={through_library}") as port:
        port.flush_input()
        port.write_all(b"ID?\r")
        assert port.read_until(b"\r\n") == b"THERMO-1 v2.0\r\n"
        try:
            port.dtr = False
        except wiretape.PortError:  # a pty has no modem lines; pyserial ignores that
            pass
        port.set_baud(57600)

    assert _kinds_and_payload_keys(through_url) == _kinds_and_payload_keys(through_library)
    assert [kind for kind, _ in _kinds_and_payload_keys(through_url)] == [
        "open", "flush_input", "tx", "rx", "settings", "close"]
    url_header = wiretape.SessionReader(str(through_url)).header
    library_header = wiretape.SessionReader(str(through_library)).header
    assert url_header.capture == library_header.capture == "client"
    assert url_header.port_type == library_header.port_type == "serial"
