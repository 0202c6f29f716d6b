"""pyserial's rfc2217:// client and the serial line (DESIGN §20): recorded
through `serve --protocol rfc2217` from a device with modem lines (a replay
of a session written here: a pty has none), replayed with `replay --listen
--protocol rfc2217`: the client reads the recorded CTS/DSR/RI/CD, and its
DTR reset pulse is checked."""

import json
import time

import pytest

import wiretape
from wiretape import bridge

from devices import announced_address, interrupt, start_cli, wait_until
from line_devices import AFTER, BEFORE, line_device_session

serial = pytest.importorskip("serial", reason="pyserial is not installed")

DEADLINE = 10.0

# pyserial's rfc2217 client uses threading names deprecated in Python 3.10.
pytestmark = pytest.mark.filterwarnings("ignore:set.*is deprecated:DeprecationWarning")


def device_session(path):
    return line_device_session(path, answer_ms=7, close_ms=10)


def lines(client):
    return {"cts": client.cts, "dsr": client.dsr, "ri": client.ri, "cd": client.cd}


def modem_state_known(client):
    try:
        lines(client)
    except serial.SerialException:  # no NOTIFY-MODEMSTATE yet
        return False
    return True


def read_exactly(port, count):
    data = bytearray()
    deadline = time.monotonic() + DEADLINE
    while len(data) < count and time.monotonic() < deadline:
        data += port.read(count - len(data))
    return bytes(data)


def board_client(address, pulse=True, extra_pulse=False):
    """What a board programmer does: reset by DTR, then talk; returns the
    lines it saw before and after."""
    with serial.serial_for_url("rfc2217://" + address, timeout=DEADLINE) as client:
        wait_until(lambda: modem_state_known(client), DEADLINE, what="the device's lines")
        before = lines(client)
        if pulse:
            client.dtr = False
            client.dtr = True
        if extra_pulse:
            client.dtr = False
            client.dtr = True
        client.write(b"PING\n")
        answer = read_exactly(client, 5)
        wait_until(lambda: lines(client) == AFTER, DEADLINE,
                   what=lambda: f"the device's answer on its lines (now {lines(client)})")
        return before, answer, lines(client)


@pytest.fixture
def recording(tmp_path):
    """A recording made through `serve --protocol rfc2217` by a client that
    pulses DTR, of a device whose lines change among the bytes."""
    device = device_session(tmp_path / "device.wtape")
    out = tmp_path / "board.wtape"
    handle = bridge.serve(f"type=replay,file={device},timing=none,check=off", "127.0.0.1:0",
                          protocol="rfc2217", output=out, quiet=True)
    try:
        before, answer, after = board_client(handle.address)
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert handle.result().ok, handle.result()
    assert before == BEFORE and answer == b"PONG\n" and after == AFTER
    return out


def test_serve_records_the_device_lines_and_the_client_pulse(recording):
    with wiretape.SessionReader(str(recording)) as reader:
        records = list(reader)
    kinds = [r.kind for r in records]
    events = [(r.kind, json.loads(r.data)) for r in records if r.kind == "modem_lines"]
    device = [e for _, e in events if "cts" in e]
    host = [e for _, e in events if "dtr" in e or "rts" in e]
    # The device's lines as the client found them, then its answer.
    assert device[0] == BEFORE and device[-1] == AFTER, device
    assert kinds.index("client_connect") < kinds.index("modem_lines")
    # The pulse, in order (after pyserial's own DTR and RTS on open).
    dtr_levels = [e["dtr"] for e in host if "dtr" in e]
    assert dtr_levels[-2:] == [False, True], host
    # Recorded where it happened: before the client's bytes; the answer after.
    ordered = [(r.kind, json.loads(r.data) if r.kind == "modem_lines" else r.data)
               for r in records if r.kind in ("modem_lines", "tx")]
    tx_at = ordered.index(("tx", b"PING\n"))
    assert ("modem_lines", {"dtr": False, "applied": True}) in ordered[:tx_at]
    assert ("modem_lines", AFTER) in ordered[tx_at:]


def replay_cli(recording, *extra):
    child = start_cli("replay", str(recording), "--listen", "127.0.0.1:0",
                      "--protocol", "rfc2217", "--timing", "none", *extra)
    host, port = announced_address(child, "tcp")
    return child, f"{host}:{port}"


def test_replay_serves_the_lines_and_passes_the_same_client(recording):
    child, address = replay_cli(recording)
    try:
        before, answer, after = board_client(address)
    finally:
        code, _, err = interrupt(child)
    assert (before, answer, after) == (BEFORE, b"PONG\n", AFTER)
    assert code == 0, err


@pytest.mark.parametrize("client, expected, actual", [
    (dict(pulse=False), "expected line change: DTR low", "actual line change:   (none)"),
    (dict(extra_pulse=True), "expected line change: (none)", "actual line change:   DTR low"),
])
def test_replay_names_a_missing_or_extra_reset_pulse(recording, client, expected, actual):
    child, address = replay_cli(recording)
    try:
        with pytest.raises(Exception):
            board_client(address, **client)
    finally:
        code, _, err = interrupt(child)
    assert code == 1, err
    assert "replay mismatch" in err and expected in err and actual in err, err
    assert "session time" in err and "exchange" in err, err


def test_protocol_needs_listen(tmp_path, recording):
    child = start_cli("replay", str(recording), "--pty", str(tmp_path / "tty"),
                      "--protocol", "rfc2217")
    _, err = child.communicate(timeout=60)
    assert child.returncode == 2, err
    assert "--protocol rfc2217 is spoken over TCP: give --listen HOST:PORT" in err, err
