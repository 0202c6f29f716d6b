"""How an operating-system error becomes text (issue 16): a device loss
without an errno never says ': Success', an errno's text is never repeated,
and one helper (system_error_message, src/core/errors.cpp) is the only place
an errno becomes text."""

import os
import re
import socket
from pathlib import Path

import pytest

import wiretape
from wiretape import bridge

from devices import TcpDevice, wait_until

DEADLINE_S = 10.0
REPO = Path(__file__).resolve().parents[3]


def test_a_device_that_closed_its_connection_is_not_reported_as_success(tmp_path):
    """EOF has no errno: the device loss recorded and logged must not end in
    ': Success' (std::system_error's text for errno 0)."""
    output = tmp_path / "lost.wtape"
    with TcpDevice() as device:
        handle = bridge.serve(device.options, "127.0.0.1:0", output=output, quiet=True)
        try:
            host, port = handle.address.rsplit(":", 1)
            with socket.create_connection((host, int(port)), timeout=DEADLINE_S) as client:
                client.sendall(b"x")
                assert client.recv(1) == b"X"
                device.close()  # the device's end closes: end of file
                assert handle.wait(DEADLINE_S)
        finally:
            handle.stop()
            handle.wait()
        messages = handle.messages() + [handle.result().message]
    lost = [r for r in wiretape.SessionReader(str(output)) if r.kind == "device_lost"]
    assert lost, messages
    for text in [lost[0].data.decode()] + messages:
        assert "Success" not in text, text


def test_an_os_error_names_its_errno_once():
    """A read of a connection the device reset fails with ECONNRESET: its
    text once in the message, not twice."""
    with TcpDevice(respond=None) as device:
        port = wiretape.open_port(device.options)
        try:
            wait_until(lambda: device.connections == 1, DEADLINE_S,
                       what="the device to accept the connection")
            device.drop()
            with pytest.raises(wiretape.PortClosed) as raised:
                port.read(1, timeout=DEADLINE_S)
        finally:
            port.close()
    text = str(raised.value)
    assert raised.value.errno is not None, text
    assert text.count(os.strerror(raised.value.errno)) == 1, text
    assert "Success" not in text


def test_only_the_message_helper_turns_an_errno_into_text():
    """system_error_message (src/core/errors.cpp) is the one place an errno
    becomes text: anywhere else, the text could repeat or say 'Success'."""
    pattern = re.compile(r"(?<![_a-z])strerror\s*\(|generic_category\(\)\s*\.message|"
                         r"system_category\(\)\s*\.message")
    offenders = []
    for path in sorted((REPO / "src").rglob("*.[ch]pp")) + sorted((REPO / "include").rglob("*.hpp")):
        if path == REPO / "src" / "core" / "errors.cpp":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if pattern.search(line):
                offenders.append(f"{path.relative_to(REPO)}:{number}: {line.strip()}")
    assert not offenders, "\n".join(offenders)
