"""wiretape.Port for serial lines (over a pty, the only terminal a test
machine is sure to have) and UDP (datagram boundaries)."""

import errno
import re
import socket

import pytest

import wiretape


@pytest.fixture
def serial_over_pty(tmp_path):
    link = tmp_path / "tty"
    device = wiretape.open_port(f"type=pty,link={link},timeout=2")
    port = wiretape.open_port(f"type=serial,device={link},baud=115200,timeout=2")
    yield port, device
    port.close()
    device.close()


def test_serial_baud_property_and_set_baud_program_the_line(serial_over_pty):
    port, device = serial_over_pty
    assert port.type == "serial"
    assert port.baud == 115200
    port.baud = 57600
    assert port.baud == 57600
    assert "57600" in port.description
    port.set_baud(19200)
    assert port.serial_settings()["baud"] == 19200
    assert device.serial_settings()["baud"] == 19200  # the terminal's side agrees


def test_serial_configure_changes_only_what_is_given(serial_over_pty):
    port, _ = serial_over_pty
    port.configure(stopbits=2, parity="even")
    settings = port.serial_settings()
    assert settings == {"baud": 115200, "databits": 8, "stopbits": 2,
                        "parity": "even", "flow": "none"}
    assert re.search(r"8E2", port.description)


def test_serial_modem_lines_on_a_pty_raise_port_error_with_errno(serial_over_pty):
    port, _ = serial_over_pty
    for line in ("cts", "dsr", "ri", "cd", "dtr", "rts"):
        with pytest.raises(wiretape.PortError) as raised:
            getattr(port, line)
        assert raised.value.errno == errno.ENOTTY, line
        assert "modem lines" in str(raised.value)
    with pytest.raises(wiretape.PortError):
        port.dtr = True
    with pytest.raises(wiretape.PortError):
        port.rts = False


def test_serial_bytes_cross_both_ways(serial_over_pty):
    port, device = serial_over_pty
    assert port.write_all(b"VV\n") == 3
    assert device.read_exactly(3) == b"VV\n"
    device.write_all(b"VV\n00P\n\n")
    assert port.read_until(b"\n\n") == b"VV\n00P\n\n"
    port.send_break(0.01)


def test_serial_device_that_does_not_exist_is_a_port_error(tmp_path):
    missing = tmp_path / "ttyUSB99"
    with pytest.raises(wiretape.PortError) as raised:
        wiretape.open_port(f"type=serial,device={missing}")
    assert raised.value.errno == errno.ENOENT
    assert str(missing) in str(raised.value)


@pytest.fixture
def udp_pair():
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(("127.0.0.1", 0))
    peer.settimeout(5)
    host, number = peer.getsockname()
    port = wiretape.open_port(
        f"type=udp,host={host},port={number},bind_host=127.0.0.1,bind_port=0,timeout=2")
    yield port, peer
    port.close()
    peer.close()


def test_udp_keeps_datagram_boundaries(udp_pair):
    port, peer = udp_pair
    assert port.write(b"first") == 5
    assert port.write(b"second") == 6
    data, address = peer.recvfrom(100)
    assert data == b"first"
    assert peer.recvfrom(100)[0] == b"second"
    peer.sendto(b"one", address)
    peer.sendto(b"two", address)
    assert port.wait_readable(5)
    assert port.read(100) == b"one"  # one datagram per read
    assert port.read(100) == b"two"
    assert port.read(100, timeout=0.05) == b""


def test_udp_short_read_truncates_the_datagram(udp_pair):
    port, peer = udp_pair
    port.write(b"hello")
    _, address = peer.recvfrom(100)
    peer.sendto(b"0123456789", address)
    peer.sendto(b"next", address)
    assert port.read(4) == b"0123"
    assert port.read(100) == b"next"
