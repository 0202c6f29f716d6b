"""wiretape.fuzzing (DESIGN §27, in process): a recording read once, each
plan a replay of it mutated; pyserial's own serial.Serial served the mutated
replay; a plan written as a session that plays as it was fuzzed."""

import os
import pathlib
import subprocess
import sys

import pytest
import serial

import wiretape
from wiretape.fuzzing import DRIVER_ERRORS, FuzzedRecording

EXAMPLE = pathlib.Path(__file__).resolve().parents[3] / "examples" / "pyserial"
RECORDING = EXAMPLE / "recordings" / "test_thermometer" / "test_identify_and_read.wtape"

DROP_FIRST_ANSWER = bytes([5, 0, 0, 0])
LAST_ANSWER_DIGIT_TO_FF = bytes([1, 1, 0, 5])


@pytest.fixture
def thermometer_class(monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLE))
    from thermometer import Thermometer
    return Thermometer


def test_empty_plan_serves_the_recording(thermometer_class):
    recording = FuzzedRecording(RECORDING)
    assert recording.units == 2
    assert recording.edits(b"") == []
    with recording.serial(b""):
        thermometer = thermometer_class()
        assert thermometer.identify().startswith("ACME THERMO")
        assert thermometer.temperature() == 21.5
        thermometer.close()


def test_plan_changes_what_the_driver_reads(thermometer_class):
    recording = FuzzedRecording(RECORDING)
    assert recording.edits(LAST_ANSWER_DIGIT_TO_FF) == ["rx record 1 byte 0: 0x32 → 0xff"]
    with recording.serial(LAST_ANSWER_DIGIT_TO_FF):
        thermometer = thermometer_class()
        thermometer.identify()
        with pytest.raises(ValueError):  # a byte that is no ASCII digit
            thermometer.temperature()


def test_port_of_a_plan_ends_at_the_recordings_end():
    recording = FuzzedRecording(RECORDING)
    port = recording.open(DROP_FIRST_ANSWER)
    port.write(b"*IDN?\n")
    port.write(b"TEMP?\n")
    assert port.read_until(b"\n", 100, 5.0) == b"21.5\n"
    with pytest.raises(wiretape.PortClosed):
        port.read(1, 5.0)
    assert isinstance(wiretape.PortClosed("x"), DRIVER_ERRORS)


def test_written_plan_replays_as_it_was_fuzzed(tmp_path):
    recording = FuzzedRecording(RECORDING)
    path = tmp_path / "finding.wtape"
    edits = recording.write(path, DROP_FIRST_ANSWER)
    assert edits == ["rx record 0 dropped"]
    reader = wiretape.SessionReader(str(path))
    assert list(reader.header.edits) == edits
    rx = [record.data for record in reader if record.kind == "rx"]
    assert rx == [b"21.5\n"]


def test_profile_that_does_not_fit_is_refused_by_name():
    with pytest.raises(wiretape.OptionError, match="'modbus-rtu' does not fit"):
        FuzzedRecording(RECORDING, profile="modbus-rtu")


def test_session_without_device_bytes_is_refused_by_name(tmp_path):
    path = tmp_path / "quiet.wtape"
    writer = wiretape.SessionWriter(str(path), wiretape.SessionHeader(port_type="serial"))
    writer.write("tx", 1000, b"PING\n")
    writer.close()
    with pytest.raises(wiretape.SessionError, match="no device bytes"):
        FuzzedRecording(path)


def test_serial_works_where_pytest_cannot_be_imported():
    # A driver fuzzed with atheris runs without pytest: FuzzedRecording.serial
    # must not need it (pytest blocked in a fresh interpreter).
    script = (
        "import sys\n"
        "sys.modules['pytest'] = None\n"
        f"sys.path.insert(0, {str(EXAMPLE)!r})\n"
        "from wiretape.fuzzing import FuzzedRecording\n"
        "from thermometer import Thermometer\n"
        f"recording = FuzzedRecording({str(RECORDING)!r})\n"
        "with recording.serial(b''):\n"
        "    thermometer = Thermometer()\n"
        "    print(thermometer.identify().startswith('ACME THERMO'), thermometer.temperature())\n"
        "    thermometer.close()\n"
        "assert 'pytest' not in sys.modules or sys.modules['pytest'] is None\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["True", "21.5"]


def modbus_tcp_session(path):
    """Two Modbus TCP reads (transaction ids 1 and 2), each answered."""
    writer = wiretape.SessionWriter(str(path), wiretape.SessionHeader(port_type="tcp"))
    for n in (1, 2):
        request = bytes([0, n, 0, 0, 0, 6, 1, 3, 0, 0, 0, 1])
        answer = bytes([0, n, 0, 0, 0, 5, 1, 3, 2, 0x12, 0x34])
        writer.write("tx", n * 10_000_000, request)
        writer.write("rx", n * 10_000_000 + 1_000_000, answer)
    writer.close()
    return path


def test_a_plan_changing_only_what_the_profile_leaves_out_is_inert(tmp_path):
    recording = FuzzedRecording(modbus_tcp_session(tmp_path / "modbus.wtape"), "modbus-tcp")
    flip = lambda frame, offset: bytes([0, frame, offset, 0])  # noqa: E731
    # The transaction id (bytes 0-1) is left out of matching: the replay
    # serves the client's own, and a driver has no right to fail on it.
    assert recording.edits(flip(0, 1)) and recording.inert(flip(0, 1))
    assert recording.inert(flip(0, 1) + flip(1, 0) + bytes([7, 1, 4, 0]))  # and a split
    # The register's value, the function code: a driver may refuse those.
    assert not recording.inert(flip(0, 10))
    assert not recording.inert(flip(0, 1) + flip(1, 7))
    # Without a profile nothing is left out.
    assert not FuzzedRecording(tmp_path / "modbus.wtape").inert(flip(0, 1))
