"""Flushes on open (DESIGN §12): on a virtual device, bytes a client
discards with an input flush before its first write are delivered again, so
a greeting reaches pyserial (which flushes input right after open) from a
recording without flush events; after the client's first write a flush
drops released rx (§7). The recordings here are written with the
SessionWriter as older files are: no flush events, no client_connect."""

import os
import select
import subprocess
import sys
import termios
from pathlib import Path

import pytest
import serial

from wiretape import _core, bridge

from test_replay_verdict import Replay
from devices import wait_until
from real_recordings import FLEXIPORT_DIR, flexiport_log

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


# --- recordings made before flush events existed ----------------------------------------------

REPOSITORY = Path(__file__).resolve().parents[3]
# The Hokuyo example's recordings (library recordings, before flush events
# and client sessions) and the hardware's flexiport logs.
OLD_WTAPE = sorted((REPOSITORY / "examples" / "hokuyo" / "recordings").glob("*.wtape"))
OLD_FLEXIPORT = ["urg04lx_2011", "utm30lx_2011"]


def first_exchange(session):
    """(what the client writes before the device's first rx, that rx up to
    the client's next write) of a .wtape session, from its first client
    session on (its start when it has no client_connect)."""
    with _core.SessionReader(str(session)) as reader:
        records = list(reader)
    kinds = [r.kind for r in records]
    if "client_connect" in kinds:
        records = records[kinds.index("client_connect"):]
    request, response = bytearray(), bytearray()
    for record in records:
        if record.kind == "tx":
            if response:
                break
            request += record.data
        elif record.kind == "rx":
            response += record.data
    assert response, f"{session}: no rx to greet a client with"
    return bytes(request), bytes(response)


def old_recordings():
    cases = [pytest.param(path, path, id=path.name) for path in OLD_WTAPE]
    cases += [pytest.param(name, None, id=f"flexiport-{name}") for name in OLD_FLEXIPORT]
    return cases


@pytest.mark.parametrize("recording, wtape", old_recordings())
def test_pyserial_gets_the_first_rx_of_a_recording_made_before_flush_events(
        recording, wtape, tmp_path):
    if wtape is None:  # a flexiport pair from the hardware, read through a converted copy
        flexiport_log(recording)
        recording = FLEXIPORT_DIR / f"{recording}.log"
        wtape = tmp_path / "converted.wtape"
        converted = subprocess.run([sys.executable, "-m", "wiretape.cli", "convert", "-q",
                                    str(recording), str(wtape)],
                                   capture_output=True, text=True, timeout=60)
        assert converted.returncode == 0, converted.stderr
    with _core.SessionReader(str(wtape)) as reader:
        kinds = {r.kind for r in reader}
    assert not kinds & {"flush_input", "flush_output"}, "not an old recording any more"
    request, response = first_exchange(wtape)
    replay = Replay(recording, tmp_path / "tty")
    try:
        # pyserial flushes input right after open, before it writes.
        with serial.Serial(replay.link, 115200, timeout=DEADLINE) as client:
            client.write(request)
            assert client.read(len(response)) == response
    finally:
        code, said = replay.stop()
    assert code == 0, said
    assert "no client was served" not in said, said
    assert "mismatch" not in said.lower(), said
