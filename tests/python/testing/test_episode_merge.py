"""episodes.append_channels, what new_episodes does to a cassette: the
recorded channels appended (ids continuing), the cassette's records kept as
they were, the new ones moved onto its clock and merged in time order, a
note in the edits; the cassette untouched when anything goes wrong."""

import time

import pytest

import wiretape
from multichannel_sessions import RECORDS, records_with_channels, write_channels_session
from wiretape import _core
from wiretape.testing.episodes import append_channels

IMU = dict(id=0, name="imu", port_options="type=tcp,host=127.0.0.1,port=4000",
           port_type="tcp", capture="client")
IMU_RECORDS = [(0, "open", b"", 0), (1_000_000, "tx", b"ask", 0),
               (2_000_000, "rx", b"ANSWER", 0), (6_000_000, "close", b"", 0)]


def write_recording(path, records=IMU_RECORDS):
    header = _core.SessionHeader.starting_now()
    header.channels = [_core.Channel(**IMU)]
    with wiretape.SessionWriter(str(path), header) as writer:
        for t_ns, kind, data, channel in records:
            writer.write(kind, t_ns, data, channel=channel)
    return path


def test_the_recording_is_appended_on_the_cassettes_clock(tmp_path):
    cassette = write_channels_session(tmp_path / "t.wtape", edits=["cut 1 exchange"])
    recording = write_recording(tmp_path / "t.wtape.recording-1")

    names = append_channels(cassette, recording, 2_500_000, "appended channel imu")

    assert names == ["imu"]
    header = wiretape.SessionReader(str(cassette)).header
    assert [(c.id, c.name) for c in header.channel_list()] == [(0, "gps"), (1, "rtk"), (2, "imu")]
    assert header.find_channel("imu").port_options == IMU["port_options"]
    assert header.edits == ["cut 1 exchange", "appended channel imu"]
    assert header.host == "robot"
    records = records_with_channels(cassette)
    assert [r for r in records if r[3] != 2] == RECORDS
    moved = [(t + 2_500_000, kind, data, 2) for t, kind, data, _ in IMU_RECORDS]
    assert [r for r in records if r[3] == 2] == moved
    assert records == sorted(RECORDS + moved, key=lambda r: r[0])


def test_a_negative_offset_never_moves_a_record_before_time_zero(tmp_path):
    cassette = write_channels_session(tmp_path / "t.wtape")
    recording = write_recording(tmp_path / "t.wtape.recording-1")
    append_channels(cassette, recording, -1_500_000, "appended channel imu")
    assert [r[0] for r in records_with_channels(cassette, 2)] == [0, 0, 500_000, 4_500_000]


def test_a_damaged_recording_leaves_the_cassette_as_it_was(tmp_path):
    cassette = write_channels_session(tmp_path / "t.wtape")
    before = cassette.read_bytes()
    recording = write_recording(tmp_path / "t.wtape.recording-1")
    data = bytearray(recording.read_bytes())
    data[-3] ^= 0xFF  # the last record's CRC no longer matches
    recording.write_bytes(bytes(data))
    with pytest.raises(wiretape.SessionError):
        append_channels(cassette, recording, 0, "appended channel imu")
    assert cassette.read_bytes() == before
    assert sorted(path.name for path in tmp_path.iterdir()) == ["t.wtape", "t.wtape.recording-1"]


def test_a_cassette_of_one_port_is_refused(tmp_path):
    cassette = tmp_path / "one.wtape"
    with wiretape.SessionWriter(str(cassette)) as writer:
        writer.write("tx", 0, b"x")
    recording = write_recording(tmp_path / "one.wtape.recording-1")
    with pytest.raises(ValueError, match="a session of one port"):
        append_channels(cassette, recording, 0, "appended channel imu")


def test_a_channel_name_the_cassette_has_is_refused(tmp_path):
    cassette = write_channels_session(tmp_path / "t.wtape")
    before = cassette.read_bytes()
    header = _core.SessionHeader.starting_now()
    header.channels = [_core.Channel(**dict(IMU, name="gps"))]
    with wiretape.SessionWriter(str(tmp_path / "r"), header) as writer:
        writer.write("tx", 0, b"x")
    with pytest.raises(Exception, match="gps"):
        append_channels(cassette, tmp_path / "r", 0, "appended channel gps")
    assert cassette.read_bytes() == before
