"""The cases of a campaign (wiretape.faults.cases): every kind at every
exchange as the replay numbers them, sampled by seed, placed kinds spelled as
the replay reads them; and the places a session has, measured and checked by
the one segmentation in C++ (``_core.session_shape``,
``FaultPlan.check_against``) as the replay's fault stage counts them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import wiretape
from wiretape import _core, faults


def make_session(path: Path) -> Path:
    """Three line exchanges: Qn\\n answered by Rn...\\n."""
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(3):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}-abcdef\n".encode())
    return path


@pytest.fixture()
def session(tmp_path: Path) -> Path:
    return make_session(tmp_path / "lines.wtape")



def test_cases_cover_every_kind_at_every_exchange(session):
    shape = faults.session_shape(str(session))
    assert shape.exchanges == 3
    everything = faults.cases(str(session))
    assert len(everything) == len(faults.KINDS) * 3
    assert everything[0].id == "drop@exchange:0"
    assert everything[0].options == "faults=drop@exchange:0,seed=0"
    assert {case.kind for case in everything} == set(faults.KINDS)


def test_cases_count_exchanges_as_the_replay_with_profile_and_match(tmp_path):
    # Two request lines in one write, each answered: two exchanges with the
    # lines profile, one without; under match=request a greeting is
    # exchange 0 of its own.
    path = tmp_path / "lines.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        writer.write("rx", 1, b"hello\n")
        writer.write("tx", 2, b"Q1\nQ2\n")
        writer.write("rx", 3, b"R1\n")
        writer.write("tx", 4, b"Q3\n")
        writer.write("rx", 5, b"R3\n")
    assert faults.session_shape(str(path)).exchanges == 2
    assert faults.session_shape(str(path), profile="lines").exchanges == 3
    assert faults.session_shape(str(path), match="request").exchanges == 3
    wheres = {case.where for case in faults.cases(str(path), kinds=["drop"], profile="lines")}
    assert wheres == {"exchange:0", "exchange:1", "exchange:2"}


def test_a_monitors_connect_does_not_cut_the_first_client_session(tmp_path):
    path = tmp_path / "proxy.wtape"
    event = lambda **fields: json.dumps(fields).encode()
    with wiretape.SessionWriter(str(path), port_type="tcp") as writer:
        writer.write("client_connect", 1, event(peer="a", role="control"))
        writer.write("tx", 2, b"Q0\n")
        writer.write("rx", 3, b"R0\n")
        writer.write("client_connect", 4, event(peer="m", role="monitor"))
        writer.write("tx", 5, b"Q1\n")
        writer.write("rx", 6, b"R1\n")
        writer.write("client_disconnect", 7, event(peer="a", reason="closed"))
        writer.write("rx", 8, b"said to nobody\n")
    shape = faults.session_shape(str(path))
    assert shape.exchanges == 2
    assert shape.rx_bytes == 6


def test_a_budget_samples_by_seed_the_same_way_each_time(session):
    first = faults.cases(str(session), budget=7, seed=3)
    assert len(first) == 7
    assert first == faults.cases(str(session), budget=7, seed=3)
    assert first != faults.cases(str(session), budget=7, seed=4)
    everything = faults.cases(str(session), seed=3)
    assert [everything.index(case) for case in first] == sorted(
        everything.index(case) for case in first)


def test_cases_refuse_unknown_kinds_and_places_past_the_end(session):
    with pytest.raises(faults.FaultInputError, match="unknown fault kind 'explode'"):
        faults.cases(str(session), kinds=["explode"])
    with pytest.raises(faults.FaultInputError, match="past its end"):
        faults.cases(str(session), kinds=["drop@exchange:3"])


def test_placed_kinds_are_the_replays_reading_of_them(session):
    # One case per fault of the item, spelled as the replay reports it.
    placed = faults.cases(str(session), kinds=["corrupt:04@exchange:1;delay:5@rx:2", "drop"])
    assert [case.id for case in placed[:2]] == ["corrupt:4@exchange:1", "delay:5@rx:2"]
    assert [case.id for case in placed[2:]] == [f"drop@exchange:{n}" for n in range(3)]
    with pytest.raises(faults.FaultInputError, match="'delay:abc'"):
        faults.cases(str(session), kinds=["delay:abc"])


# --- the places, as the replay counts them ---------------------------------------------


def late_session(path: Path) -> Path:
    """Two line exchanges recorded from 2 s of session time on."""
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        writer.write("tx", 2_000_000_000, b"Q0\n")
        writer.write("rx", 2_500_000_000, b"R0\n")
        writer.write("tx", 3_000_000_000, b"Q1\n")
        writer.write("rx", 3_500_000_000, b"R1\n")
    return path


def test_t_is_checked_on_the_sessions_clock_where_the_replay_fires_it(tmp_path):
    # The fault stage fires t:S at the first rx recorded at or after S of
    # session time (docs/faults.md), not S after the first record: t:3 fires
    # at R1 (3.5 s), and the check lets it through.
    path = late_session(tmp_path / "late.wtape")
    faults.check_where(str(path), "duplicate@t:3")
    assert faults.session_shape(str(path)).seconds == pytest.approx(3.5)
    port = wiretape.open_port(f"type=replay,file={path},timing=none,"
                              "faults=duplicate@t:3,timeout=5")
    port.write(b"Q0\n")
    assert port.read_line() == b"R0\n"
    port.write(b"Q1\n")
    assert port.read_line() == b"R1\n"
    assert port.read_line() == b"R1\n"  # the fault fired
    port.close()
    with pytest.raises(faults.FaultInputError,
                       match=r"^duplicate@t:3.6: the session lasts 3.500 s; t:3.6 is past its "
                             r"end$"):
        faults.check_where(str(path), "duplicate@t:3.6")


def test_a_proxy_recordings_places_are_in_every_client_session(tmp_path):
    # A virtual device serves each client its client session, numbered on
    # (docs/faults.md): a place in the second is one a replay fires.
    path = tmp_path / "proxy.wtape"
    event = lambda **fields: json.dumps(fields).encode()
    with wiretape.SessionWriter(str(path), port_type="tcp") as writer:
        writer.write("rx", 1, b"said to nobody\n")
        writer.write("client_connect", 2_000_000_000, event(peer="a", role="control"))
        writer.write("tx", 2_100_000_000, b"Q0\n")
        writer.write("rx", 2_500_000_000, b"R0\n")
        writer.write("client_disconnect", 2_600_000_000, event(peer="a", reason="closed"))
        writer.write("client_connect", 5_000_000_000, event(peer="b", role="control"))
        writer.write("tx", 5_100_000_000, b"Q1\n")
        writer.write("rx", 5_500_000_000, b"R1-longer\n")
    shape = faults.session_shape(str(path))
    assert (shape.first_exchange, shape.exchanges, shape.rx_bytes) == (1, 3, 13)
    assert shape.seconds == pytest.approx(5.5)
    faults.check_where(str(path), "drop@t:5.4;drop@rx:12;drop@exchange:2")
    for place, words in [("t:5.6", "lasts 5.500 s"), ("rx:13", "has 13 rx bytes"),
                         ("exchange:3", "has 3 exchanges with rx")]:
        with pytest.raises(faults.FaultInputError, match=words):
            faults.check_where(str(path), f"drop@{place}")


def test_a_channel_on_a_file_of_one_port_is_refused_by_the_plan_itself(session):
    plan = _core.parse_faults("drop@exchange:0@channel:gps")
    assert plan[0].channel == "gps"
    with pytest.raises(_core.OptionError,
                       match=r"the session has no channel 'gps' \(its channels: none: the "
                             r"session has one port \(leave @channel out\)\)"):
        plan.check_against(str(session))
