"""Writes the .jsonl descriptions of the golden session files.

The .jsonl files are the source of truth: tests/cpp/session/session_golden_test.cpp
writes each .wtape from its .jsonl with SessionWriter and requires the result
to equal the committed file byte for byte (run it with
WIRETAPE_REGENERATE_GOLDEN=1 to rewrite the .wtape files after a deliberate
format change). Each .jsonl holds:

  line 1: {"header": {...}}    the header fields given to the writer
  then one line per record written, in file order:
    {"t_ns": N, "kind": "rx", "data_hex": "..."}       (events add "event": {...})
    {"t_ns": N, "kind_code": 127, "data_hex": "...", "skipped": true}
        a kind this reader does not know: written, skipped when read
    {..., "readable": false}  a record at or after the damage
    {..., "channel": 1, "skipped": true}
        a record of another port (channels are reserved for sessions of
        several ports): written, skipped when read
  line 1 may also hold "header_room": N: the writer is made with N bytes of
  header room and the header without its "channels", and each channel is
  then added (SessionWriter::add_channel, the header rewritten in place),
  as a Recorder writes a session of several ports.
  and for a damaged file a last line
    {"corrupt": {"byte": B, "xor": X}, "damage_offset": D}
        byte B of the written file is XORed with X; reading stops at D.

v1_0.wtape/.jsonl is a file written by format version 1.0 (all_kinds as it
was then): readers must still read it; the writer, now at 1.1, no longer
writes it, so it is not regenerated (this script leaves it alone). So are
v1_1 and v1_2 (v1_2_channels as format 1.2 wrote it: two channels, no
index; a reader of one channel scans it). v2_0.wtape and v2_0_channels.wtape
are all_kinds and v1_2_channels converted with `wiretape convert --compress
zstd` (format 2.0): read, compared with those, never re-created byte for byte
(zstd's output may change with its version). v2_0_channels was made before
compressed files had an index; v2_0_index is v1_2_channels converted the
same way since, ending with the index of its one chunk.
"""
import json
import pathlib

HERE = pathlib.Path(__file__).parent


def header(capture="client", **extra):
    h = {
        "port_options": "type=loopback,log=golden.wtape,meta_robot=r2",
        "port_type": "loopback",
        "start_utc": "2026-11-23T10:00:00.000000Z",
        "wiretape_version": "0.1.0",
        "host": "golden-host",
        "capture": capture,
        "metadata": {"robot": "r2"},
    }
    h.update(extra)
    return h


def rec(t_ns, kind, data=b"", event=None, **extra):
    if event is not None:
        data = json.dumps(event, separators=(",", ":")).encode()
    line = {"t_ns": t_ns, "kind": kind, "data_hex": data.hex()}
    if event is not None:
        line["event"] = event
    line.update(extra)
    return line


def write(name, lines):
    with open(HERE / f"{name}.jsonl", "w") as out:
        for line in lines:
            out.write(json.dumps(line, separators=(",", ":")) + "\n")


ALL_KINDS = [
    rec(0, "open", event={"description": "loopback"}),
    rec(1_000, "tx", b"VV\n"),
    rec(2_500_000, "rx", b"VV\n00P\n"),
    rec(3_000_000, "rx", bytes(range(256))),
    rec(4_000_000, "flush_input", event={}),
    rec(4_100_000, "flush_output", event={}),
    rec(4_200_000, "drain", event={}),
    rec(5_000_000, "settings", event={"baud": 115200}),
    rec(5_100_000, "settings", event={"baud": 57600, "databits": 8, "stopbits": 1,
                                      "parity": "even", "flow": "none"}),
    rec(6_000_000, "modem_lines", event={"dtr": True}),
    rec(6_100_000, "modem_lines", event={"rts": False}),
    rec(7_000_000, "break", event={"duration_ms": 250}),
    rec(8_000_000, "client_connect", event={"peer": "127.0.0.1:50000"}),
    rec(8_500_000, "client_disconnect", event={}),
    rec(9_000_000, "tx", b""),
    rec(9_500_000, "device_lost", event={"error": "device went away", "errno": 6}),
    rec(9_600_000, "fault", event={"kind": "corrupt", "where": "exchange:3",
                                   "detail": "flipped bit 3 of rx byte 120"}),
    rec(9_700_000, "redaction", event={"offset": 2, "length": 4}),
    rec(9_700_000, "tx", b"pw********\n"),
    rec(10_000_000, "close", event={}),
]

write("all_kinds", [{"header": header()}] + ALL_KINDS)

