"""wiretape.tools.diff: first divergence per direction, and a summary."""

from __future__ import annotations

from pathlib import Path

import pytest
from real_recordings import flexiport_log

from wiretape import _core as core
from wiretape.tools.diff import diff


def write_session(path: Path, records) -> Path:
    with core.SessionWriter(str(path), port_type="serial") as writer:
        for kind, t_ns, data in records:
            writer.write(kind, t_ns, data)
    return path


SESSION = [
    ("rx", 0, b"HELLO\n"),
    ("tx", 10, b"PING\n"),
    ("rx", 20, b"PONG\n"),
    ("tx", 30, b"TIME\n"),
    ("rx", 40, b"12:00\n"),
]


def test_identical_sessions_split_differently_compare_equal(tmp_path):
    a = write_session(tmp_path / "a.wtape", SESSION)
    resplit = [("rx", 0, b"HEL"), ("rx", 1, b"LO\n"), ("open", 2, b"")]
    resplit += [(k, t, d) for k, t, d in SESSION[1:]]
    b = write_session(tmp_path / "b.wtape", resplit)
    result = diff(a, b)
    assert result.identical
    assert not result
    report = result.report()
    assert "rx: identical (A 17 bytes in 3 records, B 17 bytes in 4 records)" in report
    assert "tx: identical" in report
    assert "sessions are identical" in report


def test_first_divergence_shows_offset_times_and_hex_context(tmp_path):
    a = write_session(tmp_path / "a.wtape", SESSION)
    changed = list(SESSION)
    changed[4] = ("rx", 41_000_000_000, b"12:01\n")
    b = write_session(tmp_path / "b.wtape", changed)
    result = diff(a, b)
    assert not result.identical
    assert result["tx"].identical
    rx = result["rx"]
    assert rx.offset == 11 + 4
    assert rx.time_a_ns == 40 and rx.time_b_ns == 41_000_000_000
    assert rx.at_a == b"0\n" and rx.at_b == b"1\n"
    report = result.report()
    assert "rx: first difference at byte 15" in report
    assert "41.000000 s" in report
    assert "|HELLO.PONG.12:0|" in report
    assert "30 0a  |0.|" in report and "31 0a  |1.|" in report
    assert "sessions differ" in report


def test_a_shorter_session_is_reported_as_ending(tmp_path):
    a = write_session(tmp_path / "a.wtape", SESSION)
    b = write_session(tmp_path / "b.wtape", SESSION[:3])
    result = diff(a, b)
    assert not result["tx"].identical
    assert result["tx"].offset == 5
    assert result["tx"].at_b == b""
    assert "tx: B ends at byte 5" in result.report()


def test_record_lists_are_accepted(tmp_path):
    records = [core.Record(t, kind, data) for kind, t, data in SESSION]
    a = write_session(tmp_path / "a.wtape", SESSION)
    assert diff(a, records).identical
    assert not diff(records, records[:-1]).identical


def test_flexiport_log_and_its_conversion_are_identical(tmp_path):
    log = flexiport_log("urg04lx_2011")
    with core.SessionReader(str(log)) as reader:
        records = [(r.kind, r.t_ns, r.data) for r in reader]
    converted = write_session(tmp_path / "urg.wtape", records)
    assert diff(str(log), converted).identical
    other = flexiport_log("utm30lx_2011")
    result = diff(str(log), str(other))
    assert not result.identical
    assert result["tx"].identical is False or result["rx"].identical is False


def test_unreadable_file_raises_session_error(tmp_path):
    bad = tmp_path / "bad.wtape"
    bad.write_bytes(b"not a session")
    good = write_session(tmp_path / "a.wtape", SESSION)
    with pytest.raises(core.SessionError):
        diff(bad, good)
