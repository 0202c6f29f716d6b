"""The pytest plugin, run on small test files with pytester. The "real
device" is wiretape's in-memory loopback (what is written is read back)."""

import re

import wiretape
from wiretape.testing.cassette import MAX_NAME_LENGTH, safe_file_name

pytest_plugins = ["pytester"]

ECHO_TEST = """
    def test_echo(wiretape_port):
        wiretape_port.write_all(b"hello\\n")
        assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"
"""

LOOPBACK = "--wiretape-device=type=loopback"


def cassette_of(pytester, module, test):
    return pytester.path / "recordings" / module / f"{test}.wtape"


def streams(path):
    tx = b"".join(r.data for r in wiretape.SessionReader(str(path)) if r.kind == "tx")
    rx = b"".join(r.data for r in wiretape.SessionReader(str(path)) if r.kind == "rx")
    return tx, rx


def leftovers(pytester):
    return [p.name for p in pytester.path.rglob("*.recording-*")]


def test_options_are_registered_in_the_wiretape_group(pytester):
    result = pytester.runpytest("--help")
    result.stdout.fnmatch_lines(["*wiretape*", "*--wiretape-record=*", "*--wiretape-device=OPTS*",
                                 "*wiretape_record*", "*wiretape_device*"])
    result = pytester.runpytest("--markers")
    result.stdout.fnmatch_lines(["*@pytest.mark.wiretape(cassette=None, device=None, record=None*"])


def test_missing_cassette_is_an_error_naming_the_path_and_the_command(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)
    cassette = cassette_of(pytester, "test_echo", "test_echo")
    result.stdout.fnmatch_lines([f"*{cassette}*does not exist*",
                                 "*pytest --wiretape-record=once --wiretape-device=*test_echo.py::test_echo*"])


def test_once_records_from_the_device_then_replays_without_it(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    result = pytester.runpytest("--wiretape-record=once", LOOPBACK)
    result.assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_echo", "test_echo")
    assert streams(cassette) == (b"hello\n", b"hello\n")
    header = wiretape.SessionReader(str(cassette)).header
    assert "test_echo.py::test_echo" in str(header)
    assert leftovers(pytester) == []

    recorded = cassette.read_bytes()
    result = pytester.runpytest()  # no device: replay
    result.assert_outcomes(passed=1)
    result = pytester.runpytest("--wiretape-record=once", LOOPBACK)  # exists: replay
    result.assert_outcomes(passed=1)
    assert cassette.read_bytes() == recorded

    # It really is the recording answering: another request does not match.
    pytester.makepyfile(test_echo=ECHO_TEST.replace("hello", "howdy"))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)


