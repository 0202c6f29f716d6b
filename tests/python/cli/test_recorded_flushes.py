"""The record proxy records a pty client's input and output flushes as
events (its pty in packet mode), and replay waits for the client's own flush
before serving rx recorded after one (DESIGN §12, Flushes on open)."""

import os
import sys
import termios

import pytest
import serial

from wiretape import _core, bridge

from devices import TcpDevice, wait_until

DEADLINE = 10.0
GREETING = b"HELLO after the flush\r\n"

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"),
    reason="only Linux shows a pty's clients coming and going (inotify)")


def test_the_proxy_records_a_pty_clients_flushes_in_order(tmp_path):
    out = tmp_path / "flushes.wtape"
    link = str(tmp_path / "tty")
    with TcpDevice(respond=None) as device:
        handle = bridge.record(device.options, out, pty=link, quiet=True)
        try:
            fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
            try:
                termios.tcflush(fd, termios.TCIFLUSH)
                termios.tcflush(fd, termios.TCOFLUSH)
                os.write(fd, b"x")
                # The proxy reads the flushes and the byte in order, from
                # one descriptor: the byte's arrival means both are seen.
                wait_until(lambda: bytes(device.received) == b"x", DEADLINE,
                           "the client's byte to reach the device")
            finally:
                os.close(fd)
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)
    assert handle.result().ok, handle.result()
    with _core.SessionReader(str(out)) as reader:
        kinds = [r.kind for r in reader]
    wanted = ["client_connect", "flush_input", "flush_output", "tx"]
    assert [k for k in kinds if k in wanted] == wanted


def test_pyserial_is_greeted_after_its_flush_as_the_recording_shows(device_recording, tmp_path):
    recording = device_recording(name="gated.wtape", records=[
        ("client_connect", 1_000, b'{"peer":"pty","role":"control"}'),
        ("flush_input", 2_000, b"{}"),
        ("rx", 3_000, GREETING)])
    link = str(tmp_path / "tty")
    with bridge.serve_replay(recording, pty=link, replay_options="timing=none",
                             quiet=True) as handle:
        with serial.Serial(link, timeout=DEADLINE) as client:
            assert client.read(len(GREETING)) == GREETING
        handle.stop()
        assert handle.wait(DEADLINE)
    assert handle.result().ok and not handle.result().nothing_served, handle.result()