write("wire", [{"header": header(capture="wire", port_type="serial",
                                 port_options="type=serial,device=/dev/ttyACM0,baud=115200",
                                 metadata={})}] + [
    rec(0, "open", event={"description": "serial /dev/ttyACM0 @ 115200 8N1"}),
    rec(10_000, "client_connect", event={"peer": "pty /tmp/ttyV0"}),
    rec(20_000, "tx", b"V"),
    rec(20_100, "tx", b"V\n"),
    rec(1_020_000, "rx", b"VV\n00P\nVEND:Hokuyo;"),
    rec(1_020_500, "rx", b"[\n\n"),
    rec(2_000_000, "client_disconnect", event={}),
    rec(2_000_001, "close", event={}),
])

write("unknown_kind", [{"header": header()}] + [
    rec(0, "open", event={}),
    rec(100, "tx", b"ping"),
    {"t_ns": 150, "kind_code": 127, "data_hex": b'{"from":"a newer writer"}'.hex(),
     "skipped": True},
    rec(200, "rx", b"pong"),
    {"t_ns": 250, "kind_code": 0, "data_hex": "", "skipped": True},
    rec(300, "close", event={}),
])

# Damage: one bit of the third record's payload flipped. Records are 16 bytes
# of header, the payload and a 4-byte CRC; the header is 16 + JSON + 4 bytes.
damaged_header = header()
json_len = len(json.dumps(damaged_header, separators=(",", ":")).encode())
damaged_records = [
    rec(0, "open", event={}),
    rec(1_000, "tx", b"GD0044072501\n"),
    rec(2_000, "rx", b"GD0044072501\n00P\n"),
    rec(3_000, "rx", b"0C0C0C0C"),
    rec(4_000, "close", event={}),
]
offset = 16 + json_len + 4
for r in damaged_records[:2]:
    offset += 16 + len(bytes.fromhex(r["data_hex"])) + 4
damage_offset = offset
for r in damaged_records[2:]:
    r["readable"] = False
write("damaged", [{"header": damaged_header}] + damaged_records +
      [{"corrupt": {"byte": damage_offset + 16 + 3, "xor": 4},
        "damage_offset": damage_offset}])

# Format 1.1's additions: provenance and address members in the header, and
# a record of another channel (reserved for sessions of several ports).
write("v1_1_additions", [{"header": header(
    port_type="tcp", port_options="type=tcp,host=192.0.2.7,port=502",
    start_utc="", host="", metadata={},
    source_format="pcap", source_files=["plc.pcapng"],
    source_details={"stream": "tcp.stream eq 0"},
    device_address="192.0.2.7:502",
    edits=["cut 0.5:2 s", "redacted 1 match in 1 record"])}] + [
    rec(0, "open", event={"description": "tcp 192.0.2.7:502"}),
    rec(1_000, "client_connect", event={"peer": "192.0.2.1:40312", "role": "control"}),
    rec(2_000, "tx", b"\x00\x01\x00\x00\x00\x06\x01\x03\x00\x00\x00\x02"),
    {**rec(2_500, "rx", b"another port"), "channel": 1, "skipped": True},
    rec(3_000, "rx", b"\x00\x01\x00\x00\x00\x07\x01\x03\x04\x00\x2a\x00\x07"),
    rec(4_000, "close", event={}),
])

# Format 1.2's channels: a session of two ports, written as a Recorder writes
# it (header room, each channel added in place). The top-level port members
# are channel 0's, what a 1.1 reader sees; records of both channels
# interleave in time order.
GPS_OPTIONS = "type=serial,device=/dev/ttyUSB0,baud=9600"
RTK_OPTIONS = "type=tcp,host=192.0.2.9,port=2101"
write("v1_2_channels", [{"header": header(
    capture="wire", port_type="serial", port_options=GPS_OPTIONS, metadata={},
    channels=[
        {"id": 0, "name": "gps", "port_options": GPS_OPTIONS, "port_type": "serial",
         "capture": "wire"},
        {"id": 1, "name": "rtk", "port_options": RTK_OPTIONS, "port_type": "tcp",
         "capture": "wire", "device_address": "192.0.2.9:2101"},
    ]), "header_room": 512}] + [
    rec(0, "open", event={"description": "serial /dev/ttyUSB0 @ 9600 8N1"}),
    {**rec(1_000, "open", event={"description": "tcp 192.0.2.9:2101"}), "channel": 1},
    {**rec(2_000, "tx", b"GET /RTCM3 HTTP/1.0\r\n\r\n"), "channel": 1},
    rec(3_000, "rx", b"$GPGGA,1*00\r\n"),
    {**rec(4_000, "rx", b"ICY 200 OK\r\n"), "channel": 1},
    rec(5_000, "rx", b"$GPGGA,2*00\r\n"),
    {**rec(6_000, "close", event={}), "channel": 1},
    rec(7_000, "close", event={}),
])
