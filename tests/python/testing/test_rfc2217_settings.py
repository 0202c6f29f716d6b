"""The plugin on a serial line exported over RFC 2217
(``--wiretape-device=rfc2217://HOST:PORT``, wiretape's own ``serve
--protocol rfc2217`` in front of a pty): recording and live, through
``wiretape_serial`` and ``wiretape_url``, the rate the driver opens at
and the settings it changes reach the server, and the recording holds
them. The tests run with pytester in this process: they read the pty's
settings (what the server applied) by its path."""

import json

import pytest

import wiretape

from pty_device import served_over_rfc2217

pytest.importorskip("serial", reason="pyserial is not installed")

pytest_plugins = ["pytester"]

TESTS = """
    import os
    import termios

    import serial

    PTY = os.environ["WIRETAPE_TEST_PTY"]
    PATH = "/dev/ttyWIRETAPELAB0"  # the driver's path; the device setting is the device

    def speed():
        fd = os.open(PTY, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            return termios.tcgetattr(fd)[5]
        finally:
            os.close(fd)

    def test_serial(wiretape_serial):
        with serial.Serial(PATH, 115200, timeout=5) as port:
            assert speed() == termios.B115200
            port.write(b"ID?\\n")
            port.baudrate = 9600
            assert speed() == termios.B9600

    def test_url(wiretape_url):
        with serial.serial_for_url(wiretape_url, baudrate=115200, timeout=5) as port:
            assert speed() == termios.B115200
            port.write(b"ID?\\n")
            port.baudrate = 9600
            assert speed() == termios.B9600
"""


@pytest.fixture
def lab(pytester, monkeypatch):
    """The device setting of a pty served over RFC 2217, the tests written."""
    with served_over_rfc2217() as (device, address):
        monkeypatch.setenv("WIRETAPE_TEST_PTY", device.path)
        pytester.makepyfile(test_lab=TESTS)
        yield device, f"--wiretape-device=rfc2217://{address}"


def recorded(pytester, test):
    path = pytester.path / "recordings" / "test_lab" / f"{test}.wtape"
    with wiretape.SessionReader(str(path)) as reader:
        records = list(reader)
        header = reader.header
    opened = json.loads(bytes(records[0].data))["description"]
    settings = [json.loads(bytes(r.data)).get("baud") for r in records if r.kind == "settings"]
    tx = b"".join(bytes(r.data) for r in records if r.kind == "tx")
    return header, opened, settings, tx


def test_recording_passes_the_drivers_rate_and_settings_on(pytester, lab):
    device, setting = lab
    result = pytester.runpytest("--wiretape-record=once", setting)
    result.assert_outcomes(passed=2)
    assert device.read(8) == b"ID?\nID?\n"

    header, opened, settings, tx = recorded(pytester, "test_serial")
    assert header.port_type == "rfc2217" and "baud=115200" in header.port_options
    assert "@ 115200" in opened and settings == [9600] and tx == b"ID?\n"
    # pyserial sets the rate after opening: the first settings event.
    header, opened, settings, tx = recorded(pytester, "test_url")
    assert header.port_type == "rfc2217"
    assert settings == [115200, 9600] and tx == b"ID?\n"


def test_live_passes_the_drivers_rate_and_settings_on(pytester, lab):
    device, setting = lab
    # pyserial's rfc2217 client uses threading names deprecated in Python 3.10.
    result = pytester.runpytest("--wiretape-live", setting, "-W", "ignore::DeprecationWarning")
    result.assert_outcomes(passed=2)
    assert device.read(8) == b"ID?\nID?\n"
    assert not (pytester.path / "recordings").exists()
