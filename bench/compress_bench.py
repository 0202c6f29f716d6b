"""Compressed sessions (format 2.0, `compress=zstd`; issue 42, DESIGN §29):
how much they shrink and what they cost.

- hokuyo: the real Hokuyo recordings of tests/data/flexiport (a UTM-30LX
  and a URG-04LX scanning), as .wtape, compressed over uncompressed size;
- nmea: a GPS at 5 Hz (GGA + RMC each fix, the position wandering), each
  fix flushed on its own as a recorder at 5 Hz with flush_ms=100 flushes
  it, for an hour of fixes: compressed over uncompressed size;
- replay: a `timing=none` replay reading every rx byte of a session of
  4 KiB records cut from the UTM-30LX's bytes: its throughput compressed
  over uncompressed (median of interleaved rounds; target ≥ 0.5);
- write: MB/s of records the writer compresses (the recorder's share of
  keeping up with a device);
- channel: a `timing=none` replay of one channel of a compressed file of
  4 channels (their 4 KiB records interleaved, as 4 busy ports record
  them) over the replay of a compressed file of that channel alone, and
  the same pair uncompressed beside it (medians of interleaved rounds;
  target ≤ 2);
- pty: `wiretape record --pty --compress zstd` relaying 10 MB/s, offered
  for a few seconds by a writer on the device side (a pseudo-terminal
  standing for the serial device), read by a client on the recorder's pty:
  the rate the client (head, a process of its own) received over the rate
  offered (≥ 1.0, within jitter, keeps up), the best of interleaved rounds,
  and the same for the uncompressed record in the same run.

Prints one JSON line. Usage: python compress_bench.py WORKDIR [--quick] [--only replay|channel|pty]
"""

from __future__ import annotations

import json
import os
import pathlib
import select
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty

from wiretape import _core, cli

ROOT = pathlib.Path(__file__).resolve().parents[1]
FLEXIPORT = ROOT / "tests" / "data" / "flexiport"


def size(path) -> int:
    return os.path.getsize(path)


def hokuyo_ratio(work: pathlib.Path) -> float:
    plain_total = packed_total = 0
    for name in ("utm30lx_2011", "urg04lx_2011"):
        plain, packed = work / f"{name}.wtape", work / f"{name}.zst.wtape"
        if cli.main(["convert", "-q", str(FLEXIPORT / f"{name}.log"), str(plain)]) != 0:
            raise SystemExit(f"cannot convert {name}")
        if cli.main(["convert", "-q", "--compress", "zstd", str(plain), str(packed)]) != 0:
            raise SystemExit(f"cannot compress {name}")
        plain_total += size(plain)
        packed_total += size(packed)
    return packed_total / plain_total


