"""Drift for tools and for several devices: ``wiretape record … --against
OLD --json`` prints one JSON document of the places the device now answers
differently (checked here against an oracle computed from the two
recordings' own records), with the exit status of the report; and a
recording of several devices (channels) is compared channel by channel
with the live device of each channel's name.

The devices are line devices on TCP (firmware_device.FirmwareDevice); the
driver, a real program reached through the shim at fixed device paths,
asks each device for its identity and a reading."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape
from wiretape import _core
from devices import TcpDevice
from firmware_device import MASKED_TIME, FirmwareDevice

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
PATHS = {"a": "/dev/ttyWIRETAPEDRIFTJ0", "b": "/dev/ttyWIRETAPEDRIFTJ1",
         "c": "/dev/ttyWIRETAPEDRIFTJ2"}

# Asks ID? then READ of each device path it is given, in turn.
DRIVER = textwrap.dedent("""
    import os, sys, tty

    def ask(fd, question):
        os.write(fd, question)
        line = b""
        while not line.endswith(b"\\n"):
            chunk = os.read(fd, 1)
            if not chunk:
                sys.exit(3)
            line += chunk

    for path in sys.argv[1:]:
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        ask(fd, b"ID?\\n")
        ask(fd, b"READ\\n")
""")


@pytest.fixture(autouse=True)
def _shim():
    from wiretape.redirect import shim_path

    try:
        shim_path()
    except RuntimeError as missing:
        pytest.skip(f"device-redirecting shim not built: {missing}")


@pytest.fixture()
def driver(tmp_path: Path) -> Path:
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    return script


def record(devices, driver: Path, *args):
    """``wiretape record`` of the driver's session with `devices`: one
    TcpDevice (unnamed), or a dict of channel name to TcpDevice."""
    if isinstance(devices, TcpDevice):
        endpoints, paths = ["--device", devices.options, "--as", PATHS["a"]], [PATHS["a"]]
    else:
        endpoints, paths = [], []
        for name, device in devices.items():
            endpoints += ["--device", f"{name}={device.options}", "--as", f"{name}={PATHS[name]}"]
            paths.append(PATHS[name])
    return subprocess.run([*WIRETAPE, "record", *endpoints, *args, "--", sys.executable,
                           str(driver), *paths], capture_output=True, text=True, timeout=120)


def recorded(result, path: Path) -> Path:
    assert result.returncode == 0, result.stdout + result.stderr
    assert path.exists()
    return path


# --- the oracle: exchanges read off the records, compared through the mask -------------


def exchanges(path: Path, channel: str = ""):
    """Each exchange's (request, response) of a channel: the driver asks a
    line and waits for the answer line, so the n-th tx line and the n-th rx
    line are exchange n."""
    with wiretape.SessionReader(str(path)) as reader:
        ids = {c.name: c.id for c in reader.header.channel_list()}
        records = [r for r in reader if r.channel == ids[channel]]
    streams = {kind: b"".join(bytes(r.data) for r in records if r.kind == kind)
               for kind in ("tx", "rx")}
    lines = {kind: [line + b"\n" for line in data.split(b"\n")[:-1]]
             for kind, data in streams.items()}
    return list(zip(lines["tx"], lines["rx"]))


def masked(line: bytes, masking: bool) -> bytes:
    """MASKED_TIME's key: the time stamp's five digits left out."""
    return line[:-6] + line[-1:] if masking else line


def first_difference(a: bytes, b: bytes, masking: bool) -> int:
    kept = [i for i in range(max(len(a), len(b)))
            if not (masking and len(a) - 6 <= i < len(a) - 1)]
    return next(i for i in kept if i >= len(a) or i >= len(b) or a[i] != b[i])


def oracle(old: Path, new: Path, channels=("",), masking=False):
    places = []
    for channel in channels:
        for number, (stored, now) in enumerate(zip(exchanges(old, channel),
                                                   exchanges(new, channel))):
            for direction, a, b in (("tx", stored[0], now[0]), ("rx", stored[1], now[1])):
                if masked(a, masking) != masked(b, masking):
                    places.append({"channel": channel, "exchange": number,
                                   "direction": direction,
                                   "offset": first_difference(a, b, masking),
                                   "expected": {"hex": a.hex(), "text": a.decode()},
                                   "got": {"hex": b.hex(), "text": b.decode()}})
    return places


def places_of(document):
    keys = ("channel", "exchange", "direction", "offset", "expected", "got")
    return [{key: place[key] for key in keys} for place in document["places"]]


# --- one device ----------------------------------------------------------------------


@pytest.fixture()
def old(tmp_path: Path, driver: Path) -> Path:
    path = tmp_path / "ident.wtape"
    with TcpDevice(respond=FirmwareDevice("1.2", 100)) as device:
        return recorded(record(device, driver, "-o", str(path)), path)


def test_json_lists_every_place_that_drifted_as_the_recordings_say(old, driver, tmp_path):
    new = tmp_path / "now.wtape"
    with TcpDevice(respond=FirmwareDevice("1.3", 500)) as device:
        result = record(device, driver, "--against", str(old), "-o", str(new), "--json")
    assert result.returncode == 1, result.stdout + result.stderr
    document = json.loads(result.stdout)  # the document alone on stdout
    expected = oracle(old, new)
    # without a mask: the firmware (exchange 0) and both time stamps
    assert [place["exchange"] for place in expected] == [0, 1]
    assert places_of(document) == expected
    assert document["count"] == len(expected)
    assert (document["drift"], document["status"], document["updated"]) == (True, 1, False)
    assert (document["stored"], document["now"]) == (str(old), str(new))
    assert all(place["field"] is None for place in document["places"])  # no profile


def test_json_through_a_profile_names_the_frame_and_masks_the_time(old, driver, tmp_path):
    new = tmp_path / "now.wtape"
    with TcpDevice(respond=FirmwareDevice("1.3", 500)) as device:
        result = record(device, driver, "--against", str(old), "-o", str(new), "--json",
                        "--profile", MASKED_TIME)
    assert result.returncode == 1, result.stdout + result.stderr
    document = json.loads(result.stdout)
    expected = oracle(old, new, masking=True)
    assert [(p["exchange"], p["direction"], p["offset"]) for p in expected] == [(0, "rx", 12)]
    assert places_of(document) == expected
    profile = _core.profile_from_spec(MASKED_TIME)
    stored, now = exchanges(old)[0][1], exchanges(new)[0][1]
    assert document["places"][0]["field"] == {
        "name": profile.frame_name("rx", stored),
        "expected": profile.describe("rx", stored), "got": profile.describe("rx", now)}
    assert document["profile"] == MASKED_TIME


def test_json_of_a_device_that_answers_as_recorded_is_exit_0(old, driver, tmp_path):
    with TcpDevice(respond=FirmwareDevice("1.2", 900)) as device:
        result = record(device, driver, "--against", str(old), "--json",
                        "--profile", MASKED_TIME)
    assert result.returncode == 0, result.stdout + result.stderr
    document = json.loads(result.stdout)
    assert (document["drift"], document["count"], document["places"]) == (False, 0, [])


def test_json_without_against_is_exit_2(tmp_path, driver):
    with TcpDevice() as device:
        result = record(device, driver, "-o", str(tmp_path / "x.wtape"), "--json")
    assert result.returncode == 2
    assert "--json goes with --against" in result.stderr


# --- several devices -----------------------------------------------------------------


@pytest.fixture()
def old_pair(tmp_path: Path, driver: Path) -> Path:
    path = tmp_path / "pair.wtape"
    with TcpDevice(respond=FirmwareDevice("1.2", 100)) as a, \
            TcpDevice(respond=FirmwareDevice("2.0", 100)) as b:
        return recorded(record({"a": a, "b": b}, driver, "-o", str(path)), path)


def test_each_channel_is_compared_with_the_live_device_of_its_name(old_pair, driver, tmp_path):
    new = tmp_path / "pair.now.wtape"
    # the same answers (clocks too) but b's firmware
    def now(firmware_b):
        return (TcpDevice(respond=FirmwareDevice("1.2", 100)),
                TcpDevice(respond=FirmwareDevice(firmware_b, 100)))

    a, b = now("2.1")
    with a, b:
        as_json = record({"a": a, "b": b}, driver, "--against", str(old_pair), "-o", str(new),
                         "--json")
    a, b = now("2.1")
    with a, b:
        report = record({"b": b, "a": a}, driver, "--against", str(old_pair),
                        "-o", str(tmp_path / "report.wtape"))
    assert as_json.returncode == 1, as_json.stdout + as_json.stderr
    expected = oracle(old_pair, new, channels=("a", "b"))
    assert [(p["channel"], p["exchange"], p["offset"]) for p in expected] == [("b", 0, 12)]
    assert places_of(json.loads(as_json.stdout)) == expected
    # the report names the channel; the flags' order does not pair them
    assert report.returncode == 1, report.stdout + report.stderr
    assert "1 divergence by exchange" in report.stdout
    assert "channel b exchange 0 response (rx) differs at byte 12" in report.stdout


def test_a_channel_without_its_live_device_is_exit_2_naming_it(old_pair, driver):
    with TcpDevice() as a:
        result = record({"a": a}, driver, "--against", str(old_pair))
        assert a.connections == 0  # refused before anything ran
    assert result.returncode == 2, result.stdout + result.stderr
    assert "its channel 'b' has no live device here" in result.stderr
    assert "--device b=DEVICE" in result.stderr


def test_a_live_device_of_no_channel_of_old_is_exit_2_naming_it(old_pair, driver, tmp_path):
    with TcpDevice() as a, TcpDevice() as b, TcpDevice() as c:
        extra = record({"a": a, "b": b, "c": c}, driver, "--against", str(old_pair))
        unnamed = record(a, driver, "--against", str(old_pair))
        assert a.connections == b.connections == c.connections == 0
    assert extra.returncode == 2, extra.stdout + extra.stderr
    assert "it has no channel 'c'" in extra.stderr
    assert unnamed.returncode == 2, unnamed.stdout + unnamed.stderr
    assert "its channel 'a' has no live device here" in unnamed.stderr


def test_several_devices_against_the_recording_of_one_is_exit_2(old, driver):
    with TcpDevice() as a, TcpDevice() as b:
        result = record({"a": a, "b": b}, driver, "--against", str(old))
    assert result.returncode == 2, result.stdout + result.stderr
    assert "it is the recording of one device" in result.stderr
