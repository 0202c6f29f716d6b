"""wiretape.tools.edit_child and edit_in_child(): the edit runs in a child
process started as every child is (``Child``); its result, or its error,
comes back as edit() would give it."""

import pytest

from wiretape import _core
from wiretape.tools.edit import edit, edit_in_child, parse_cut, parse_redaction


def write_session(path, items):
    with _core.SessionWriter(path, capture="wire", port_type="serial",
                             port_options="type=serial,device=/dev/ttyUSB0",
                             start_utc="2026-11-24T00:00:00Z") as writer:
        for t_ns, kind, data in items:
            writer.write(kind, t_ns, data)
    return path


ITEMS = [(1, "tx", b"pw=secret\r\n"), (2, "rx", b"OK\r\n")]


def test_the_child_gives_what_edit_gives(tmp_path):
    src = write_session(tmp_path / "in.wtape", ITEMS)
    options = dict(redact=[parse_redaction("secret")], profile=None)
    in_child = edit_in_child(src, tmp_path / "child.wtape", **options)
    here = edit(src, tmp_path / "here.wtape", **options)
    assert in_child == here
    assert (tmp_path / "child.wtape").read_bytes() == (tmp_path / "here.wtape").read_bytes()


def test_an_error_of_the_edit_is_raised_here_as_itself(tmp_path):
    src = write_session(tmp_path / "in.wtape", ITEMS)
    with pytest.raises(ValueError, match="no exchange 9"):
        edit_in_child(src, tmp_path / "out.wtape", cut=parse_cut("9e:"), profile=None)
    with pytest.raises(_core.PortError):
        edit_in_child(tmp_path / "missing.wtape", tmp_path / "out.wtape",
                      redact=[parse_redaction("x")])


class _Unimportable:
    """A pattern the child cannot unpickle (this test module is not on its
    path): the child ends without an outcome."""

    pattern = None

    def __reduce__(self):
        return (_Unimportable, ())


def test_a_child_that_ends_without_an_outcome_is_an_error_naming_how(tmp_path):
    src = write_session(tmp_path / "in.wtape", ITEMS)
    out = tmp_path / "out.wtape"
    with pytest.raises(RuntimeError, match=r"ended without a result \(exit status 1\)"):
        edit_in_child(src, out, redact=[_Unimportable()])
    assert not out.exists()
