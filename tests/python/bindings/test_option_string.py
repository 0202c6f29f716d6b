"""_core.option_string: the one builder of option strings Python makes.
Values are quoted by quote_option_value, numbers and booleans written by one
rule in C++, keys checked to be keys; parse_options gives the pairs back."""

import math
import pathlib

import pytest
from hypothesis import given, settings, strategies as st

from wiretape import _core, OptionError

HOSTILE = ["", "a,b", "k=v", 'say "x"', "back\\slash", "tab\tnew\nline\r", "café ✓ 日本",
           '=,"\\', " lead", "trail ", "=", ",", '"', "a=b,c=d"]


@pytest.mark.parametrize("value", HOSTILE)
def test_a_hostile_value_comes_back_from_parse_options(value):
    text = _core.option_string([("type", "replay"), ("meta_note", value), ("file", "s.wtape")])
    assert _core.parse_options(text) == [("type", "replay"), ("meta_note", value),
                                         ("file", "s.wtape")]


@settings(max_examples=300, derandomize=True)
@given(st.lists(st.text(alphabet=st.characters(blacklist_characters="\0",
                                               blacklist_categories=("Cs",))),
                max_size=6))
def test_any_text_comes_back_from_parse_options(values):
    pairs = [(f"meta_{i}", value) for i, value in enumerate(values)]
    assert _core.parse_options(_core.option_string(pairs)) == pairs


def test_numbers_and_booleans_are_written_by_one_rule():
    text = _core.option_string([("speed", 2.0), ("gap", 0.25), ("jitter", 1e-6), ("seed", 7),
                                ("big", 2**53 + 1), ("fsync", True), ("restart", False),
                                ("file", pathlib.Path("/a b/s.wtape"))])
    assert text == ('speed=2,gap=0.25,jitter=1e-06,seed=7,big=9007199254740993,'
                    'fsync=true,restart=false,file="/a b/s.wtape"')
    # The shortest text that reads back as the same double.
    for number in (0.1, 1 / 3, 123456.789, 1e300, -2.5e-12):
        (_, written), = _core.parse_options(_core.option_string([("x", number)]))
        assert float(written) == number


@pytest.mark.parametrize("key", ["", "a,b", "a b", "a=b", 'q"', "n\0l", "tab\t"])
def test_a_key_that_is_not_a_key_is_an_option_error_naming_it(key):
    with pytest.raises(OptionError, match="is not a key") as caught:
        _core.option_string([(key, "v")])
    assert caught.value.key == key


def test_a_key_given_twice_a_nul_or_an_infinite_number_is_refused():
    with pytest.raises(OptionError, match="'speed' is given twice"):
        _core.option_string([("speed", 1), ("speed", 2)])
    with pytest.raises(OptionError, match="NUL") as caught:
        _core.option_string([("log", "a\0b")])
    assert caught.value.key == "log"
    for number in (math.inf, -math.inf, math.nan):
        with pytest.raises(OptionError, match="finite") as caught:
            _core.option_string([("gap", number)])
        assert caught.value.key == "gap"
    with pytest.raises(OptionError, match="64-bit"):
        _core.option_string([("seed", 2**64)])


def test_a_value_of_another_type_is_a_type_error_naming_the_key():
    with pytest.raises(TypeError, match="'file'"):
        _core.option_string([("file", None)])
    with pytest.raises(TypeError, match="pairs"):
        _core.option_string(["type=replay"])


def test_option_value_reads_a_value_as_the_port_reads_its_key():
    assert _core.option_value("replay", "speed", "2.5") == 2.5
    assert _core.option_value("replay", "seed", "7") == 7
    assert _core.option_value("replay", "timing", "NONE") == "none"
    assert _core.option_value("serial", "timeout", "forever") is None
    assert _core.option_value("serial", "timeout", "0.5") == 0.5
    assert _core.option_value("loopback", "fsync", "yes") is True


@pytest.mark.parametrize("text", ["0", "-1", "2e6", "nan", "inf", "fast", ""])
def test_option_value_refuses_what_the_key_table_refuses(text):
    with pytest.raises(OptionError, match="speed") as caught:
        _core.option_value("replay", "speed", text)
    assert caught.value.key == "speed"


def test_option_value_of_a_key_the_type_lacks_names_it():
    with pytest.raises(OptionError, match="not a key of type=replay") as caught:
        _core.option_value("replay", "baud", "9600")
    assert caught.value.key == "baud"
