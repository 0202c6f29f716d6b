"""Exports to pcapng (Wireshark) and MCAP (Foxglove): every record comes out,
in order, in its direction, with its time; the files open in the real tools."""

import base64
import json
import shutil
import struct
import subprocess

import pytest
from shared_test_data import flexiport_log

import wiretape
from wiretape import exports

SESSION_RECORDS = [
    (0, "open", b""),
    (1_000, "tx", b"VV\n"),
    (2_500_000, "rx", b"VV\n00P\nVEND:Hokuyo\x00\xff;[\n\n"),
    (3_000_000, "settings", b'{"baud": 115200}'),
    (4_000_000, "tx", b"\x00\x01\x02binary\x80"),
    (7_000_000, "rx", b"x"),
    (9_000_000, "close", b""),
]


@pytest.fixture
def session(tmp_path):
    path = tmp_path / "session.wtape"
    with wiretape.SessionWriter(str(path), port_options="type=loopback",
                                port_type="loopback") as writer:
        for t_ns, kind, data in SESSION_RECORDS:
            writer.write(kind, t_ns, data)
    return path


def read_pcapng(path):
    """A small independent pcapng reader: (interfaces, packets) where each
    packet is (interface name, timestamp ns, flags, payload, comment)."""
    blob = path.read_bytes()
    offset = 0
    interfaces = []
    packets = []
    section_comment = None

    def options(body):
        found = {}
        position = 0
        while position + 4 <= len(body):
            code, length = struct.unpack_from("<HH", body, position)
            position += 4
            if code == 0:
                break
            found.setdefault(code, body[position:position + length])
            position += length + (-length % 4)
        return found

    while offset < len(blob):
        block_type, length = struct.unpack_from("<II", blob, offset)
        assert length >= 12 and length % 4 == 0, f"bad block length {length} at {offset}"
        (trailer,) = struct.unpack_from("<I", blob, offset + length - 4)
        assert trailer == length, f"block at {offset}: trailing length differs"
        body = blob[offset + 8:offset + length - 4]
        if block_type == 0x0A0D0D0A:
            magic, major, minor = struct.unpack_from("<IHH", body)
            assert (magic, major, minor) == (0x1A2B3C4D, 1, 0)
            section_comment = options(body[16:]).get(1, b"").decode()
        elif block_type == 1:
            link_type, _, _ = struct.unpack_from("<HHI", body)
            opts = options(body[8:])
            interfaces.append({"link_type": link_type, "name": opts[2].decode(),
                               "tsresol": opts.get(9)})
        elif block_type == 6:
            interface, high, low, captured, original = struct.unpack_from("<IIIII", body)
            payload = body[20:20 + captured]
            assert captured == original
            opts = options(body[20 + captured + (-captured % 4):])
            flags = struct.unpack("<I", opts[2])[0] if 2 in opts else 0
            comment = opts[1].decode() if 1 in opts else None
            packets.append((interfaces[interface]["name"], (high << 32) | low, flags,
                            payload, comment))
        offset += length
    return section_comment, interfaces, packets


def test_pcapng_holds_every_record_in_order_with_direction_and_time(session, tmp_path):
    out = tmp_path / "session.pcapng"
    counts = exports.write_pcapng(session, out)
    assert counts == {"rx": 2, "tx": 2, "events": 3}

    comment, interfaces, packets = read_pcapng(out)
    assert [i["name"] for i in interfaces] == ["rx", "tx", "events"]
    assert all(i["link_type"] == exports.LINKTYPE_USER0 for i in interfaces)
    assert all(i["tsresol"] == bytes([9]) for i in interfaces)
    assert json.loads(comment)  # the session header, as JSON

    assert [p[0] if p[0] != "events" else p[3].split(b" ")[0].decode() for p in packets] == \
        [kind for _, kind, _ in SESSION_RECORDS]
    start = packets[0][1]
    assert [p[1] - start for p in packets] == [t for t, _, _ in SESSION_RECORDS]
    data_packets = [p for p in packets if p[0] in ("rx", "tx")]
    assert [p[3] for p in data_packets] == [d for _, k, d in SESSION_RECORDS if k in ("rx", "tx")]
    assert [p[2] for p in data_packets] == [1 if p[0] == "rx" else 2 for p in data_packets]
    settings = [p for p in packets if p[3].startswith(b"settings ")]
    assert json.loads(settings[0][3][len(b"settings "):]) == {"baud": 115200}
    assert settings[0][4] == "wiretape event: settings"


