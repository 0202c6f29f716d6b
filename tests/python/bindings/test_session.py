"""Session files from Python: SessionReader, SessionWriter, Record,
export_flexiport, and the golden files of tests/data/golden."""

import json
import pathlib
import struct

import pytest

from wiretape import _core

from real_recordings import FLEXIPORT_DIR as FLEXIPORT

ROOT = pathlib.Path(__file__).resolve().parents[3]
GOLDEN = ROOT / "tests" / "data" / "golden"
GOLDEN_NAMES = ["all_kinds", "wire", "unknown_kind", "damaged", "v1_1_additions"]
# Written by an older format version: read, no longer written.
READ_ONLY_GOLDEN = {"v1_0": 0, "v1_1": 1, "v1_2": 2}
PROVENANCE = ("source_format", "source_files", "source_details", "device_address", "edits")


def load_jsonl(name):
    lines = [json.loads(line) for line in (GOLDEN / f"{name}.jsonl").read_text().splitlines() if line]
    header = lines[0]["header"]
    records = [line for line in lines[1:] if "t_ns" in line]
    corrupt = next((line for line in lines if "corrupt" in line), None)
    return header, records, corrupt


@pytest.mark.parametrize("name", GOLDEN_NAMES + list(READ_ONLY_GOLDEN))
def test_golden_file_reads_as_its_jsonl_says(name):
    header, records, corrupt = load_jsonl(name)
    reader = _core.SessionReader(GOLDEN / f"{name}.wtape")
    got = reader.header
    assert (got.version_major, got.version_minor) == (1, READ_ONLY_GOLDEN.get(name, 3))
    # The golden .jsonl name the writer's members by attribute (make_jsonl.py).
    for key in ("port_options", "port_type", "start_utc", "wiretape_version", "host", "capture",
                "metadata"):
        assert getattr(got, key) == header[key], key
    assert got.source_format == (header.get("source_format") or "wiretape")
    assert got.source_files == header.get("source_files", [])
    assert got.source_details == header.get("source_details", {})
    assert got.device_address == header.get("device_address", "")
    assert got.edits == header.get("edits", [])
    expected = [r for r in records if not r.get("skipped") and r.get("readable", True)]
    actual = [(r.t_ns, r.kind, r.data.hex()) for r in reader]
    assert actual == [(r["t_ns"], r["kind"], r["data_hex"]) for r in expected]
    if corrupt:
        assert reader.damage is not None
        assert reader.damage.offset == corrupt["damage_offset"]
        assert "corrupt" in reader.damage.message
    else:
        assert reader.damage is None


@pytest.mark.parametrize("name", GOLDEN_NAMES)
def test_writer_recreates_golden_file_byte_for_byte(tmp_path, name):
    header, records, corrupt = load_jsonl(name)
    path = tmp_path / "out.wtape"
    with _core.SessionWriter(
        path,
        capture=header["capture"],
        port_options=header["port_options"],
        port_type=header["port_type"],
        metadata=header["metadata"],
        start_utc=header["start_utc"],
        host=header["host"],
        wiretape_version=header["wiretape_version"],
        **{key: header[key] for key in PROVENANCE if key in header},
    ) as writer:
        for r in records:
            kind = r["kind"] if "kind" in r else r["kind_code"]
            writer.write(kind, r["t_ns"], bytes.fromhex(r["data_hex"]), channel=r.get("channel", 0))
    data = bytearray(path.read_bytes())
    if corrupt:
        data[corrupt["corrupt"]["byte"]] ^= corrupt["corrupt"]["xor"]
    assert bytes(data) == (GOLDEN / f"{name}.wtape").read_bytes()


def test_record_fields_and_equality():
    record = _core.Record(12, "rx", b"\x00\xff")
    assert (record.t_ns, record.kind, record.data, record.kind_code) == (12, "rx", b"\x00\xff", 1)
    assert record == _core.Record(12, "rx", b"\x00\xff")
    assert _core.Record(0, "break").kind == "break"
    assert "kind='rx'" in repr(record)
    with pytest.raises(ValueError, match="unknown record kind 'nope'"):
        _core.Record(0, "nope")


def test_writer_and_reader_round_trip_with_paths_and_rewind(tmp_path):
    path = tmp_path / "s.wtape"
    writer = _core.SessionWriter(str(path), capture="wire", port_type="tcp", metadata={"k": "v"})
    writer.write("open", 0, b"{}")
    writer.write("tx", 10, b"hello")
    writer.write("rx", 20, bytes(range(256)) * 10)
    writer.close()
    writer.close()  # closing twice is harmless
    with pytest.raises(ValueError, match="closed"):
        writer.write("rx", 30, b"late")
    reader = _core.SessionReader(path)
    assert reader.header.capture == "wire"
    assert reader.header.port_type == "tcp"
    assert reader.header.metadata == {"k": "v"}
    assert reader.header.source_format == "wiretape"
    first = [(r.kind, r.t_ns, r.data) for r in reader]
    assert first == [("open", 0, b"{}"), ("tx", 10, b"hello"), ("rx", 20, bytes(range(256)) * 10)]
    reader.rewind()
    assert [(r.kind, r.t_ns, r.data) for r in reader] == first


