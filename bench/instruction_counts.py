"""User-space instructions of the recording proxies, counted (issue 42,
DESIGN §30): `wiretape record --pty`, `--listen` and `--udp` against socat
on the same work, each run by wiretape_relay_bench under `valgrind
--tool=callgrind` (all threads in one total). Like the system calls
(bench/syscall_counts.py), a count does not move with the machine's load.

Each relay runs twice: the baseline (the bench's warm-up, one byte, one
message) and the same with BULK_BYTES more streamed from the device (pty,
TCP) or UDP_DATAGRAMS more datagrams (UDP); the baseline's instructions are
subtracted and the rest divided by the MB relayed.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import bench_devices
from bench_devices import Skip

BULK_BYTES = 4 << 20
UDP_RATE = 500  # datagrams a second: a relay under valgrind keeps up
UDP_MILLISECONDS = 2000
UDP_DATAGRAM = 1200
READY_S = 300  # Python's start-up under callgrind takes ~20 s on a busy machine
CLIENTS = {"pty": "pty", "tcp": "listen", "udp": "udp"}


def parse_callgrind_totals(text: str) -> int:
    """The instructions (Ir) of a callgrind output file: its `totals:` line,
    else its `summary:` line (both are written; the first event is Ir)."""
    found = {}
    for line in text.splitlines():
        for key in ("totals:", "summary:"):
            if line.startswith(key):
                words = line[len(key):].split()
                if not words or not words[0].isdigit():
                    raise ValueError(f"callgrind output: {line!r} holds no count")
                found[key] = int(words[0])
    if "events:" not in text:
        raise ValueError("not a callgrind output file (no events: line)")
    for key in ("totals:", "summary:"):
        if key in found:
            return found[key]
    raise ValueError("callgrind output without a totals: or summary: line")


class InstructionJobs:
    """Mixed into run.py's Bench (uses work, python, relay_program, results,
    notes): the `relay_instructions` figure group."""

    def callgrind_relay(self, kind: str, client: str, first: int, second: int) -> tuple[dict, int]:
        out = self.work / f"callgrind-{kind}-{client}.out"
        out.unlink(missing_ok=True)
        command = bench_devices.relay_command(kind, client, self.python, self.work)
        traced = ["valgrind", "--tool=callgrind", "--quiet", f"--callgrind-out-file={out}",
                  *command]
        environment = dict(os.environ, WIRETAPE_RELAY_BENCH_READY_S=str(READY_S),
                           PYTHONHASHSEED="0")
        figures = bench_devices.run_relay(self.relay_program, client, first, second,
                                          self.work, traced, kind, env=environment)
        if not out.exists():
            raise Skip(f"{kind} relay under callgrind wrote no output")
        return figures, parse_callgrind_totals(out.read_text())

    def instructions_per_mb(self, kind: str, client: str) -> float:
        if client == "udp":
            # The shortest flood of one datagram: relay_bench's figures of none are not numbers.
            shortest = -(-1000 // UDP_RATE)
            alone, baseline = self.callgrind_relay(kind, client, UDP_RATE, shortest)
            figures, loaded = self.callgrind_relay(kind, client, UDP_RATE,
                                                   shortest + UDP_MILLISECONDS)
            datagrams = figures["received"] - alone["received"]
            if datagrams <= 0:
                raise Skip(f"no datagram reached the device through {kind} under callgrind")
            return (loaded - baseline) / (datagrams * UDP_DATAGRAM / 1e6)
        _, baseline = self.callgrind_relay(kind, client, 1, 1)
        _, loaded = self.callgrind_relay(kind, client, 1 + BULK_BYTES, 1)
        return (loaded - baseline) / (BULK_BYTES / 1e6)

    def relay_instructions(self) -> None:
        """User-space instructions per MB relayed: wiretape record vs socat."""
        if shutil.which("valgrind") is None:
            raise Skip("valgrind is not installed (apt-get install valgrind)")
        for client, option in CLIENTS.items():
            ours = self.instructions_per_mb("wiretape", client)
            theirs = self.instructions_per_mb("socat", client)
            self.results[f"record_{option}_instructions_per_MB"] = round(ours)
            self.results[f"record_{option}_vs_socat_instructions_ratio"] = round(ours / theirs, 3)
            self.notes[f"record_{option}_instructions"] = (
                f"wiretape {ours / 1e6:.2f} M instructions a MB, socat {theirs / 1e6:.2f} M "
                "(callgrind, baseline subtracted)")
