"""The plugin on the real device (issue 41, DESIGN §28): ``--wiretape-drift``
fails a test whose device now answers differently from its cassette,
through the profile's masks; ``--wiretape-live`` keeps a failing test's
recording next to the report and prints the one command that replays it
(``--wiretape-cassette=FILE``), which replays it.

The device is firmware_device's line device on TCP, in this process."""

import re

import pytest

import wiretape
from devices import TcpDevice
from firmware_device import FirmwareDevice

pytest_plugins = ["pytester"]

# The marker declares the profile: framing by lines, the time stamp masked.
IDENT_TEST = """
    import pytest

    @pytest.mark.wiretape(framing="delimiter:0a", ignore="-6:5")
    def test_ident(wiretape_port):
        wiretape_port.write_all(b"ID?\\n")
        ident = wiretape_port.read_until(b"\\n", timeout=5)
        assert ident.startswith(b"ID ACME FW"), ident
        wiretape_port.write_all(b"READ\\n")
        assert wiretape_port.read_until(b"\\n", timeout=5).startswith(b"VAL 17")
        assert {check}
"""

# Passes on any firmware: only drift tells a firmware change.
ANY_FIRMWARE = IDENT_TEST.format(check="True")
# A driver that knows firmware 1.2 only.
FIRMWARE_12 = IDENT_TEST.format(check='b"FW1.2" in ident, ident')


@pytest.fixture()
def device():
    with TcpDevice(respond=FirmwareDevice("1.2", 100)) as running:
        yield running


def device_flag(device):
    return f"--wiretape-device={device.options}"


def cassette_of(pytester):
    return pytester.path / "recordings" / "test_ident" / "test_ident.wtape"


def kept_of(pytester):
    return pytester.path / "wiretape-failures" / "test_ident" / "test_ident.wtape"


def record_cassette(pytester, device):
    pytester.makepyfile(test_ident=ANY_FIRMWARE)
    pytester.runpytest("--wiretape-record=once", device_flag(device)).assert_outcomes(passed=1)
    assert cassette_of(pytester).exists()


def test_drift_through_the_masks_passes_and_keeps_nothing(pytester, device):
    record_cassette(pytester, device)
    stored = cassette_of(pytester).read_bytes()
    device.respond = FirmwareDevice("1.2", 700)  # only the masked time stamps differ
    result = pytester.runpytest("--wiretape-drift", device_flag(device))
    result.assert_outcomes(passed=1)
    assert cassette_of(pytester).read_bytes() == stored
    assert not kept_of(pytester).exists()


def test_a_changed_firmware_fails_the_test_with_where(pytester, device):
    record_cassette(pytester, device)
    stored = cassette_of(pytester).read_bytes()
    device.respond = FirmwareDevice("1.3", 700)
    result = pytester.runpytest("--wiretape-drift", device_flag(device))
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*wiretape drift: the device now answers differently from*test_ident.wtape*",
        "*exchange 0 response (rx) differs at byte 12*",
        "*replay it: pytest test_ident.py::test_ident --wiretape-cassette=*",
    ])
    assert "exchange 1" not in result.stdout.str()  # its time stamp is masked
    assert cassette_of(pytester).read_bytes() == stored
    kept = kept_of(pytester)
    assert b"FW1.3" in b"".join(r.data for r in wiretape.SessionReader(str(kept))
                                if r.kind == "rx")


def test_drift_without_a_cassette_names_the_command_that_records_it(pytester, device):
    pytester.makepyfile(test_ident=ANY_FIRMWARE)
    result = pytester.runpytest("--wiretape-drift", device_flag(device))
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*--wiretape-drift compares with the cassette*",
                                 "*pytest --wiretape-record=once*"])


def test_a_failing_live_test_keeps_its_recording_and_the_command_replays_it(pytester, device):
    pytester.makepyfile(test_ident=FIRMWARE_12)
    pytester.runpytest("--wiretape-live", device_flag(device)).assert_outcomes(passed=1)
    assert not kept_of(pytester).exists()  # a passing live test keeps nothing

    device.respond = FirmwareDevice("1.3", 700)  # the device the driver fails on
    result = pytester.runpytest("--wiretape-live", device_flag(device))
    result.assert_outcomes(failed=1)
    assert not cassette_of(pytester).exists()  # live touches no cassette
    kept = kept_of(pytester)
    assert kept.exists()
    output = result.stdout.str()
    commands = re.findall(r"^    (pytest test_ident\.py::test_ident --wiretape-cassette=\S+)$",
                          output, re.M)
    assert commands, output  # in the end-of-run summary
    assert commands[0].endswith(str(kept))

    # The printed command, without the device: the same failure, replayed.
    argv = commands[0].split()[1:]
    replayed = pytester.runpytest(*argv)
    replayed.assert_outcomes(failed=1)
    replayed.stdout.fnmatch_lines(["*assert*FW1.3*"])


def test_the_recording_is_kept_next_to_the_junit_report(pytester, device):
    pytester.makepyfile(test_ident=FIRMWARE_12)
    device.respond = FirmwareDevice("1.3", 700)
    report = pytester.path / "reports" / "junit.xml"
    result = pytester.runpytest("--wiretape-live", device_flag(device), f"--junitxml={report}")
    result.assert_outcomes(failed=1)
    assert (report.parent / "wiretape-failures" / "test_ident" / "test_ident.wtape").exists()


def test_wiretape_failures_names_where_the_recording_is_kept(pytester, device, tmp_path):
    pytester.makepyfile(test_ident=FIRMWARE_12)
    device.respond = FirmwareDevice("1.3", 700)
    chosen = tmp_path / "kept"
    result = pytester.runpytest("--wiretape-live", device_flag(device),
                                f"--wiretape-failures={chosen}",
                                f"--junitxml={pytester.path / 'junit.xml'}")
    result.assert_outcomes(failed=1)
    assert (chosen / "test_ident" / "test_ident.wtape").exists()
    assert not (pytester.path / "wiretape-failures").exists()
