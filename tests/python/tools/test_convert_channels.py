"""convert and sessions of several channels (DESIGN §19): jsonl keeps each
record's channel and the header's channels both ways; --from pcap imports
several named conversations into channels of one session on the capture's
clock; a flexiport log (one port) refuses a session of several channels."""

import json
import os
import shutil

import pytest
from multichannel_sessions import (CHANNELS, RECORDS, channel_list, records_with_channels,
                                   write_channels_session)

import wiretape
from wiretape import cli
from wiretape.tools.convert import convert

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "data", "pcap")


def run(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    return code, capsys.readouterr().err


def jsonl_lines(path):
    return [json.loads(line) for line in open(path, encoding="utf-8") if line.strip()]


# --- jsonl, both ways --------------------------------------------------------

def test_jsonl_round_trip_keeps_every_record_its_channel_and_the_channel_list(tmp_path):
    source = write_channels_session(tmp_path / "run.wtape")
    text = tmp_path / "run.jsonl"
    back = tmp_path / "back.wtape"
    assert convert(source, text).records == len(RECORDS)
    assert convert(text, back).records == len(RECORDS)

    lines = jsonl_lines(text)
    assert [c["name"] for c in lines[0]["header"]["channels"]] == ["gps", "rtk"]
    assert [line["channel"] for line in lines[1:]] == \
        [CHANNELS[channel]["name"] for *_, channel in RECORDS]
    # The oracle: both sessions read back, every record and the channel list.
    assert records_with_channels(back) == records_with_channels(source) == RECORDS
    assert channel_list(back) == channel_list(source)
    assert [c["name"] for c in channel_list(back)] == ["gps", "rtk"]
    assert channel_list(back)[1]["device_address"] == "127.0.0.1:2101"
    original = wiretape.SessionReader(str(source)).header.to_dict()
    assert wiretape.SessionReader(str(back)).header.to_dict() == original
    # One channel read alone, as replay reads it.
    assert records_with_channels(back, 1) == [r for r in RECORDS if r[3] == 1]
    # And .wtape to .wtape: a copy with its channels.
    copy = tmp_path / "copy.wtape"
    convert(source, copy)
    assert records_with_channels(copy) == RECORDS and channel_list(copy) == channel_list(source)


def test_a_session_without_channels_gives_the_jsonl_of_before(tmp_path, session_file):
    source = session_file([("open", 0, b""), ("tx", 10, b"ID\n"), ("rx", 20, b"OK\n")])
    text = tmp_path / "s.jsonl"
    convert(source, text)
    lines = jsonl_lines(text)
    assert "channels" not in lines[0]["header"]
    assert all("channel" not in line for line in lines[1:])
    assert [line["data_hex"] for line in lines[1:]] == ["", "49440a", "4f4b0a"]


@pytest.mark.parametrize("record, expected", [
    ({"channel": "imu"}, "channel: unknown channel 'imu': the header's channels are gps, rtk"),
    ({"channel": 1}, "channel: expected the name of one of the header's channels, got the "
                     "number 1"),
])
def test_a_bad_channel_in_jsonl_is_an_error_naming_the_line(tmp_path, record, expected):
    source = write_channels_session(tmp_path / "run.wtape")
    text = tmp_path / "run.jsonl"
    convert(source, text)
    lines = open(text, encoding="utf-8").read().splitlines()
    bad = dict(json.loads(lines[3]), **record)
    lines[3] = json.dumps(bad)
    text.write_text("\n".join(lines) + "\n")
    with pytest.raises(wiretape.SessionError) as error:
        convert(text, tmp_path / "back.wtape")
    assert f"{text}:4: {expected}" in str(error.value)


def test_a_channel_in_a_jsonl_without_channels_is_an_error(tmp_path):
    text = tmp_path / "s.jsonl"
    text.write_text('{"header": {"port_type": "serial"}}\n'
                    '{"t_ns": 0, "kind": "tx", "data_hex": "41", "channel": "gps"}\n')
    with pytest.raises(wiretape.SessionError) as error:
        convert(text, tmp_path / "s.wtape")
    assert f"{text}:2: channel: 'gps', but the header names no channels" in str(error.value)


def test_jsonl_of_channels_exports_straight_to_pcapng_and_mcap(tmp_path):
    text = tmp_path / "run.jsonl"
    convert(write_channels_session(tmp_path / "run.wtape"), text)
    convert(text, tmp_path / "run.mcap")
    from mcap.reader import make_reader
    with open(tmp_path / "run.mcap", "rb") as stream:
        topics = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert topics == {"/wiretape/gps", "/wiretape/rtk"}


# --- flexiport: one port -----------------------------------------------------

def test_flexiport_refuses_a_session_of_several_channels(capsys, tmp_path):
    source = write_channels_session(tmp_path / "run.wtape")
    code, err = run(capsys, "convert", source, tmp_path / "run.log")
    assert code == 2, err
    assert "run.wtape: a session of 2 channels (gps, rtk); a flexiport log holds one port" in err
    assert not (tmp_path / "run.logr").exists() and not (tmp_path / "run.logw").exists()
    # A jsonl of channels too (it goes through a scratch session).
    convert(source, tmp_path / "run.jsonl")
    code, err = run(capsys, "convert", tmp_path / "run.jsonl", tmp_path / "run.log")
    assert code == 2 and "a session of 2 channels (gps, rtk)" in err, err
    assert not (tmp_path / "run.logr").exists()


def test_flexiport_takes_a_session_of_one_named_channel(tmp_path):
    source = write_channels_session(tmp_path / "one.wtape", channels=CHANNELS[:1],
                                    records=[r for r in RECORDS if r[3] == 0])
    assert convert(source, tmp_path / "one.log").records == \
        len([r for r in RECORDS if r[3] == 0 and r[1] in ("rx", "tx")])
    assert (tmp_path / "one.logr").read_bytes()


# --- several conversations of a capture --------------------------------------

@pytest.fixture
def multi_pcap():
    if shutil.which("tshark") is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed (apt-get install tshark); "
                    "convert --from pcap is not tested")
    return os.path.join(DATA, "multi.pcap")


