"""Exports to pcapng (Wireshark) and MCAP (Foxglove): every record comes out,
in order, in its direction, with its time; the files open in the real tools."""

import base64
import json
import shutil
import subprocess

import pytest
from pcapng_reader import read_pcapng
from real_recordings import flexiport_log

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


def test_pcapng_holds_every_record_in_order_with_direction_and_time(session, tmp_path):
    out = tmp_path / "session.pcapng"
    counts = exports.write_pcapng(session, out)
    assert counts == {"rx": 2, "tx": 2, "events": 3}

    comment, interfaces, packets = read_pcapng(out)
    assert [i["name"] for i in interfaces] == ["rx", "tx", "events"]
    assert all(i["link_type"] == exports.LINKTYPE_USER0 for i in interfaces)
    assert all(i["tsresol"] == bytes([9]) for i in interfaces)
    # The session header, as the file holds it (its header JSON, DESIGN §25).
    assert json.loads(comment) == json.loads(wiretape.SessionReader(str(session)).header.to_json())

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


# --- TCP and UDP sessions as IP packets -----------------------------------------

MODBUS_REQUEST = bytes.fromhex("0001 0000 0006 01 03 0000 0002")
MODBUS_REPLY = bytes.fromhex("0001 0000 0007 01 03 04 0011 002a")
MODBUS_REQUEST_2 = bytes.fromhex("0002 0000 0006 01 03 0004 0001")
MODBUS_REPLY_2 = bytes.fromhex("0002 0000 0005 01 03 02 1267")


def network_session(tmp_path, port_type, port_options, records, name="net.wtape"):
    path = tmp_path / name
    with wiretape.SessionWriter(str(path), port_options=port_options, port_type=port_type,
                                capture="wire") as writer:
        for t_ns, kind, data in records:
            writer.write(kind, t_ns, data)
    return path


