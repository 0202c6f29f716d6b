"""_core.check_session_records: the reader's walk with what it skips, for
verify (src/python/bind_record_check.cpp)."""

import os

import pytest

from wiretape import _core

from channel_sessions import gnss_records, write_channel_session

CHANNELS = [("gps", "serial"), ("rtk", "tcp")]


def test_it_counts_per_channel_and_notes_the_first_stray(tmp_path):
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records(),
                                    stray=[(5, "rx", 9, b"a"), (7, "tx", 10, b"b")])
    check = _core.check_session_records(session.path)
    listed = len(session.records) - 2
    assert check.records == listed
    assert check.unlisted_records == 2
    assert check.first_unlisted_channel == 5
    assert check.channel_records[5] == check.channel_records[7] == 1
    assert check.channel_records[0] + check.channel_records[1] == listed
    assert check.damage is None
    assert [c.name for c in check.header.channels] == ["gps", "rtk"]
    # the first stray's offset: its record header names channel 5
    with open(session.path, "rb") as file:
        file.seek(check.first_unlisted_offset + 6)
        assert int.from_bytes(file.read(2), "little") == 5


def test_damage_is_reported_not_raised(tmp_path):
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records())
    # Into the last record, before the index (its trailer: own offset, mark, CRC).
    with open(session.path, "rb") as file:
        file.seek(-20, os.SEEK_END)
        index_offset = int.from_bytes(file.read(8), "little")
    os.truncate(session.path, index_offset - 1)
    check = _core.check_session_records(session.path)
    assert isinstance(check.damage, _core.SessionError)
    assert check.records == len(session.records) - 1
    assert check.first_unlisted_offset is None


def test_a_file_that_is_not_a_session_raises(tmp_path):
    path = tmp_path / "not.wtape"
    path.write_bytes(b"hello, world, not a session")
    with pytest.raises(_core.SessionError, match="not a wiretape session"):
        _core.check_session_records(str(path))
    with pytest.raises(_core.PortError):
        _core.check_session_records(str(tmp_path / "missing.wtape"))
