"""The pytest record mode new_episodes (issue 26): with several ports (the
marker's ports=) the episode is a port. The channels the cassette holds are
replayed (their devices are never connected to), the ports it lacks are
recorded and appended to it when the test passes; a cassette of one port is
recorded as under once. The "real devices" are small TCP servers that answer
in upper case and count their connections (devices.TcpDevice)."""

import os
import re

import pytest

import wiretape
from devices import TcpDevice
from multichannel_sessions import records_with_channels

pytest_plugins = ["pytester"]

PORTS_TEST = """
    import pytest

    @pytest.mark.wiretape(ports={ports})
    def test_ports(wiretape_ports):
        for name, port in wiretape_ports.items():
            port.write_all(name.encode() + b" {said}")
            expected = (name.encode() + b" {said}").upper()
            assert port.read_exactly(len(expected), timeout=5) == expected
        {end}
"""


def ports_test(devices, said="hello", end="pass"):
    ports = "{" + ", ".join(f"{name!r}: {device.options!r}" for name, device in devices.items()) \
        + "}"
    return PORTS_TEST.format(ports=ports, said=said, end=end)


def cassette_of(pytester):
    return pytester.path / "recordings" / "test_episodes" / "test_ports.wtape"


def leftovers(pytester):
    """Files next to the cassette that are not cassettes (partial recordings)."""
    return [path.name for path in cassette_of(pytester).parent.iterdir()
            if path.suffix != ".wtape"]


@pytest.fixture
def devices():
    with TcpDevice() as a, TcpDevice() as b:
        yield {"a": a, "b": b}


@pytest.fixture
def recorded_a(pytester, devices):
    """A cassette of the port a alone (recorded once, under once)."""
    pytester.makepyfile(test_episodes=ports_test({"a": devices["a"]}))
    pytester.runpytest("--wiretape-record=once").assert_outcomes(passed=1)
    assert devices["a"].connections == 1
    return cassette_of(pytester)


def channel_names(path):
    return {channel.id: channel.name
            for channel in wiretape.SessionReader(str(path)).header.channel_list()}


def test_new_episodes_replays_the_channels_held_and_appends_the_port_lacking(
        pytester, devices, recorded_a):
    before = records_with_channels(recorded_a)
    header_before = wiretape.SessionReader(str(recorded_a)).header
    pytester.makepyfile(test_episodes=ports_test(devices))

    result = pytester.runpytest("--wiretape-record=new_episodes")

    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 appended*"])
    assert devices["a"].connections == 1  # replayed: its device never connected to
    assert devices["b"].connections == 1  # recorded
    assert channel_names(recorded_a) == {0: "a", 1: "b"}
    after = records_with_channels(recorded_a)
    # a's records byte for byte, at their times and in their order
    assert [r for r in after if r[3] == 0] == before
    b_records = [r for r in after if r[3] == 1]
    assert b"".join(r[2] for r in b_records if r[1] == "tx") == b"b hello"
    assert b"".join(r[2] for r in b_records if r[1] == "rx") == b"B HELLO"
    assert [r[0] for r in after] == sorted(r[0] for r in after)  # merged in time order
    header = wiretape.SessionReader(str(recorded_a)).header
    b_channel = header.find_channel("b")
    assert b_channel.port_type == "tcp" and f"port={devices['b'].port}" in b_channel.port_options
    assert header.find_channel("a") == header_before.find_channel("a")
    assert header.start_utc == header_before.start_utc
    assert header.metadata == header_before.metadata
    assert len(header.edits) == len(header_before.edits) + 1
    assert header.edits[-1].startswith("appended channel b at ")
    assert "new_episodes" in header.edits[-1]
    # b's times are moved onto the replay's clock by what the note says: the
    # replay of a opened first, so b's open is that much after time 0.
    shift = int(re.search(r"moved by (-?\d+) ns", header.edits[-1]).group(1))
    assert shift > 0
    assert b_records[0][:2] == (shift, "open")
    assert leftovers(pytester) == []

    # The next run replays both channels, in the default mode, with no device.
    appended = recorded_a.read_bytes()
    result = pytester.runpytest()
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 replayed*"])
    assert (devices["a"].connections, devices["b"].connections) == (1, 1)
    assert recorded_a.read_bytes() == appended

    # new_episodes again: nothing lacks, nothing is appended.
    result = pytester.runpytest("--wiretape-record=new_episodes")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 replayed*"])
    assert recorded_a.read_bytes() == appended