def single_import(capture, stream, tmp_path):
    out = tmp_path / f"single-{stream.replace(':', '')}.wtape"
    convert(capture, out, stream=stream)
    return out


def test_named_streams_import_into_channels_of_one_session_on_the_capture_clock(
        capsys, tmp_path, multi_pcap):
    out = tmp_path / "both.wtape"
    code, err = run(capsys, "convert", multi_pcap, out, "--stream", "cmd=tcp:1",
                    "--stream", "data=udp.port == 15023")
    assert code == 0, err
    channels = channel_list(out)
    assert [(c["id"], c["name"], c["port_type"]) for c in channels] == \
        [(0, "cmd", "tcp"), (1, "data", "udp")]
    header = wiretape.SessionReader(str(out)).header
    assert header.port_type == "tcp"  # channel 0's, at the top level
    assert header.source_details == {"streams": "cmd=tcp:1,data=udp:0"}

    # The oracle: each channel holds what the stream imported alone holds,
    # its times shifted onto the first packet of either conversation.
    alone = {name: records_with_channels(single_import(multi_pcap, stream, tmp_path))
             for name, stream in (("cmd", "tcp:1"), ("data", "udp:0"))}
    starts = {name: wiretape.SessionReader(str(single_import(multi_pcap, stream, tmp_path)))
              .header.start_utc for name, stream in (("cmd", "tcp:1"), ("data", "udp:0"))}
    assert header.start_utc == min(starts.values())
    both = records_with_channels(out)
    assert [t for t, *_ in both] == sorted(t for t, *_ in both)
    for channel_id, name in enumerate(("cmd", "data")):
        mine = [(k, d) for _, k, d, c in both if c == channel_id]
        assert mine == [(k, d) for _, k, d, _ in alone[name]]
        shifts = {t - t_alone for (t, _, _, c), (t_alone, *_) in
                  zip([r for r in both if r[3] == channel_id], alone[name])}
        assert len(shifts) == 1
    assert b"".join(d for _, k, d, c in both if c == 1 and k == "tx") == b"PING 1PING 2\x00\xff"
    assert b"".join(d for _, k, d, c in both if c == 0 and k == "tx") == b"second;"


def test_named_streams_take_their_device_addresses_by_name(capsys, tmp_path, multi_pcap):
    out = tmp_path / "both.wtape"
    code, err = run(capsys, "convert", multi_pcap, out, "--stream", "a=tcp:0",
                    "--stream", "b=tcp:1", "--device-addr", "a=127.0.0.1:15021")
    assert code == 0, err
    assert b"".join(d for _, k, d, c in records_with_channels(out) if c == 0 and k == "rx") \
        == b"R:ABCD;R:hello;"


