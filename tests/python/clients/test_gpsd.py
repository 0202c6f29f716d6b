"""A real client: gpsd on a replayed NMEA stream (DESIGN §12: a virtual
device a program that drops root, changes speeds and flushes can use).
gpspipe -w must show the recorded fix. Skipped, loudly, without gpsd and
gpspipe (Debian: gpsd gpsd-clients)."""

import json
import os
import select
import shutil
import socket
import subprocess
import sys
import time

import pytest

from wiretape import _core, bridge, scaled_clock

from devices import wait_until

DEADLINE = 20.0
LATITUDE = 48.1173
LONGITUDE = 11.5167

pytestmark = [
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="gpsd test: Linux only"),
    pytest.mark.skipif(shutil.which("gpsd") is None or shutil.which("gpspipe") is None,
                       reason="SKIPPED LOUDLY: gpsd/gpspipe not installed "
                              "(apt-get install gpsd gpsd-clients)"),
]


def sentence(body):
    checksum = 0
    for byte in body.encode():
        checksum ^= byte
    return f"${body}*{checksum:02X}\r\n".encode()


def nmea_fix(second):
    hhmmss = f"1235{second % 60:02d}"
    return (sentence(f"GPGGA,{hhmmss}.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,") +
            sentence(f"GPRMC,{hhmmss}.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W"))