def test_a_failing_test_appends_nothing(pytester, devices, recorded_a):
    before = recorded_a.read_bytes()
    pytester.makepyfile(test_episodes=ports_test(devices, end="assert False, 'driver bug'"))

    result = pytester.runpytest("--wiretape-record=new_episodes")

    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 not kept*"])
    assert devices["b"].connections == 1
    assert recorded_a.read_bytes() == before
    assert leftovers(pytester) == []


def test_a_mismatch_on_a_replayed_channel_fails_and_is_not_recorded(
        pytester, devices, recorded_a):
    before = recorded_a.read_bytes()
    pytester.makepyfile(test_episodes=ports_test(devices, said="howdy"))

    result = pytester.runpytest("--wiretape-record=new_episodes")

    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*new_episodes replays the channels the cassette holds (a)*"
                                 "never re-recorded*",
                                 "*--wiretape-record=rewrite*"])
    assert devices["a"].connections == 1  # not re-recorded
    assert recorded_a.read_bytes() == before
    assert leftovers(pytester) == []


def test_a_missing_cassette_of_several_ports_is_recorded_as_under_once(pytester, devices):
    pytester.makepyfile(test_episodes=ports_test(devices))
    result = pytester.runpytest("--wiretape-record=new_episodes")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 recorded*"])
    assert (devices["a"].connections, devices["b"].connections) == (1, 1)
    assert sorted(channel_names(cassette_of(pytester)).values()) == ["a", "b"]


ONE_PORT_TEST = """
    def test_ports(wiretape_port):
        wiretape_port.write_all(b"hello")
        assert wiretape_port.read_exactly(5, timeout=5) == b"HELLO"
"""


def test_a_cassette_of_one_port_is_under_new_episodes_as_under_once(pytester, devices):
    pytester.makepyfile(test_episodes=ONE_PORT_TEST)
    device = f"--wiretape-device={devices['a'].options}"
    result = pytester.runpytest("--wiretape-record=new_episodes", device)
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 recorded*"])
    recorded = cassette_of(pytester).read_bytes()

    result = pytester.runpytest("--wiretape-record=new_episodes", device)
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 replayed*"])
    assert devices["a"].connections == 1
    assert cassette_of(pytester).read_bytes() == recorded


def test_ports_on_a_cassette_of_one_port_are_refused_naming_rewrite(pytester, devices):
    pytester.makepyfile(test_episodes=ONE_PORT_TEST)
    pytester.runpytest("--wiretape-record=once",
                       f"--wiretape-device={devices['a'].options}").assert_outcomes(passed=1)
    before = cassette_of(pytester).read_bytes()
    pytester.makepyfile(test_episodes=ports_test(devices))
    result = pytester.runpytest("--wiretape-record=new_episodes")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*is a session of one port*--wiretape-record=rewrite*"])
    assert cassette_of(pytester).read_bytes() == before
    assert devices["b"].connections == 0


def test_new_episodes_in_the_marker(pytester, devices, recorded_a):
    source = ports_test(devices).replace("ports={", "record='new_episodes', ports={")
    pytester.makepyfile(test_episodes=source)
    pytester.runpytest().assert_outcomes(passed=1)
    assert channel_names(recorded_a) == {0: "a", 1: "b"}
    assert devices["a"].connections == 1


def test_help_lists_new_episodes(pytester):
    result = pytester.runpytest("--help")
    result.stdout.fnmatch_lines(["*--wiretape-record*", "*new_episodes*"])
    assert "new_episodes" in os.linesep.join(result.stdout.lines)


def test_new_episodes_in_the_ini(pytester, devices, recorded_a):
    pytester.makeini("[pytest]\nwiretape_record = new_episodes\n")
    pytester.makepyfile(test_episodes=ports_test(devices))
    result = pytester.runpytest()
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 appended*"])
    assert channel_names(recorded_a) == {0: "a", 1: "b"}
    assert devices["a"].connections == 1
