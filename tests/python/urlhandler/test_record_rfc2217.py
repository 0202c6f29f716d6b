"""``wiretape+record://`` on a serial line exported over RFC 2217
(``device=rfc2217://HOST:PORT``, wiretape's own ``serve --protocol
rfc2217`` in front of a pty): the driver's settings reach the server, as
on a local serial port, and the recording holds them."""

import json
import termios

import pytest

import wiretape

from pty_device import served_over_rfc2217

serial = pytest.importorskip("serial", reason="pyserial is not installed")


@pytest.fixture
def served():
    with served_over_rfc2217() as (device, address):
        yield device, address


def settings_events(path):
    with wiretape.SessionReader(str(path)) as reader:
        return [json.loads(bytes(r.data)) for r in reader if r.kind == "settings"]


def test_the_rate_a_driver_opens_at_and_its_changes_reach_the_server(served, tmp_path):
    device, address = served
    cassette = tmp_path / "lab.wtape"
    url = f"wiretape+record://{cassette}?device=rfc2217://{address}"
    with serial.serial_for_url(url, baudrate=115200, timeout=5) as port:
        assert device.speed() == termios.B115200
        port.write(b"ID?\n")
        assert device.read(4) == b"ID?\n"
        device.write(b"LAB-1\n")
        assert port.read_until(b"\n") == b"LAB-1\n"
        port.baudrate = 9600
        assert device.speed() == termios.B9600
        port.stopbits = serial.STOPBITS_TWO
        assert device.stop_bits() == 2
    events = settings_events(cassette)
    assert [event.get("baud") for event in events][:2] == [115200, 9600]
    assert events[-1].get("stopbits") == 2
    with wiretape.SessionReader(str(cassette)) as reader:
        assert reader.header.port_type == "rfc2217"


def test_the_rate_in_the_url_is_the_rate_it_opens_at(served, tmp_path):
    device, address = served
    cassette = tmp_path / "lab.wtape"
    url = f"wiretape+record://{cassette}?device=rfc2217://{address}&baud=115200"
    with serial.serial_for_url(url, timeout=5) as port:
        assert device.speed() == termios.B115200
        port.baudrate = 9600
        assert device.speed() == termios.B9600
    with wiretape.SessionReader(str(cassette)) as reader:
        opened = next(iter(reader))
        assert "baud=115200" in reader.header.port_options
    assert "@ 115200" in json.loads(bytes(opened.data))["description"]
    assert settings_events(cassette) == [{"baud": 9600}]


def test_another_pyserial_url_is_refused_naming_it(tmp_path):
    with pytest.raises(serial.SerialException, match="'socket://127.0.0.1:1' is a pyserial URL"):
        serial.serial_for_url(f"wiretape+record://{tmp_path / 'x.wtape'}"
                              "?device=socket://127.0.0.1:1")
