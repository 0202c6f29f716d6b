"""profile=mavlink with packets made by pymavlink (DESIGN §13): a ground
station's steps recorded against a simulated vehicle replay to a station
that sends them in another order, with an extra heartbeat first and its own
sequence numbers; broken packets are reported as such."""

import pytest

from wiretape import _core, open_port

try:
    from pymavlink.dialects.v20 import common as mavlink2
except ImportError as error:  # pragma: no cover - the set-up installs it
    pytest.skip(f"pymavlink not installed: {error} (make installs it)", allow_module_level=True)


class Station:
    """pymavlink's encoder for one system, v1 or v2, counting its own seq."""

    def __init__(self, system, component, v1=False, first_seq=0):
        self.mav = mavlink2.MAVLink(None, srcSystem=system, srcComponent=component)
        self.mav.seq = first_seq
        if v1:
            # pymavlink's v2 dialect writes v1 framing when WIRE_PROTOCOL says so.
            self.mav.WIRE_PROTOCOL_VERSION = "1.0"
        self.v1 = v1

    def pack(self, message):
        packet = bytes(message.pack(self.mav, force_mavlink1=self.v1))
        self.mav.seq = (self.mav.seq + 1) % 256
        return packet


def heartbeat(station):
    return station.pack(mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3))


def param_request_list(station):
    return station.pack(mavlink2.MAVLink_param_request_list_message(1, 1))


def request_version(station):
    return station.pack(mavlink2.MAVLink_command_long_message(
        1, 1, mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 0, 1, 0, 0, 0, 0, 0, 0))


def vehicle_answers():
    vehicle = Station(1, 1)
    param = vehicle.pack(mavlink2.MAVLink_param_value_message(
        b"SYSID_THISMAV", 1.0, mavlink2.MAV_PARAM_TYPE_REAL32, 1, 0))
    version = vehicle.pack(mavlink2.MAVLink_autopilot_version_message(
        0, 4, 0, 0, 0, b"\0" * 8, b"\0" * 8, b"\0" * 8, 0, 0, 0))
    beat = vehicle.pack(mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4, 3))
    return {"params": param, "version": version, "heartbeat": beat}


@pytest.fixture(params=["v1", "v2"])
def recording(request, session_file):
    """The station's run against the simulated vehicle: heartbeat, parameter
    list, version; the vehicle answers each."""
    v1 = request.param == "v1"
    station = Station(255, 190, v1=v1)
    answers = vehicle_answers()
    steps = [(heartbeat(station), answers["heartbeat"]),
             (param_request_list(station), answers["params"]),
             (request_version(station), answers["version"])]
    records = []
    t = 1_000
    for sent, answer in steps:
        records.append(("tx", t, sent))
        records.append(("rx", t + 500, answer))
        t += 1_000_000
    return session_file(records), v1, answers


def test_the_recording_frames_as_mavlink(recording):
    path, _, _ = recording
    profile = _core.find_profile("mavlink")
    names = [profile.frame_name(kind, data)
             for _, kind, data, description in profile.decode_session(str(path))
             if description is not None]
    assert names == ["HEARTBEAT", "HEARTBEAT", "PARAM_REQUEST_LIST", "PARAM_VALUE",
                     "COMMAND_LONG", "AUTOPILOT_VERSION"]


def test_steps_in_another_order_with_an_extra_heartbeat_first(recording):
    path, v1, answers = recording
    # Another run of the station: its sequence numbers start elsewhere.
    station = Station(255, 190, v1=v1, first_seq=100)
    port = open_port(f"type=replay,file={path},timing=none,match=request,"
                     "profile=mavlink,repeat=last,timeout=10")
    try:
        for packet, answer in [(heartbeat(station), "heartbeat"),
                               (heartbeat(station), "heartbeat"),
                               (request_version(station), "version"),
                               (param_request_list(station), "params")]:
            port.write(packet)
            assert port.read_exactly(len(answers[answer])) == answers[answer], answer
    finally:
        port.close()


def test_without_the_profile_other_sequence_numbers_do_not_match(recording):
    path, v1, _ = recording
    station = Station(255, 190, v1=v1, first_seq=100)
    port = open_port(f"type=replay,file={path},timing=none,match=request,"
                     "unused=ignore,timeout=10")
    try:
        with pytest.raises(_core.ReplayMismatch):
            port.write(heartbeat(station))
    finally:
        port.close()


def test_a_broken_packet_is_reported_naming_its_problem(recording):
    path, v1, _ = recording
    station = Station(255, 190, v1=v1)
    packet = bytearray(param_request_list(station))
    packet[-3] ^= 0xFF  # a payload byte: the CRC no longer matches
    port = open_port(f"type=replay,file={path},timing=none,match=request,"
                     "profile=mavlink,unused=ignore,timeout=10")
    try:
        with pytest.raises(_core.ReplayMismatch, match="bad CRC"):
            port.write(bytes(packet))
    finally:
        port.close()
    profile = _core.find_profile("mavlink")
    frames = profile.frames("tx", b"\x00\x01" + heartbeat(station))
    assert frames[0] == b"\x00\x01"
