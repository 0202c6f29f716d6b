"""Sessions of several ports from Python (format 1.2 channels): Channel,
SessionHeader.channels, SessionReader(path, channel=...) and Record.channel."""

import pytest

import wiretape
from wiretape import _core


def two_channel_header():
    return _core.SessionHeader(
        channels=[
            {"id": 0, "name": "cmd", "port_type": "tcp", "port_options": "type=tcp", "capture": "wire"},
            _core.Channel(id=1, name="data", port_type="udp", capture="wire",
                          device_identity={"vendor_id": "0403"}),
        ]
    )


def write(path, header, records):
    writer = _core.SessionWriter(path, header)
    for t_ns, kind, data, channel in records:
        writer.write(kind, t_ns, data, channel=channel)
    writer.close()


RECORDS = [(10, "tx", b"START\n", 0), (20, "rx", b"d1", 1), (30, "rx", b"OK\n", 0), (40, "rx", b"d2", 1)]


def test_channels_round_trip_and_records_name_theirs(tmp_path):
    path = tmp_path / "two.wtape"
    write(path, two_channel_header(), RECORDS)
    with wiretape.SessionReader(path) as reader:
        header = reader.header
        records = list(reader)
    assert [(c.id, c.name, c.port_type, c.capture) for c in header.channels] == [
        (0, "cmd", "tcp", "wire"),
        (1, "data", "udp", "wire"),
    ]
    assert header.channels[1].device_identity["vendor_id"] == "0403"
    assert header.port_type == "tcp", "the port members are channel 0's"
    assert header.find_channel("data").id == 1
    assert header.find_channel("nope") is None
    assert header.to_dict()["channels"][1]["name"] == "data"
    assert [(r.t_ns, r.kind, r.data, r.channel) for r in records] == RECORDS
    assert _core.SessionHeader.from_dict(header.to_dict()).to_json() == header.to_json()


@pytest.mark.parametrize("channel, expected", [(0, [b"START\n", b"OK\n"]), (1, [b"d1", b"d2"]), (9, [])])
def test_a_reader_of_one_channel_returns_only_its_records(tmp_path, channel, expected):
    path = tmp_path / "two.wtape"
    write(path, two_channel_header(), RECORDS)
    with wiretape.SessionReader(path, channel=channel) as reader:
        assert [r.data for r in reader] == expected


def test_a_session_of_one_port_is_one_unnamed_channel(tmp_path):
    path = tmp_path / "one.wtape"
    write(path, _core.SessionHeader(port_type="serial"), [(1, "rx", b"x", 0)])
    header = wiretape.SessionReader(path).header
    assert header.channels == []
    (only,) = header.channel_list()
    assert (only.id, only.name, only.port_type) == (0, "", "serial")


def test_bad_channels_are_refused_naming_the_problem(tmp_path):
    header = two_channel_header()
    with pytest.raises(ValueError, match="Channel has no member 'colour'"):
        header.channels = [{"id": 0, "name": "a", "colour": "red"}]
    with pytest.raises(TypeError, match="'id' must be an int"):
        header.channels = [{"id": "0", "name": "a"}]
    header.channels = [{"id": 0, "name": "a"}, {"id": 1, "name": "a"}]
    with pytest.raises(_core.OptionError, match='two channels are named "a"'):
        header.to_json()
    assert "option key" in _core.channel_name_problem("baud")
    assert _core.channel_name_problem("gps") is None
