"""The plugin's record modes beyond none/once/rewrite (DESIGN §11): `all` as
VCR's name for rewrite, `--wiretape-live` (hardware in the loop: the device,
nothing recorded), and the end-of-run summary of cassettes. The "real device"
is wiretape's in-memory loopback."""

import wiretape

pytest_plugins = ["pytester"]

ECHO_TEST = """
    def test_echo(wiretape_port):
        wiretape_port.write_all(b"hello\\n")
        assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"
"""

PTY_TEST = """
    import os, select

    def test_echo_pty(wiretape_pty):
        fd = os.open(wiretape_pty, os.O_RDWR | os.O_NOCTTY)
        import tty; tty.setraw(fd)
        os.write(fd, b"hello\\n")
        got = b""
        while len(got) < 6 and select.select([fd], [], [], 10)[0]:
            got += os.read(fd, 6 - len(got))
        os.close(fd)
        assert got == b"hello\\n"
"""

LOOPBACK = "--wiretape-device=type=loopback"


def cassette_of(pytester, module, test):
    return pytester.path / "recordings" / module / f"{test}.wtape"


def tx_of(path):
    return b"".join(r.data for r in wiretape.SessionReader(str(path)) if r.kind == "tx")


def test_all_is_rewrite(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_echo", "test_echo")
    first = cassette.read_bytes()
    pytester.makepyfile(test_echo=ECHO_TEST.replace("hello", "howdy"))
    result = pytester.runpytest("--wiretape-record=all", LOOPBACK)
    result.assert_outcomes(passed=1)
    assert cassette.read_bytes() != first
    assert tx_of(cassette) == b"howdy\n"


def test_all_in_the_marker_and_ini_too(pytester):
    pytester.makepyfile(test_echo="""
        import pytest

        @pytest.mark.wiretape(record="all", device="type=loopback")
        def test_echo(wiretape_port):
            wiretape_port.write_all(b"hello\\n")
            assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"
    """)
    pytester.runpytest().assert_outcomes(passed=1)
    assert tx_of(cassette_of(pytester, "test_echo", "test_echo")) == b"hello\n"


def test_a_bad_mode_names_the_choices(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    result = pytester.runpytest("--wiretape-record=new")
    assert result.ret != 0
    result.stderr.fnmatch_lines(["*--wiretape-record*invalid choice*'new'*"])


def test_live_talks_to_the_device_and_records_nothing(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    result = pytester.runpytest("--wiretape-live", LOOPBACK)
    result.assert_outcomes(passed=1)
    assert not (pytester.path / "recordings").exists()
    result.stdout.fnmatch_lines(["*wiretape*", "*1 cassette: 1 live*"])


def test_live_ignores_a_cassette_that_would_not_match(pytester):
    # The cassette says "hello"; the device is live, so "howdy" passes.
    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_echo", "test_echo")
    kept = cassette.read_bytes()
    pytester.makepyfile(test_echo=ECHO_TEST.replace("hello", "howdy"))
    pytester.runpytest().assert_outcomes(failed=1)  # the replay: a mismatch
    pytester.runpytest("--wiretape-live", LOOPBACK).assert_outcomes(passed=1)
    assert cassette.read_bytes() == kept


def test_live_through_a_pty(pytester):
    pytester.makepyfile(test_echo_pty=PTY_TEST)
    result = pytester.runpytest("--wiretape-live", LOOPBACK)
    result.assert_outcomes(passed=1)
    assert not (pytester.path / "recordings").exists()


def test_live_without_a_device_is_an_error_naming_the_way(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    result = pytester.runpytest("--wiretape-live")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*--wiretape-live*no device*--wiretape-device*"])


def test_live_from_the_ini(pytester):
    pytester.makeini("[pytest]\nwiretape_live = true\nwiretape_device = type=loopback\n")
    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest().assert_outcomes(passed=1)
    assert not (pytester.path / "recordings").exists()


def test_the_summary_counts_replayed_recorded_and_orphaned_cassettes(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST + ECHO_TEST.replace("test_echo", "test_again"))
    result = pytester.runpytest("--wiretape-record=once", LOOPBACK)
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(["*- wiretape -*", "2 cassettes: 2 recorded"])
    result = pytester.runpytest()
    result.stdout.fnmatch_lines(["2 cassettes: 2 replayed"])
    # A renamed test leaves its old cassette behind: the summary names it,
    # also when -k runs only some tests.
    pytester.makepyfile(test_echo=ECHO_TEST + ECHO_TEST.replace("test_echo", "test_renamed"))
    result = pytester.runpytest("-k", "not test_renamed")
    result.assert_outcomes(passed=1, deselected=1)
    orphan = cassette_of(pytester, "test_echo", "test_again")
    result.stdout.fnmatch_lines(["1 cassette: 1 replayed",
                                 "1 cassette no collected test names*", f"    {orphan}"])


def test_the_summary_says_when_a_recording_was_not_kept(pytester):
    pytester.makepyfile(test_echo="""
        def test_echo(wiretape_port):
            wiretape_port.write_all(b"hello\\n")
            assert wiretape_port.read_exactly(6, timeout=5) == b"nope!\\n"
    """)
    result = pytester.runpytest("--wiretape-record=rewrite", LOOPBACK)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["1 cassette: 1 not kept*the test failed while recording*"])
    assert not cassette_of(pytester, "test_echo", "test_echo").exists()


def test_no_summary_without_cassettes(pytester):
    pytester.makepyfile(test_plain="def test_plain():\n    assert True\n")
    result = pytester.runpytest()
    result.assert_outcomes(passed=1)
    assert " wiretape " not in result.stdout.str()  # no summary section
    assert "cassette:" not in result.stdout.str() and "cassettes:" not in result.stdout.str()