def test_bad_arguments_are_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="capture must be 'client' or 'wire'"):
        _core.SessionWriter(tmp_path / "x.wtape", capture="proxy")
    with pytest.raises(_core.PortError) as info:
        _core.SessionWriter(tmp_path / "no" / "such" / "dir.wtape")
    assert "no/such/dir.wtape" in str(info.value)


@pytest.mark.parametrize(
    "content, words, offset",
    [
        (b"", "empty file", 0),
        (b"not a session at all, just text\n", "wrong magic", 0),
        (b"\x89WTAPE\r\n\x01\x00", "truncated header", 10),
        (b"\x89WTAPE\r\n\x03\x00\x00\x00\x02\x00\x00\x00{}\x00\x00\x00\x00", "newer than this reader", 8),
    ],
)
def test_unusable_files_raise_session_error_with_offset(tmp_path, content, words, offset):
    path = tmp_path / "bad.wtape"
    path.write_bytes(content)
    with pytest.raises(_core.SessionError) as info:
        _core.SessionReader(path)
    assert words in str(info.value)
    assert info.value.offset == offset
    assert isinstance(info.value, ValueError)


def test_truncated_file_keeps_every_whole_record(tmp_path):
    path = tmp_path / "s.wtape"
    with _core.SessionWriter(path) as writer:
        for i in range(10):
            writer.write("rx", i, b"x" * i)
    data = path.read_bytes()
    path.write_bytes(data[:-3])
    reader = _core.SessionReader(path)
    assert [r.t_ns for r in reader] == list(range(9))
    assert reader.damage is not None
    assert "truncated" in reader.damage.message


def flexiport_chunks(path):
    data = path.read_bytes()
    at, chunks = 0, []
    while at < len(data):
        sec, usec, length = struct.unpack(">III", data[at:at + 12])
        chunks.append((sec * 10**9 + usec * 1000, data[at + 12:at + 12 + length]))
        at += 12 + length
    return chunks


@pytest.mark.parametrize("name", ["urg04lx_2011", "utm30lx_2011"])
def test_flexiport_import_keeps_every_byte_and_time(name):
    prefix = FLEXIPORT / f"{name}.log"
    reader = _core.SessionReader(prefix)
    assert reader.header.source_format == "flexiport"
    records = list(reader)
    assert reader.damage is None
    assert [(r.t_ns, r.data) for r in records if r.kind == "rx"] == flexiport_chunks(FLEXIPORT / f"{name}.logr")
    assert [(r.t_ns, r.data) for r in records if r.kind == "tx"] == flexiport_chunks(FLEXIPORT / f"{name}.logw")
    times = [r.t_ns for r in records]
    assert times == sorted(times)


@pytest.mark.parametrize("name", ["urg04lx_2011", "utm30lx_2011"])
def test_flexiport_round_trip_through_wtape_is_byte_for_byte(tmp_path, name):
    prefix = FLEXIPORT / f"{name}.log"
    session = tmp_path / "s.wtape"
    with _core.SessionWriter(session) as writer:
        for record in _core.SessionReader(prefix):
            writer.write(record.kind, record.t_ns, record.data)
    _core.export_flexiport(session, tmp_path / "out.log")
    assert (tmp_path / "out.logr").read_bytes() == (FLEXIPORT / f"{name}.logr").read_bytes()
    assert (tmp_path / "out.logw").read_bytes() == (FLEXIPORT / f"{name}.logw").read_bytes()


def test_crc32c_check_value():
    assert _core.crc32c(b"123456789") == 0xE3069283
    assert _core.crc32c(b"6789", _core.crc32c(b"12345")) == 0xE3069283


def test_port_with_log_option_records_what_crossed(tmp_path):
    path = tmp_path / "loop.wtape"
    port = _core.open_port(f"type=loopback,timeout=2,log={path},meta_robot=r2")
    port.write(b"ping")
    assert port.read_exactly(4) == b"ping"
    port.close()
    reader = _core.SessionReader(path)
    assert reader.header.port_type == "loopback"
    assert reader.header.metadata == {"robot": "r2"}
    records = list(reader)
    assert records[0].kind == "open" and records[0].t_ns == 0
    assert records[-1].kind == "close"
    assert b"".join(r.data for r in records if r.kind == "tx") == b"ping"
    assert b"".join(r.data for r in records if r.kind == "rx") == b"ping"


# --- the format's knowledge, bound once from the library ----------------------

DOC = ROOT / "docs" / "session-format.md"


