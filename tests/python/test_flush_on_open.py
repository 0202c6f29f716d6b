"""Flushes on open (DESIGN §12): on a virtual device, bytes a client
discards with an input flush before its first write are delivered again, so
a greeting reaches pyserial (which flushes input right after open) from a
recording without flush events; after the client's first write a flush
drops released rx (§7). The recordings here are written with the
SessionWriter as older files are: no flush events, no client_connect."""

import os
import select
import sys
import termios

import pytest
import serial

from wiretape import bridge

from test_replay_verdict import Replay
from devices import wait_until

DEADLINE = 10.0
GREETING = b"HELLO from the device\r\n"

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"),
    reason="only Linux shows a pty's clients coming and going (inotify)")


@pytest.fixture
def greeting(device_recording):
    return device_recording(name="greeting.wtape", records=[
        ("rx", 0, GREETING), ("tx", 2_000_000, b"PING\n"), ("rx", 2_500_000, b"PONG\n")])


def read_exactly(fd, count):
    data = bytearray()
    while len(data) < count:
        ready, _, _ = select.select([fd], [], [], DEADLINE)
        assert ready, f"timed out with {bytes(data)!r}"
        data += os.read(fd, count - len(data))
    return bytes(data)


def open_raw(path):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    attributes = termios.tcgetattr(fd)
    attributes[3] &= ~(termios.ICANON | termios.ECHO | termios.ISIG | termios.IEXTEN)
    attributes[1] &= ~termios.OPOST
    termios.tcsetattr(fd, termios.TCSANOW, attributes)
    return fd


def test_a_greeting_flushed_before_the_first_write_is_delivered_again(greeting, tmp_path):
    link = str(tmp_path / "tty")
    with bridge.serve_replay(greeting, pty=link, replay_options="timing=none",
                             quiet=True) as handle:
        fd = open_raw(link)
        try:
            # The greeting is in the terminal, unread; then the opening flush
            # that pyserial makes.
            ready, _, _ = select.select([fd], [], [], DEADLINE)
            assert ready, "the greeting never reached the terminal"
            termios.tcflush(fd, termios.TCIFLUSH)
            assert read_exactly(fd, len(GREETING)) == GREETING
            os.write(fd, b"PING\n")
            assert read_exactly(fd, 5) == b"PONG\n"
        finally:
            os.close(fd)
        handle.stop()
        assert handle.wait(DEADLINE)
        assert handle.result().ok and not handle.result().nothing_served, handle.result()


def test_after_the_first_write_a_flush_drops_released_rx(device_recording, tmp_path):
    recording = device_recording(name="two.wtape", records=[
        ("tx", 1_000_000, b"a"), ("rx", 1_500_000, b"A1"),
        ("tx", 2_000_000, b"b"), ("rx", 2_500_000, b"B1")])
    link = str(tmp_path / "tty")
    with bridge.serve_replay(recording, pty=link, replay_options="timing=none",
                             quiet=True) as handle:
        fd = open_raw(link)
        try:
            os.write(fd, b"a")
            ready, _, _ = select.select([fd], [], [], DEADLINE)
            assert ready, "the answer never came"
            termios.tcflush(fd, termios.TCIFLUSH)
            os.write(fd, b"b")
            assert read_exactly(fd, 2) == b"B1"
        finally:
            os.close(fd)
        handle.stop()
        assert handle.wait(DEADLINE)


def test_pyserial_reads_the_greeting_of_a_recording_without_flush_events(greeting, tmp_path):
    link = str(tmp_path / "tty")
    with bridge.serve_replay(greeting, pty=link, replay_options="timing=none",
                             quiet=True) as handle:
        with serial.Serial(link, timeout=DEADLINE) as client:
            assert client.read(len(GREETING)) == GREETING
            client.write(b"PING\n")
            assert client.read(5) == b"PONG\n"
        handle.stop()
        assert handle.wait(DEADLINE)
        assert handle.result().ok, handle.result()


def test_the_cli_exits_0_for_a_pyserial_client_served_the_greeting(greeting, tmp_path):
    replay = Replay(greeting, tmp_path / "tty")
    try:
        with serial.Serial(replay.link, 115200, timeout=DEADLINE) as client:
            assert client.read(len(GREETING)) == GREETING
        replay.wait_for("client closed")
    finally:
        code, said = replay.stop()
    assert code == 0, said
    assert "no client was served" not in said
