"""wiretape.tools: show, stats, verify and convert."""

import io
import json
import pathlib
import subprocess
import sys

import pytest
from real_recordings import flexiport_log

from wiretape import _core
from wiretape.tools import convert as convert_module
from wiretape.tools.convert import ConvertResult
from wiretape.tools.show import show
from wiretape.tools.stats import stats as session_stats
from wiretape.tools.verify import VerifyResult, verify

ROOT = pathlib.Path(__file__).resolve().parents[3]
GOLDEN = ROOT / "tests" / "data" / "golden"


def golden_records(name):
    lines = [json.loads(line) for line in (GOLDEN / f"{name}.jsonl").read_text().splitlines() if line]
    return [line for line in lines[1:] if "t_ns" in line and not line.get("skipped")
            and line.get("readable", True)]


@pytest.mark.parametrize("name", ["all_kinds", "wire", "unknown_kind"])
def test_show_jsonl_gives_one_object_per_record(name):
    out = io.StringIO()
    count = show(GOLDEN / f"{name}.wtape", fmt="jsonl", out=out)
    lines = [json.loads(line) for line in out.getvalue().splitlines()]
    expected = golden_records(name)
    assert count == len(expected) == len(lines)
    for got, want in zip(lines, expected):
        assert (got["t_ns"], got["kind"], got["data_hex"]) == (want["t_ns"], want["kind"], want["data_hex"])
        assert got["size"] == len(bytes.fromhex(want["data_hex"]))
        if "event" in want:
            assert got["event"] == want["event"]
        else:
            assert "event" not in got


def test_show_text_lists_header_events_and_data():
    out = io.StringIO()
    show(GOLDEN / "all_kinds.wtape", out=out)
    text = out.getvalue()
    assert "capture      client" in text
    assert "started      2026-11-23T10:00:00.000000Z on golden-host" in text
    assert "meta         robot=r2" in text
    assert "-> VV\\n" in text
    assert "<- VV\\n00P\\n" in text
    assert '{"baud":115200}' in text
    assert "break" in text and '{"duration_ms":250}' in text
    assert text.rstrip().endswith("20 records")


def test_show_hex_dumps_payloads():
    out = io.StringIO()
    show(GOLDEN / "all_kinds.wtape", fmt="hex", out=out)
    assert "00000000  56 56 0a" in out.getvalue()
    assert "|VV.|" in out.getvalue()


def test_show_reports_damage_after_the_good_records():
    out = io.StringIO()
    count = show(GOLDEN / "damaged.wtape", out=out)
    assert count == 2
    assert "DAMAGED at byte 296" in out.getvalue()


def test_show_scip_reassembles_commands_and_replies():
    out = io.StringIO()
    show(flexiport_log("urg04lx_2011"), decode="scip", out=out)
    lines = [line for line in out.getvalue().splitlines() if "  tx  " in line or "  rx  " in line]
    # time, Δt, kind, size ("3 B"), then the frame's name
    commands = [line.split("  tx  ")[1].split()[2] for line in lines if "  tx  " in line]
    assert commands == ["VV", "VV", "PP", "II", "BM", "CR00", "VV", "PP", "II", "GD0044072501"]
    replies = [line for line in lines if "  rx  " in line]
    assert len(replies) == 10
    assert "reply to BM (laser on): status 02" in replies[4]
    assert "reply to GD" in replies[-1]


def test_show_rejects_unknown_format_and_decoder():
    with pytest.raises(ValueError, match="unknown format 'xml'"):
        show(GOLDEN / "wire.wtape", fmt="xml")
    with pytest.raises(ValueError, match="unknown profile 'nmea-xyz'"):
        show(GOLDEN / "wire.wtape", decode="nmea-xyz")


def test_stats_counts_bytes_records_and_header():
    stats = session_stats(GOLDEN / "wire.wtape")
    assert stats.records == 8
    assert stats.tx_records == 2 and stats.tx_bytes == 3
    assert stats.rx_records == 2 and stats.rx_bytes == len(b"VV\n00P\nVEND:Hokuyo;") + 3
    assert stats.event_records == 4
    assert stats.events == {"open": 1, "client_connect": 1, "client_disconnect": 1, "close": 1}
    assert stats.duration_s == pytest.approx(0.002000001)
    assert stats.capture == "wire"
    assert stats.port_type == "serial"
    assert stats.damaged is False


def test_stats_of_real_flexiport_log():
    stats = session_stats(flexiport_log("utm30lx_2011"))
    assert stats.source_format == "flexiport"
    assert stats.rx_bytes == stats.rx_records  # one byte per read call
    assert stats.tx_bytes == sum(len(c) for c in [b"VV\n", b"VV\n", b"PP\n", b"II\n", b"BM\n", b"CR00\n",
                                                     b"VV\n", b"PP\n", b"II\n", b"ME0000108001101\n"])


