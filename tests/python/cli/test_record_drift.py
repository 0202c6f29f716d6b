"""Drift (issue 41, DESIGN §28): ``wiretape record … --against OLD
[--profile P] [--update]`` runs the driver on the device, then reports
every place the device now answers differently from the stored recording,
through the profile's masks: exit 1 on drift, 0 when it answers as
recorded; ``--update`` replaces OLD only when the run passed.

The device is a small line device on TCP whose identity answer carries a
firmware string and a time stamp; the driver (a real program, reached
through the shim at a fixed device path) asks for it and for a reading.
A firmware that changed is drift; a time stamp that changed is drift only
when no profile masks it. Last, examples/hokuyo's simulator given another
firmware string drifts by SCIP frames (the profile from OLD's metadata)."""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape
from devices import TcpDevice
from firmware_device import MASKED_TIME, FirmwareDevice

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
DEVICE_PATH = "/dev/ttyWIRETAPEDRIFT0"

DRIVER = textwrap.dedent("""
    import os, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)

    def ask(question):
        os.write(fd, question)
        line = b""
        while not line.endswith(b"\\n"):
            chunk = os.read(fd, 1)
            if not chunk:
                sys.exit(3)
            line += chunk
        return line

    ask(b"ID?\\n")
    ask(b"READ\\n")
    sys.exit(int(sys.argv[2]) if len(sys.argv) > 2 else 0)
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


def record(device: TcpDevice, driver: Path, *args, status: int = 0):
    """``wiretape record`` of the driver's session with `device`."""
    return subprocess.run(
        [*WIRETAPE, "record", "--device", device.options, "--as", DEVICE_PATH, *args,
         "--", sys.executable, str(driver), DEVICE_PATH, str(status)],
        capture_output=True, text=True, timeout=120)


@pytest.fixture()
def old(tmp_path: Path, driver: Path) -> Path:
    """The stored recording: firmware 1.2, its clock from 100."""
    path = tmp_path / "ident.wtape"
    with TcpDevice(respond=FirmwareDevice("1.2", 100)) as device:
        result = record(device, driver, "-o", str(path))
    assert result.returncode == 0, result.stdout + result.stderr
    return path


def rx_of(path: Path) -> bytes:
    with wiretape.SessionReader(str(path)) as reader:
        return b"".join(bytes(r.data) for r in reader if r.kind == "rx")


def test_a_masked_field_that_changes_is_not_drift(old, driver, tmp_path):
    with TcpDevice(respond=FirmwareDevice("1.2", 500)) as device:
        masked = record(device, driver, "--against", str(old), "--profile", MASKED_TIME)
        unmasked = record(device, driver, "--against", str(old), "-o",
                          str(tmp_path / "unmasked.wtape"))
    assert masked.returncode == 0, masked.stdout + masked.stderr
    assert "no drift" in masked.stdout
    # The same answers without the mask: the time stamps differ.
    assert unmasked.returncode == 1, unmasked.stdout + unmasked.stderr
    assert "drift: the device now answers differently" in unmasked.stdout
    assert "exchange 0 response (rx) differs at byte" in unmasked.stdout


def test_a_changed_firmware_is_drift_named_where_it_is(old, driver, tmp_path):
    stored = old.read_bytes()
    with TcpDevice(respond=FirmwareDevice("1.3", 500)) as device:
        result = record(device, driver, "--against", str(old), "--profile", MASKED_TIME)
    assert result.returncode == 1, result.stdout + result.stderr
    report = result.stdout
    assert f"drift: the device now answers differently from {old}" in report
    # exchange 0 (ID?) answers otherwise, at the firmware's last digit;
    # exchange 1 (READ) differs only by its masked time stamp: not listed.
    assert "1 divergence by exchange" in report
    assert "exchange 0 response (rx) differs at byte 12" in report
    assert "exchange 1" not in report
    new = tmp_path / "ident.new.wtape"
    assert b"FW1.3" in rx_of(new)
    assert old.read_bytes() == stored  # no --update: OLD as it was


def test_the_stored_recordings_profile_is_the_default(tmp_path, driver):
    old = tmp_path / "meta.wtape"
    with TcpDevice(respond=FirmwareDevice("1.2", 100)) as device:
        made = record(device, driver, "-o", str(old), "--meta", f"profile={MASKED_TIME}")
        assert made.returncode == 0, made.stdout + made.stderr
        device.respond = FirmwareDevice("1.2", 900)
        result = record(device, driver, "--against", str(old))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "no drift" in result.stdout
    # and the new recording keeps it, for a replay through the same masks
    with wiretape.SessionReader(str(tmp_path / "meta.new.wtape")) as reader:
        assert reader.header.metadata.get("profile") == MASKED_TIME


def test_update_replaces_old_only_when_the_run_passed(old, driver, tmp_path):
    stored = old.read_bytes()
    new = tmp_path / "new.wtape"
    with TcpDevice(respond=FirmwareDevice("1.3", 500)) as device:
        failed = record(device, driver, "--against", str(old), "--profile", MASKED_TIME,
                        "--update", "-o", str(new), status=4)
        assert failed.returncode == 4, failed.stdout + failed.stderr
        assert "drift" in failed.stdout  # reported all the same
        assert f"{old} left as it was" in failed.stderr
        assert old.read_bytes() == stored

        passed = record(device, driver, "--against", str(old), "--profile", MASKED_TIME,
                        "--update", "-o", str(new))
    assert passed.returncode == 1, passed.stdout + passed.stderr  # it drifted
    assert f"{old} updated" in passed.stderr
    assert old.read_bytes() == new.read_bytes()
    assert b"FW1.3" in rx_of(old)
    assert not list(tmp_path.glob("*.update"))  # no partial copy left


def test_against_a_recording_of_another_device_type_is_exit_2(tmp_path, driver):
    other = tmp_path / "serial.wtape"
    with wiretape.SessionWriter(str(other), port_type="serial") as writer:
        writer.write("tx", 0, b"ID?\n")
        writer.write("rx", 1_000_000, b"ID ACME FW1.2 T=00001\n")
    with TcpDevice(respond=FirmwareDevice("1.2", 100)) as device:
        result = record(device, driver, "--against", str(other))
        assert device.connections == 0  # refused before anything ran
    assert result.returncode == 2, result.stdout + result.stderr
    assert "of type 'serial'" in result.stderr and "of type 'tcp'" in result.stderr
    assert not (tmp_path / "serial.new.wtape").exists()


@pytest.mark.parametrize("flag", [["--update"], ["--profile", "lines"]])
def test_drift_flags_without_against_are_exit_2(tmp_path, driver, flag):
    with TcpDevice() as device:
        result = record(device, driver, "-o", str(tmp_path / "x.wtape"), *flag)
    assert result.returncode == 2
    assert f"{flag[0]} goes with --against" in result.stderr


def test_against_a_missing_file_is_exit_3(tmp_path, driver):
    with TcpDevice() as device:
        result = record(device, driver, "--against", str(tmp_path / "none.wtape"))
    assert result.returncode == 3
    assert "none.wtape: no such file" in result.stderr


def test_a_serial_device_exported_over_rfc2217_is_the_same_device_type(tmp_path, driver):
    # OLD recorded through RFC 2217 against a local serial device: no type
    # error (exit 2); the missing device itself is the failure (exit 3).
    exported = tmp_path / "exported.wtape"
    with wiretape.SessionWriter(str(exported), port_type="rfc2217") as writer:
        writer.write("tx", 0, b"ID?\n")
    result = subprocess.run(
        [*WIRETAPE, "record", "--device", str(tmp_path / "ttyMissing"), "--against",
         str(exported), "--", sys.executable, str(driver), str(tmp_path / "ttyMissing")],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 3, result.stdout + result.stderr
    assert "of type" not in result.stderr


# --- the Hokuyo simulator (examples/hokuyo) with another firmware -------------------

HOKUYO_SIM = Path(__file__).resolve().parents[3] / "examples" / "hokuyo" / "sim"

# The simulator as it is, its URG-04LX's firmware string given first.
SIM_WITH_FIRMWARE = textwrap.dedent(f"""
    import runpy, sys
    sys.path.insert(0, {str(HOKUYO_SIM)!r})
    import scip_sim
    scip_sim.MODELS["urg04lx"]["firm"] = sys.argv.pop(1)
    runpy.run_path({str(HOKUYO_SIM / "__main__.py")!r}, run_name="__main__")
""")

# A SCIP 2.0 driver: version and parameters, each reply up to its blank line.
SCIP_DRIVER = textwrap.dedent("""
    import os, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    for command in (b"VV\\n", b"PP\\n"):
        os.write(fd, command)
        reply = b""
        while not reply.endswith(b"\\n\\n"):
            chunk = os.read(fd, 256)
            if not chunk:
                sys.exit(3)
            reply += chunk
""")


class HokuyoSimulator:
    """examples/hokuyo's simulator on TCP with the firmware string given."""

    def __init__(self, tmp_path: Path, firmware: str):
        script = tmp_path / "sim_with_firmware.py"
        script.write_text(SIM_WITH_FIRMWARE)
        self.child = subprocess.Popen(
            [sys.executable, str(script), firmware, "--scip2", "--listen", "127.0.0.1:0"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        ready = self.child.stdout.readline().split()  # blocks until it listens
        assert ready[:1] == ["ready"], (ready, self.child.stderr.read())
        host, _, port = ready[1].split("=", 1)[1].rpartition(":")
        self.options = f"type=tcp,host={host},port={port}"

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.child.terminate()
        self.child.wait(30)
        self.child.stdout.close()
        self.child.stderr.close()


def test_the_hokuyo_simulator_with_another_firmware_drifts_by_scip_frames(tmp_path):
    driver = tmp_path / "scip_driver.py"
    driver.write_text(SCIP_DRIVER)
    old = tmp_path / "urg.wtape"

    def record_scip(simulator, *args):
        return subprocess.run(
            [*WIRETAPE, "record", "--device", simulator.options, "--as", DEVICE_PATH, *args,
             "--", sys.executable, str(driver), DEVICE_PATH],
            capture_output=True, text=True, timeout=120)

    # a simulator powered on for each recording, as the device on a bench
    with HokuyoSimulator(tmp_path, "3.1.04(02/Aug./2007)") as simulator:
        made = record_scip(simulator, "-o", str(old), "--meta", "profile=scip")
    assert made.returncode == 0, made.stdout + made.stderr
    with HokuyoSimulator(tmp_path, "3.1.04(02/Aug./2007)") as simulator:
        same = record_scip(simulator, "--against", str(old))
    assert same.returncode == 0, same.stdout + same.stderr
    assert "no drift" in same.stdout and "through profile scip" in same.stdout

    with HokuyoSimulator(tmp_path, "3.1.05(09/Dec./2026)") as simulator:
        newer = record_scip(simulator, "--against", str(old))
    assert newer.returncode == 1, newer.stdout + newer.stderr
    assert "1 divergence by exchange" in newer.stdout
    assert "exchange 0 response (rx) differs at byte" in newer.stdout
    assert "3.1.05" in newer.stdout  # the new firmware shown where it differs
