"""The bridge's end of the shim's side channel (src/bridge/line_channel.cpp,
DESIGN §20), spoken to directly: a line change that arrives before the
client's bytes preceding it are readable at the pty's master is held until
the bridge has relayed them, then applied and recorded in its place, even
inside one read of the terminal."""

import json
import os
import select
import socket
import sys

import pytest

import wiretape
from wiretape import _core, bridge

from devices import wait_until
from shim_channel import MAGIC, REPLY, REQUEST, TIOCM_CTS, TIOCM_DSR, TIOCM_CD, \
    TIOCM_DTR, TIOCM_RTS

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the shim's side channel is Linux only")

DEADLINE_S = 30.0
HELLO, SET_OUTPUTS, GET = 1, 2, 8


def request(op, written=0, set_bits=0, clear_bits=0, value=0):
    return REQUEST.pack(MAGIC, op, written, set_bits, clear_bits, value, 0)


def device_session(path):
    with wiretape.SessionWriter(str(path), capture="wire", port_type="serial",
                                port_options="type=serial,device=/dev/ttyUSB0") as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 1_000_000, b"abcdefg")
        writer.write("close", 2_000_000, b"{}")
    return str(path)


def test_a_change_is_held_until_the_bytes_before_it_are_relayed(tmp_path):
    channel = str(tmp_path / "lines")
    recording = tmp_path / "out.wtape"
    device = device_session(tmp_path / "device.wtape")
    handle = bridge.record(f"type=replay,file={device}", recording, pty=True, quiet=True,
                           line_channel=channel)
    try:
        terminal = os.open(handle.pty_path, os.O_RDWR | os.O_NOCTTY)
        shim = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        shim.settimeout(DEADLINE_S)
        try:
            shim.connect(channel)
            shim.send(request(HELLO))
            assert REPLY.unpack(shim.recv(REPLY.size))[0] == 0
            # TIOCMGET: a recording without line events shows CTS, DSR, CD;
            # DTR and RTS are up from the open.
            shim.send(request(GET))
            lines = REPLY.unpack(shim.recv(REPLY.size))[1]
            assert lines == TIOCM_CTS | TIOCM_DSR | TIOCM_CD | TIOCM_DTR | TIOCM_RTS
            # DTR dropped after the client's 5th byte, told before any byte
            # is in the terminal: nothing can be answered yet.
            shim.send(request(SET_OUTPUTS, written=5, clear_bits=TIOCM_DTR))
            assert select.select([shim], [], [], 0)[0] == []
            os.write(terminal, b"abc")
            # One write across the change: the bridge splits its read there.
            os.write(terminal, b"defg")
            error, lines, *_ = REPLY.unpack(shim.recv(REPLY.size))
            assert error == 0
            assert lines & TIOCM_DTR == 0
            wait_until(lambda: handle.stats().bytes_to_device >= 7, DEADLINE_S,
                       "the bridge relaying the client's 7 bytes")
        finally:
            shim.close()
            os.close(terminal)
    finally:
        handle.stop()
        handle.wait(DEADLINE_S)
    with _core.SessionReader(str(recording)) as reader:
        # The client's line changes, not the device's inputs.
        records = [(r.kind, bytes(r.data)) for r in reader
                   if r.kind == "tx" or (r.kind == "modem_lines" and b"dtr" in r.data)]
    joined = []
    for kind, data in records:
        if joined and kind == "tx" and joined[-1][0] == "tx":
            joined[-1] = ("tx", joined[-1][1] + data)
        else:
            joined.append((kind, data))
    assert [kind for kind, _ in joined] == ["tx", "modem_lines", "tx"]
    assert joined[0][1] == b"abcde" and joined[2][1] == b"fg"
    assert json.loads(joined[1][1])["dtr"] is False