def nmea_fix(n: int) -> bytes:
    """What a GPS receiver sends each fix: GGA, GSA, three GSV, RMC, VTG."""
    seconds = 36000 + n / 5
    hh, mm, ss = int(seconds // 3600), int(seconds // 60) % 60, seconds % 60
    when = f"{hh:02d}{mm:02d}{ss:05.2f}"
    lat = f"{4807.038 + (n % 997) * 0.0001:.4f}"
    lon = f"{1131.000 + (n % 773) * 0.0001:08.4f}"
    used = 8 + n % 4
    sats = [(3 + 2 * k, 10 + (n // 50 + 7 * k) % 70, (n // 20 + 37 * k) % 360, 20 + (n + k) % 25)
            for k in range(12)]
    bodies = [
        f"$GPGGA,{when},{lat},N,{lon},E,1,{used:02d},0.9,{545.4 + (n % 50) * 0.1:.1f},M,46.9,M,,",
        "$GPGSA,A,3," + ",".join(f"{s[0]:02d}" for s in sats[:used]) + "," * (12 - used)
        + ",1.5,0.9,1.2",
    ]
    for page in range(3):
        group = sats[4 * page:4 * page + 4]
        bodies.append(f"$GPGSV,3,{page + 1},12," + ",".join(
            f"{s[0]:02d},{s[1]:02d},{s[2]:03d},{s[3]:02d}" for s in group))
    speed, course = (n % 30) * 0.1, (n * 7) % 360
    bodies.append(f"$GPRMC,{when},A,{lat},N,{lon},E,{speed:.1f},{course:.1f},031226,,,A")
    bodies.append(f"$GPVTG,{course:.1f},T,,M,{speed:.1f},N,{speed * 1.852:.1f},K,A")

    def sentence(body: str) -> str:
        checksum = 0
        for ch in body[1:]:
            checksum ^= ord(ch)
        return f"{body}*{checksum:02X}\r\n"

    return "".join(sentence(body) for body in bodies).encode()


def nmea_ratio(work: pathlib.Path, fixes: int) -> float:
    sizes = []
    for compress in ("none", "zstd"):
        path = work / f"nmea-{compress}.wtape"
        with _core.SessionWriter(path, compress=compress) as writer:
            for n in range(fixes):
                writer.write("rx", n * 200_000_000, nmea_fix(n))
                writer.flush()  # 200 ms apart: every fix reaches the file alone
        sizes.append(size(path))
    return sizes[1] / sizes[0]


def write_session(path, compress: str, mib: int, scans: bytes) -> int:
    """`mib` MiB of 4 KiB rx records cut from the scanner's recorded bytes."""
    total = 0
    with _core.SessionWriter(path, compress=compress) as writer:
        for n in range(mib * 256):
            at = (n * 4096) % (len(scans) - 4096)
            frame = scans[at:at + 4096]
            writer.write("rx", n * 1000, frame)
            total += len(frame)
    return total


def replay_seconds(path, expected: int) -> float:
    start = time.perf_counter()
    port = _core.open_port(f"type=replay,file={path},timing=none,unused=ignore,timeout=10")
    got = 0
    while got < expected:
        chunk = port.read(1 << 16)
        if not chunk:
            raise SystemExit(f"replay of {path} stopped after {got} of {expected} bytes")
        got += len(chunk)
    port.close()
    return time.perf_counter() - start


def write_channels(path, compress: str, mib: int, scans: bytes, channels: int) -> int:
    """`mib` MiB of 4 KiB rx records a channel, for `channels` channels
    c0, c1, ... interleaved record by record; returns channel c1's bytes
    (every channel's when there is one: the file of c1 alone)."""
    header = _core.SessionHeader()
    header.channels = [_core.Channel(id=n, name=f"c{n}", port_type="serial",
                                     port_options=f"type=serial,device=/dev/c{n}")
                       for n in range(channels)]
    c1 = 0
    with _core.SessionWriter(path, header, compress=compress) as writer:
        for n in range(mib * 256):
            for channel in range(channels):
                at = ((n * channels + channel) * 4096) % (len(scans) - 4096)
                frame = scans[at:at + 4096]
                writer.write("rx", (n * channels + channel) * 1000, frame, channel=channel)
                if channel == min(1, channels - 1):
                    c1 += len(frame)
    return c1


def replay_channel_seconds(path, channel: str, expected: int) -> float:
    start = time.perf_counter()
    port = _core.open_port(f"type=replay,file={path},channel={channel},timing=none,"
                           f"unused=ignore,timeout=10")
    got = 0
    while got < expected:
        chunk = port.read(1 << 16)
        if not chunk:
            raise SystemExit(f"replay of {channel} of {path} stopped after {got} of "
                             f"{expected} bytes")
        got += len(chunk)
    port.close()
    return time.perf_counter() - start


def channel_ratios(folder: pathlib.Path, mib: int, scans: bytes, rounds: int) -> dict:
    figures = {}
    for compress in ("zstd", "none"):
        mixed, alone = folder / f"mixed-{compress}.wtape", folder / f"alone-{compress}.wtape"
        expected = write_channels(mixed, compress, mib, scans, 4)
        write_channels(alone, compress, mib, scans, 1)
        ratios = []
        for _ in range(rounds):  # interleaved: both see the same machine
            ratios.append(replay_channel_seconds(mixed, "c1", expected)
                          / replay_channel_seconds(alone, "c0", expected))
        figures[compress] = ratios
        mixed.unlink()
        alone.unlink()
    return {"channel_ratio": statistics.median(figures["zstd"]), "channel_ratios": figures["zstd"],
            "plain_channel_ratio": statistics.median(figures["none"]),
            "plain_channel_ratios": figures["none"]}


def wait_for(condition, seconds: float, what: str) -> None:
    end = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > end:
            raise SystemExit(f"timed out waiting for {what}")
        select.select([], [], [], 0.01)


def pty_record_rate(folder: pathlib.Path, compress: str, data: bytes, rate: float) -> dict:
    """`wiretape record --pty` relaying `data` offered at `rate` bytes a
    second from the device side; the client's received rate over the
    offered rate, and whether the file holds every byte."""
    master, slave = os.openpty()
    tty.setraw(slave)
    tty.setraw(master)
    link, output = folder / f"client-{compress}", folder / f"pty-{compress}.wtape"
    child = subprocess.Popen(
        [sys.executable, "-m", "wiretape.cli", "record", "--device",
         f"type=serial,device={os.ttyname(slave)},baud=115200", "--pty", str(link),
         "-o", str(output), "--compress", compress],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    client = -1
    try:
        wait_for(link.exists, 30, f"the recorder's pty {link}")
        client = os.open(link, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(client)
        # The client is a process of its own (head, reading what the
        # recorder relays until it has every byte), so that it does not
        # share this process's interpreter with the writer.
        received = folder / f"received-{compress}"
        with open(received, "wb") as sink:
            reader = subprocess.Popen(["head", "-c", str(len(data))], stdin=client,
                                      stdout=sink)
        done = {}

        def wait_reader():
            reader.wait()
            done["at"] = time.perf_counter()
            done["bytes"] = size(received)

        waiter = threading.Thread(target=wait_reader)
        waiter.start()
        block = 1 << 14
        start = time.perf_counter()
        for at in range(0, len(data), block):
            pause = start + at / rate - time.perf_counter()
            if pause > 0:
                time.sleep(pause)  # pacing the offered rate, not waiting on an event
            os.write(master, data[at:at + block])
        offered_s = time.perf_counter() - start
        waiter.join(60)
        if done.get("bytes", 0) < len(data):
            reader.kill()
            raise SystemExit(f"record --pty ({compress}) relayed {done.get('bytes', 0)} of "
                             f"{len(data)} bytes")
        relayed_s = done["at"] - start
    finally:
        if client >= 0:
            os.close(client)
        child.send_signal(signal.SIGINT)
        try:
            child.wait(60)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()
        os.close(master)
        os.close(slave)
    recorded = sum(len(r.data) for r in _core.SessionReader(output) if r.kind == "rx")
    output.unlink(missing_ok=True)
    (folder / f"received-{compress}").unlink(missing_ok=True)
    offered_rate = len(data) / offered_s
    return {"ratio": (len(data) / relayed_s) / rate, "offered_MBps": offered_rate / 1e6,
            "recorded_all": recorded == len(data)}


def pty_rates(folder: pathlib.Path, scans: bytes, seconds: float, rounds: int) -> dict:
    rate = 10e6
    total = int(rate * seconds)
    data = (scans * (total // len(scans) + 1))[:total]
    runs = {"zstd": [], "none": []}
    for _ in range(rounds):  # interleaved: both see the same machine
        for compress in ("zstd", "none"):
            runs[compress].append(pty_record_rate(folder, compress, data, rate))
    figures = {}
    for compress, name in (("zstd", "pty_zstd"), ("none", "pty_plain")):
        # The best round: a loaded machine only ever takes rate away (a
        # writer or relay not scheduled), as the shim's figures take theirs.
        figures[f"{name}_ratio"] = max(r["ratio"] for r in runs[compress])
        figures[f"{name}_ratios"] = [r["ratio"] for r in runs[compress]]
        figures[f"{name}_recorded_all"] = all(r["recorded_all"] for r in runs[compress])
        figures[f"{name}_offered_MBps"] = min(r["offered_MBps"] for r in runs[compress])
    figures["pty_MB"] = total / 1e6
    return figures


def main() -> None:
    work = pathlib.Path(sys.argv[1])
    quick = "--quick" in sys.argv
    # --only replay|channel|pty: that figure alone (and the Hokuyo sizes)
    only = sys.argv[sys.argv.index("--only") + 1] if "--only" in sys.argv else None
    work.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=work) as scratch:
        folder = pathlib.Path(scratch)
        figures = {"hokuyo_ratio": hokuyo_ratio(folder)}
        if only is None:
            figures["nmea_ratio"] = nmea_ratio(folder, 2000 if quick else 18000)
        mib = 16 if quick else 64
        scans = b"".join(r.data for r in _core.SessionReader(folder / "utm30lx_2011.wtape")
                         if r.kind == "rx")
        if only in (None, "replay"):
            plain, packed = folder / "plain.wtape", folder / "packed.wtape"
            write_session(plain, "none", mib, scans)
            start = time.perf_counter()
            expected = write_session(packed, "zstd", mib, scans)
            figures["write_MBps"] = expected / (time.perf_counter() - start) / 1e6
            ratios = []
            for _ in range(3 if quick else 5):  # interleaved: both see the same machine
                # throughput compressed / uncompressed: uncompressed time / compressed time
                ratios.append(replay_seconds(plain, expected) / replay_seconds(packed, expected))
            figures["replay_ratio"] = statistics.median(ratios)
            figures["replay_ratios"] = ratios
            figures["replay_file_ratio"] = size(packed) / size(plain)
        if only in (None, "channel"):
            figures.update(channel_ratios(folder, 8 if quick else 32, scans, 3 if quick else 5))
        if only in (None, "pty"):
            figures.update(pty_rates(folder, scans, 2.0 if quick else 4.0, 1 if quick else 3))
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