def test_mismatch_fails_with_the_replay_report_and_the_cassette(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    pytester.makepyfile(test_echo=ECHO_TEST.replace("hello", "hellx"))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    cassette = cassette_of(pytester, "test_echo", "test_echo")
    result.stdout.fnmatch_lines(["*ReplayMismatch*", "*wiretape*", f"*cassette: {cassette}*",
                                 "*--wiretape-record=rewrite*"])


def test_a_test_failing_while_recording_leaves_no_recording(pytester):
    pytester.makepyfile(test_fail="""
        def test_fails(wiretape_port):
            wiretape_port.write_all(b"hello\\n")
            assert wiretape_port.read_exactly(6, timeout=5) == b"other\\n"
    """)
    result = pytester.runpytest("--wiretape-record=once", LOOPBACK)
    result.assert_outcomes(failed=1)
    assert not cassette_of(pytester, "test_fail", "test_fails").exists()
    assert leftovers(pytester) == []


def test_a_failed_rewrite_restores_the_previous_recording(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_echo", "test_echo")
    previous = cassette.read_bytes()

    pytester.makepyfile(test_echo="""
        def test_echo(wiretape_port):
            wiretape_port.write_all(b"changed\\n")
            assert wiretape_port.read_exactly(8, timeout=5) == b"changed\\n"
            raise RuntimeError("driver broke half way")
    """)
    result = pytester.runpytest("--wiretape-record=rewrite", LOOPBACK)
    result.assert_outcomes(failed=1)
    assert cassette.read_bytes() == previous
    assert leftovers(pytester) == []

    pytester.makepyfile(test_echo=ECHO_TEST.replace("hello", "again"))
    pytester.runpytest("--wiretape-record=rewrite", LOOPBACK).assert_outcomes(passed=1)
    assert streams(cassette) == (b"again\n", b"again\n")


def test_unused_recorded_data_fails_the_test_under_unused_error(pytester):
    pytester.makepyfile(test_two="""
        import pytest

        def test_two(wiretape_port):
            for word in (b"one\\n", b"two\\n"):
                wiretape_port.write_all(word)
                assert wiretape_port.read_exactly(4, timeout=5) == word

        @pytest.mark.wiretape(cassette="recordings/test_two/test_two.wtape", unused="error")
        def test_only_first_strict(wiretape_port):
            wiretape_port.write_all(b"one\\n")
            assert wiretape_port.read_exactly(4, timeout=5) == b"one\\n"

        @pytest.mark.wiretape(cassette="recordings/test_two/test_two.wtape", unused="ignore")
        def test_only_first_lenient(wiretape_port):
            wiretape_port.write_all(b"one\\n")
            assert wiretape_port.read_exactly(4, timeout=5) == b"one\\n"
    """)
    result = pytester.runpytest("--wiretape-record=once", LOOPBACK, "test_two.py::test_two")
    result.assert_outcomes(passed=1)
    result = pytester.runpytest("-k", "only_first")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(["*FAILED*test_only_first_strict*"])


def test_command_line_beats_marker_beats_ini(pytester):
    pytester.makeini("""
        [pytest]
        wiretape_device = type=loopback,meta_source=ini
        wiretape_record = rewrite
    """)
    pytester.makepyfile(test_precedence="""
        import pytest

        def test_ini(wiretape_options):
            print("OPTIONS", wiretape_options)

        @pytest.mark.wiretape(device="type=loopback,meta_source=marker", timing="session")
        def test_marker(wiretape_options):
            print("OPTIONS", wiretape_options)

        @pytest.mark.wiretape(record="none", timing="session", match="request")
        def test_marker_replays(wiretape_options):
            print("OPTIONS", wiretape_options)
    """)
    result = pytester.runpytest("-s", "-W", "ignore::wiretape.testing.WiretapeWarning",
                                "-k", "test_ini or test_marker")
    result.stdout.fnmatch_lines(["*OPTIONS type=loopback,meta_source=ini,log=*"])
    result.stdout.fnmatch_lines(["*OPTIONS type=loopback,meta_source=marker,log=*"])
    # marker record=none beats ini rewrite: replay of a cassette that is missing
    result.assert_outcomes(passed=2, errors=1)
    result.stdout.fnmatch_lines(["*test_marker_replays.wtape does not exist*"])

    result = pytester.runpytest("-s", "-W", "ignore::wiretape.testing.WiretapeWarning",
                                "--wiretape-record=once", "--wiretape-device=type=loopback,meta_source=cli")
    result.assert_outcomes(passed=3)
    assert result.stdout.str().count("meta_source=cli") == 3

    # replay: timing=none by default, the marker overrides it and adds keys
    for test in ("test_ini", "test_marker_replays"):
        cassette = cassette_of(pytester, "test_precedence", test)
        cassette.parent.mkdir(parents=True, exist_ok=True)
        cassette.write_bytes(b"")
    result = pytester.runpytest("-s", "--wiretape-record=none", "-k", "test_ini or replays")
    result.stdout.fnmatch_lines(["*OPTIONS type=replay,file=*test_ini.wtape,timing=none"])
    result.stdout.fnmatch_lines(
        ["*OPTIONS type=replay,file=*test_marker_replays.wtape,timing=session,match=request"])


def test_bad_settings_are_clear_errors(pytester):
    pytester.makepyfile(test_bad="""
        import pytest

        @pytest.mark.wiretape(record="sometimes")
        def test_bad_mode(wiretape_port):
            pass

        def test_no_device(wiretape_port):
            pass
    """)
    result = pytester.runpytest("-k", "bad_mode")
    assert result.ret != 0
    result.stdout.fnmatch_lines(["*'sometimes' (from the marker) is not one of none, once, new_episodes, rewrite*"])
    result = pytester.runpytest("-k", "no_device", "--wiretape-record=once")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*must be recorded*no device is given*--wiretape-device*"])
    result = pytester.runpytest("--wiretape-record=always")
    assert result.ret != 0
    result.stderr.fnmatch_lines(["*invalid choice: 'always'*"])


def test_parametrized_ids_become_safe_distinct_file_names(pytester):
    pytester.makepyfile(test_params="""
        import pytest

        LONG = "x" * 150

        WORDS = ["a/b c", LONG + "1", LONG + "2"]

        @pytest.mark.parametrize("word", WORDS, ids=WORDS)
        def test_word(wiretape_port, word):
            data = word.encode()[:20] + b"\\n"
            wiretape_port.write_all(data)
            assert wiretape_port.read_exactly(len(data), timeout=5) == data

        class TestGroup:
            def test_in_class(self, wiretape_port):
                wiretape_port.write_all(b"k")
                assert wiretape_port.read_exactly(1, timeout=5) == b"k"
    """)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=4)
    names = sorted(p.name for p in (pytester.path / "recordings" / "test_params").iterdir())
    # A name that had to change ends with a hash of the whole name.
    assert any(re.fullmatch(r"test_word_a_b_c-[0-9a-f]{12}\.wtape", n) for n in names), names
    assert "TestGroup.test_in_class.wtape" in names
    long_names = [n for n in names if n.startswith("test_word_xxx")]
    assert len(long_names) == 2
    assert all(len(n) <= MAX_NAME_LENGTH + len(".wtape") for n in long_names)
    pytester.runpytest().assert_outcomes(passed=4)


def test_safe_file_name():
    assert safe_file_name("test_plain") == "test_plain"
    assert safe_file_name("test_a[x-1]").startswith("test_a_x-1-")
    assert safe_file_name("test_b[../../etc/passwd]").startswith("test_b_.._.._etc_passwd-")
    assert "/" not in safe_file_name("a/b")
    long_a, long_b = safe_file_name("t" * 300 + "a"), safe_file_name("t" * 300 + "b")
    assert long_a != long_b and len(long_a) == len(long_b) <= MAX_NAME_LENGTH


def test_wiretape_url_serves_pyserial_drivers(pytester):
    pytester.makepyfile(test_url="""
        import serial

        def test_pyserial(wiretape_url):
            with serial.serial_for_url(wiretape_url, timeout=5) as port:
                port.write(b"PING\\r")
                assert port.read_until(b"\\r") == b"PING\\r"
    """)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_url", "test_pyserial")
    assert streams(cassette) == (b"PING\r", b"PING\r")
    pytester.runpytest().assert_outcomes(passed=1)


def test_wiretape_pty_serves_the_replay_on_a_terminal(pytester):
    pytester.makepyfile(test_pty="""
        import serial

        def test_through_pty(wiretape_pty):
            with serial.Serial(wiretape_pty, timeout=5) as port:
                port.write(b"PING\\r")
                assert port.read_until(b"\\r") == b"PING\\r"
    """)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_pty", "test_through_pty")
    assert streams(cassette) == (b"PING\r", b"PING\r")
    pytester.runpytest().assert_outcomes(passed=1)


def test_wiretape_udp_serves_the_replay_as_datagrams(pytester):
    pytester.makepyfile(test_udp="""
        import socket

        def test_through_udp(wiretape_udp):
            host, port = wiretape_udp.rsplit(":", 1)
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
                client.settimeout(10)
                for ping in (b"PING 1", b"PING 2"):
                    client.sendto(ping, (host, int(port)))
                    assert client.recv(100) == ping
    """)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_udp", "test_through_udp")
    assert streams(cassette) == (b"PING 1PING 2", b"PING 1PING 2")
    pytester.runpytest().assert_outcomes(passed=1)
    # The replay checks what the driver sends.
    pytester.makepyfile(test_udp=pytester.path.joinpath("test_udp.py").read_text()
                        .replace('b"PING 2"', 'b"PONG 2"'))
    pytester.runpytest().assert_outcomes(failed=1)


def test_request_mode_mismatch_shows_the_closest_recorded_requests(pytester):
    pytester.makepyfile(test_cmds="""
        import pytest

        @pytest.mark.wiretape(match="request")
        def test_cmds(wiretape_port):
            for command in (b"VV\\n", b"PP\\n"):
                wiretape_port.write_all(command)
                assert wiretape_port.read_exactly(3, timeout=5) == command
    """)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    pytester.makepyfile(test_cmds=pytester.path.joinpath("test_cmds.py").read_text()
                        .replace('b"PP\\n"', 'b"PX\\n"'))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*ReplayMismatch*matches no unused exchange*",
                                 "*closest unused requests*", "*50 50 0a*|PP.|*"])