@pytest.mark.parametrize("options, code, expected", [
    (["--stream", "gps=tcp:0", "--stream", "gps=tcp:1"], 2,
     "--stream gps=tcp:1: the channel name 'gps' is given twice (also --stream gps=tcp:0)"),
    (["--stream", "gps=tcp:0", "--stream", "tcp:1"], 2,
     "--stream tcp:1: no NAME= while --stream gps=tcp:0 has one"),
    (["--stream", "tcp:0", "--stream", "tcp:1"], 2,
     "--stream is given 2 times without names"),
    (["--stream", "type=tcp:0"], 2, "--stream type=tcp:0: "),
    (["--stream", "gps=tcp:0", "--device-addr", "rtk=127.0.0.1:15021"], 2,
     "--device-addr rtk=127.0.0.1:15021: no --stream names 'rtk' (the streams are gps)"),
    (["--stream", "gps=tcp:0", "--device-addr", "127.0.0.1:15021"], 2,
     "--device-addr 127.0.0.1:15021: with named streams, say whose device it is"),
    (["--stream", "gps=tcp:0", "--stream", "rtk=tcp:7"], 1,
     "no conversation matching --stream rtk=tcp:7 in the capture; its conversations:"),
    (["--stream", "gps=tcp:0", "--stream", "rtk=tcp"], 1,
     "2 conversations match --stream rtk=tcp:"),
    (["--stream", "gps=tcp:0", "--stream", "rtk=tcp.port == 15021"], 1,
     "--stream gps=tcp:0 and --stream rtk=tcp.port == 15021 choose the same conversation"),
])
def test_bad_named_streams_are_errors_naming_the_flag(capsys, tmp_path, multi_pcap, options,
                                                      code, expected):
    out = tmp_path / "out.wtape"
    got, err = run(capsys, "convert", multi_pcap, out, *options)
    assert got == code, err
    assert expected in err, err
    assert "Traceback" not in err
    assert not out.exists()
    if code == 1 and "its conversations" in expected:
        assert "tcp:0" in err and "tcp:1" in err and "udp:0" in err


def test_a_channel_whose_capture_lost_bytes_is_refused_or_marked_as_a_gap(tmp_path,
                                                                         multi_pcap):
    from captures import pcap, tcp_conversation, udp_frame

    exchanges = [("tx", b"ID;"), ("rx", b"OK;"), ("tx", b"GET;"), ("rx", b"42;")]
    sensor, driver = ("10.0.0.3", 2368), ("10.0.0.1", 50000)
    frames = [udp_frame(sensor, driver, b"SCAN1")]
    frames += tcp_conversation(exchanges, lose=[2])  # GET; lost
    frames += [udp_frame(sensor, driver, b"SCAN2")]
    capture = tmp_path / "lost.pcap"
    capture.write_bytes(pcap(frames))
    out = tmp_path / "run.wtape"
    streams = ["cmd=tcp:0", "scan=udp:0"]
    with pytest.raises(wiretape.SessionError) as error:
        convert(capture, out, from_format="pcap", stream=streams)
    assert ("tcp:0 (channel cmd): 4 bytes missing from the client to device (tx) stream at "
            "offset 3") in str(error.value)
    assert not out.exists()

    convert(capture, out, from_format="pcap", stream=streams, allow_gaps=True)
    records = records_with_channels(out)
    cmd = [(k, d) for _, k, d, c in records if c == 0]
    assert [d for k, d in cmd if k in ("rx", "tx")] == [b"ID;", b"OK;", b"42;"]
    assert [json.loads(d) for k, d in cmd if k == "capture_gap"] == \
        [{"direction": "tx", "offset": 3, "length": 4}]
    assert [d for _, k, d, c in records if c == 1 and k == "rx"] == [b"SCAN1", b"SCAN2"]
    # On the capture's clock: the first datagram is time 0, the SYN 1 ms later.
    assert records[0] == (0, "rx", b"SCAN1", 1)
    assert records[1][1:2] + records[1][3:] == ("client_connect", 0)
    assert records[1][0] == 1_000_000


def test_a_recorders_session_round_trips_through_jsonl_and_exports_by_channel(tmp_path):
    path = tmp_path / "run.wtape"
    recorder = wiretape.Recorder(str(path))
    ports = [recorder.open_port(f"name={name},type=loopback") for name in ("cmd", "data")]
    for port, payload in zip(ports, (b"START\n", b"\x00\x01scan")):
        port.write(payload)
        assert port.read(len(payload)) == payload
    for port in ports:
        port.close()
    recorder.close()

    convert(path, tmp_path / "run.jsonl")
    convert(tmp_path / "run.jsonl", tmp_path / "back.wtape")
    assert records_with_channels(tmp_path / "back.wtape") == records_with_channels(path)
    assert channel_list(tmp_path / "back.wtape") == channel_list(path)
    assert {record[3] for record in records_with_channels(path)} == {0, 1}
    convert(path, tmp_path / "run.mcap")
    from mcap.reader import make_reader
    with open(tmp_path / "run.mcap", "rb") as stream:
        topics = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert topics == {"/wiretape/cmd", "/wiretape/data"}
