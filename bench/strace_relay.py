"""Runs a relay under `strace -c -f`, so that wiretape_relay_bench can start
and stop it as it does the relay alone (bench/syscall_counts.py).

Usage: python strace_relay.py SUMMARY_FILE -- COMMAND...

wiretape_relay_bench stops its relay with SIGINT. strace started with `-o
FILE COMMAND` blocks fatal signals, and one let through would only make it
detach and leave the relay running untraced; so this wrapper passes SIGINT
and SIGTERM on to the traced command itself (strace's child), which ends as
it would untraced, and strace then writes the summary.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path


def children_of(pid: int) -> list[int]:
    found = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            found += [int(word) for word in (task / "children").read_text().split()]
        except OSError:
            continue
    return found


def main(argv: list[str]) -> int:
    if len(argv) < 3 or argv[1] != "--":
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    summary, command = argv[0], argv[2:]
    tracer = subprocess.Popen(["strace", "-f", "-c", "-o", summary, "--", *command])

    def forward(signum: int, _frame: object) -> None:
        for child in children_of(tracer.pid):
            os.kill(child, signum)

    signal.signal(signal.SIGINT, forward)
    signal.signal(signal.SIGTERM, forward)
    return tracer.wait()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
