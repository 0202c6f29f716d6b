"""Damage sweep of the session files of format 1.3 (a per-channel index)
and 2.0 (zstd chunks, with and without the index of its chunks): each golden file truncated at every byte, and a bit
flipped in every byte, is read by the one reader (every channel, and one
channel: through the index where it holds) and by verify. What comes out
is always the records the intact file begins with, never another; a
damaged file says so (verify exits non-zero, or the open fails) unless
the flip fell where no reader looks (the header's padding, an index a
reader then scans past)."""

import pathlib

import pytest

from wiretape import _core
from wiretape.tools.verify import verify

GOLDEN = pathlib.Path(__file__).resolve().parents[3] / "tests" / "data" / "golden"
FILES = ["v1_2_channels", "v2_0", "v2_0_channels", "v2_0_index"]


def records(path, channel=None):
    """(records, damaged) as the reader gives them; None when the file does
    not open as a session."""
    try:
        reader = _core.SessionReader(path) if channel is None else _core.SessionReader(path, channel)
    except _core.SessionError:
        return None
    got = [(r.t_ns, r.kind, r.data, r.channel) for r in reader]
    return got, reader.damage is not None


def damaged_copies(data: bytes):
    for cut in range(len(data)):
        yield f"cut at {cut}", data[:cut]
    for at in range(len(data)):
        flipped = bytearray(data)
        flipped[at] ^= 1 << (at % 8)
        yield f"bit flipped at {at}", bytes(flipped)


@pytest.mark.parametrize("name", FILES)
def test_a_damaged_file_gives_a_prefix_of_its_records(tmp_path, name):
    original = (GOLDEN / f"{name}.wtape").read_bytes()
    intact, damaged = records(GOLDEN / f"{name}.wtape")
    assert not damaged
    channels = {record[3] for record in intact}
    intact_by_channel = {c: [r for r in intact if r[3] == c] for c in channels}
    path = tmp_path / "damaged.wtape"
    for what, data in damaged_copies(original):
        path.write_bytes(data)
        result = records(path)
        if result is None:
            continue  # refused at open: a damaged header
        got, _ = result
        assert got == intact[:len(got)], what
        if len(channels) > 1:
            for channel in channels:
                one = records(path, channel)
                assert one is not None, what
                expected = intact_by_channel[channel]
                assert one[0] == expected[:len(one[0])], f"{what}, channel {channel}"
        outcome = verify(path)
        if what.startswith("cut") and len(data) < len(original):
            assert not outcome.ok or outcome.records <= len(intact), what
