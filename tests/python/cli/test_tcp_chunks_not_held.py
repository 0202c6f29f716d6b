"""A device's answer in two pieces reaches a TCP client piece by piece:
`wiretape record --listen` sends each read of the device at once
(TCP_NODELAY, docs/recording.md). With Nagle's algorithm the second piece
would wait for the client to acknowledge the first, which a client waiting
for the rest of its answer delays by about 40 ms on Linux."""

import os
import socket
import statistics
import time
import tty

from devices import announced_address, interrupt, start_cli

EXCHANGES = 10
DEADLINE = 10.0
# Each second piece arrives within a millisecond when sent at once and
# after the client's delayed acknowledgement (40 ms or more) when held.
HELD_MS = 20.0


def read_exactly(sock: socket.socket, size: int) -> bytes:
    data = b""
    while len(data) < size:
        chunk = sock.recv(size - len(data))
        assert chunk, f"the relay closed after {len(data)} of {size} bytes"
        data += chunk
    return data


def read_device(master: int, size: int) -> bytes:
    data = b""
    while len(data) < size:
        data += os.read(master, size - len(data))
    return data


def test_second_piece_of_an_answer_is_not_held_for_the_clients_acknowledgement(tmp_path):
    master, slave = os.openpty()
    tty.setraw(master)
    child = start_cli("record", "--device", f"type=serial,device={os.ttyname(slave)}",
                      "--listen", "127.0.0.1:0", "-o", str(tmp_path / "pieces.wtape"))
    try:
        client = socket.create_connection(announced_address(child, "tcp"), timeout=DEADLINE)
        second_piece_ms = []
        with client:
            for index in range(EXCHANGES):
                request = b"REQ%02d" % index
                client.sendall(request)
                assert read_device(master, len(request)) == request
                os.write(master, b"first piece;")
                # The first piece has crossed the relay before the second is
                # written: the second cannot join it in one segment.
                assert read_exactly(client, 12) == b"first piece;"
                written = time.monotonic()
                os.write(master, b"second piece\n")
                assert read_exactly(client, 13) == b"second piece\n"
                second_piece_ms.append((time.monotonic() - written) * 1e3)
    finally:
        status, _, err = interrupt(child)
        os.close(master)
        os.close(slave)
    assert status == 0, err
    assert statistics.median(second_piece_ms) < HELD_MS, second_piece_ms
