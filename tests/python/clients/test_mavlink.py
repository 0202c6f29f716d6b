"""A real protocol stack end to end: a pymavlink ground station talking
MAVLink 2 to a pymavlink vehicle over TCP and over UDP, recorded through
``wiretape record --listen`` / ``--udp``, then replayed with the vehicle gone
(``wiretape replay FILE --listen`` / ``--udp``): the ground station gets the
heartbeat and the same parameter list.

MAVLink frames carry a sequence number and a CRC, so the ground station's
bytes are the same only when it repeats its run exactly; the replay matches
them in recorded order (``match=sequence``, the default) with ``timing=none``
or ``causal`` (docs/replay.md). The peers are in mavlink_peers.py. Skipped,
loudly, without pymavlink (the Makefile installs it)."""

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from wiretape import _core

pytest.importorskip("pymavlink", reason="SKIPPED LOUDLY: pymavlink is not installed "
                    "(pip install pymavlink; make installs it): MAVLink is not tested")

from devices import announced_address, interrupt, start_cli  # noqa: E402
from mavlink_peers import PARAMETERS, VEHICLE_SYSTEM, Vehicle  # noqa: E402

DEADLINE = 20.0
PEERS = str(Path(__file__).resolve().parents[1] / "support" / "mavlink_peers.py")






def _interrupt(child):
    """Ctrl-C, then the command's exit status and its stderr."""
    code, _, err = interrupt(child, DEADLINE)
    if code == -signal.SIGKILL:
        raise AssertionError("the command did not end at Ctrl-C: " + err)
    return code, err


def _ground_station(transport, host, port):
    """Runs the pymavlink ground station against HOST:PORT; what it got."""
    connection = f"tcp:{host}:{port}" if transport == "tcp" else f"udpout:{host}:{port}"
    run = subprocess.run([sys.executable, PEERS, connection, "--timeout", str(DEADLINE)],
                         capture_output=True, text=True, timeout=DEADLINE * 2)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


def _client_flag(transport):
    return "--listen" if transport == "tcp" else "--udp"


def _record(tmp_path, transport):
    out = tmp_path / f"mavlink-{transport}.wtape"
    with Vehicle(transport) as vehicle:
        child = start_cli("record", "--device", vehicle.options,
                           _client_flag(transport), "127.0.0.1:0", "-o", str(out))
        try:
            host, port = announced_address(child, transport)
            got = _ground_station(transport, host, port)
        finally:
            code, err = _interrupt(child)
        assert code == 0, err
        assert vehicle.param_requests == 1
    return out, got


def _records(path):
    with _core.SessionReader(str(path)) as reader:
        records = list(reader)
        assert reader.damage is None, reader.damage
        return reader.header, records


@pytest.fixture(scope="module", params=["tcp", "udp"])
def recorded(request, tmp_path_factory):
    """(transport, recording, what the ground station got while recording)."""
    transport = request.param
    out, got = _record(tmp_path_factory.mktemp("mavlink"), transport)
    return transport, out, got


def test_the_ground_station_gets_the_vehicle_through_the_record_proxy(recorded):
    transport, out, got = recorded
    assert got["heartbeat"]["system"] == VEHICLE_SYSTEM
    assert got["heartbeat"]["mavlink_version"] == 2
    assert got["params"] == PARAMETERS

    header, records = _records(out)
    assert header.port_type == transport
    kinds = [r.kind for r in records]
    assert "client_connect" in kinds and kinds[-1] == "close"
    # The ground station's HEARTBEAT then its PARAM_REQUEST_LIST, both MAVLink 2
    # frames (0xFD), after its connect.
    tx = [r.data for r in records if r.kind == "tx"]
    assert b"".join(tx)[:1] == b"\xfd"
    assert kinds.index("client_connect") < kinds.index("tx")
    if transport == "udp":
        # One record a datagram, one MAVLink message a datagram: the
        # heartbeat, the request list; the vehicle's heartbeat(s) and one
        # PARAM_VALUE each.
        assert len(tx) == 2 and all(d[0] == 0xFD for d in tx)
        rx = [r.data for r in records if r.kind == "rx"]
        assert all(d[0] == 0xFD for d in rx)
        assert len(rx) >= 1 + len(PARAMETERS)


@pytest.mark.parametrize("timing", ["none", "causal"])
def test_the_replay_answers_the_same_ground_station_with_the_vehicle_gone(recorded, timing):
    transport, out, got = recorded
    child = start_cli("replay", str(out), _client_flag(transport), "127.0.0.1:0",
                       "--timing", timing)
    try:
        host, port = announced_address(child, transport)
        replayed = _ground_station(transport, host, port)
    finally:
        code, err = _interrupt(child)
    assert replayed == got
    assert code == 0, err
    assert "mismatch" not in err.lower(), err
