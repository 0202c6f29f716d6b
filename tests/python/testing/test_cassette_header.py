"""Cassettes recorded by the pytest plugin name no directory of the machine
that recorded them: the header's option string names the cassette itself
(``log=<cassette name>``), not the temporary file it was recorded to."""

import os

import wiretape
from wiretape.testing.cassette import publish_recording

pytest_plugins = ["pytester"]

TESTS = """
    import serial
    import wiretape

    def test_port(wiretape_port):
        wiretape_port.write_all(b"hello\\n")
        assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"

    def test_options(wiretape_options):
        port = wiretape.open_port(wiretape_options)
        port.write_all(b"hi\\n")
        assert port.read_exactly(3, timeout=5) == b"hi\\n"
        port.close()

    def test_url(wiretape_url):
        with serial.serial_for_url(wiretape_url, timeout=5) as port:
            port.write(b"yo\\n")
            assert port.read(3) == b"yo\\n"
"""


def test_recorded_cassettes_hold_no_absolute_temporary_path(pytester):
    pytester.makepyfile(test_cassettes=TESTS)
    result = pytester.runpytest("--wiretape-record=once", "--wiretape-device=type=loopback")
    result.assert_outcomes(passed=3)
    directory = pytester.path / "recordings" / "test_cassettes"
    for test in ("test_port", "test_options", "test_url"):
        cassette = directory / f"{test}.wtape"
        header = wiretape.SessionReader(str(cassette)).header
        assert header.port_options.startswith("type=loopback"), header.port_options
        assert f"log={test}.wtape" in header.port_options, header.port_options
        text = header.metadata_json
        assert str(pytester.path) not in text, text
        assert os.sep + "tmp" not in text and ".recording-" not in text, text
    assert not list(directory.glob("*.recording-*")) and not list(directory.glob("*.header"))
    # ... and they replay.
    result = pytester.runpytest()
    result.assert_outcomes(passed=3)


def test_publishing_keeps_every_record_and_the_rest_of_the_header(tmp_path):
    recording = tmp_path / "t.wtape.recording-1"
    port = wiretape.open_port(f"type=loopback,log={recording},meta_robot=r2")
    port.write_all(b"abc")
    assert port.read_exactly(3, timeout=5) == b"abc"
    port.close()
    before = wiretape.SessionReader(str(recording))
    records = [(r.kind, r.t_ns, r.data) for r in before]
    cassette = tmp_path / "t.wtape"
    publish_recording(recording, cassette)
    assert not recording.exists()
    after = wiretape.SessionReader(str(cassette))
    assert [(r.kind, r.t_ns, r.data) for r in after] == records
    assert after.header.port_options == "type=loopback,log=t.wtape,meta_robot=r2"
    for field in ("start_utc", "host", "capture", "port_type", "wiretape_version", "metadata"):
        assert getattr(after.header, field) == getattr(before.header, field), field


def test_publishing_a_recording_that_names_no_file_moves_it_as_it_is(tmp_path):
    recording = tmp_path / "r.wtape.recording-1"
    with wiretape.SessionWriter(str(recording), port_options="type=loopback") as writer:
        writer.write("tx", 1, b"x")
    data = recording.read_bytes()
    publish_recording(recording, tmp_path / "r.wtape")
    assert (tmp_path / "r.wtape").read_bytes() == data
