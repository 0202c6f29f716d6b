"""wiretape diff aligns exchanges as diff -u aligns lines (issue 38): two
runs that differ by a handshake at the start differ by those exchanges,
not by every exchange after them; --json gives the same alignment; the
alignment's cost is bounded on sessions that differ everywhere."""

import json
import random
from pathlib import Path

import pytest

import wiretape
from wiretape import cli
from wiretape.tools.diff import diff
from wiretape.tools.diff_exchanges import MAX_EDITS, align, common_runs

REQUEST = b"GD0044072501\n"
HANDSHAKE = [b"VV\n", b"PP\n", b"II\n"]


def write(path: Path, scans: int, handshake=(), changed=()) -> str:
    """A Hokuyo-like session: the handshake's exchanges, then `scans` GD
    requests, each answered by a reply numbered by the scan (scan n's reply
    one more in `changed`)."""
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options="type=serial,device=/dev/ttyX") as writer:
        t = 0
        for word in handshake:
            writer.write("tx", t, word)
            writer.write("rx", t + 500_000, word + b"00P\n\n")
            t += 1_000_000
        for n in range(scans):
            writer.write("tx", t, REQUEST)
            number = n + 1 if n in changed else n
            writer.write("rx", t + 500_000, REQUEST + b"00P\n%03d\n\n" % number)
            t += 1_000_000
    return str(path)


@pytest.fixture()
def handshake_pair(tmp_path):
    return (write(tmp_path / "a.wtape", 22, handshake=HANDSHAKE),
            write(tmp_path / "b.wtape", 22))


def test_a_handshake_at_the_start_is_those_exchanges_only(handshake_pair):
    result = diff(*handshake_pair)
    summary = result.alignments[0].summary()
    assert summary == "3 exchanges only in A at the start (A 0-2); the rest is identical"
    assert f"by exchange: {summary}" in result.report()
    # the handshake's requests and responses, and nothing of the 22 scans after it
    assert result.divergence_count == 6
    assert {(d.exchange_a, d.exchange_b) for d in result.divergences} == {
        (0, None), (1, None), (2, None)}


def test_the_other_way_round_they_are_only_in_b(handshake_pair):
    result = diff(handshake_pair[1], handshake_pair[0])
    assert result.alignments[0].summary() == (
        "3 exchanges only in B at the start (B 0-2); the rest is identical")


def test_an_exchange_that_differs_after_the_handshake_is_paired_with_its_own(tmp_path):
    a = write(tmp_path / "a.wtape", 22, handshake=HANDSHAKE)
    b = write(tmp_path / "b.wtape", 22, changed=[7])
    result = diff(a, b)
    assert result.alignments[0].summary() == (
        "3 exchanges only in A at the start (A 0-2); 1 exchange differs (A 10, B 7); "
        "the rest is identical")
    changed = [d for d in result.divergences if d.exchange_a is not None
               and d.exchange_b is not None]
    assert [(d.exchange_a, d.exchange_b, d.direction, d.offset) for d in changed] == [
        (10, 7, "rx", 19)]
    assert "exchange 10 of A, 7 of B response (rx) differs at byte 19" in result.report()


def test_with_a_profile_the_alignment_is_by_frames(tmp_path):
    a = write(tmp_path / "a.wtape", 22, handshake=HANDSHAKE)
    b = write(tmp_path / "b.wtape", 22, changed=[7])
    result = diff(a, b, profile="scip")
    assert result.alignments[0].summary() == (
        "3 exchanges only in A at the start (A 0-2); 1 exchange differs (A 10, B 7); "
        "the rest is identical")


def test_json_gives_the_same_alignment(handshake_pair, capsys):
    assert cli.main(["diff", *handshake_pair, "--json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["identical"] is False
    (alignment,) = data["alignments"]
    assert alignment["summary"] == diff(*handshake_pair).alignments[0].summary()
    assert alignment["blocks"] == [
        {"kind": "only_a", "a_start": 0, "b_start": 0, "count": 3},
        {"kind": "same", "a_start": 3, "b_start": 0, "count": 22}]
    assert data["divergence_count"] == 6
    assert data["divergences"][0]["exchange_a"] == 0
    assert data["divergences"][0]["exchange_b"] is None
    assert data["divergences"][0]["bytes_a"] == b"VV\n".hex()


def test_identical_sessions_say_so_in_json_too(tmp_path, capsys):
    a = write(tmp_path / "a.wtape", 5)
    assert cli.main(["diff", a, a, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["identical"] is True and data["divergence_count"] == 0


def lcs_length(a, b) -> int:
    row = [0] * (len(b) + 1)
    for x in reversed(a):
        previous = row[:]
        for j in range(len(b) - 1, -1, -1):
            row[j] = previous[j + 1] + 1 if x == b[j] else max(previous[j], row[j + 1])
    return row[0]


def test_the_alignment_is_a_longest_common_subsequence_and_covers_both():
    rng = random.Random(38)
    for _ in range(500):
        a = [rng.randrange(4) for _ in range(rng.randrange(14))]
        b = [rng.randrange(4) for _ in range(rng.randrange(14))]
        runs = common_runs(a, b)
        assert all(a[i:i + n] == b[j:j + n] for i, j, n in runs)
        assert sum(n for _, _, n in runs) == lcs_length(a, b), (a, b)
        at_a = at_b = 0
        for block in align(a, b, a, b).blocks:
            assert (block.a_start, block.b_start) == (at_a, at_b), (a, b)
            at_a += block.count if block.kind != "only_b" else 0
            at_b += block.count if block.kind != "only_a" else 0
        assert (at_a, at_b) == (len(a), len(b))


def test_sessions_that_differ_everywhere_are_paired_by_position_past_the_bound():
    """Nothing in common: Myers' search stops at MAX_EDITS differences (its
    cost bounded), and the summary says the rest is paired by position."""
    a = list(range(3 * MAX_EDITS))
    b = [n + 10 * MAX_EDITS for n in a]
    alignment = align(a, b, a, a)
    assert alignment.by_position_from == (0, 0)
    assert [(block.kind, block.count) for block in alignment.blocks] == [
        ("changed", 3 * MAX_EDITS)]
    assert "paired by position" in alignment.summary()


def test_many_runs_of_differences_are_counted_not_listed():
    a = list(range(100))
    b = [n + 1000 if n % 10 == 5 else n for n in a]
    summary = align(a, b, a, a).summary()
    assert summary.count("differs") == 5
    assert "5 more runs of differences (5 exchanges)" in summary


def test_the_lines_docs_cli_md_shows_are_what_diff_says(tmp_path):
    """docs/cli.md's example of the alignment's line, held to the sessions
    it describes (a handshake only in A; then also scan 7 answered otherwise)."""
    from doc_examples import REPO, blocks_of

    (block,) = [b for b in blocks_of(REPO / "docs" / "cli.md")
                if b.first_line.startswith("by exchange: ")]
    a = write(tmp_path / "a.wtape", 22, handshake=HANDSHAKE)
    said = [line for other in (write(tmp_path / "b.wtape", 22),
                               write(tmp_path / "c.wtape", 22, changed=[7]))
            for line in diff(a, other).report().splitlines() if line.startswith("by exchange: ")]
    assert said == block.text.strip().splitlines()
