"""``replay --udp`` serves and checks empty datagrams (DESIGN.md section 23:
a zero-length datagram is a record like any other, both ways): a recorded
empty reply goes out as an empty datagram at its place, and a client's
datagram is checked against a recorded empty request under check=data."""

import socket
import subprocess

import pytest

from wiretape import bridge

from devices import announced_address, interrupt, start_cli

DEADLINE = 10.0

EMPTY_BOTH_WAYS = [
    ("open", 0, b"{}"),
    ("tx", 1_000_000, b""),
    ("rx", 2_000_000, b""),
    ("tx", 3_000_000, b"after"),
    ("rx", 4_000_000, b"AFTER"),
    ("close", 5_000_000, b""),
]


def udp_socket():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(DEADLINE)
    return sock


def start_replay(path, timing="none"):
    child = start_cli("replay", str(path), "--udp", "127.0.0.1:0", "--timing", timing)
    return child, announced_address(child, "udp")


def record_empty_both_ways(out):
    """Records, through ``record --udp``, a device that answers each
    datagram with it in upper case: an empty request and its empty reply,
    then b"after" and b"AFTER"."""
    with udp_socket() as device, udp_socket() as driver:
        options = "type=udp,host=127.0.0.1,port=%d" % device.getsockname()[1]
        handle = bridge.record(options, out, udp="127.0.0.1:0", quiet=True)
        host, port = handle.address.rsplit(":", 1)
        for request in (b"", b"after"):
            driver.sendto(request, (host, int(port)))
            data, proxy = device.recvfrom(65535)
            device.sendto(data.upper(), proxy)
            assert driver.recv(65535) == request.upper()
        handle.stop()
        assert handle.wait(DEADLINE)
        assert handle.result().ok


@pytest.mark.parametrize("timing", ["none", "causal", "session"])
def test_a_recorded_empty_exchange_replays_as_empty_datagrams(tmp_path, timing):
    out = tmp_path / "udp.wtape"
    record_empty_both_ways(out)
    child, where = start_replay(out, timing)
    try:
        with udp_socket() as client:
            client.sendto(b"", where)
            assert client.recv(65535) == b""
            client.sendto(b"after", where)
            assert client.recv(65535) == b"AFTER"
    finally:
        status, _, err = interrupt(child)
    assert status == 0, err
    assert "never" not in err, err  # nothing recorded was left unused


def wait_for_exit(child):
    try:
        _, err = child.communicate(timeout=DEADLINE)
    except subprocess.TimeoutExpired:
        child.kill()
        _, err = child.communicate()
        raise AssertionError("the replay did not end on the mismatch: " + err)
    return child.returncode, err


def test_a_datagram_in_place_of_a_recorded_empty_one_is_a_mismatch(session_file):
    path = session_file(EMPTY_BOTH_WAYS, port_type="udp")
    child, where = start_replay(path)
    with udp_socket() as client:
        client.sendto(b"after", where)
        status, err = wait_for_exit(child)
    assert status == 1, err
    assert "the client's datagram differs from the recorded one " \
           "(5 bytes written, 0 recorded)" in err, err
    assert "expected: (an empty datagram)" in err, err


def test_an_empty_datagram_in_place_of_a_recorded_one_is_a_mismatch(session_file):
    records = [("open", 0, b"{}"), ("tx", 1_000_000, b"ping"), ("rx", 2_000_000, b"pong"),
               ("close", 3_000_000, b"")]
    path = session_file(records, port_type="udp")
    child, where = start_replay(path)
    with udp_socket() as client:
        client.sendto(b"", where)
        status, err = wait_for_exit(child)
    assert status == 1, err
    assert "the client's datagram differs from the recorded one " \
           "(0 bytes written, 4 recorded)" in err, err


def test_a_peer_gets_an_unprompted_empty_datagram_at_its_place(session_file):
    records = [("open", 0, b"{}"), ("rx", 1_000_000, b"scan 0"), ("rx", 2_000_000, b""),
               ("rx", 3_000_000, b"scan 1"), ("close", 4_000_000, b"")]
    path = session_file(records, port_type="udp")
    with udp_socket() as peer:
        host, port = peer.getsockname()
        child = start_cli("replay", str(path), "--udp", "127.0.0.1:0",
                          "--peer", "%s:%d" % (host, port), "--timing", "none")
        try:
            got = [peer.recv(65535) for _ in range(3)]
        finally:
            status, _, err = interrupt(child)
    assert got == [b"scan 0", b"", b"scan 1"]
    assert status == 0, err
