"""The pytest plugin's several ports, one cassette (issue 25): the marker's
ports= records every device into one session of several channels through
wiretape.Recorder, replays each channel (channel=NAME), and the summary
counts the cassette once. The "real devices" are in-memory loopbacks."""

import wiretape

pytest_plugins = ["pytester"]

PORTS_TEST = """
    import pytest

    @pytest.mark.wiretape(ports={"gps": "type=loopback", "rtk": "type=loopback"})
    def test_two(wiretape_ports):
        assert sorted(wiretape_ports) == ["gps", "rtk"]
        wiretape_ports["gps"].write_all(b"$GPGGA\\n")
        assert wiretape_ports["gps"].read_exactly(7, timeout=5) == b"$GPGGA\\n"
        wiretape_ports["rtk"].write_all(b"RTCM")
        assert wiretape_ports["rtk"].read_exactly(4, timeout=5) == b"RTCM"
"""


def cassette_of(pytester):
    return pytester.path / "recordings" / "test_ports" / "test_two.wtape"


def test_ports_record_into_one_cassette_of_several_channels_then_replay(pytester):
    pytester.makepyfile(test_ports=PORTS_TEST)
    result = pytester.runpytest("--wiretape-record=once")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 recorded*"])
    cassette = cassette_of(pytester)
    reader = wiretape.SessionReader(str(cassette))
    names = {channel.id: channel.name for channel in reader.header.channel_list()}
    assert sorted(names.values()) == ["gps", "rtk"]
    streams = {}
    for record in reader:
        if record.kind in ("tx", "rx"):
            streams.setdefault((names[record.channel], record.kind), b"")
            streams[names[record.channel], record.kind] += record.data
    assert streams == {("gps", "tx"): b"$GPGGA\n", ("gps", "rx"): b"$GPGGA\n",
                       ("rtk", "tx"): b"RTCM", ("rtk", "rx"): b"RTCM"}

    recorded = cassette.read_bytes()
    result = pytester.runpytest()  # no device: each channel replayed
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*1 cassette: 1 replayed*"])
    assert cassette.read_bytes() == recorded

    # It is the recording answering, channel by channel.
    pytester.makepyfile(test_ports=PORTS_TEST.replace('b"RTCM"', 'b"RTCX"'))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)


def test_a_channel_the_cassette_lacks_fails_naming_it(pytester):
    pytester.makepyfile(test_ports=PORTS_TEST)
    pytester.runpytest("--wiretape-record=once").assert_outcomes(passed=1)
    pytester.makepyfile(test_ports=PORTS_TEST.replace('"rtk": "type=loopback"',
                                                      '"imu": "type=loopback"'))
    result = pytester.runpytest()
    result.assert_outcomes(errors=1)  # in the fixture's setup, before the test runs
    result.stdout.fnmatch_lines(["*has no channel 'imu' (its channels: gps, rtk)*"])


def test_bad_channel_name_in_ports_is_refused(pytester):
    pytester.makepyfile(test_ports=PORTS_TEST.replace('"gps"', '"type"', 1))
    result = pytester.runpytest("--wiretape-record=once")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*ports= channel name 'type'*"])