def test_verify_good_damaged_and_unreadable(tmp_path):
    good = verify(GOLDEN / "all_kinds.wtape")
    assert good == VerifyResult(ok=True, path=str(GOLDEN / "all_kinds.wtape"), records=20,
                                offset=None, message=None)
    damaged = verify(GOLDEN / "damaged.wtape")
    assert damaged.ok is False and damaged.records == 2 and damaged.offset == 296
    assert "CRC32C" in damaged.message
    (tmp_path / "junk.wtape").write_bytes(b"junk")
    junk = verify(tmp_path / "junk.wtape")
    assert junk.ok is False and junk.offset == 0 and "wrong magic" in junk.message


def records_of(path):
    return [(r.t_ns, r.kind, r.data) for r in _core.SessionReader(path)]


def test_convert_round_trips_between_wiretape_jsonl_and_flexiport(tmp_path):
    source = flexiport_log("urg04lx_2011")
    a = tmp_path / "a.wtape"
    assert convert_module.convert(source, a).records == len(records_of(source))
    jsonl = tmp_path / "a.jsonl"
    convert_module.convert(a, jsonl)
    b = tmp_path / "b.wtape"
    convert_module.convert(jsonl, b)
    assert records_of(b) == records_of(a) == records_of(source)
    assert _core.SessionReader(b).header == _core.SessionReader(a).header
    convert_module.convert(jsonl, tmp_path / "back.log")
    assert (tmp_path / "back.logr").read_bytes() == source.with_suffix(".logr").read_bytes()
    assert (tmp_path / "back.logw").read_bytes() == source.with_suffix(".logw").read_bytes()


def test_converted_flexiport_log_names_its_source_and_invents_no_time_or_host(tmp_path):
    source = flexiport_log("urg04lx_2011")
    converted = tmp_path / "a.wtape"
    convert_module.convert(source, converted)
    header = _core.SessionReader(converted).header
    assert (header.version_major, header.version_minor) == _core.SESSION_VERSION
    assert header.source_format == "flexiport"
    assert header.source_files == ["urg04lx_2011.logr", "urg04lx_2011.logw"]
    assert header.source_details == {"read_format": "new", "write_format": "new"}
    assert (header.start_utc, header.host) == ("", "")
    for session in (source, converted):
        out = io.StringIO()
        show(session, out=out)
        text = out.getvalue()
        assert "imported     from flexiport (urg04lx_2011.logr, urg04lx_2011.logw)" in text
        assert "started      at a time not recorded\n" in text
    assert "flexiport log (name.logr + name.logw)" in _show_text(source)
    assert f"format       wiretape {_core.SESSION_VERSION[0]}.{_core.SESSION_VERSION[1]}" in _show_text(converted)


def _show_text(path) -> str:
    out = io.StringIO()
    show(path, out=out)
    return out.getvalue()


def test_format_1_1_header_members_survive_conversion_through_jsonl(tmp_path):
    jsonl = tmp_path / "g.jsonl"
    convert_module.convert(GOLDEN / "v1_1_additions.wtape", jsonl)
    out = tmp_path / "g.wtape"
    convert_module.convert(jsonl, out)
    assert _core.SessionReader(out).header == _core.SessionReader(GOLDEN / "v1_1_additions.wtape").header
    text = _show_text(out)
    assert "imported     from pcap (plc.pcapng); stream: tcp.stream eq 0" in text
    assert "device       192.0.2.7:502" in text
    assert "edited       cut 0.5:2 s" in text


def test_the_device_identity_is_shown_and_kept_by_stats_and_jsonl(tmp_path):
    # Format 1.2's device_identity (DESIGN §20): show prints it, stats and a
    # round trip through jsonl keep it.
    identity = {"kernel_name": "ttyACM0", "subsystem": "usb", "vendor_id": "2341",
                "product_id": "0043", "serial_number": "8573", "manufacturer": "Arduino",
                "product": "Uno", "interface": "", "location": "1-2:1.0",
                "by_id": "/dev/serial/by-id/usb-Arduino_Uno_8573-if00"}
    source = tmp_path / "id.wtape"
    with _core.SessionWriter(source, port_type="serial", device_identity=identity) as writer:
        writer.write("rx", 1, b"x")
    assert ("identity     kernel_name=ttyACM0, subsystem=usb, vendor_id=2341, "
            "product_id=0043, serial_number=8573, manufacturer=Arduino, product=Uno, "
            "location=1-2:1.0, by_id=/dev/serial/by-id/usb-Arduino_Uno_8573-if00"
            in _show_text(source))
    # As the file holds it: the members not known ("interface") left out.
    known = {name: value for name, value in identity.items() if value}
    assert session_stats(source).to_json()["device_identity"] == known
    jsonl = tmp_path / "id.jsonl"
    convert_module.convert(source, jsonl)
    assert json.loads(jsonl.read_text().splitlines()[0])["header"]["device_identity"] == known
    back = tmp_path / "back.wtape"
    convert_module.convert(jsonl, back)
    assert _core.SessionReader(back).header.device_identity == identity


