"""What the pytest plugin tells a developer: the command that records a
cassette again names the device the cassette was recorded from, the summary
names the cassettes a passing test left partly unread, and a cassette that
several tests share counts once."""

pytest_plugins = ["pytester"]

ECHO_TEST = """
    def test_echo(wiretape_port):
        wiretape_port.write_all(b"hello\\n")
        assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"
"""

TWO_WORDS = """
    import pytest

    SHARED = "recordings/test_two/test_two.wtape"

    def test_two(wiretape_port):
        for word in (b"one\\n", b"two\\n"):
            wiretape_port.write_all(word)
            assert wiretape_port.read_exactly(4, timeout=5) == word

    @pytest.mark.wiretape(cassette=SHARED)
    def test_only_first(wiretape_port):
        wiretape_port.write_all(b"one\\n")
        assert wiretape_port.read_exactly(4, timeout=5) == b"one\\n"

    @pytest.mark.wiretape(cassette=SHARED)
    def test_both_again(wiretape_port):
        for word in (b"one\\n", b"two\\n"):
            wiretape_port.write_all(word)
            assert wiretape_port.read_exactly(4, timeout=5) == word
"""


def test_the_rerecord_command_names_the_device_the_cassette_was_recorded_from(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    device = "type=loopback,timeout=5,meta_bench=it's"
    pytester.runpytest("--wiretape-record=once",
                       f"--wiretape-device={device}").assert_outcomes(passed=1)
    pytester.makepyfile(test_echo=ECHO_TEST.replace("hello", "hellx"))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    # shell-quoted, as a shell gives it back
    result.stdout.fnmatch_lines([
        "*to record it again: pytest --wiretape-record=rewrite "
        "--wiretape-device='type=loopback,timeout=5,meta_bench=it'\"'\"'s' "
        "test_echo.py::test_echo"])
    assert "OPTS" not in result.stdout.str()


def test_a_passing_test_that_left_its_cassette_partly_unread_is_named_in_the_summary(pytester):
    pytester.makepyfile(test_two=TWO_WORDS)
    pytester.runpytest("--wiretape-record=once", "--wiretape-device=type=loopback",
                       "test_two.py::test_two").assert_outcomes(passed=1)
    result = pytester.runpytest("-k", "only_first or both_again")
    result.assert_outcomes(passed=2)
    cassette = pytester.path / "recordings" / "test_two" / "test_two.wtape"
    result.stdout.fnmatch_lines([
        "1 cassette left partly unread by a passing test (replay key unused=error makes "
        "it a failure; docs/testing.md):",
        f"    {cassette}: *"])
    result = pytester.runpytest("-k", "both_again")
    assert "partly unread" not in result.stdout.str()


def test_a_cassette_that_several_tests_share_counts_once(pytester):
    pytester.makepyfile(test_two=TWO_WORDS)
    pytester.runpytest("--wiretape-record=once", "--wiretape-device=type=loopback",
                       "test_two.py::test_two").assert_outcomes(passed=1)
    result = pytester.runpytest("-k", "only_first or both_again")
    result.stdout.fnmatch_lines(["1 cassette: 1 replayed"])
    result = pytester.runpytest()
    result.stdout.fnmatch_lines(["1 cassette: 1 replayed"])


def test_a_mismatch_traceback_shows_the_tests_frames_not_wiretapes(pytester):
    pytester.makepyfile(test_url="""
        import serial

        def test_pyserial(wiretape_url):
            with serial.serial_for_url(wiretape_url, timeout=5) as port:
                port.write(b"hello\\n")
                assert port.read(6) == b"hello\\n"
    """)
    pytester.runpytest("--wiretape-record=once",
                       "--wiretape-device=type=loopback").assert_outcomes(passed=1)
    pytester.makepyfile(test_url="""
        import serial

        def test_pyserial(wiretape_url):
            with serial.serial_for_url(wiretape_url, timeout=5) as port:
                port.write(b"hellx\\n")
                assert port.read(6) == b"hello\\n"
    """)
    result = pytester.runpytest("--tb=long")
    result.assert_outcomes(failed=1)
    output = result.stdout.str()
    assert "mismatch" in output
    assert "test_url.py" in output
    assert "wiretape/urlhandler" not in output and "wiretape/testing" not in output, output


def test_unused_error_fails_without_the_plugins_frames(pytester):
    pytester.makepyfile(test_two=TWO_WORDS.replace("cassette=SHARED", "cassette=SHARED, unused='error'"))
    pytester.runpytest("--wiretape-record=once", "--wiretape-device=type=loopback",
                       "test_two.py::test_two").assert_outcomes(passed=1)
    result = pytester.runpytest("--tb=long", "-k", "only_first")
    result.assert_outcomes(failed=1)
    output = result.stdout.str()
    assert "never read" in output
    assert "wiretape/testing" not in output, output
