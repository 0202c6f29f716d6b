"""The tools on sessions of several ports (issue 25, DESIGN §19): show,
stats, diff, edit and verify name channels; every expectation is computed
from the records the test wrote (support/channel_sessions.py)."""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import pytest

import wiretape
from wiretape import _core, cli
from wiretape.tools.diff import diff
from wiretape.tools.edit import edit, parse_cut, parse_redaction
from wiretape.tools.show import Selection, show
from wiretape.tools.stats import stats
from wiretape.tools.textconv import textconv
from wiretape.tools.verify import verify

from channel_sessions import gnss_records, write_channel_session

CHANNELS = [("gps", "serial"), ("rtk", "tcp")]


@pytest.fixture()
def gnss(tmp_path: Path):
    return write_channel_session(tmp_path / "gnss.wtape", CHANNELS, gnss_records())


def _record_lines(text: str):
    """The timeline's record lines (they start with the time)."""
    return [line for line in text.splitlines() if line[:1] in "+-" and line[1:2].isdigit()]


# ---------------------------------------------------------------- show


def test_show_names_each_records_channel_and_lists_channels_in_the_header(gnss):
    out = io.StringIO()
    shown = show(gnss.path, out=out)
    assert shown == len(gnss.records)
    text = out.getvalue()
    assert "  channel      0 gps: serial: type=serial,name=gps (capture wire)" in text
    assert "  channel      1 rtk: tcp: type=tcp,name=rtk (capture wire)" in text
    lines = _record_lines(text)
    assert len(lines) == len(gnss.records)
    for line, (channel, kind, _, _) in zip(lines, gnss.records):
        columns = line.split()
        # time, Δt (blank on the first line), channel, kind
        assert gnss.names[channel] in columns[1:3], line
        assert kind in columns[2:4], line


def test_show_channel_filters_records_of_that_channel(gnss):
    out = io.StringIO()
    shown = show(gnss.path, out=out, select=Selection(channels=frozenset({"rtk"})))
    expected = gnss.of("rtk")
    assert shown == len(expected)
    lines = _record_lines(out.getvalue())
    assert [line.split()[0] for line in lines] == [f"{t / 1e9:+.6f}s" for _, t, _ in expected]
    assert all(" rtk " in line and " gps " not in line for line in lines)
    assert f"{len(expected)} of {len(gnss.records)} records shown" in out.getvalue()


def test_show_jsonl_has_the_channel_name(gnss):
    out = io.StringIO()
    show(gnss.path, fmt="jsonl", out=out)
    objects = [json.loads(line) for line in out.getvalue().splitlines()]
    assert [(o["channel"], o["kind"], o["t_ns"]) for o in objects] == \
        [(gnss.names[c], k, t) for c, k, t, _ in gnss.records]


def test_show_unknown_channel_is_a_usage_error_naming_the_channels(gnss, capsys):
    assert cli.main(["show", gnss.path, "--channel", "gsp"]) == 2
    err = capsys.readouterr().err
    assert "--channel" in err and "'gsp'" in err and "did you mean gps?" in err
    assert "gps, rtk" in err


def test_show_profile_frames_each_channel_apart(tmp_path):
    # gps's line is split over records, and rtk's record comes in between:
    # framed together the line would be broken by rtk's bytes.
    session = write_channel_session(tmp_path / "lines.wtape", CHANNELS, [
        ("gps", "tx", 1_000, b"POLL\n"),
        ("gps", "rx", 2_000, b"$GPGGA,1"),
        ("rtk", "rx", 3_000, b"RTCM\n"),
        ("gps", "rx", 4_000, b",FIX\n"),
    ])
    out = io.StringIO()
    show(session.path, profile="lines", out=out)
    lines = _record_lines(out.getvalue())
    gps_rx = [line for line in lines if " gps " in line and " rx " in line]
    assert len(gps_rx) == 1 and "$GPGGA,1,FIX" in gps_rx[0]
    assert gps_rx[0].split()[0] == f"{2_000 / 1e9:+.6f}s"
    assert any(" rtk " in line and "RTCM" in line for line in lines)


def test_textconv_keeps_the_channel_of_each_record(gnss):
    out = io.StringIO()
    textconv(gnss.path, times=False, out=out)
    body = out.getvalue().split("\n\n", 1)[1]
    record_lines = [line for line in body.splitlines() if line.split()[:1] in (["gps"], ["rtk"])]
    assert [line.split()[0] for line in record_lines] == [gnss.names[c] for c, *_ in gnss.records]


