"""wiretape.Recorder from Python: several ports recorded into one session
file, one channel each, on one clock (DESIGN §19); and Bridge(recorder=...)."""

import socket

import pytest

import wiretape
from wiretape import _core


def read_all(path):
    with wiretape.SessionReader(path) as reader:
        return reader.header, list(reader)


def test_ports_of_a_recorder_record_their_channels_on_one_clock(tmp_path):
    path = tmp_path / "run.wtape"
    with wiretape.Recorder(path) as recorder:
        gps = recorder.open_port("name=gps,type=loopback")
        rtk = recorder.open_port("name=rtk,type=loopback")
        assert isinstance(gps, wiretape.Port)
        gps.write(b"$GPGGA\r\n")
        assert gps.read_exactly(8) == b"$GPGGA\r\n"
        rtk.write(b"RTCM")
        assert rtk.read_exactly(4) == b"RTCM"
        gps.close()
        rtk.close()
        assert [c.name for c in recorder.header.channels] == ["gps", "rtk"]
    header, records = read_all(path)
    assert [(c.id, c.name, c.port_options) for c in header.channels] == [
        (0, "gps", "type=loopback"),
        (1, "rtk", "type=loopback"),
    ]
    assert header.port_options == "type=loopback"  # channel 0's, for 1.1 readers
    times = [r.t_ns for r in records]
    assert times == sorted(times)
    assert records[0].kind == "open" and records[0].t_ns == 0
    tx = [(r.channel, r.data) for r in records if r.kind == "tx"]
    assert tx == [(0, b"$GPGGA\r\n"), (1, b"RTCM")]


@pytest.mark.parametrize(
    "options, key",
    [
        ("type=loopback", "name"),
        ("name=9lives,type=loopback", "name"),
        ("name=type,type=loopback", "name"),
        ("name=gps,type=loopback,log=other.wtape", "log"),
    ],
)
def test_bad_port_options_are_refused_naming_the_key(tmp_path, options, key):
    with wiretape.Recorder(tmp_path / "bad.wtape") as recorder:
        with pytest.raises(wiretape.OptionError) as raised:
            recorder.open_port(options)
        assert raised.value.key == key
    assert not (tmp_path / "other.wtape").exists()


def test_a_name_taken_twice_is_refused(tmp_path):
    with wiretape.Recorder(tmp_path / "dup.wtape") as recorder:
        recorder.open_port("name=gps,type=loopback")
        with pytest.raises(wiretape.OptionError, match='already has a channel named "gps"'):
            recorder.open_port("name=gps,type=loopback")


def test_header_members_and_room_are_given_at_construction(tmp_path):
    path = tmp_path / "meta.wtape"
    with wiretape.Recorder(path, metadata={"robot": "r2"}, header_room=170) as recorder:
        recorder.open_port("name=a,type=loopback")
        with pytest.raises(wiretape.SessionError, match="fit 1 channel"):
            recorder.open_port("name=b,type=loopback")
    header, _ = read_all(path)
    assert header.metadata == {"robot": "r2"}
    assert [c.name for c in header.channels] == ["a"]


def test_session_writer_header_room_is_spaces_readers_skip(tmp_path):
    path = tmp_path / "room.wtape"
    with _core.SessionWriter(path, header_room=100) as writer:
        writer.write("rx", 1, b"x")
        json_text = writer.header.metadata_json
    raw = path.read_bytes()
    assert raw[16 + len(json_text) : 16 + len(json_text) + 100] == b" " * 100
    _, records = read_all(path)
    assert [r.data for r in records] == [b"x"]


def test_bridges_record_into_channels_of_one_recorder(tmp_path):
    path = tmp_path / "bridges.wtape"
    recorder = wiretape.Recorder(path)
    bridges = {
        name: _core.Bridge("type=loopback", client_side="tcp", recorder=recorder,
                           channel=name, quiet=True)
        for name in ("cmd", "data")
    }
    for bridge in bridges.values():
        bridge.start()
    for name, bridge in bridges.items():
        host, port = bridge.listen_address.rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=10) as client:
            client.sendall(name.encode())
            got = b""
            while len(got) < len(name):
                got += client.recv(64)
            assert got == name.encode()
    for bridge in bridges.values():
        bridge.stop()
        assert bridge.wait(10)
        assert bridge.result().ok, bridge.result().message
    recorder.close()
    header, records = read_all(path)
    assert [(c.name, c.capture) for c in header.channels] == [("cmd", "wire"), ("data", "wire")]
    assert [(r.channel, r.data) for r in records if r.kind == "tx"] == [(0, b"cmd"), (1, b"data")]


GOLDEN = __import__("pathlib").Path(__file__).resolve().parents[3] / "tests" / "data" / "golden"


def golden_channels():
    import json

    lines = [json.loads(line) for line in (GOLDEN / "v1_2_channels.jsonl").read_text().splitlines()]
    return lines[0], [line for line in lines[1:] if "t_ns" in line]


def test_golden_file_of_two_channels_reads_as_its_jsonl_says():
    first, records = golden_channels()
    header, read = read_all(GOLDEN / "v1_2_channels.wtape")
    want = first["header"]["channels"]
    assert [(c.id, c.name, c.port_options, c.port_type, c.capture, c.device_address)
            for c in header.channels] == [
        (c["id"], c["name"], c["port_options"], c["port_type"], c["capture"],
         c.get("device_address", "")) for c in want]
    assert header.port_options == want[0]["port_options"]
    assert header.metadata_json.endswith("}")  # the header room's spaces are not in it
    assert [(r.t_ns, r.kind, r.data.hex(), r.channel) for r in read] == [
        (r["t_ns"], r["kind"], r["data_hex"], r.get("channel", 0)) for r in records]


def test_writer_recreates_the_golden_file_of_two_channels(tmp_path):
    first, records = golden_channels()
    header = dict(first["header"])
    channels = header.pop("channels")
    path = tmp_path / "out.wtape"
    with _core.SessionWriter(path, header_room=first["header_room"], **header) as writer:
        for channel in channels:
            writer.add_channel(_core.Channel(**channel))
        for r in records:
            writer.write(r["kind"], r["t_ns"], bytes.fromhex(r["data_hex"]),
                         channel=r.get("channel", 0))
    assert path.read_bytes() == (GOLDEN / "v1_2_channels.wtape").read_bytes()
