#!/usr/bin/env python3
"""`wiretape show`'s time on a 10 MB session (bench/run.py, group "show"):
prints one JSON line. Usage: show_bench.py WORKDIR

Two sessions of 10 MB: 4 KiB rx records (what the replay figures use), and
a sensor's traffic (a 13-byte request answered by 1 KiB, as Hokuyo's GD).
Each is shown, text format, to /dev/null:
- anchor_s: show's loop before issue 26 (time, kind, size, the first 64
  bytes escaped; no Δt, no colour), kept here as it was, in this process;
- loop_s: show() with colour and its Δt column, in this process;
- show_s: what a user waits for: the whole command line run,
  `wiretape show --color always FILE` (start-up, imports, the loop), the
  best of three.
The target (issue 26) is show_s ≤ 0.5 s for each session.
"""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from wiretape import _core
from wiretape.session import open_session, printable
from wiretape.tools.show import show

SIZE = 10_000_000


def make_sessions(work: Path):
    bulk = work / "show-bulk-10MB.wtape"
    if not bulk.exists():
        with _core.SessionWriter(str(bulk)) as writer:
            block = bytes(range(256)) * 16
            for n in range(SIZE // len(block)):
                writer.write("rx", n * 1_000_000, block)
    sensor = work / "show-sensor-10MB.wtape"
    if not sensor.exists():
        with _core.SessionWriter(str(sensor)) as writer:
            reply = b"GD0044072501\n00P\n" + b"0123456789abcdef" * 63 + b"\n\n"
            t = 0
            for _ in range(SIZE // (13 + len(reply))):
                writer.write("tx", t, b"GD0044072501\n")
                writer.write("rx", t + 2_000_000, reply)
                t += 25_000_000
    return {"bulk": bulk, "sensor": sensor}


def anchor(path: Path, out) -> None:
    """show's text loop before issue 26."""
    for record in open_session(str(path)):
        size = f"{len(record.data):>6} B"
        arrow = "<-" if record.kind == "rx" else "->"
        line = f"{record.t_ns / 1e9:+.6f}s  {record.kind:<17} {size}  "
        out.write(f"{line}{arrow} {printable(record.data)}\n".rstrip() + "\n")


def timed(work) -> float:
    started = time.perf_counter()
    work()
    return time.perf_counter() - started


def command_line(path: Path) -> float:
    """The best of three whole runs of `wiretape show --color always`."""
    best = None
    for _ in range(3):
        started = time.perf_counter()
        subprocess.run([sys.executable, "-m", "wiretape.cli", "show", "--color", "always",
                        str(path)], stdout=subprocess.DEVNULL, check=True)
        elapsed = time.perf_counter() - started
        best = elapsed if best is None else min(best, elapsed)
    return best


def main() -> int:
    work = Path(sys.argv[1])
    work.mkdir(parents=True, exist_ok=True)
    figures = {}
    with open(os.devnull, "w") as devnull:
        for name, path in make_sessions(work).items():
            figures[f"{name}_anchor_s"] = round(timed(lambda: anchor(path, devnull)), 3)
            figures[f"{name}_loop_s"] = round(
                timed(lambda: show(str(path), out=devnull, color=True)), 3)
            figures[f"{name}_show_s"] = round(command_line(path), 3)
            figures[f"{name}_records"] = sum(1 for _ in open_session(str(path)))
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
