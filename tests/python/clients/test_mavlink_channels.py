"""pymavlink and a vehicle of two links (issue 25): the autopilot on UDP and
a second component (a gimbal) on a serial line, recorded through one
``wiretape record`` into one file of two channels, then replayed with both
gone: a ground station on each link gets the same heartbeat and parameters,
each from its own component. Skipped, loudly, without pymavlink."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

import wiretape

pytest.importorskip("pymavlink", reason="SKIPPED LOUDLY: pymavlink is not installed "
                    "(pip install pymavlink; make installs it): MAVLink is not tested")

from devices import announced_address, interrupt, start_cli  # noqa: E402
from mavlink_peers import PARAMETERS, VEHICLE_SYSTEM, Vehicle  # noqa: E402

DEADLINE_S = 20.0
GIMBAL = 154  # MAV_COMP_ID_GIMBAL
PEERS = str(Path(__file__).resolve().parents[1] / "support" / "mavlink_peers.py")


def ground_station(connection):
    run = subprocess.run([sys.executable, PEERS, connection, "--timeout", str(DEADLINE_S)],
                         capture_output=True, text=True, timeout=DEADLINE_S * 2)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


def both_links(child, link):
    """The ground station on the UDP link, then on the serial one."""
    host, port = announced_address(child, "udp")
    return ground_station(f"udpout:{host}:{port}"), ground_station(link)


def test_a_vehicle_on_udp_and_a_component_on_a_pty_recorded_in_one_file_and_replayed(tmp_path):
    recording = tmp_path / "vehicle.wtape"
    link = str(tmp_path / "ttyGIMBAL")
    with Vehicle("udp") as autopilot, Vehicle("pty", component=GIMBAL) as gimbal:
        child = start_cli("record", "-o", str(recording),
                          "--device", f"autopilot={autopilot.options}",
                          "--udp", "autopilot=127.0.0.1:0",
                          "--device", f"gimbal={gimbal.options}", "--pty", f"gimbal={link}")
        try:
            recorded = both_links(child, link)
        finally:
            status, _, err = interrupt(child, DEADLINE_S)
    assert status == 0, err
    for got, component in zip(recorded, (1, GIMBAL)):
        assert got["heartbeat"]["system"] == VEHICLE_SYSTEM
        assert got["heartbeat"]["component"] == component
        assert got["params"] == PARAMETERS
    with wiretape.SessionReader(str(recording)) as reader:
        assert sorted(c.name for c in reader.header.channel_list()) == ["autopilot", "gimbal"]

    link = str(tmp_path / "ttyGIMBAL-replayed")
    child = start_cli("replay", str(recording), "--timing", "causal",
                      "--udp", "autopilot=127.0.0.1:0", "--pty", f"gimbal={link}")
    try:
        replayed = both_links(child, link)
    finally:
        status, _, err = interrupt(child, DEADLINE_S)
    assert replayed == recorded
    assert status == 0, err
    assert "mismatch" not in err.lower(), err
