"""A real client of several devices (issue 25): gpsd reading NMEA from a
pty, a ``tcp://`` and a ``udp://`` source at once, recorded through one
``wiretape record`` into one file of three channels, then replayed to a new
gpsd with every device's fixes delivered and attributed to its own path
(``gpspipe -w``, the TPV ``device``). The ``udp://`` receiver sends to gpsd,
so it is recorded with ``--udp LISTEN --peer GPSD_ADDR`` (DESIGN.md section
19). Skipped, loudly, without gpsd and gpspipe (Debian: gpsd gpsd-clients)."""

import shutil
import socket
import sys

import pytest

import wiretape

from devices import interrupt, start_cli, wait_until
from nmea_sources import (PtyNmeaSource, TcpNmeaSource, UdpNmeaSource, fixes_by_device,
                          free_port, listening, start_gpsd, stop)

DEADLINE_S = 30.0
# Fixes of each receiver recorded past gpsd's first ones (5 Hz: 3 s).
EXTRA_FIXES = 15
LATITUDES = {"gps1": 48.1173, "gps2": 52.52, "gps3": 40.7128}

pytestmark = [
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="gpsd test: Linux only"),
    pytest.mark.skipif(shutil.which("gpsd") is None or shutil.which("gpspipe") is None,
                       reason="SKIPPED LOUDLY: gpsd/gpspipe not installed "
                              "(apt-get install gpsd gpsd-clients)"),
]


def wait_for_announcements(child, count):
    """The child's stderr lines until `count` say where clients go."""
    lines = []
    while sum("clients use" in line for line in lines) < count:
        line = child.stderr.readline()
        if not line:
            raise AssertionError("the command ended: " + "".join(lines))
        lines.append(line)
    return lines


def run_gpsd(tmp_path, sources, expected, watching=None):
    """A gpsd on `sources` until every path of `expected` ({device: lat})
    has reported its fix; the fixes it reported. `watching` starts a feed
    once gpspipe watches."""
    port = free_port()
    gpsd = start_gpsd(port, sources, tmp_path)
    try:
        wait_until(lambda: gpsd.poll() is not None or listening(port), DEADLINE_S,
                   "gpsd to listen")
        assert gpsd.poll() is None, gpsd.stderr.read().decode(errors="replace")
        return fixes_by_device(port, expected, DEADLINE_S, watching)
    finally:
        stop(gpsd)


def assert_fixes(fixes, expected):
    assert set(fixes) >= set(expected), fixes
    for device, latitude in expected.items():
        assert fixes[device] == pytest.approx(latitude, abs=1e-3), (device, fixes)


def test_gpsd_reads_a_udp_source_recorded_between_it_and_the_receiver(tmp_path):
    """One udp:// source: the receiver streams to wiretape, wiretape to
    gpsd; the recording replays to a new gpsd as the receiver did."""
    recording = tmp_path / "udp.wtape"
    listen, gpsd_udp = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
    device = f"udp://127.0.0.1:{gpsd_udp}"
    with UdpNmeaSource(LATITUDES["gps3"], ("127.0.0.1", listen)):
        child = start_cli("record", "--udp", f"127.0.0.1:{listen}",
                          "--peer", f"127.0.0.1:{gpsd_udp}", "-o", str(recording), "-q")
        try:
            wait_for_announcements(child, 1)
            fixes = run_gpsd(tmp_path, [device], {device: LATITUDES["gps3"]})
        finally:
            status, _, err = interrupt(child)
    assert status == 0, err
    assert_fixes(fixes, {device: LATITUDES["gps3"]})

    gpsd_udp = free_port(socket.SOCK_DGRAM)
    device = f"udp://127.0.0.1:{gpsd_udp}"
    replay = []

    def start_replay():
        # Once gpsd watches for gpspipe: the stream is reported from its start.
        replay.append(start_cli("replay", str(recording), "--udp", "127.0.0.1:0",
                                "--peer", f"127.0.0.1:{gpsd_udp}", "--timing", "session",
                                "--check", "off", "--unused", "ignore", "-q"))
        wait_for_announcements(replay[0], 1)
    try:
        fixes = run_gpsd(tmp_path, [device], {device: LATITUDES["gps3"]}, start_replay)
    finally:
        for child in replay:
            interrupt(child)
    assert_fixes(fixes, {device: LATITUDES["gps3"]})


def test_gpsd_of_three_sources_recorded_in_one_file_and_replayed(tmp_path):
    recording = tmp_path / "three.wtape"
    pty_link = str(tmp_path / "gps1")
    tcp_port, listen, gpsd_udp = (free_port(), free_port(socket.SOCK_DGRAM),
                                  free_port(socket.SOCK_DGRAM))
    expected = {pty_link: LATITUDES["gps1"], f"tcp://127.0.0.1:{tcp_port}": LATITUDES["gps2"],
                f"udp://127.0.0.1:{gpsd_udp}": LATITUDES["gps3"]}
    with PtyNmeaSource(LATITUDES["gps1"]) as gps1, TcpNmeaSource(LATITUDES["gps2"]) as gps2, \
            UdpNmeaSource(LATITUDES["gps3"], ("127.0.0.1", listen)) as gps3:
        sources = (gps1, gps2, gps3)
        child = start_cli("record", "-o", str(recording), "-q",
                          "--device", f"gps1={gps1.options}", "--pty", f"gps1={pty_link}",
                          "--device", f"gps2={gps2.options}",
                          "--listen", f"gps2=127.0.0.1:{tcp_port}",
                          "--udp", f"gps3=127.0.0.1:{listen}",
                          "--peer", f"gps3=127.0.0.1:{gpsd_udp}")
        try:
            wait_for_announcements(child, 3)
            fixes = run_gpsd(tmp_path, list(expected), expected)
            sent = [source.sent for source in sources]
            wait_until(lambda: all(source.sent >= count + EXTRA_FIXES
                                   for source, count in zip(sources, sent)),
                       DEADLINE_S, "more fixes of every receiver")
        finally:
            status, _, err = interrupt(child)
    assert status == 0, err
    assert_fixes(fixes, expected)
    with wiretape.SessionReader(str(recording)) as reader:
        names = {channel.id: channel.name for channel in reader.header.channel_list()}
        rx_channels = {names[record.channel] for record in reader if record.kind == "rx"}
    assert rx_channels == {"gps1", "gps2", "gps3"}

    # The replay: the same three paths, a new gpsd; each path's fixes are
    # its own receiver's.
    pty_link = str(tmp_path / "gps1-replayed")
    tcp_port, gpsd_udp = free_port(), free_port(socket.SOCK_DGRAM)
    expected = {pty_link: LATITUDES["gps1"], f"tcp://127.0.0.1:{tcp_port}": LATITUDES["gps2"],
                f"udp://127.0.0.1:{gpsd_udp}": LATITUDES["gps3"]}
    # gpsd starts after the virtual devices it opens: the recording holds
    # EXTRA_FIXES more of each receiver past the first fixes, for it.
    child = start_cli("replay", str(recording), "-q", "--timing", "session",
                      "--check", "off", "--unused", "ignore",
                      "--pty", f"gps1={pty_link}", "--listen", f"gps2=127.0.0.1:{tcp_port}",
                      "--udp", "gps3=127.0.0.1:0", "--peer", f"gps3=127.0.0.1:{gpsd_udp}")
    try:
        wait_for_announcements(child, 3)
        fixes = run_gpsd(tmp_path, list(expected), expected)
    finally:
        interrupt(child)
    assert_fixes(fixes, expected)