# ---------------------------------------------------------------- stats


def test_stats_per_channel_figures_and_latency_measured_within_each_channel(gnss):
    result = stats(gnss.path)
    assert result.records == len(gnss.records)
    by_name = {channel.name: channel for channel in result.channel_stats}
    assert set(by_name) == {"gps", "rtk"}
    for name, figures in by_name.items():
        records = gnss.of(name)
        assert figures.records == len(records)
        for kind in ("rx", "tx"):
            assert getattr(figures, f"{kind}_records") == sum(1 for k, _, _ in records if k == kind)
            assert getattr(figures, f"{kind}_bytes") == sum(len(d) for k, _, d in records if k == kind)
        assert figures.event_records == sum(1 for k, _, _ in records if k not in ("rx", "tx"))
    # gps answers 4 ms after each poll, rtk 20 ms after each request; with
    # the channels mixed, gps's answer would be timed from rtk's request.
    assert by_name["gps"].latency[0].requests == 3
    assert by_name["gps"].latency[0].max_s == pytest.approx(0.004)
    assert by_name["gps"].latency[0].p50_s == pytest.approx(0.004)
    assert by_name["rtk"].latency[0].requests == 2
    assert by_name["rtk"].latency[0].p50_s == pytest.approx(0.020)
    total = result.latency[0]
    assert total.requests == 5 and total.max_s == pytest.approx(0.020)


def test_stats_command_prints_a_section_per_channel(gnss, capsys):
    assert cli.main(["stats", gnss.path]) == 0
    out = capsys.readouterr().out
    for name in ("gps", "rtk"):
        records = gnss.of(name)
        rx = [d for k, _, d in records if k == "rx"]
        tx = [d for k, _, d in records if k == "tx"]
        events = len(records) - len(rx) - len(tx)
        row = next(line for line in out.splitlines() if line.startswith(f"channel {name} "))
        assert row.split(None, 2)[2] == (
            f"{len(records)} records: rx {len(rx)} ({sum(map(len, rx))} B), "
            f"tx {len(tx)} ({sum(map(len, tx))} B), events {events}")
    document = json.loads(cli_json(["stats", gnss.path, "--json"], capsys))
    assert [channel["name"] for channel in document["channel_stats"]] == ["gps", "rtk"]


def cli_json(argv, capsys) -> str:
    cli.main(argv)
    return capsys.readouterr().out


# ---------------------------------------------------------------- diff


def test_diff_of_a_session_with_itself_is_identical_channel_by_channel(gnss, tmp_path):
    copy = write_channel_session(tmp_path / "copy.wtape", CHANNELS, gnss_records())
    result = diff(gnss.path, copy.path)
    assert result.identical
    assert {(d.channel, d.direction) for d in result.directions} == \
        {(name, direction) for name in ("gps", "rtk") for direction in ("tx", "rx")}


def test_diff_names_the_channel_that_differs(gnss, tmp_path):
    changed = [(name, kind, t, data.replace(b"RTCM1", b"RTCMX") if name == "rtk" else data)
               for name, kind, t, data in gnss_records()]
    other = write_channel_session(tmp_path / "other.wtape", CHANNELS, changed)
    result = diff(gnss.path, other.path)
    assert not result.identical
    assert result["gps", "rx"].identical and result["gps", "tx"].identical
    rtk_rx = result["rtk", "rx"]
    assert not rtk_rx.identical
    first = [d for k, _, d in gnss.of("rtk") if k == "rx"]
    assert rtk_rx.offset == len(first[0]) + 4  # "RTCM" of the second answer
    assert [(d.channel, d.exchange, d.direction) for d in result.divergences] == [("rtk", 1, "rx")]
    report = result.report()
    assert "channel rtk rx: first difference at byte" in report
    assert "channel rtk exchange 1 response (rx) differs" in report


def test_diff_a_channel_only_in_one_session_is_a_difference(gnss, tmp_path):
    three = write_channel_session(tmp_path / "three.wtape", CHANNELS + [("imu", "serial")],
                                  gnss_records() + [("imu", "rx", 900_000_000, b"IMU")])
    result = diff(gnss.path, three.path)
    assert not result.identical
    assert result.only_in == {"imu": "B"}
    assert result["gps", "rx"].identical and result["rtk", "rx"].identical
    assert "channel imu: only in B" in result.report()