def test_a_bad_replay_key_names_itself(pytester):
    pytester.makepyfile(test_key="""
        import pytest

        @pytest.mark.wiretape(timming="none")
        def test_key(wiretape_port):
            pass
    """)
    cassette = cassette_of(pytester, "test_key", "test_key")
    cassette.parent.mkdir(parents=True)
    with wiretape.SessionWriter(str(cassette), port_type="loopback") as writer:
        writer.write("rx", 0, b"x")
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*test_key.py::test_key: bad wiretape options "
                                 "(check the marker's replay keys)*timming*"])


OPTIONS_TEST = """
    import pytest

    def echo(port):
        port.write_all(b"hello\\n")
        assert port.read_exactly(6, timeout=5) == b"hello\\n"

    def test_echo(wiretape_port, wiretape_options):
        echo(wiretape_port)
        print("OPTIONS", wiretape_options)

    @pytest.mark.wiretape(timing="causal")
    def test_marker(wiretape_port, wiretape_options):
        echo(wiretape_port)
        print("OPTIONS", wiretape_options)
"""


def test_wiretape_config_in_a_conftest_sets_the_defaults_of_its_tests(pytester):
    pytester.makeini("""
        [pytest]
        wiretape_record = none
    """)
    pytester.makeconftest("""
        import pytest

        @pytest.fixture
        def wiretape_config():
            return {"record": "once", "device": "type=loopback", "timing": "session",
                    "unused": "warn"}
    """)
    pytester.makepyfile(test_config=OPTIONS_TEST)
    # The conftest's record=once and device beat the ini's none: it records.
    result = pytester.runpytest("-s")
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(["*OPTIONS type=loopback,log=*test_echo.wtape.recording-*"])
    cassette = cassette_of(pytester, "test_config", "test_echo")
    assert streams(cassette) == (b"hello\n", b"hello\n")

    # Now it replays, with the conftest's replay keys; the marker's win.
    result = pytester.runpytest("-s")
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(
        ["*OPTIONS type=replay,file=*test_echo.wtape,timing=session,unused=warn"])
    result.stdout.fnmatch_lines(
        ["*OPTIONS type=replay,file=*test_marker.wtape,timing=causal,unused=warn"])

    # The command line beats the conftest: rewrite records even what exists.
    recorded = cassette.read_bytes()
    result = pytester.runpytest("--wiretape-record=rewrite",
                                "--wiretape-device=type=loopback,meta_source=cli", "-k", "echo")
    result.assert_outcomes(passed=1)
    assert cassette.read_bytes() != recorded
    assert "meta_source=cli" in str(wiretape.SessionReader(str(cassette)).header)


