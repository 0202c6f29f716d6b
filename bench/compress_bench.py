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
  keeping up with a device).

Prints one JSON line. Usage: python compress_bench.py WORKDIR [--quick]
"""

from __future__ import annotations

import json
import os
import pathlib
import statistics
import sys
import tempfile
import time

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


def main() -> None:
    work = pathlib.Path(sys.argv[1])
    quick = "--quick" in sys.argv
    work.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=work) as scratch:
        folder = pathlib.Path(scratch)
        figures = {"hokuyo_ratio": hokuyo_ratio(folder),
                   "nmea_ratio": nmea_ratio(folder, 2000 if quick else 18000)}
        mib = 16 if quick else 64
        scans = b"".join(r.data for r in _core.SessionReader(folder / "utm30lx_2011.wtape")
                         if r.kind == "rx")
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
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
