"""--speed K is checked once, by the key table's row of the replay key
``speed`` (C++): the replay's flag, the campaign's flag and CMD's scaled
clock (wiretape.scaled_clock) ask it, so they accept the same K."""

import pytest

from wiretape import _core, scaled_clock
from wiretape.cli import build_parser
from wiretape.cli.parser import ParserError

SPEED = next(key for key in _core.option_keys() if key.name == "speed")


def test_the_scaled_clock_takes_the_replay_keys_range():
    assert scaled_clock.check_speed(10) == 10.0
    assert scaled_clock.check_speed("2.5") == 2.5
    assert scaled_clock.check_speed(SPEED.maximum) == SPEED.maximum
    # Above the key's range the replay refuses K: CMD's clock does too (it
    # took any finite number above 0 before).
    for speed in (SPEED.maximum * 2, 0, -1, float("inf"), float("nan"), "fast", None):
        with pytest.raises(ValueError, match=r"^--speed .*option 'speed'"):
            scaled_clock.check_speed(speed)


@pytest.mark.parametrize("argv", [["replay", "s.wtape", "--pty", "p"], ["faults", "s.wtape"]])
@pytest.mark.parametrize("text", ["0", "2e6", "nan", "fast"])
def test_both_flags_refuse_what_the_key_table_refuses(argv, text):
    with pytest.raises(ParserError, match=r"argument --speed: option 'speed': .* is not a number"):
        build_parser().parse_args(argv + ["--speed", text])


@pytest.mark.parametrize("argv", [["replay", "s.wtape", "--pty", "p"], ["faults", "s.wtape"]])
def test_both_flags_read_k_as_a_number(argv):
    assert build_parser().parse_args(argv + ["--speed", "1e3"]).speed == 1000.0