def tshark_fields(path, fields, *options):
    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed (apt-get install tshark): cannot "
                    "check that Wireshark decodes the pcapng export")
    command = [tshark, "-r", str(path), *options, "-T", "fields", "-E", "occurrence=a",
               "-E", "aggregator=,"]
    for field in fields:
        command += ["-e", field]
    result = subprocess.run(command, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return [line.split("\t") for line in result.stdout.splitlines()]


def modbus_records(peer):
    connect = json.dumps({"peer": peer, "role": "control"}).encode()
    return [
        (0, "open", b""),
        (1_000, "client_connect", connect),
        (2_000_000, "tx", MODBUS_REQUEST),
        (3_000_000, "rx", MODBUS_REPLY),
        (4_000_000, "tx", MODBUS_REQUEST_2),
        (5_000_000, "rx", MODBUS_REPLY_2),
        (6_000_000, "client_disconnect", json.dumps({"peer": peer}).encode()),
    ]


def test_a_modbus_tcp_session_exports_as_ip_frames_wireshark_decodes_as_modbus(tmp_path):
    session = network_session(tmp_path, "tcp", "type=tcp,host=10.0.0.5,port=502",
                              modbus_records("10.0.0.9:40312"))
    out = tmp_path / "modbus.pcapng"
    assert exports.write_pcapng(session, out) == {"rx": 2, "tx": 2, "events": 3}
    _, interfaces, _ = read_pcapng(out)
    assert [(i["name"], i["link_type"]) for i in interfaces] == \
        [("rx", exports.LINKTYPE_RAW), ("tx", exports.LINKTYPE_RAW),
         ("events", exports.LINKTYPE_USER0)]

    rows = tshark_fields(out, ["ip.src", "tcp.srcport", "ip.dst", "tcp.dstport", "mbtcp.trans_id",
                               "modbus.func_code", "modbus.regval_uint16", "tcp.flags.str"],
                         "-Y", "mbtcp")
    assert [row[:6] for row in rows] == [
        ["10.0.0.9", "40312", "10.0.0.5", "502", "1", "3"],
        ["10.0.0.5", "502", "10.0.0.9", "40312", "1", "3"],
        ["10.0.0.9", "40312", "10.0.0.5", "502", "2", "3"],
        ["10.0.0.5", "502", "10.0.0.9", "40312", "2", "3"],
    ]
    assert [rows[1][6], rows[3][6]] == ["17,42", "4711"]
    # a whole connection: handshake, data, FIN both ways; no analysis complaints
    flags = tshark_fields(out, ["tcp.flags.str"], "-Y", "tcp")
    assert len(flags) == 3 + 4 + 3
    assert not tshark_fields(out, ["frame.number"], "-Y", "tcp.analysis.flags")


def test_a_tcp_session_on_another_port_decodes_with_the_port_preference_and_splits_big_payloads(tmp_path):
    big = bytes(range(256)) * 600  # 153600 bytes: more than one IP packet holds
    session = network_session(tmp_path, "tcp", "type=tcp,host=127.0.0.1,port=15020", [
        (0, "tx", MODBUS_REQUEST), (1_000_000, "rx", MODBUS_REPLY), (2_000_000, "rx", big)])
    out = tmp_path / "modbus.pcapng"
    exports.write_pcapng(session, out)
    rows = tshark_fields(out, ["mbtcp.trans_id", "modbus.func_code"],
                         "-o", "mbtcp.tcp.port:15020", "-Y", "mbtcp")
    assert rows[:2] == [["1", "3"], ["1", "3"]]
    lengths = tshark_fields(out, ["ip.src", "tcp.len", "tcp.srcport"], "-Y", "tcp.len > 0")
    from_device = [int(length) for _, length, port in lengths if port == "15020"]
    assert sum(from_device) == len(MODBUS_REPLY) + len(big)
    assert max(from_device) <= 65000
    # no client_connect: placeholders for the client, the recorded device address
    assert {row[0] for row in lengths} == {"127.0.0.1", "192.0.2.1"}


def test_a_udp_session_exports_as_udp_datagrams_with_the_recorded_ports(tmp_path):
    session = network_session(tmp_path, "udp", "type=udp,host=192.168.1.201,port=40000", [
        (0, "client_connect", json.dumps({"peer": "192.168.1.7:5000",
                                          "role": "control"}).encode()),
        (1_000, "tx", b"PING"), (2_000, "rx", b"PONG\x00\xff"), (3_000, "rx", b"")])
    out = tmp_path / "udp.pcapng"
    exports.write_pcapng(session, out)
    rows = tshark_fields(out, ["ip.src", "udp.srcport", "ip.dst", "udp.dstport", "udp.length",
                               "udp.payload"], "-Y", "udp")
    assert rows == [
        ["192.168.1.7", "5000", "192.168.1.201", "40000", "12", b"PING".hex()],
        ["192.168.1.201", "40000", "192.168.1.7", "5000", "14", b"PONG\x00\xff".hex()],
        ["192.168.1.201", "40000", "192.168.1.7", "5000", "8", ""],
    ]
    good = tshark_fields(out, ["frame.number"], "-o", "udp.check_checksum:TRUE",
                         "-o", "ip.check_checksum:TRUE",
                         "-Y", "udp.checksum.status == 1 and ip.checksum.status == 1")
    assert len(good) == 3


def test_ipv6_addresses_are_kept(tmp_path):
    session = network_session(tmp_path, "tcp", "type=tcp,host=\"::1\",port=502",
                              modbus_records("[::1]:40000"))
    out = tmp_path / "v6.pcapng"
    exports.write_pcapng(session, out)
    rows = tshark_fields(out, ["ipv6.src", "tcp.srcport", "mbtcp.trans_id"], "-Y", "mbtcp")
    assert [row[:2] for row in rows] == [["::1", "40000"], ["::1", "502"]] * 2


def test_a_serial_session_keeps_the_user_link_type(tmp_path):
    session = network_session(tmp_path, "serial", "type=serial,device=/dev/ttyUSB0",
                              [(0, "tx", b"VV\n"), (1_000, "rx", b"VV\n00P\n")])
    out = tmp_path / "serial.pcapng"
    exports.write_pcapng(session, out)
    _, interfaces, packets = read_pcapng(out)
    assert {i["link_type"] for i in interfaces} == {exports.LINKTYPE_USER0}
    assert [(p[0], p[3]) for p in packets] == [("tx", b"VV\n"), ("rx", b"VV\n00P\n")]
    rows = tshark_fields(out, ["frame.interface_name", "frame.protocols", "data.data"])
    assert rows == [["tx", "user_dlt:data", b"VV\n".hex()],
                    ["rx", "user_dlt:data", b"VV\n00P\n".hex()]]


def test_a_monitors_connect_and_disconnect_leave_the_clients_tcp_connection_alone():
    # Client connections follow the bridge's rule (bound from C++): a
    # read-only monitor's connect opens no connection and its disconnect
    # closes none; the client's own disconnect does.
    from wiretape.exports.network import NetworkSession

    net = NetworkSession.of_header({"port_type": "tcp",
                                    "port_options": "type=tcp,host=10.0.0.5,port=502"})
    event = lambda **fields: json.dumps(fields).encode()
    flags = []
    for kind, data in [("client_connect", event(peer="10.0.0.9:4000", role="control")),
                       ("tx", MODBUS_REQUEST),
                       ("client_connect", event(peer="10.0.0.7:4001", role="monitor")),
                       ("rx", MODBUS_REPLY),
                       ("client_disconnect", event(peer="10.0.0.7:4001")),
                       ("tx", MODBUS_REQUEST_2),
                       ("rx", MODBUS_REPLY_2),
                       ("client_disconnect", event(peer="10.0.0.9:4000"))]:
        for _, packet in net.packets(kind, data):
            header_length = (packet[0] & 0x0F) * 4
            flags.append(packet[header_length + 13])
    syn, fin = 0x02, 0x01
    assert sum(1 for f in flags if f & syn) == 2  # one handshake: SYN, SYN-ACK
    fins = [i for i, f in enumerate(flags) if f & fin]
    assert len(fins) == 2 and fins[0] >= len(flags) - 3  # closed once, at the end
