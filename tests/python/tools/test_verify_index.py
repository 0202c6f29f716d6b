"""The per-channel index of a session of several channels (format 1.3) as
``wiretape verify`` reports it and ``verify --repair`` appends it: the
reader's walk (C++) says whether the file's index matches its records."""

import json
import os
import struct
from pathlib import Path

from wiretape import _core, cli
from wiretape.tools.verify import verify

from channel_sessions import gnss_records, write_channel_session

CHANNELS = [("gps", "serial"), ("rtk", "tcp")]
# The end of an index record (docs/session-format.md, "The index record"):
# its own offset, the mark, the CRC.
TRAILER = struct.Struct("<Q8sI")


def index_offset(path) -> int:
    tail = Path(path).read_bytes()[-TRAILER.size:]
    offset, mark, _ = TRAILER.unpack(tail)
    assert mark == b"WTINDEX1"
    return offset


def run(capsys, *argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_closed_session_of_several_channels_has_a_current_index(tmp_path):
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records())
    result = verify(session.path)
    assert result.ok and result.index == "current"
    assert result.index_detail == f"at byte {index_offset(session.path)}"
    assert result.records == len(session.records)  # the index is not a record


def test_a_session_of_one_channel_needs_none(tmp_path):
    session = write_channel_session(tmp_path / "s.wtape", [("only", "serial")],
                                    [("only", "tx", 1, b"a")])
    assert verify(session.path).index == "not needed"


def test_verify_names_a_missing_index_and_repair_appends_it(tmp_path, capsys):
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records())
    closed = Path(session.path).read_bytes()
    offset = index_offset(session.path)
    os.truncate(session.path, offset)  # as a recorder killed before its close leaves it
    code, out, _ = run(capsys, "verify", session.path)
    assert code == 0, out  # not damage: every record is intact
    assert "index absent" in out and "verify --repair" in out
    code, out, _ = run(capsys, "verify", "--repair", session.path)
    assert code == 0
    assert f"index appended at byte {offset}" in out
    assert Path(session.path).read_bytes() == closed
    code, out, _ = run(capsys, "verify", "--json", session.path)
    assert json.loads(out)["index"] == "current"
    # The channels read the same through it.
    for name in ("gps", "rtk"):
        channel = next(c.id for c in _core.SessionReader(session.path).header.channels
                       if c.name == name)
        got = [(r.kind, r.t_ns, r.data) for r in _core.SessionReader(session.path, channel)]
        assert got == session.of(name)


def test_repair_leaves_a_current_index_alone(tmp_path, capsys):
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records())
    before = Path(session.path).read_bytes()
    code, out, _ = run(capsys, "verify", "--repair", session.path)
    assert code == 0 and "appended" not in out
    assert Path(session.path).read_bytes() == before


def test_repair_refuses_a_damaged_session_and_leaves_it_as_it_was(tmp_path, capsys):
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records())
    offset = index_offset(session.path)
    raw = bytearray(Path(session.path).read_bytes()[:offset])
    raw[offset - 3] ^= 0x01  # the last record's CRC
    Path(session.path).write_bytes(bytes(raw))
    code, out, _ = run(capsys, "verify", "--repair", session.path)
    assert code == 1 and "DAMAGED" in out
    assert Path(session.path).read_bytes() == bytes(raw)
    assert verify(session.path).index == "unchecked"


def test_a_compressed_session_of_several_channels_has_the_index_of_its_chunks(tmp_path, capsys):
    """Format 2.0 (compress=zstd): the same index record, of whole chunks;
    verify checks it, and --repair appends it again as the writer wrote it."""
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records())
    packed = tmp_path / "packed.wtape"
    assert cli.main(["convert", "-q", "--compress", "zstd", session.path, str(packed)]) == 0
    result = verify(packed)
    assert result.ok and result.index == "current", result
    assert result.index_detail == f"at byte {index_offset(packed)}"
    closed = packed.read_bytes()
    os.truncate(packed, index_offset(packed))
    assert verify(packed).index == "absent"
    code, out, _ = run(capsys, "verify", "--repair", str(packed))
    assert code == 0 and "index appended at byte" in out, out
    assert packed.read_bytes() == closed
