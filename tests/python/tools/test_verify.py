"""wiretape.tools.verify: every record read by the session reader
(``_core.check_session_records``), the records of channels the header does
not list named by the reader that skips them; no walk of the layout."""

import os
import struct
import threading
from pathlib import Path

from wiretape import _core
from wiretape.tools.verify import verify

from channel_sessions import gnss_records, write_channel_session

CHANNELS = [("gps", "serial"), ("rtk", "tcp")]


def test_a_stray_of_a_kind_the_reader_does_not_know_is_still_named(tmp_path):
    """The reader passes over a kind it does not know and over an unlisted
    channel: a record of both is a stray all the same."""
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records())
    raw = bytearray(Path(session.path).read_bytes())
    record = struct.pack("<IBBHQ", 1, 250, 0, 9, 5) + b"x"
    offset = len(raw)
    raw += record + struct.pack("<I", _core.crc32c(record))
    Path(session.path).write_bytes(bytes(raw))
    result = verify(session.path)
    assert not result.ok
    assert (result.offset, result.unlisted_channel) == (offset, 9)
    assert result.records == len(session.records) + 1
    assert result.channel_records["#9"] == 1


def test_a_stray_followed_by_damage_says_both(tmp_path):
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records(),
                                    stray=[(4, "rx", 999_000_000, b"who?"),
                                           (0, "rx", 999_500_000, b"last")])
    size = os.path.getsize(session.path)
    os.truncate(session.path, size - 3)  # the last record's CRC cut short
    result = verify(session.path)
    assert not result.ok and result.unlisted_channel == 4
    assert "names channel 4, which the header does not list (its channels: gps, rtk)" \
        in result.message
    assert "; and damaged at byte " in result.message


def test_a_fifo_is_verified_as_it_streams_strays_included(tmp_path):
    """Read once, as a stream: the reader reports the strays it skips (the
    struct walk read the file a second time, which a FIFO cannot give)."""
    session = write_channel_session(tmp_path / "s.wtape", CHANNELS, gnss_records(),
                                    stray=[(6, "tx", 999_000_000, b"x")])
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    data = Path(session.path).read_bytes()

    def feed():
        with open(fifo, "wb") as out:
            out.write(data)

    writer = threading.Thread(target=feed)
    writer.start()
    result = verify(str(fifo))
    writer.join(timeout=60)
    assert not result.ok and result.unlisted_channel == 6
    assert result.records == len(session.records)


def test_a_good_session_of_one_port_has_no_channel_counts(tmp_path):
    session = write_channel_session(tmp_path / "s.wtape", [("only", "serial")],
                                    [("only", "tx", 1, b"a"), ("only", "rx", 2, b"b")])
    result = verify(session.path)
    assert result.ok and result.records == 2 and result.channel_records == {}
