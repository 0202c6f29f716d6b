"""wiretape.tools.edit_cut: the window of ``edit --cut``, its exchanges
numbered by the one segmentation (``_core.session_exchanges``) with the
profile the edit uses, so that ``--cut Ne --profile P`` cuts the exchange N
that a replay with P names in its mismatch reports."""

import subprocess
import sys

import pytest

from wiretape import _core
from wiretape.tools.edit import edit, parse_cut
from wiretape.tools.edit_cut import cut_window, exchange_starts

# A request frame ("Q2\r\n") written in two records with the device's
# byte between them: raw, that is two exchanges; framed by lines, one.
ITEMS = [(1, "tx", b"Q1\r\n"), (2, "rx", b"R1\r\n"), (3, "tx", b"Q"), (4, "rx", b"?"),
         (5, "tx", b"2\r\n"), (6, "rx", b"R2\r\n"), (7, "tx", b"Q3\r\n"), (8, "rx", b"R3\r\n")]


def write_session(path, items, metadata=None):
    with _core.SessionWriter(path, capture="wire", port_type="serial",
                             port_options="type=serial,device=/dev/ttyUSB0",
                             metadata=metadata or {},
                             start_utc="2026-11-24T00:00:00Z") as writer:
        for t_ns, kind, data in items:
            writer.write(kind, t_ns, data)
    return path


def tx_bytes(path):
    return b"".join(r.data for r in _core.SessionReader(path) if r.kind == "tx")


def test_exchanges_are_counted_as_a_replay_with_the_profile_counts_them(tmp_path):
    src = str(write_session(tmp_path / "in.wtape", ITEMS))
    lines = _core.profile_from_spec("lines")
    replayed = _core.session_exchanges(src, profile="lines")
    assert len(exchange_starts(src, profile=lines)) == len(replayed) == 3
    assert len(exchange_starts(src)) == len(_core.session_exchanges(src)) == 4


def test_cut_from_exchange_n_with_a_profile_keeps_the_exchange_replay_names_n(tmp_path):
    """Exchange 2 of a replay with profile=lines is Q3; counted raw (as
    edit did before), exchange 2 was the second half of Q2."""
    src = write_session(tmp_path / "in.wtape", ITEMS)
    out = tmp_path / "out.wtape"
    edit(src, out, cut=parse_cut("2e:"), profile="lines")
    assert tx_bytes(out) == b"Q3\r\n"


def test_an_exchange_past_the_profiles_count_is_refused(tmp_path):
    src = write_session(tmp_path / "in.wtape", ITEMS)
    with pytest.raises(ValueError, match=r"has 3 exchanges \(0 to 2\), no exchange 3"):
        edit(src, tmp_path / "out.wtape", cut=parse_cut("3e:"), profile="lines")


def test_the_sessions_profile_meta_numbers_them_too(tmp_path):
    """Without --profile, edit takes the profile the session names
    (profile=lines), for the cut as for the checksums."""
    src = write_session(tmp_path / "in.wtape", ITEMS, metadata={"profile": "lines"})
    out = tmp_path / "out.wtape"
    edit(src, out, cut=parse_cut("2e:"))
    assert tx_bytes(out) == b"Q3\r\n"
    edit(src, tmp_path / "raw.wtape", cut=parse_cut("2e:"), profile=None)
    assert tx_bytes(tmp_path / "raw.wtape") == b"2\r\nQ3\r\n"


def test_a_declared_profile_numbers_them_by_its_framing(tmp_path):
    src = str(write_session(tmp_path / "in.wtape", ITEMS))
    declared = _core.profile_from_spec("framing=delimiter:0a")
    assert exchange_starts(src, profile=declared) == exchange_starts(
        src, profile=_core.profile_from_spec("lines"))


def test_the_cli_cuts_by_the_profile_given(tmp_path):
    src = write_session(tmp_path / "in.wtape", ITEMS)
    out = tmp_path / "out.wtape"
    done = subprocess.run([sys.executable, "-m", "wiretape.cli", "edit", "--cut", "2e:",
                           "--profile", "lines", str(src), str(out)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert tx_bytes(out) == b"Q3\r\n"


def test_a_window_in_seconds_needs_no_segmentation(tmp_path):
    assert cut_window("/nonexistent", parse_cut("1.5:2")) == (1_500_000_000, 2_000_000_000)


def test_a_declared_profile_in_the_metadata_is_the_default_too(tmp_path):
    """The one rule of the profile metadata (wiretape.session.chosen_profile):
    a declared profile's keys count as a name does."""
    src = write_session(tmp_path / "in.wtape", ITEMS,
                        metadata={"profile": "framing=delimiter:0a"})
    out = tmp_path / "out.wtape"
    edit(src, out, cut=parse_cut("2e:"))
    assert tx_bytes(out) == b"Q3\r\n"
