"""wiretape record --pty: a client's last bytes are recorded before its
client_disconnect, also when it writes and closes at once (DESIGN §12,
Order). The proxy sees the close (inotify) and the bytes (the pty master)
in one round of its loop; it must take the bytes first."""

import os
import sys

import pytest

from wiretape import _core, bridge

from devices import TcpDevice, wait_until

DEADLINE = 10.0
CLIENTS = 60


def read_records(path):
    with _core.SessionReader(str(path)) as reader:
        records = list(reader)
        assert reader.damage is None, reader.damage
        return records


def disconnects(handle):
    return sum(1 for m in handle.messages() if m.startswith("client closed"))


def write_and_close(path, data):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(fd, data)
    finally:
        os.close(fd)


@pytest.mark.skipif(not sys.platform.startswith("linux"),
                    reason="only Linux shows a pty's clients coming and going (inotify)")
def test_a_client_that_writes_and_closes_at_once_has_its_bytes_recorded_first(tmp_path):
    out = tmp_path / "order.wtape"
    link = tmp_path / "ttyOrder"
    with TcpDevice(respond=None) as device:
        handle = bridge.record(device.options, out, pty=str(link), quiet=True)
        try:
            messages = [b"client %03d says goodbye\n" % i for i in range(CLIENTS)]
            for number, message in enumerate(messages, start=1):
                write_and_close(str(link), message)
                # One client at a time: the next opens after this one's
                # close was seen, so that their opens cannot merge.
                wait_until(lambda: disconnects(handle) >= number, DEADLINE,
                           lambda: f"client {number}'s close: {handle.messages()[-3:]}")
            wait_until(lambda: len(device.received) >= sum(map(len, messages)), DEADLINE,
                       "the device to receive every client's bytes")
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)
        assert handle.result().ok, handle.result()

    records = read_records(out)
    kinds = [r.kind for r in records if r.kind in ("client_connect", "tx", "client_disconnect")]
    sessions = []
    for record in records:
        if record.kind == "client_connect":
            sessions.append(bytearray())
        elif record.kind == "tx":
            assert sessions, "bytes recorded before any client connected"
            sessions[-1] += record.data
    # Between each connect and its disconnect, exactly that client's bytes;
    # none after a disconnect.
    assert len(sessions) == CLIENTS, kinds[:12]
    assert [bytes(s) for s in sessions] == messages
    state = "out"
    for kind in kinds:
        if kind == "client_connect":
            assert state == "out"
            state = "in"
        elif kind == "client_disconnect":
            assert state == "in"
            state = "out"
        else:
            assert state == "in", f"a client's bytes were recorded after its disconnect: {kinds}"
