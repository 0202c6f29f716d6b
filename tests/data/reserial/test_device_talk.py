"""pyserial client code recorded by pytest-reserial into test_device_talk.jsonl
(its cassette: the file's stem + .jsonl), for tests/python/tools/test_reserial_import.py.

Regenerate with pytest-reserial installed (it records real serial traffic,
here with a pseudo-terminal for the device):

    python -m pytest -p no:cacheprovider --record tests/data/reserial/test_device_talk.py

The importer test runs the same talk functions against the imported
session, replayed through ``wiretape://``.
"""

import os
import threading
import tty

import serial


def answer(request: bytes) -> bytes:
    """The device: one answer for each line."""
    if request.startswith(b"BIN"):
        return b"\x00\xff\xfe" + request[3:] + b"^\r\n"
    return b"OK " + request.rstrip(b"\n") + b"\r\n"


def talk_text(port):
    answers = []
    for request in (b"ID\n", b"GET 1\n", b"SET 2 5\n"):
        port.write(request)
        answers.append(port.read_until(b"\r\n"))
    return answers


def talk_binary(port):
    port.write(b"BIN\x01\x02\n")
    return [port.read(len(answer(b"BIN\x01\x02\n")))]


def expected(talk):
    requests = {talk_text: (b"ID\n", b"GET 1\n", b"SET 2 5\n"), talk_binary: (b"BIN\x01\x02\n",)}
    return [answer(request) for request in requests[talk]]


class Device:
    """A pseudo-terminal whose far end answers each line."""

    def __init__(self):
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self.slave = slave
        threading.Thread(target=self.serve, daemon=True).start()

    def serve(self):
        pending = b""
        while True:
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            pending += data
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                os.write(self.master, answer(line + b"\n"))


def run(talk):
    device = Device()
    port = serial.Serial(device.path, 115200, timeout=10)
    try:
        assert talk(port) == expected(talk)
    finally:
        port.close()


def test_text(reserial):
    run(talk_text)


def test_binary(reserial):
    run(talk_binary)
