"""A LiDAR of two ports (issue 25): commands on TCP, a UDP data stream that
starts only after ``START``. Recorded through one ``wiretape record`` into
two channels (the stream with ``--udp LISTEN --peer DRIVER``), then replayed
under ``timing=causal``: no data datagram may reach the driver before its
START, however long it waits to send it (DESIGN.md section 19)."""

import socket

import pytest

import wiretape

from devices import announced_address, interrupt, start_cli
from lidar_sim import Lidar, LidarDriver
from nmea_sources import free_port

DEADLINE_S = 20.0
SCANS = 10


def record_lidar(tmp_path):
    recording = tmp_path / "lidar.wtape"
    driver = LidarDriver()
    listen = free_port(socket.SOCK_DGRAM)
    try:
        with Lidar(("127.0.0.1", listen)) as lidar:
            child = start_cli("record", "-o", str(recording), "-q",
                              "--device", f"cmd={lidar.options}", "--listen", "cmd=127.0.0.1:0",
                              "--udp", f"data=127.0.0.1:{listen}",
                              "--peer", f"data=127.0.0.1:{driver.data_port}")
            try:
                address = announced_address(child, "tcp")
                driver.run(address, SCANS, quiet_s=0.1, deadline_s=DEADLINE_S)
            finally:
                status, _, err = interrupt(child)
    finally:
        driver.close()
    assert status == 0, err
    assert driver.answer == b"OK\n"
    assert not driver.early
    return recording


def test_a_causal_replay_sends_no_data_before_the_start_command(tmp_path):
    recording = record_lidar(tmp_path)
    with wiretape.SessionReader(str(recording)) as reader:
        assert sorted(c.name for c in reader.header.channel_list()) == ["cmd", "data"]

    driver = LidarDriver()
    child = start_cli("replay", str(recording), "-q", "--timing", "causal",
                      "--listen", "cmd=127.0.0.1:0", "--udp", "data=127.0.0.1:0",
                      "--peer", f"data=127.0.0.1:{driver.data_port}")
    try:
        address = announced_address(child, "tcp")
        # The driver waits a second before START, far longer than it did
        # when recorded: a replay on the recorded clock alone would stream
        # within that second.
        driver.run(address, SCANS, quiet_s=1.0, deadline_s=DEADLINE_S)
    finally:
        interrupt(child)
        driver.close()
    assert driver.early == [], f"data before START: {driver.early}"
    assert driver.answer == b"OK\n"
    assert [datagram for _, datagram in driver.data] == [b"SCAN %d" % n for n in range(SCANS)]
    assert all(arrival > driver.start_sent for arrival, _ in driver.data)
