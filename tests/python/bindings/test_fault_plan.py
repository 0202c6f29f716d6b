"""faults= parsed by the replay's own parser from Python (_core.parse_faults,
DESIGN.md section 17): every kind and place, bad input named as the replay
names it, and the table of kinds that campaigns inject."""

import pytest

import wiretape
from wiretape import _core, faults


def test_every_kind_and_place():
    plan = _core.parse_faults(
        "drop@exchange:3; corrupt:4@rx:100;garbage@t:1.5;truncate:2@every:2;duplicate@p:0.25;"
        "delay:50@exchange:0;stall:20@exchange:1;trickle@exchange:2;silence@exchange:4;"
        "disconnect@exchange:5;reconnect:100@exchange:6", seed=7)
    assert plan.seed == 7
    assert len(plan) == 11
    got = [(f.kind, f.amount, f.where, f.number, f.value) for f in plan]
    assert got == [
        ("drop", None, "exchange", 3, None),
        ("corrupt", 4, "rx", 100, None),
        ("garbage", None, "t", None, 1.5),
        ("truncate", 2, "every", 2, None),
        ("duplicate", None, "p", None, 0.25),
        ("delay", 50, "exchange", 0, None),
        ("stall", 20, "exchange", 1, None),
        ("trickle", None, "exchange", 2, None),
        ("silence", None, "exchange", 4, None),
        ("disconnect", None, "exchange", 5, None),
        ("reconnect", 100, "exchange", 6, None),
    ]
    # The item as written (trimmed) for messages; the normal spelling for reports.
    assert plan[1].text == "corrupt:4@rx:100"
    assert (plan[1].kind_text, plan[1].where_text) == ("corrupt:4", "rx:100")
    assert plan[4].where_text == "p:0.25"
    assert [f.text for f in plan] == [f.text for f in plan.faults]
    with pytest.raises(IndexError):
        plan[11]
    assert len(_core.parse_faults("")) == 0
    assert _core.parse_faults("drop@exchange:0").seed == 0


@pytest.mark.parametrize("text, problem", [
    ("bogus@exchange:1", "unknown fault kind 'bogus'"),
    ("drop", "no '@WHERE'"),
    ("drop@exchange:x", "needs a whole number"),
    ("drop@when:1", "unknown WHERE 'when'"),
    ("delay@exchange:1", "needs ':MS'"),
    ("duplicate:2@exchange:1", "takes no ':N'"),
    ("drop@p:1.5", "probability"),
    ("drop@exchange:1;silence", "no '@WHERE'"),
])
def test_bad_input_names_the_key_and_the_item(text, problem):
    with pytest.raises(wiretape.OptionError) as caught:
        _core.parse_faults(text)
    assert caught.value.key == "faults"
    message = str(caught.value)
    assert problem in message
    bad_item = text.split(";")[-1] if problem == "no '@WHERE'" and ";" in text else text
    assert f"'{bad_item}'" in message
    assert "KIND@WHERE" in message


def test_the_replay_and_the_binding_refuse_the_same_plans(tmp_path):
    with pytest.raises(wiretape.OptionError) as bound:
        _core.parse_faults("boom@exchange:0")
    with pytest.raises(wiretape.OptionError) as replayed:
        wiretape.open_port(f"type=replay,file={tmp_path / 'none.wtape'},faults=boom@exchange:0")
    assert str(bound.value) == str(replayed.value)


def test_the_kinds_table_is_the_campaigns():
    kinds = _core.fault_kinds()
    assert [kind.name for kind in kinds] == list(faults.KIND_NAMES)
    assert [kind.campaign for kind in kinds] == list(faults.KINDS)
    by_name = {kind.name: kind for kind in kinds}
    assert by_name["delay"].amount == "required" and by_name["delay"].campaign == "delay:500"
    assert by_name["drop"].amount == "optional" and by_name["drop"].campaign == "drop"
    assert by_name["silence"].amount == "none"
    # Every campaign KIND is one the replay takes.
    for kind in faults.KINDS:
        assert _core.parse_faults(f"{kind}@exchange:0")[0].kind_text == kind


def test_a_single_kind_in_its_normal_spelling():
    assert _core.normal_fault_kind(" corrupt:04 ") == "corrupt:4"
    assert faults._kind_spec("delay") == "delay:500"
    assert faults._kind_spec("delay:20") == "delay:20"
    for bad in ("delay:abc", "drop@exchange:1", "nope"):
        with pytest.raises(faults.FaultInputError, match=bad.split(":")[0]):
            faults._kind_spec(bad)


def test_campaign_places_are_checked_by_the_replays_parser():
    # A plan the replay would refuse is bad campaign input, named as the
    # replay names it, before the session is read.
    with pytest.raises(faults.FaultInputError, match="'drop@exchange:x'.*whole number"):
        faults.check_where("never-read.wtape", "drop@exchange:x")
    with pytest.raises(faults.FaultInputError, match="unknown fault kind 'boom'"):
        faults.check_where("never-read.wtape", "silence@t:1;boom@exchange:0")


def test_a_fault_may_name_its_channel():
    plan = _core.parse_faults("drop@exchange:3@channel:gps;corrupt@rx:1")
    assert (plan[0].where_text, plan[0].channel) == ("exchange:3@channel:gps", "gps")
    assert (plan[1].where_text, plan[1].channel) == ("rx:1", "")
    with pytest.raises(wiretape.OptionError, match="@channel:NAME"):
        _core.parse_faults("drop@exchange:3@chan:gps")
