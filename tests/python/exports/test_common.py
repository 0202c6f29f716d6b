"""wiretape.exports._common: the exports' clock starts at the header's
start_utc as the session model reads it (_core.parse_start_utc)."""

from wiretape import _core
from wiretape.exports._common import start_epoch_ns


def test_the_start_is_the_session_models_reading():
    text = "2026-11-23T10:00:00.123456789Z"
    assert start_epoch_ns({"start_utc": text}) == _core.parse_start_utc(text)


def test_a_leap_second_start_is_a_time_not_zero():
    """The reader accepts :60 (a leap second); Python's datetime did not,
    and the exports' clock then started at 1970."""
    assert start_epoch_ns({"start_utc": "2016-12-31T23:59:60.5Z"}) == \
        1483228800 * 10**9 + 500_000_000


def test_no_start_is_zero():
    assert start_epoch_ns({}) == 0
    assert start_epoch_ns({"start_utc": ""}) == 0
    assert start_epoch_ns({"start_utc": "yesterday"}) == 0
