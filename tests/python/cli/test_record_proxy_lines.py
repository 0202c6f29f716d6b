"""The record proxy records the device's modem lines (DESIGN §20) for any
client, not only RFC 2217 ones: at the client's connect, then each change,
polled often enough to land among the bytes where it happened."""

import json
import socket

import wiretape
from wiretape import bridge

from line_devices import AFTER, BEFORE, line_device_session

DEADLINE = 10.0


def device_session(path):
    return line_device_session(path, answer_ms=300, close_ms=400)


def test_a_raw_tcp_client_gets_the_device_lines_recorded(tmp_path):
    device = device_session(tmp_path / "device.wtape")
    out = tmp_path / "proxy.wtape"
    # timing=causal: the answer comes 295 ms after the lines changed, far
    # more than the 10 ms poll, so the change is recorded before it.
    handle = bridge.record(f"type=replay,file={device},check=off", out,
                           listen="127.0.0.1:0", quiet=True)
    try:
        host, port = handle.address.rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=DEADLINE) as client:
            client.sendall(b"PING\n")
            received = b""
            while len(received) < 5:
                chunk = client.recv(16)
                assert chunk, "the proxy closed the connection"
                received += chunk
        assert received == b"PONG\n"
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert handle.result().ok, handle.result()
    with wiretape.SessionReader(str(out)) as reader:
        records = [(r.kind, json.loads(r.data) if r.kind == "modem_lines" else bytes(r.data))
                   for r in reader]
    kinds = [kind for kind, _ in records]
    lines = [(i, data) for i, (kind, data) in enumerate(records) if kind == "modem_lines"]
    assert [data for _, data in lines] == [BEFORE, AFTER], records
    assert kinds.index("client_connect") < lines[0][0] < kinds.index("tx")
    assert kinds.index("tx") < lines[1][0] < kinds.index("rx"), records