def test_pcapng_opens_in_tshark(session, tmp_path):
    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("tshark is not installed (apt-get install tshark): cannot check that "
                    "Wireshark opens the pcapng export")
    out = tmp_path / "session.pcapng"
    exports.write_pcapng(session, out)
    result = subprocess.run(
        [tshark, "-r", str(out), "-T", "fields", "-e", "frame.interface_name",
         "-e", "data.data"],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    rows = [line.split("\t") for line in result.stdout.splitlines() if line.strip()]
    assert [row[0] for row in rows] == \
        [k if k in ("rx", "tx") else "events" for _, k, _ in SESSION_RECORDS]
    assert [bytes.fromhex(row[1]) for row in rows if row[0] in ("rx", "tx")] == \
        [d for _, k, d in SESSION_RECORDS if k in ("rx", "tx")]


def test_mcap_has_one_channel_per_direction_and_reads_back(session, tmp_path):
    from mcap.reader import make_reader

    out = tmp_path / "session.mcap"
    counts = exports.write_mcap(session, out)
    assert counts == {"rx": 2, "tx": 2, "events": 3}

    with open(out, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        topics = {channel.topic: channel for channel in summary.channels.values()}
        assert set(topics) == {"/wiretape/rx", "/wiretape/tx", "/wiretape/events"}
        for channel in topics.values():
            assert channel.message_encoding == "json"
            assert summary.schemas[channel.schema_id].encoding == "jsonschema"
        bytes_schema = json.loads(summary.schemas[topics["/wiretape/rx"].schema_id].data)
        assert bytes_schema["properties"]["data"]["contentEncoding"] == "base64"
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        assert metadata["wiretape"]["port_type"] == "loopback"

    with open(out, "rb") as stream:
        messages = [(channel.topic, message.log_time, json.loads(message.data))
                    for _, channel, message in make_reader(stream).iter_messages()]
    assert [m[2]["kind"] for m in messages] == [k for _, k, _ in SESSION_RECORDS]
    assert [m[2]["t_ns"] for m in messages] == [t for t, _, _ in SESSION_RECORDS]
    start = messages[0][1]
    assert [m[1] - start for m in messages] == [t for t, _, _ in SESSION_RECORDS]
    for (topic, _, body), (_, kind, data) in zip(messages, SESSION_RECORDS):
        if kind in ("rx", "tx"):
            assert topic == f"/wiretape/{kind}"
            assert base64.b64decode(body["data"]) == data
            assert body["size"] == len(data)
        else:
            assert topic == "/wiretape/events"
    assert messages[3][2]["event"] == {"baud": 115200}
    assert messages[2][2]["text"].startswith("VV\\n00P\\nVEND:Hokuyo\\x00\\xff")


def test_real_flexiport_recording_exports_every_record(tmp_path):
    urg_log = str(flexiport_log("urg04lx_2011"))
    reader = wiretape.SessionReader(urg_log)
    expected = [(r.kind, bytes(r.data)) for r in reader if r.kind in ("rx", "tx")]
    assert expected

    pcap = tmp_path / "urg.pcapng"
    exports.write_pcapng(urg_log, pcap)
    _, _, packets = read_pcapng(pcap)
    assert [(p[0], p[3]) for p in packets if p[0] in ("rx", "tx")] == expected

    from mcap.reader import make_reader

    mcap_path = tmp_path / "urg.mcap"
    exports.write_mcap(urg_log, mcap_path)
    with open(mcap_path, "rb") as stream:
        got = [(channel.topic.rsplit("/", 1)[1], base64.b64decode(json.loads(m.data)["data"]))
               for _, channel, m in make_reader(stream).iter_messages()
               if channel.topic != "/wiretape/events"]
    assert got == expected


def test_damaged_or_missing_input_is_a_clear_error_and_leaves_no_output(tmp_path):
    missing = tmp_path / "missing.wtape"
    out = tmp_path / "out.pcapng"
    with pytest.raises(Exception) as error:
        exports.write_pcapng(missing, out)
    assert "missing.wtape" in str(error.value)
    assert not out.exists() and not (tmp_path / "out.pcapng.partial").exists()


def test_escape_bytes_keeps_printable_ascii():
    assert exports.escape_bytes(b"AB\r\n\t\\\x00\xff") == "AB\\r\\n\\t\\\\\\x00\\xff"