# ---------------------------------------------------------------- edit


def _read(path):
    reader = wiretape.SessionReader(str(path))
    return reader.header, [(r.channel, r.kind, r.t_ns, r.data) for r in reader]


def test_edit_redact_limited_to_a_channel_keeps_the_others_and_the_channels_header(gnss, tmp_path):
    out = tmp_path / "out.wtape"
    result = edit(gnss.path, out, redact=[parse_redaction("[0-9]")], channels=["gps"])
    header, records = _read(out)
    assert [(c.id, c.name, c.port_type, c.port_options) for c in header.channels] == \
        [(0, "gps", "serial", "type=serial,name=gps"), (1, "rtk", "tcp", "type=tcp,name=rtk")]
    kept = [(c, k, t, d) for c, k, t, d in records if k != "redaction"]
    assert len(kept) == len(gnss.records)
    for (channel, kind, t, data), (c0, k0, t0, d0) in zip(kept, gnss.records):
        assert (channel, kind, t) == (c0, k0, t0)
        if gnss.names[channel] == "gps" and kind in ("rx", "tx"):
            assert data == bytes(b"*"[0] if 0x30 <= b <= 0x39 else b for b in d0)
        else:
            assert data == d0  # rtk's digits stay
    marks = [(c, t) for c, k, t, _ in records if k == "redaction"]
    assert marks and all(gnss.names[c] == "gps" for c, _ in marks)
    digits = sum(sum(1 for b in d if 0x30 <= b <= 0x39) for c, k, _, d in gnss.records
                 if gnss.names[c] == "gps" and k in ("rx", "tx"))
    assert result.matches == digits
    assert "redacted 1 pattern of channel gps" in header.edits[-1]


def test_edit_cut_cuts_every_channel_on_the_one_clock(gnss, tmp_path):
    out = tmp_path / "cut.wtape"
    start_s, end_s = 0.05, 0.1  # the second round of every channel
    edit(gnss.path, out, cut=parse_cut(f"{start_s}:{end_s}"))
    _, records = _read(out)
    start, end = int(start_s * 1e9), int(end_s * 1e9)
    first_write = min(t for _, k, t, d in gnss.records if k == "tx" and d)
    shift = start - first_write
    greeting = [(c, k, t, d) for c, k, t, d in gnss.records if t < first_write]
    window = [(c, k, t - shift, d) for c, k, t, d in gnss.records if start <= t < end]
    assert records == greeting + window
    # both channels kept their order against each other, moved by one shift
    assert {gnss.names[c] for c, *_ in window} == {"gps", "rtk"}


def test_edit_cut_limited_to_a_channel_keeps_the_others_in_place(gnss, tmp_path):
    out = tmp_path / "cut.wtape"
    edit(gnss.path, out, cut=parse_cut("0.05:0.1"), channels=["gps"])
    _, records = _read(out)
    rtk = [(c, k, t, d) for c, k, t, d in records if gnss.names[c] == "rtk"]
    assert rtk == [(c, k, t, d) for c, k, t, d in gnss.records if gnss.names[c] == "rtk"]
    gps_times = [t for c, k, t, d in records if gnss.names[c] == "gps" and k != "open"]
    assert gps_times and all(50_000_000 <= t < 100_000_000 for t in gps_times)


def test_edit_unknown_channel_is_refused_naming_it(gnss, tmp_path):
    with pytest.raises(ValueError, match=r"no channel 'gsp' \(did you mean gps\?\)"):
        edit(gnss.path, tmp_path / "x.wtape", redact=[parse_redaction("x")], channels=["gsp"])
    assert not (tmp_path / "x.wtape").exists()


def test_edit_cut_in_exchanges_needs_one_channel(gnss, tmp_path):
    with pytest.raises(ValueError, match="numbered per channel"):
        edit(gnss.path, tmp_path / "x.wtape", cut=parse_cut("1e:2e"))


# ---------------------------------------------------------------- verify


def test_verify_counts_records_per_channel(gnss):
    result = verify(gnss.path)
    assert result.ok
    assert result.channel_records == {"gps": len(gnss.of("gps")), "rtk": len(gnss.of("rtk"))}