def test_wiretape_cassette_dir_in_a_conftest_moves_the_cassettes(pytester):
    pytester.makeconftest("""
        import pytest

        @pytest.fixture
        def wiretape_cassette_dir(request):
            return request.path.parent / "tapes" / request.path.stem
    """)
    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    moved = pytester.path / "tapes" / "test_echo" / "test_echo.wtape"
    assert streams(moved) == (b"hello\n", b"hello\n")
    assert not cassette_of(pytester, "test_echo", "test_echo").exists()
    pytester.runpytest().assert_outcomes(passed=1)  # replays from the moved cassette

    moved.unlink()
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines([f"*{moved} does not exist*"])


def test_a_wiretape_config_that_is_not_a_dict_is_a_clear_error(pytester):
    pytester.makeconftest("""
        import pytest

        @pytest.fixture
        def wiretape_config():
            return "timing=none"
    """)
    pytester.makepyfile(test_echo=ECHO_TEST)
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*wiretape_config fixture must return a dict of settings, not str*"])


def test_a_compressed_cassette_replays_as_the_plain_one(pytester):
    """A cassette converted with ``--compress zstd`` (format 2.0) replays: the
    plugin reads it through the one C++ reader."""
    from wiretape import cli

    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester, "test_echo", "test_echo")
    packed = cassette.with_name("packed.wtape")
    assert cli.main(["convert", "-q", "--compress", "zstd", str(cassette), str(packed)]) == 0
    packed.replace(cassette)
    assert wiretape.SessionReader(str(cassette)).header.version_major == 2
    result = pytester.runpytest()
    result.assert_outcomes(passed=1)
