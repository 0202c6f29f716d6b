"""Exports of a session of several channels (DESIGN §19): pcapng has one
interface per channel, named after it, with its records on it (tshark reads
it); mcap has one channel per session channel, topic /wiretape/NAME (the
mcap library reads it back). Sessions without named channels keep their
layout (test_exports.py)."""

import base64
import json
import shutil
import subprocess

import pytest
from multichannel_sessions import RECORDS, RTK_CLIENT, RTK_DEVICE, write_channels_session
from pcapng_reader import read_pcapng

from wiretape import exports

GPS, RTK = 0, 1


@pytest.fixture
def session(tmp_path):
    return write_channels_session(tmp_path / "run.wtape")


def of_channel(channel, kinds=("rx", "tx")):
    return [(t, k, d) for t, k, d, c in RECORDS if c == channel and k in kinds]


def test_pcapng_has_an_interface_per_channel_with_its_records(session, tmp_path):
    out = tmp_path / "run.pcapng"
    counts = exports.write_pcapng(session, out)
    assert counts == {"rx": 4, "tx": 2, "events": 5}

    comment, interfaces, packets = read_pcapng(out)
    # A TCP channel's interface carries IP packets, which an event is not:
    # its events have an interface of their own.
    assert [(i["name"], i["link_type"]) for i in interfaces] == [
        ("gps", exports.LINKTYPE_USER0), ("rtk", exports.LINKTYPE_RAW),
        ("rtk events", exports.LINKTYPE_USER0)]
    assert [c["name"] for c in json.loads(comment)["channels"]] == ["gps", "rtk"]

    start = packets[0][1]
    gps = [p for p in packets if p[0] == "gps"]
    expected = [(t, k, d) for t, k, d, c in RECORDS if c == GPS]
    assert [p[1] - start for p in gps] == [t for t, _, _ in expected]
    for (_, _, flags, payload, comment_text), (_, kind, data) in zip(gps, expected):
        if kind in ("rx", "tx"):
            assert (payload, flags) == (data, 1 if kind == "rx" else 2)
        else:
            assert payload.split(b" ")[0].decode() == kind
            assert comment_text == f"wiretape event: {kind}"
    rtk_events = [p[3].split(b" ")[0].decode() for p in packets if p[0] == "rtk events"]
    assert rtk_events == [k for _, k, _ in of_channel(RTK, ("client_connect",
                                                            "client_disconnect"))]
    # Every rtk packet is an IP packet, stamped within the channel's records.
    rtk = [p for p in packets if p[0] == "rtk"]
    assert rtk and all(p[3][0] >> 4 == 4 for p in rtk)


def tshark_rows(path, fields, *options):
    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed (apt-get install tshark): cannot "
                    "check that Wireshark opens the pcapng export of channels")
    command = [tshark, "-r", str(path), *options, "-T", "fields", "-E", "occurrence=a"]
    for field in fields:
        command += ["-e", field]
    result = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return [line.split("\t") for line in result.stdout.splitlines() if line.strip()]


def test_tshark_reads_each_channel_on_its_interface(session, tmp_path):
    out = tmp_path / "run.pcapng"
    exports.write_pcapng(session, out)
    serial = tshark_rows(out, ["frame.p2p_dir", "data.data"],
                         "-Y", 'frame.interface_name == "gps" && frame.p2p_dir')
    assert [(row[0], bytes.fromhex(row[1])) for row in serial] == \
        [("1" if k == "rx" else "0", d) for _, k, d in of_channel(GPS)]
    tcp = tshark_rows(out, ["ip.src", "tcp.srcport", "tcp.payload"],
                      "-Y", 'frame.interface_name == "rtk" && tcp.len > 0')
    device_host, device_port = RTK_DEVICE.rsplit(":", 1)
    client_host, client_port = RTK_CLIENT.rsplit(":", 1)
    assert [(row[0], row[1], bytes.fromhex(row[2])) for row in tcp] == [
        ((device_host, device_port) if k == "rx" else (client_host, client_port)) + (d,)
        for _, k, d in of_channel(RTK)]
    assert not tshark_rows(out, ["frame.number"], "-Y", "_ws.malformed || tcp.analysis.flags")
    names = [row[0] for row in tshark_rows(out, ["frame.interface_name"])]
    assert set(names) == {"gps", "rtk", "rtk events"}


def test_mcap_has_a_topic_per_channel_and_reads_back(session, tmp_path):
    from mcap.reader import make_reader

    out = tmp_path / "run.mcap"
    counts = exports.write_mcap(session, out)
    assert counts == {"rx": 4, "tx": 2, "events": 5}
    with open(out, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        topics = {channel.topic: channel for channel in summary.channels.values()}
        assert set(topics) == {"/wiretape/gps", "/wiretape/rtk"}
        assert topics["/wiretape/rtk"].metadata["port_type"] == "tcp"
        schema = summary.schemas[topics["/wiretape/gps"].schema_id]
        assert schema.encoding == "jsonschema" and schema.name == "wiretape.Record"
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        assert [c["name"] for c in json.loads(metadata["wiretape"]["channels"])] == \
            ["gps", "rtk"]
    with open(out, "rb") as stream:
        messages = [(channel.topic, message.log_time, json.loads(message.data))
                    for _, channel, message in make_reader(stream).iter_messages()]
    assert len(messages) == len(RECORDS)
    start = messages[0][1]
    for (topic, log_time, body), (t_ns, kind, data, channel) in zip(messages, RECORDS):
        name = ("gps", "rtk")[channel]
        assert (topic, body["channel"], body["kind"], body["t_ns"]) == \
            (f"/wiretape/{name}", name, kind, t_ns)
        assert log_time - start == t_ns
        if kind in ("rx", "tx"):
            assert base64.b64decode(body["data"]) == data
        else:
            assert "event" in body
    assert messages[5][2]["event"] == {"baud": 115200}
