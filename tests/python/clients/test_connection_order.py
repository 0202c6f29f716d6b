"""match=request serves connections in any order (DESIGN §12): the k-th
connection gets the k-th recorded connection's greeting and matches the
requests of every recorded connection, its own first. Two Modbus TCP clients
(mbpoll, Debian's, and pymodbus's), recorded through `wiretape record
--listen` against pymodbus's server, replayed in the other order."""

import re
import shutil
import subprocess

import pytest

from wiretape import bridge

from test_modbus_profile import DEADLINE, REGISTERS, ModbusDevice, poll

REPLAY = "timing=none,match=request,profile=modbus-tcp"
# What each client reads: (first register, count), 0-based.
FIRST_CLIENT = [(0, 2), (10, 3)]
SECOND_CLIENT = [(20, 1), (30, 4)]


def mbpoll(host, port, address, count):
    """mbpoll's reading of `count` holding registers from `address`
    (0-based), as (address, values)."""
    done = subprocess.run(
        ["mbpoll", "-m", "tcp", "-a", "1", "-0", "-r", str(address), "-c", str(count),
         "-t", "4", "-1", "-o", "5", "-p", str(port), host],
        capture_output=True, text=True, timeout=DEADLINE)
    assert done.returncode == 0, done.stdout + done.stderr
    values = [int(value) for value in re.findall(r"^\[\d+\]:\s+(-?\d+)", done.stdout, re.M)]
    return address, values


def record_two_connections(tmp_path, client):
    device = ModbusDevice()
    path = tmp_path / "two.wtape"
    try:
        handle = bridge.record(f"type=tcp,host=127.0.0.1,port={device.port}", path,
                               listen="127.0.0.1:0", quiet=True)
        try:
            host, port = handle.address.rsplit(":", 1)
            for polls in (FIRST_CLIENT, SECOND_CLIENT):
                client(host, int(port), polls)
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)
    finally:
        device.close()
    return path


def replay_in_reverse(recording, client):
    handle = bridge.serve_replay(recording, listen="127.0.0.1:0", quiet=True,
                                 replay_options=REPLAY)
    try:
        host, port = handle.address.rsplit(":", 1)
        results = [client(host, int(port), polls) for polls in (SECOND_CLIENT, FIRST_CLIENT)]
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert handle.result().ok, handle.result()
    return results


def registers(polls):
    return [REGISTERS[address:address + count] for address, count in polls]


def pymodbus_client(host, port, polls):
    return [values for _, values, _ in poll(host, port, polls)]


def mbpoll_client(host, port, polls):
    # One mbpoll run is one connection; a client here is one run per poll
    # would be several connections, so each client reads one block.
    (address, count), = polls[:1]
    return [mbpoll(host, port, address, count)[1]]


def test_pymodbus_clients_recorded_in_one_order_replay_in_the_other(tmp_path):
    recording = record_two_connections(tmp_path, pymodbus_client)
    second, first = replay_in_reverse(recording, pymodbus_client)
    assert second == registers(SECOND_CLIENT)
    assert first == registers(FIRST_CLIENT)


@pytest.mark.skipif(shutil.which("mbpoll") is None,
                    reason="SKIPPED LOUDLY: mbpoll not installed (apt-get install mbpoll)")
def test_mbpoll_runs_recorded_in_one_order_replay_in_the_other(tmp_path):
    recording = record_two_connections(tmp_path, mbpoll_client)
    second, first = replay_in_reverse(recording, mbpoll_client)
    assert second == registers(SECOND_CLIENT[:1])
    assert first == registers(FIRST_CLIENT[:1])
