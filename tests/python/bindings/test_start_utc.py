"""_core.parse_start_utc and format_start_utc: a header's start_utc read
and written by the session model's one rule (session/header.cpp)."""

import pytest

from wiretape import _core


def test_parse_gives_exact_nanoseconds():
    assert _core.parse_start_utc("2026-11-23T10:00:00.123456789Z") == \
        1795428000 * 10**9 + 123456789
    assert _core.parse_start_utc("2026-11-23T10:00:00Z") == 1795428000 * 10**9
    assert _core.parse_start_utc("") is None  # not known


def test_parse_refuses_what_a_header_may_not_hold_saying_why():
    with pytest.raises(_core.OptionError, match="not an ISO 8601 UTC time"):
        _core.parse_start_utc("2026-11-23 10:00:00")
    with pytest.raises(_core.OptionError, match="outside the years 1970 to 2261"):
        _core.parse_start_utc("1969-12-31T23:59:59Z")


def test_format_writes_nine_digits_and_reads_back():
    ns = 1795428000 * 10**9 + 5
    text = _core.format_start_utc(ns)
    assert text == "2026-11-23T10:00:00.000000005Z"
    assert _core.parse_start_utc(text) == ns


def test_format_refuses_a_time_no_header_can_hold():
    with pytest.raises(ValueError, match="outside the years 1970 to 2261"):
        _core.format_start_utc(-1)
    with pytest.raises(ValueError, match="outside the years"):
        _core.format_start_utc(2**63 - 1)
