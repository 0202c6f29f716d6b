"""wiretape.tools.edit_specs: ``--cut FROM:TO`` and ``--redact
PATTERN[=REPLACEMENT]`` parsed, or refused naming the problem."""

import pytest
from hypothesis import given, strategies as st

from wiretape.tools.edit_specs import Cut, parse_cut, parse_redaction


@given(st.text(max_size=40))
def test_any_cut_or_redact_spec_parses_or_names_its_problem(spec):
    for parse in (parse_cut, parse_redaction):
        try:
            parse(spec)
        except ValueError as error:
            assert str(error).startswith(("--cut", "--redact"))


def test_a_cut_counts_seconds_or_exchanges():
    assert parse_cut("1.5:4") == Cut(1.5, 4.0, False, "1.5:4")
    assert parse_cut("3e:") == Cut(3.0, None, True, "3e:")
    assert parse_cut(":2s").describe() == "cut :2 s"


@pytest.mark.parametrize("spec, message", [
    ("3e:4", None),  # one unit on one side is that unit for both
    ("3e:4s", "both sides must count the same"),
    ("1.5e:", "exchanges are whole numbers"),
    ("4:2", "TO must be after FROM"),
    (":", "expected FROM:TO"),
    ("x:", "FROM 'x' is not a number"),
])
def test_a_bad_cut_names_its_problem(spec, message):
    if message is None:
        assert parse_cut(spec).exchanges
        return
    with pytest.raises(ValueError, match=message):
        parse_cut(spec)


def test_a_redaction_splits_at_the_unescaped_equals_sign():
    redaction = parse_redaction(r"pw\=[a-z]+=#")
    assert redaction.pattern.pattern == rb"pw\=[a-z]+"
    assert redaction.scrub(5) == b"#####"
    assert parse_redaction("(?<=SERI:)[^;]*").replacement == b"*"
    assert parse_redaction("ab=xy").scrub(5) == b"xyxyx"


@pytest.mark.parametrize("spec, message", [
    ("=x", "the pattern is empty"),
    ("a=", "the replacement is empty"),
    ("(", "not a regular expression"),
    ("a*", "matches the empty string"),
])
def test_a_bad_redaction_names_its_problem(spec, message):
    with pytest.raises(ValueError, match=message):
        parse_redaction(spec)