def markdown_table(text, heading):
    """The rows of the first table after `heading`, as lists of cell texts
    with their backticks removed."""
    section = text.split(heading + "\n", 1)[1]
    rows = []
    for line in section.splitlines():
        if not line.startswith("|"):
            if rows:
                break
            continue
        cells = [cell.strip().strip("`") for cell in line.strip().strip("|").split("|")]
        if set("".join(cells)) <= set("-"):
            continue
        rows.append(cells)
    return rows[1:]  # without the column names


def test_record_kind_table_in_the_spec_says_what_the_library_says():
    text = DOC.read_text()
    kinds = [
        [f"0x{kind['code']:02X}", kind["name"], "event" if kind["is_event"] else "direction",
         kind["meaning"]]
        for kind in _core.RECORD_KINDS
    ]
    assert markdown_table(text, "### Record kinds") == kinds
    fields = [
        [kind["name"], field["name"], field["type"], "yes" if field["required"] else "no",
         field["meaning"]]
        for kind in _core.RECORD_KINDS
        for field in kind["fields"]
    ]
    assert markdown_table(text, "### Event payloads") == fields


def test_record_kinds_are_the_ones_records_and_writers_know(tmp_path):
    names = [kind["name"] for kind in _core.RECORD_KINDS]
    assert names[:2] == ["rx", "tx"] and "break" in names and "client_connect" in names
    path = tmp_path / "kinds.wtape"
    with _core.SessionWriter(path) as writer:
        for kind in _core.RECORD_KINDS:
            writer.write(kind["name"], 0, b"{}")
    assert [(r.kind, r.kind_code) for r in _core.SessionReader(path)] == [
        (kind["name"], kind["code"]) for kind in _core.RECORD_KINDS
    ]
    with pytest.raises(ValueError, match="one of rx, tx, open, .*device_lost"):
        _core.Record(0, "nonsense")


def test_layout_constants_match_a_written_file(tmp_path):
    path = tmp_path / "layout.wtape"
    with _core.SessionWriter(path, start_utc="2026-01-01T00:00:00Z", host="h", wiretape_version="1") as writer:
        writer.write("tx", 7, b"abc")
    data = path.read_bytes()
    assert data.startswith(_core.SESSION_MAGIC)
    assert _core.SESSION_MAGIC == b"\x89WTAPE\r\n"
    assert struct.unpack_from("<HH", data, 8) == _core.SESSION_VERSION
    json_length = struct.unpack_from("<I", data, 12)[0]
    assert _core.FILE_HEADER_FIXED_SIZE == 16 and _core.CRC_SIZE == 4
    header_end = json_length + _core.FILE_HEADER_OVERHEAD
    assert len(data) == header_end + _core.RECORD_OVERHEAD + 3
    assert data[header_end + _core.RECORD_HEADER_SIZE:][:3] == b"abc"
    assert _core.MAX_HEADER_JSON == 16 << 20


def test_flexiport_prefix_is_the_library_rule(tmp_path):
    (tmp_path / "scan.logr").write_bytes(b"")
    (tmp_path / "scan.logw").write_bytes(b"")
    prefix = str(tmp_path / "scan.log")
    assert _core.flexiport_prefix(tmp_path / "scan.log") == prefix
    assert _core.flexiport_prefix(str(tmp_path / "scan.logr")) == prefix
    assert _core.flexiport_prefix(str(tmp_path / "scan.logw")) == prefix
    assert _core.flexiport_prefix(str(tmp_path / "other.wtape")) is None


@pytest.mark.parametrize("packed, plain", [("v2_0", "all_kinds"), ("v2_0_channels", "v1_2_channels"),
                                           ("v2_0_index", "v1_2_channels")])
def test_a_compressed_golden_file_reads_as_the_file_it_was_made_from(packed, plain):
    """Format 2.0 (zstd chunks), made by ``convert --compress zstd``: read,
    not re-created byte for byte (zstd's output may change with its version)."""
    reader = _core.SessionReader(GOLDEN / f"{packed}.wtape")
    assert (reader.header.version_major, reader.header.version_minor) == (2, 0)

    def records(r):
        return [(x.t_ns, x.kind, x.data, x.channel) for x in r]

    assert records(reader) == records(_core.SessionReader(GOLDEN / f"{plain}.wtape"))
    assert reader.damage is None


def test_a_compressed_golden_file_of_two_channels_is_read_through_its_index():
    """v2_0_index ends with the index of its chunks (v2_0_channels, written
    before compressed files had one, has none): verify says it is current,
    and a reader of one channel gives that channel's records."""
    assert _core.check_session_records(str(GOLDEN / "v2_0_index.wtape")).index_state == "current"
    assert _core.check_session_records(str(GOLDEN / "v2_0_channels.wtape")).index_state == "absent"
    for channel in (0, 1):
        def records(name):
            return [(x.t_ns, x.kind, x.data) for x in _core.SessionReader(GOLDEN / name, channel)]
        assert records("v2_0_index.wtape") == records("v1_2_channels.wtape")
