#!/usr/bin/env python3
"""`make soak`: record+replay in a loop for a long time; fails if the resident
memory or the number of open file descriptors grows.

Usage: bench/soak.py [--minutes 30] [--build build] [--work build/soak]

The loop (bench_tool soak) records a loopback session of 100 messages, then
replays it with check=data and unused=error, again and again, printing its
current RSS and open fds once a second. Verdict: open fds never change after
the first sample; the RSS of the last tenth of the run is within 10 % + 2 MiB
of the RSS of the second tenth (the first tenth is warm-up: allocator pools).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--build", type=Path, default=ROOT / "build")
    parser.add_argument("--work", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.minutes <= 0:
        parser.error("--minutes must be positive")
    build = args.build.resolve()
    work = (args.work or build / "soak").resolve()
    work.mkdir(parents=True, exist_ok=True)
    subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build), "-DWIRETAPE_BENCH=ON"],
                   check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", str(build), "--target", "wiretape_bench_tool"], check=True)

    seconds = max(1, int(args.minutes * 60))
    print(f"soak: {seconds} s of record+replay, samples in {work / 'soak.jsonl'}", flush=True)
    samples = []
    with open(work / "soak.jsonl", "w") as log, subprocess.Popen(
            [str(build / "bin" / "wiretape_bench_tool"), "soak", str(seconds), str(work)],
            stdout=subprocess.PIPE, text=True) as process:
        for line in process.stdout:
            log.write(line)
            sample = json.loads(line)
            samples.append(sample)
            if len(samples) % 60 == 1:
                print(f"  t={sample['t']:.0f}s iterations={sample['iterations']} "
                      f"rss={sample['rss_MB']:.1f} MiB fds={sample['fds']}", flush=True)
    if process.returncode != 0:
        print(f"soak: FAILED: the loop stopped with status {process.returncode}")
        return 1
    if len(samples) < 10:
        print(f"soak: FAILED: only {len(samples)} samples")
        return 1
    tenth = max(1, len(samples) // 10)
    early = statistics.mean(s["rss_MB"] for s in samples[tenth:2 * tenth])
    late = statistics.mean(s["rss_MB"] for s in samples[-tenth:])
    fds = sorted({s["fds"] for s in samples})
    print(f"soak: {samples[-1]['iterations']} iterations; RSS {early:.1f} -> {late:.1f} MiB; "
          f"open fds seen: {fds}")
    ok = True
    if late > early * 1.10 + 2.0:
        print(f"soak: FAILED: RSS grew from {early:.1f} to {late:.1f} MiB")
        ok = False
    if len(fds) != 1:
        print(f"soak: FAILED: open file descriptors changed: {fds}")
        ok = False
    print("soak: ok" if ok else "soak: FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
