"""An error whose message holds bytes that are not UTF-8 (a file name, text
made from device bytes) reaches Python as the error thrown, with those bytes
as \\xNN: before, converting the message failed and Python saw a RuntimeError
(``UnicodeDecodeError``), which the command line reports as exit 3."""

import pytest

import wiretape
from wiretape import _core


def test_a_port_error_naming_a_file_that_is_not_utf8_stays_a_port_error(tmp_path):
    missing = bytes(tmp_path) + b"/\xffno-such.wtape"
    with pytest.raises(wiretape.PortError) as raised:
        _core.SessionReader(missing)
    assert "\\xffno-such.wtape" in str(raised.value)
    assert "cannot open" in str(raised.value)
