"""System calls of the recording proxies, counted (issue 42, DESIGN §30):
`wiretape record --pty`, `--listen` and `--udp` against socat doing the same
relay, each run by wiretape_relay_bench under `strace -c -f`
(bench/strace_relay.py). A count does not depend on the machine's load the
way a time does, so these figures can be compared from run to run.

Each relay runs three times: with no traffic beyond the bench's warm-up
(the baseline: start-up, imports, shutdown), with MESSAGE_COUNT single
messages more, and with BULK_BYTES more streamed from the device; the
baseline is subtracted from the other two. pty and tcp messages are 64 bytes, one at a
time, alternating direction; udp ones are 1,200-byte datagrams at a rate low
enough that each arrives alone.
"""

from __future__ import annotations

import shutil
import statistics
import sys
from pathlib import Path

import bench_devices
from bench_devices import Skip

HERE = Path(__file__).resolve().parent
MESSAGE_COUNT = 1000
BULK_BYTES = 8 << 20
UDP_RATE = 1000  # datagrams a second: one at a time, as the stream messages are
UDP_DATAGRAM = 1200  # bytes (relay_bench.cpp's kDatagram)
# client of wiretape_relay_bench -> the record option it stands for.
CLIENTS = {"pty": "pty", "tcp": "listen", "udp": "udp"}


def parse_strace_summary(text: str) -> dict[str, int]:
    """Calls per system call in `strace -c` output: the rows between a
    `% time` header and the dashes before `total`; several tables (one per
    personality) are summed. A table's name column is the last one."""
    calls: dict[str, int] = {}
    in_table = False
    tables = 0
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split()
        if line.startswith("% time"):
            if words[-1] != "syscall" or "calls" not in words:
                raise ValueError(f"line {number}: not a strace -c header: {line!r}")
            column = words.index("calls") - 1  # "% time" is two words, one column
            in_table = True
            tables += 1
        elif not in_table or not words or line.startswith("---"):
            continue
        elif words[-1] == "total":
            in_table = False
        else:
            try:
                calls[words[-1]] = calls.get(words[-1], 0) + int(words[column])
            except (IndexError, ValueError):
                raise ValueError(f"line {number}: not a strace -c row: {line!r}") from None
    if tables == 0:
        raise ValueError("no strace -c table (no line starts with '% time')")
    return calls


def per_unit(loaded: dict[str, int], baseline: dict[str, int], units: float) -> dict[str, float]:
    """(loaded - baseline) / units for every call either run made."""
    names = set(loaded) | set(baseline)
    return {name: (loaded.get(name, 0) - baseline.get(name, 0)) / units for name in names}


def beyond(ours: dict[str, float], theirs: dict[str, float], least: float = 0.05) -> dict[str, float]:
    """The calls ours makes more of than theirs, by at least `least` a unit."""
    extra = {name: value - theirs.get(name, 0.0) for name, value in ours.items()}
    return dict(sorted(((name, value) for name, value in extra.items() if value >= least),
                       key=lambda item: -item[1]))


def shown(counts: dict[str, float], least: float = 0.05) -> str:
    """The calls of at least `least` a unit, most first."""
    kept = sorted(((name, value) for name, value in counts.items() if abs(value) >= least),
                  key=lambda item: -item[1])
    return ", ".join(f"{name} {value:.2f}" for name, value in kept) or "none"


class CountJobs:
    """Mixed into run.py's Bench (uses work, python, relay_program, results,
    notes and quick): the `relay_counts` figure group."""

    def counted_relay(self, kind: str, client: str, first: int, second: int) -> tuple[dict, dict]:
        """One relay run under strace: (relay_bench's figures, calls per name)."""
        summary = self.work / f"strace-{kind}-{client}.txt"
        summary.unlink(missing_ok=True)
        command = bench_devices.relay_command(kind, client, self.python, self.work)
        traced = [sys.executable, str(HERE / "strace_relay.py"), str(summary), "--", *command]
        figures = bench_devices.run_relay(self.relay_program, client, first, second,
                                          self.work, traced, kind)
        if not summary.exists():
            raise Skip(f"{kind} relay under strace wrote no summary")
        return figures, parse_strace_summary(summary.read_text())

    def relay_counts_of(self, kind: str, client: str) -> dict[str, dict[str, float]]:
        """Calls per message and per MB of one relay, baseline subtracted."""
        # wiretape_relay_bench takes no zero counts: the baseline relays one
        # byte, one message (UDP: one millisecond, a datagram), and the runs
        # that count add to it.
        if client == "udp":
            milliseconds = MESSAGE_COUNT * 1000 // UDP_RATE
            alone, baseline = self.counted_relay(kind, client, UDP_RATE, 1)
            figures, loaded = self.counted_relay(kind, client, UDP_RATE, 1 + milliseconds)
            messages = figures["received"] - alone["received"]
            if messages <= 0:
                raise Skip(f"no datagram reached the device through {kind} under strace")
            return {"per_msg": per_unit(loaded, baseline, messages),
                    "per_MB": per_unit(loaded, baseline, messages * UDP_DATAGRAM / 1e6)}
        _, baseline = self.counted_relay(kind, client, 1, 1)
        _, loaded = self.counted_relay(kind, client, 1, 1 + MESSAGE_COUNT)
        _, bulk = self.counted_relay(kind, client, 1 + BULK_BYTES, 1)
        return {"per_msg": per_unit(loaded, baseline, MESSAGE_COUNT),
                "per_MB": per_unit(bulk, baseline, BULK_BYTES / 1e6)}

    def relay_counts(self) -> None:
        """System calls per message and per MB: wiretape record vs socat."""
        if shutil.which("strace") is None:
            raise Skip("strace is not installed (apt-get install strace)")
        rounds = 1 if self.quick else 3
        for client, option in CLIENTS.items():
            runs: dict[str, list] = {"wiretape": [], "socat": []}
            for index in range(rounds):
                order = ("wiretape", "socat") if index % 2 == 0 else ("socat", "wiretape")
                for kind in order:
                    runs[kind].append(self.relay_counts_of(kind, client))
            totals = {kind: {unit: statistics.median(sum(run[unit].values()) for run in kind_runs)
                             for unit in ("per_msg", "per_MB")}
                      for kind, kind_runs in runs.items()}
            prefix = f"record_{option}"
            self.results[f"{prefix}_syscalls_per_msg"] = round(totals["wiretape"]["per_msg"], 2)
            self.results[f"{prefix}_syscalls_per_MB"] = round(totals["wiretape"]["per_MB"], 1)
            self.results[f"{prefix}_vs_socat_syscalls_ratio"] = round(
                totals["wiretape"]["per_msg"] / totals["socat"]["per_msg"], 3)
            last = {kind: kind_runs[-1] for kind, kind_runs in runs.items()}
            self.notes[f"{prefix}_syscalls"] = (
                f"a message: wiretape {totals['wiretape']['per_msg']:.2f} calls "
                f"({shown(last['wiretape']['per_msg'])}), socat {totals['socat']['per_msg']:.2f} "
                f"({shown(last['socat']['per_msg'])}); beyond socat's: "
                f"{shown(beyond(last['wiretape']['per_msg'], last['socat']['per_msg']))}; "
                f"a MB: wiretape {totals['wiretape']['per_MB']:.0f}, socat "
                f"{totals['socat']['per_MB']:.0f} (medians of {rounds} runs each)")
