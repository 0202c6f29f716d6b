"""_core.hex_ascii and _core.escape_bytes: the C++ byte renderings (src/util/hex.hpp)
that mismatch reports use, bound for the Python tools."""

import re

import pytest
from hypothesis import given, strategies as st

from wiretape import _core

ESCAPES = [
    (b"", ""),
    (b"VV\n", "VV\\n"),
    (b"PING\r\n", "PING\\r\\n"),
    (b"a\tb", "a\\tb"),
    (b"back\\slash", "back\\\\slash"),
    (b" ~", " ~"),
    (b"\x00\x01\x1f", "\\x00\\x01\\x1f"),
    (b"\x7f", "\\x7f"),  # DEL
    (b"\x80\xc3\xa9\xff", "\\x80\\xc3\\xa9\\xff"),  # high bytes, UTF-8 included
    (b"\x1b[2J\x1b[31mred\x1b[0m", "\\x1b[2J\\x1b[31mred\\x1b[0m"),  # ANSI
    (b"\x1b]0;title\x07", "\\x1b]0;title\\x07"),  # OSC with BEL
    (b"\x9b31m", "\\x9b31m"),  # the 8-bit CSI
    (b"\x0b\x0c\x08", "\\x0b\\x0c\\x08"),
]


@pytest.mark.parametrize("data, expected", ESCAPES)
def test_escape_bytes_renders_each_byte_for_a_terminal(data, expected):
    assert _core.escape_bytes(data) == expected


def test_escape_bytes_cuts_at_the_limit_and_counts_the_rest():
    assert _core.escape_bytes(b"x" * 64) == "x" * 64
    assert _core.escape_bytes(b"x" * 65) == "x" * 64 + "... (+1 bytes)"
    assert _core.escape_bytes(b"ab\ncd", 3) == "ab\\n... (+2 bytes)"
    assert _core.escape_bytes(b"\x1b[0m", limit=1) == "\\x1b... (+3 bytes)"
    assert _core.escape_bytes(b"abc", 0) == "... (+3 bytes)"
    assert _core.escape_bytes(b"abc", limit=3) == "abc"


def test_escape_bytes_rejects_bad_arguments_clearly():
    with pytest.raises(ValueError, match="limit must be 0 or more"):
        _core.escape_bytes(b"abc", -1)
    with pytest.raises(TypeError):
        _core.escape_bytes("text")


def _unescape(text: str) -> bytes:
    simple = {"n": b"\n", "r": b"\r", "t": b"\t", "\\": b"\\"}
    out = bytearray()
    for match in re.finditer(r"\\x([0-9a-f]{2})|\\(.)|(.)", text, re.S):
        hex_digits, escaped, plain = match.groups()
        if hex_digits is not None:
            out.append(int(hex_digits, 16))
        elif escaped is not None:
            out += simple[escaped]
        else:
            out += plain.encode("ascii")
    return bytes(out)


@given(st.binary(max_size=200), st.integers(min_value=0, max_value=100))
def test_escape_bytes_is_printable_ascii_and_reversible(data, limit):
    text = _core.escape_bytes(data, limit)
    assert all(0x20 <= ord(c) < 0x7F for c in text), text  # ESC never raw
    shown, _, rest = text.partition("... (+")
    if len(data) > limit:
        assert rest == f"{len(data) - limit} bytes)"
    else:
        assert rest == ""
    assert _unescape(shown) == data[:limit]


@pytest.mark.parametrize(
    "data, expected",
    [
        (b"", "(none)"),
        (b"VV\n", "56 56 0a  |VV.|"),
        (b"\x00\x1b\x7f\xff A", "00 1b 7f ff 20 41  |.... A|"),
    ],
)
def test_hex_ascii_matches_the_mismatch_reports(data, expected):
    assert _core.hex_ascii(data) == expected