def write_nmea_recording(path, seconds=30):
    writer = _core.SessionWriter(str(path), capture="wire",
                                 port_options="type=serial,device=/dev/ttyGPS", port_type="serial")
    writer.write("open", 0, b"{}")
    for tick in range(seconds * 5):  # 5 Hz
        writer.write("rx", tick * 200_000_000, nmea_fix(tick // 5))
    writer.close()
    return path


def free_port():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


# --speed K (DESIGN §22): gpsd on a clock K times faster and the replay's
# timing with it read the same fixes.
@pytest.mark.parametrize("speed", [1.0, 10.0], ids=["speed1", "speed10"])
def test_gpsd_reads_the_recorded_fixes_from_a_replayed_pty(tmp_path, speed):
    recording = write_nmea_recording(tmp_path / "nmea.wtape")
    link = str(tmp_path / "ttyGPS")
    port = free_port()
    handle = bridge.serve_replay(recording, pty=link,
                                 replay_options="timing=session,check=off,unused=ignore,"
                                                f"speed={speed!r}",
                                 quiet=True)
    gpsd = gpspipe = None
    try:
        pty = handle.pty_path
        # -b: read-only (no probing writes); -n: open the device at once.
        gpsd = subprocess.Popen(["gpsd", "-N", "-n", "-b", "-S", str(port),
                                 "-F", str(tmp_path / "gpsd.sock"), pty],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                env=scaled_clock.environment(speed))
        wait_until(lambda: gpsd.poll() is not None or _listening(port), DEADLINE,
                   "gpsd to listen")
        assert gpsd.poll() is None, gpsd.stderr.read().decode(errors="replace")
        gpspipe = subprocess.Popen(["gpspipe", "-w", f"127.0.0.1:{port}"],
                                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        fix = None
        lines = []
        end = time.monotonic() + DEADLINE
        buffered = b""
        while fix is None and time.monotonic() < end:
            ready, _, _ = select.select([gpspipe.stdout], [], [], end - time.monotonic())
            if not ready:
                break
            chunk = os.read(gpspipe.stdout.fileno(), 65536)
            if not chunk:
                break
            buffered += chunk
            *complete, buffered = buffered.split(b"\n")
            for line in complete:
                lines.append(line)
                try:
                    report = json.loads(line)
                except ValueError:
                    continue
                if report.get("class") == "TPV" and "lat" in report:
                    fix = report
        assert fix is not None, b"\n".join(lines[-10:]).decode(errors="replace")
        assert fix["lat"] == pytest.approx(LATITUDE, abs=1e-3)
        assert fix["lon"] == pytest.approx(LONGITUDE, abs=1e-3)
    finally:
        for child in (gpspipe, gpsd):
            if child is not None and child.poll() is None:
                child.terminate()
                try:
                    child.wait(timeout=DEADLINE)
                except subprocess.TimeoutExpired:
                    child.kill()
                    child.wait()
        handle.stop()
        assert handle.wait(DEADLINE)


def _listening(port):
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            return True
    except OSError:
        return False


# Every fix delivered (DESIGN §12): a proxy recording of gpsd holds the
# flushes gpsd made on open and while it hunted for the speed, and how many
# it makes depends on timing (two made back to back also reach the pty as
# one). The replay must not hold the fixes for good on a flush gpsd does not
# make again: each recorded fix must reach gpspipe. `make soak` runs this
# WIRETAPE_GPSD_REPEAT times (default once).
FIXES = 10
RECORDED_FLUSHES = 40  # a gpsd that hunted longer than this one will: more than it makes
GPSD_CLIENT = b'{"peer":"pty","role":"control"}'


def fix_time(index):
    return f"12:35:{index:02d}"


def write_gpsd_proxy_recording(path):
    writer = _core.SessionWriter(str(path), capture="wire",
                                 port_options="type=serial,device=/dev/ttyGPS", port_type="serial")
    writer.write("open", 0, b"{}")
    writer.write("client_connect", 1_000_000, GPSD_CLIENT)
    for flush in range(RECORDED_FLUSHES):
        writer.write("flush_input", 2_000_000 + flush * 1_000, b"{}")
    # One fix a second apart in NMEA time, 200 ms apart on the wire, and a
    # last one whose arrival ends the cycle before it (gpsd reports a cycle
    # when the next begins).
    for index in range(FIXES + 1):
        writer.write("rx", 100_000_000 + index * 200_000_000, nmea_fix(index))
    writer.close()
    return path


def fix_times_reported(port, expected):
    """The fix times gpspipe -w reports until `expected` are all seen or the
    deadline passes."""
    gpspipe = subprocess.Popen(["gpspipe", "-w", f"127.0.0.1:{port}"],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    seen = set()
    try:
        end = time.monotonic() + DEADLINE
        buffered = b""
        while not expected <= seen and time.monotonic() < end:
            ready, _, _ = select.select([gpspipe.stdout], [], [], end - time.monotonic())
            if not ready:
                break
            chunk = os.read(gpspipe.stdout.fileno(), 65536)
            if not chunk:
                break
            buffered += chunk
            *complete, buffered = buffered.split(b"\n")
            for line in complete:
                try:
                    report = json.loads(line)
                except ValueError:
                    continue
                if report.get("class") == "TPV" and "lat" in report and "time" in report:
                    # "2094-03-23T12:35:07.000Z" (gpsd's century guess aside)
                    seen.add(report["time"].split("T")[1][:8])
    finally:
        gpspipe.terminate()
        gpspipe.wait(timeout=DEADLINE)
    return seen


@pytest.mark.parametrize("repetition", range(int(os.environ.get("WIRETAPE_GPSD_REPEAT", "1"))))
def test_gpsd_gets_every_recorded_fix_whatever_it_flushed(tmp_path, repetition):
    recording = write_gpsd_proxy_recording(tmp_path / "gpsd.wtape")
    link = str(tmp_path / "ttyGPS")
    port = free_port()
    handle = bridge.serve_replay(recording, pty=link, replay_options="timing=causal,check=data",
                                 quiet=True)
    gpsd = None
    try:
        # Without -n gpsd opens the device when gpspipe asks for reports: the
        # client session, and the fixes, begin while gpspipe is watching.
        gpsd = subprocess.Popen(["gpsd", "-N", "-b", "-S", str(port),
                                 "-F", str(tmp_path / "gpsd.sock"), handle.pty_path],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        wait_until(lambda: gpsd.poll() is not None or _listening(port), DEADLINE,
                   "gpsd to listen")
        assert gpsd.poll() is None, gpsd.stderr.read().decode(errors="replace")
        expected = {fix_time(index) for index in range(FIXES)}
        seen = fix_times_reported(port, expected)
        assert expected <= seen, f"missing fixes: {sorted(expected - seen)}"
    finally:
        if gpsd is not None and gpsd.poll() is None:
            gpsd.terminate()
            try:
                gpsd.wait(timeout=DEADLINE)
            except subprocess.TimeoutExpired:
                gpsd.kill()
                gpsd.wait()
        handle.stop()
        assert handle.wait(DEADLINE)