def test_verify_reports_a_record_of_a_channel_the_header_does_not_list(tmp_path):
    session = write_channel_session(tmp_path / "stray.wtape", CHANNELS, gnss_records(),
                                    stray=[(7, "rx", 999_000_000, b"who?"),
                                           (0, "rx", 999_500_000, b"ok")])
    result = verify(session.path)
    assert not result.ok
    assert result.unlisted_channel == 7
    # the oracle's offset: the header, then every record before it
    raw = Path(session.path).read_bytes()
    (json_length,) = struct.unpack_from("<I", raw, 12)
    offset = _core.FILE_HEADER_OVERHEAD + json_length + sum(
        _core.RECORD_OVERHEAD + len(d) for *_, d in session.records[:-2])
    assert struct.unpack_from("<H", raw, offset + 6)[0] == 7
    assert result.offset == offset
    assert f"record at byte {offset} names channel 7" in result.message
    assert result.channel_records == {"gps": len(session.of("gps")),
                                      "rtk": len(session.of("rtk")), "#7": 1}


def test_verify_command_exits_1_naming_the_stray_record(tmp_path, capsys):
    session = write_channel_session(tmp_path / "stray.wtape", CHANNELS, gnss_records(),
                                    stray=[(3, "tx", 999_000_000, b"x")])
    assert cli.main(["verify", session.path]) == 1
    out = capsys.readouterr().out
    assert "names channel 3, which the header does not list (its channels: gps, rtk)" in out


# ---------------------------------------------------------------- combinations


def _nmea(body: bytes) -> bytes:
    checksum = 0
    for byte in body:
        checksum ^= byte
    return b"$" + body + b"*%02X\r\n" % checksum


def test_redact_with_a_profile_reseals_split_frames_of_one_channel_only(tmp_path):
    # gps's sentences are split over records, with rtk's NMEA-looking bytes
    # in between: framed together, rtk's bytes would break gps's frames.
    sentences = [_nmea(b"GPGGA,123519,4807.038,N,01131.%03d,E" % n) for n in range(3)]
    rtk_text = _nmea(b"GPTXT,01,01,02,SERIAL 4711")
    records = [("gps", "tx", 0, b"POLL\r\n"), ("rtk", "tx", 100, b"GET\r\n")]
    t = 1_000
    for sentence in sentences:
        records += [("gps", "rx", t, sentence[:20]), ("rtk", "rx", t + 1, rtk_text[:10]),
                    ("gps", "rx", t + 2, sentence[20:]), ("rtk", "rx", t + 3, rtk_text[10:])]
        t += 1_000
    session = write_channel_session(tmp_path / "nmea.wtape", CHANNELS, records)
    out = tmp_path / "scrubbed.wtape"
    result = edit(session.path, out, redact=[parse_redaction(r"4807\.038=X")], profile="nmea",
                  channels=["gps"])
    assert result.matches == 3 and result.resealed_frames == 3
    _, written = _read(out)
    by_channel = {}
    for channel, kind, _, data in written:
        if kind == "rx":
            by_channel.setdefault(session.names[channel], b"")
            by_channel[session.names[channel]] += data
    expected_gps = b"".join(_nmea(s[1:s.index(b"*")].replace(b"4807.038", b"XXXXXXXX"))
                            for s in sentences)
    assert by_channel["gps"] == expected_gps
    assert by_channel["rtk"] == rtk_text * 3  # not scrubbed, not resealed
    # the records kept their sizes and places
    assert [(c, k, t, len(d)) for c, k, t, d in written if k != "redaction"] == \
        [(c, k, t, len(d)) for c, k, t, d in session.records]


# ---------------------------------------------------------------- view


def test_view_has_a_lane_group_per_named_channel(gnss):
    from wiretape.tools.view import page_data

    data = page_data(gnss.path)
    assert data["channels"] == [{"id": 0, "name": "gps"}, {"id": 1, "name": "rtk"}]
    assert data["records"]["channel"] == [channel for channel, *_ in gnss.records]


def test_edit_command_names_the_flag_of_an_unknown_channel(gnss, tmp_path, capsys):
    out = tmp_path / "x.wtape"
    assert cli.main(["edit", gnss.path, str(out), "--redact", "x", "--channel", "gsp"]) == 2
    assert "--channel: " in capsys.readouterr().err
    assert not out.exists()