def test_convert_keeps_events_and_header_through_jsonl(tmp_path):
    jsonl = tmp_path / "g.jsonl"
    convert_module.convert(GOLDEN / "all_kinds.wtape", jsonl)
    out = tmp_path / "g.wtape"
    convert_module.convert(jsonl, out)
    assert out.read_bytes() == (GOLDEN / "all_kinds.wtape").read_bytes()


def test_convert_explicit_formats_and_bad_names(tmp_path):
    odd = tmp_path / "session.bin"
    convert_module.convert(GOLDEN / "wire.wtape", odd, to_format="wiretape")
    assert convert_module.detect_format(odd, reading=True) == "wiretape"
    convert_module.convert(odd, tmp_path / "x.txt", to_format="jsonl")
    assert (tmp_path / "x.txt").read_text().startswith('{"header":')
    with pytest.raises(ValueError, match="cannot tell the format"):
        convert_module.convert(GOLDEN / "wire.wtape", tmp_path / "x.unknown")
    with pytest.raises(ValueError, match="unknown format 'csv'"):
        convert_module.convert(GOLDEN / "wire.wtape", tmp_path / "x", to_format="csv")
    with pytest.raises(ValueError, match="cannot be read"):
        convert_module.convert(tmp_path / "x.mcap", tmp_path / "y.wtape")


def test_convert_damaged_source_writes_the_good_part_then_raises(tmp_path):
    out = tmp_path / "d.wtape"
    with pytest.raises(_core.SessionError) as info:
        convert_module.convert(GOLDEN / "damaged.wtape", out)
    assert info.value.offset == 296
    assert len(records_of(out)) == 2


def test_convert_bad_jsonl_names_the_line(tmp_path):
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"header": {}}\n{"t_ns": 1, "kind": "rx", "data_hex": "zz"}\n')
    with pytest.raises(ValueError, match=r"bad.jsonl:2"):
        convert_module.convert(bad, tmp_path / "out.wtape")


def test_convert_to_pcapng_and_mcap_calls_the_exporters(tmp_path):
    pcap = tmp_path / "s.pcapng"
    result = convert_module.convert(GOLDEN / "wire.wtape", pcap)
    assert result == ConvertResult(records=8, from_format="wiretape", to_format="pcapng")
    assert pcap.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"  # pcapng section header block
    mcap = tmp_path / "s.mcap"
    convert_module.convert(GOLDEN / "wire.jsonl", mcap, from_format="jsonl")
    assert mcap.read_bytes()[:5] == b"\x89MCAP"


@pytest.mark.parametrize("layout", ["new", "old"])
def test_flexiport_export_in_either_layout_reads_back_the_same(tmp_path, layout):
    source = flexiport_log("urg04lx_2011")
    out = tmp_path / "out.log"
    done = subprocess.run([sys.executable, "-m", "wiretape.cli", "convert", str(source), str(out),
                           "--flexiport-format", layout, "-q"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    reader = _core.SessionReader(out)
    assert reader.header.source_details == {"read_format": layout, "write_format": layout}
    assert records_of(out) == records_of(source)
    chunk_header = 24 if layout == "old" else 12
    rx = [r for r in records_of(source) if r[1] == "rx"]
    assert (tmp_path / "out.logr").stat().st_size == sum(chunk_header + len(r[2]) for r in rx)
    with pytest.raises(ValueError, match="expected new .* or old"):
        _core.export_flexiport(source, tmp_path / "x.log", "ancient")


def test_stats_reports_format_1_1_provenance():
    result = session_stats(GOLDEN / "v1_1_additions.wtape")
    assert (result.source_format, result.source_files) == ("pcap", ["plc.pcapng"])
    assert result.device_address == "192.0.2.7:502"
    assert result.edits == ["cut 0.5:2 s", "redacted 1 match in 1 record"]
    rows = dict(result.text_rows())
    assert rows["source_files"] == "plc.pcapng" and rows["device_address"] == "192.0.2.7:502"
    # --json: the header as the file holds it, and the file's format version.
    document = result.to_json()
    assert document["source"] == {"format": "pcap", "files": ["plc.pcapng"],
                                  "stream": "tcp.stream eq 0"}
    assert "source_format" not in document and "source_files" not in document
    assert (document["version_major"], document["version_minor"]) == (1, 3)
    assert result.rx_records == 1  # the record of channel 1 is not this port's
