#!/usr/bin/env python3
"""Runs wiretape's benchmarks and writes BUILD/bench/results.json.

Usage: bench/run.py --build DIR [--only NAME[,NAME...]] [--quick] [--udp-seconds S]

Each figure is measured side by side with its anchor (cat, an unrecorded
port, socat, pytest-reserial) in the same run and reported as a ratio; see
docs/benchmarks.md for what each key means. A figure whose subject or tool is
missing is skipped with the reason (printed, and kept in notes.json).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_devices  # noqa: E402  (bench/bench_devices.py)
from bench_devices import Skip, need_disk  # noqa: E402
from relay_jobs import RelayJobs  # noqa: E402  (bench/relay_jobs.py: pty/tcp/udp_proxy)
from syscall_counts import CountJobs  # noqa: E402  (bench/syscall_counts.py: relay_counts)
from instruction_counts import InstructionJobs  # noqa: E402  (relay_instructions)
from report import print_table  # noqa: E402  (bench/report.py)

MiB = 1 << 20
GiB = 1 << 30
# The 4-channel file of `channels`: 1 GiB (256 MiB a channel), smaller with
# --quick or WIRETAPE_BENCH_CHANNELS_MIB (the whole file's MiB).
CHANNELS_FILE_MIB = int(os.environ.get("WIRETAPE_BENCH_CHANNELS_MIB", "1024"))

# Google Benchmark counters that are figures of the table: benchmark name ->
# ((counter, results key), ...). The benchmarks run both sides in one process,
# interleaved (bench/wiretape_bench.cpp).
GBENCH_FIGURES = {
    "BM_RequestVsSequence": (("request_over_sequence", "request_vs_sequence_time_ratio"),),
    "BM_ModbusTcpReordering": (("modbus_over_sequence",
                                "modbus_reordering_vs_sequence_time_ratio"),),
    "BM_RequestModePeakRss": (("peak_rss_mib", "request_rss_MB_1GiB"),),
}


class Bench(RelayJobs, CountJobs, InstructionJobs):
    def __init__(self, build: Path, quick: bool, udp_seconds: float | None = None):
        self.build = build
        self.quick = quick
        self.udp_seconds = udp_seconds
        self.work = build / "bench"
        self.work.mkdir(parents=True, exist_ok=True)
        self.tool = build / "bin" / "wiretape_bench_tool"
        self.gbench_program = build / "bin" / "wiretape_bench"
        self.relay_program = build / "bin" / "wiretape_relay_bench"
        self.python = ROOT / ".venv" / "bin" / "python"
        if not self.python.exists():
            self.python = Path(sys.executable)
        self.results: dict[str, float] = {}
        self.notes: dict[str, str] = {}
        self.env = dict(os.environ, WIRETAPE_BENCH_DIR=str(self.work))

    # --- helpers ----------------------------------------------------------
    def run_tool(self, *args: str, timeout: float = 600) -> dict:
        proc = subprocess.run([str(self.tool), *args], capture_output=True, text=True,
                              timeout=timeout, env=self.env)
        if proc.returncode != 0:
            raise Skip(proc.stderr.strip().splitlines()[-1] if proc.stderr.strip()
                       else f"exit status {proc.returncode}")
        return json.loads(proc.stdout.strip().splitlines()[-1])

    def session(self, size: int) -> Path:
        path = self.work / f"rx-{size // MiB}MiB.wtape"
        if not path.exists():
            self.run_tool("make-session", str(path), str(size))
        return path

    @staticmethod
    def cat_seconds(path: Path) -> float:
        start = time.perf_counter()
        subprocess.run(["cat", str(path)], stdout=subprocess.DEVNULL, check=True)
        return time.perf_counter() - start

    def python_replay(self, path: Path, size: int) -> dict:
        code = (
            "import json, sys, time, wiretape\n"
            "path, expected = sys.argv[1], int(sys.argv[2])\n"
            "start = time.perf_counter()\n"
            "port = wiretape.open_port(f'type=replay,file={path},timing=none,unused=ignore,timeout=10')\n"
            "total = 0\n"
            "while total < expected:\n"
            "    data = port.read(65536)\n"
            "    if not data:\n"
            "        sys.exit(f'replay timed out after {total} bytes')\n"
            "    total += len(data)\n"
            "seconds = time.perf_counter() - start\n"
            "port.close()\n"
            "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')]\n"
            "print(json.dumps({'seconds': seconds,"
            " 'peak_rss_MB': int(hwm[0].split()[1]) / 1024 if hwm else -1}))\n")
        proc = subprocess.run([str(self.python), "-c", code, str(path), str(size)],
                              capture_output=True, text=True, timeout=600)
        if proc.returncode != 0:
            raise Skip("Python replay: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        return json.loads(proc.stdout.strip().splitlines()[-1])

    # --- figures ----------------------------------------------------------
    def replay(self) -> None:
        """timing=none replay vs cat, C++ and Python; RSS at 100 MiB."""
        need_disk(self.work, 300 * MiB, "replay 100 MiB")
        size = 100 * MiB
        path = self.session(size)
        rounds = 3 if self.quick else 5
        cat, cpp, py = [], [], []
        for _ in range(2):
            self.cat_seconds(path)  # warm the page cache
        cpp_rss = 0.0
        py_error = None
        for _ in range(rounds):  # interleaved, so both see the same machine
            cat.append(self.cat_seconds(path))
            result = self.run_tool("replay", str(path), str(size))
            cpp.append(result["seconds"])
            cpp_rss = max(cpp_rss, result["peak_rss_MB"])
            if py_error is None:
                try:
                    py.append(self.python_replay(path, size)["seconds"])
                except Skip as error:
                    py_error = str(error)
        cat_s = statistics.median(cat)
        self.results["replay_throughput_cpp_MBps"] = round(size / statistics.median(cpp) / 1e6, 1)
        self.results["replay_vs_cat_ratio"] = round(cat_s / statistics.median(cpp), 3)
        self.results["replay_rss_MB_100MiB"] = round(cpp_rss, 1)
        self.notes["cat_100MiB_MBps"] = f"{size / cat_s / 1e6:.0f} MB/s"
        if py:
            self.results["replay_python_vs_cat_ratio"] = round(cat_s / statistics.median(py), 3)
        else:
            self.notes["replay_python_vs_cat_ratio"] = py_error or "not measured"

    def replay_1gib(self) -> None:
        """Peak RSS replaying a 1 GiB session (file size must not matter)."""
        size = GiB
        path = self.work / "rx-1024MiB.wtape"
        if not path.exists():
            need_disk(self.work, 2 * GiB + 512 * MiB, "replay 1 GiB")
        try:
            path = self.session(size)
            result = self.run_tool("replay", str(path), str(size))
            self.results["replay_rss_MB_1GiB"] = round(result["peak_rss_MB"], 1)
            self.notes["replay_1GiB_MBps"] = f"{result['MBps']:.0f} MB/s"
        finally:
            path.unlink(missing_ok=True)  # a GiB is too much to leave behind

    def channels(self) -> None:
        """One channel of a 4-channel file vs its data alone; causal latency
        across channels vs on one."""
        file_size = (100 if self.quick else CHANNELS_FILE_MIB) * MiB
        channel_size = file_size // 4
        need_disk(self.work, file_size + channel_size + 256 * MiB, "channels")
        mixed = self.work / f"channels-{file_size // MiB}MiB.wtape"
        alone = self.work / f"channel-alone-{channel_size // MiB}MiB.wtape"
        try:
            self.run_tool("make-channels", str(mixed), str(channel_size))
            self.run_tool("make-session", str(alone), str(channel_size))
            rounds = 3 if self.quick else 5
            mixed_runs, alone_runs = [], []
            for _ in range(rounds):  # interleaved, so both see the same machine
                mixed_runs.append(self.run_tool("replay-c1", str(mixed), str(channel_size)))
                alone_runs.append(self.run_tool("replay", str(alone), str(channel_size)))
            mixed_s = statistics.median(r["seconds"] for r in mixed_runs)
            alone_s = statistics.median(r["seconds"] for r in alone_runs)
            mixed_rss = max(r["peak_rss_MB"] for r in mixed_runs)
            alone_rss = max(r["peak_rss_MB"] for r in alone_runs)
            self.results["channel_replay_time_ratio"] = round(mixed_s / alone_s, 3)
            self.results["channel_replay_rss_ratio"] = round(mixed_rss / alone_rss, 3)
            self.notes["channel_replay"] = (
                f"{file_size // MiB} MiB file of 4 channels: channel c1 in {mixed_s:.2f} s, "
                f"{mixed_rss:.0f} MiB; alone {alone_s:.2f} s, {alone_rss:.0f} MiB")
        finally:
            mixed.unlink(missing_ok=True)
            alone.unlink(missing_ok=True)
        rounds = "500" if self.quick else "2000"
        ones, twos = [], []
        for _ in range(3):  # interleaved; the median run of each, as a p99 is noisy
            ones.append(self.run_tool("causal-latency", rounds, "1", timeout=120))
            twos.append(self.run_tool("causal-latency", rounds, "2", timeout=120))
        one = sorted(ones, key=lambda r: r["p99_us"])[1]
        two = sorted(twos, key=lambda r: r["p99_us"])[1]
        self.results["causal_cross_channel_p99_extra_us"] = round(two["p99_us"] - one["p99_us"], 2)
        self.notes["causal_latency"] = (
            f"write->rx p50/p99: one channel {one['p50_us']:.1f}/{one['p99_us']:.1f} µs, "
            f"across channels {two['p50_us']:.1f}/{two['p99_us']:.1f} µs")

    def timing(self) -> None:
        """timing=session lateness of 10,000 records 1 ms apart; naive player."""
        records = 2000 if self.quick else 10000
        result = self.run_tool("timing", str(records), "1000", timeout=120)
        self.results["timing_session_p50_us"] = round(result["p50_us"], 2)
        self.results["timing_session_p99_us"] = round(result["p99_us"], 2)
        self.results["timing_session_drift_pct"] = round(result["drift_pct"], 5)
        self.results["naive_player_drift_pct"] = round(result["naive_drift_pct"], 3)
        self.notes["timing_session"] = (
            f"lateness min {result['min_us']:.0f} µs, max {result['max_us']:.0f} µs; "
            f"open took {result['open_us']:.0f} µs, t=0 taken {result['anchor_after_open_start_us']:.0f} µs "
            f"into it (median {result['p50_from_open_start_us']:.0f} µs if due times count "
            f"from the start of open); the machine's floor, a thread sleeping until each "
            f"due time: median {result['sleep_until_p50_us']:.0f} µs, p99 "
            f"{result['sleep_until_p99_us']:.0f} µs; naive player ends "
            f"{result['naive_last_late_ms']:.0f} ms late")

    def record(self) -> None:
        """Recording overhead on a loopback TCP pair: throughput and RTT."""
        need_disk(self.work, GiB, "record throughput")
        size = (64 if self.quick else 128) * MiB
        result = self.run_tool("record-throughput", str(size), "5" if self.quick else "15")
        self.results["record_throughput_ratio"] = round(result["ratio"], 3)
        self.notes["record_throughput"] = (
            f"median of {result['rounds']} interleaved pairs (range {result['ratio_min']:.2f}–"
            f"{result['ratio_max']:.2f}); unrecorded {result['plain_MBps']:.0f} MB/s on "
            f"{result['plain_cores']:.2f} of {result['cores']} cores, recorded "
            f"{result['recorded_MBps']:.0f} MB/s on {result['recorded_cores']:.2f} cores")
        result = self.run_tool("record-latency", "2000", "3" if self.quick else "5")
        self.results["record_latency_ratio"] = round(result["ratio"], 3)
        self.notes["record_latency"] = (
            f"median RTT unrecorded {result['plain_median_us']:.1f} µs, "
            f"recorded {result['recorded_median_us']:.1f} µs")

    def record_1gib(self) -> None:
        """Peak RSS while recording 1 GiB (buffers must stay bounded)."""
        need_disk(self.work, 2 * GiB, "record 1 GiB")
        path = self.work / "record-1GiB.wtape"
        try:
            result = self.run_tool("record-rss", str(GiB), str(path))
            self.results["record_rss_MB_1GiB"] = round(result["peak_rss_MB"], 1)
        finally:
            path.unlink(missing_ok=True)

    def reserial(self) -> None:
        """10,000 request/response exchanges through pyserial: wiretape:// vs
        pytest-reserial, in one pytest run of a bench-only venv."""
        pairs = bench_devices.reserial_comparison(self.work, self.tool, self.python,
                                                  1000 if self.quick else 10000,
                                                  3 if self.quick else 9)
        ratios = [pair["wiretape"] / pair["reserial"] for pair in pairs]
        median = {key: statistics.median(pair[key] for pair in pairs)
                  for key in ("reserial", "wiretape", "reserial_wall", "wiretape_wall")}
        self.results["reserial_replay_s"] = round(median["reserial"], 4)
        self.results["wiretape_pyserial_replay_s"] = round(median["wiretape"], 4)
        self.results["wiretape_vs_reserial_time_ratio"] = round(statistics.median(ratios), 3)
        self.notes["reserial"] = (
            f"exchange loops only, medians of {len(pairs)} interleaved pairs "
            f"(ratio {self.spread(ratios)}); whole pytest runs took "
            f"{median['wiretape_wall']:.2f} s (wiretape) and {median['reserial_wall']:.2f} s "
            "(reserial)")

    def replay_ready(self) -> None:
        """`wiretape replay FILE --pty LINK`: start to the first answer."""
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / "replay_ready_bench.py"),
                               str(self.work / "ready"), "5" if self.quick else "15"],
                              capture_output=True, text=True, timeout=600, env=self.env)
        if proc.returncode != 0:
            raise Skip("replay_ready_bench.py: "
                       + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["replay_pty_ready_ms"] = round(figures["ready_ms"], 1)
        self.notes["replay_pty_ready"] = (
            f"median of {len(figures['runs_ms'])} (range {min(figures['runs_ms']):.0f}–"
            f"{max(figures['runs_ms']):.0f} ms); the link after {figures['linked_ms']:.0f} ms; "
            f"the interpreter alone {figures['python_ms']:.0f} ms, `import wiretape.cli` "
            f"{figures['import_cli_ms']:.0f} ms (best of 5); slowest imports: "
            + ", ".join(f"{name} {ms:.0f} ms" for name, ms in figures["slowest_imports"])
            + ("" if figures.get("startup_instructions") is None else
               f"; the CLI's start-up {figures['startup_instructions'] / 1e6:.0f} M "
               "instructions beyond the interpreter's"))

    def cassette_suite(self) -> None:
        """1,000 cassette tests: wiretape's pytest plugin vs pytest-reserial."""
        tests = 200 if self.quick else 1000
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / "cassette_suite_bench.py"),
                               str(self.work / "suites"), str(tests), "3" if self.quick else "5"],
                              capture_output=True, text=True, timeout=3600, env=self.env)
        if proc.returncode != 0:
            raise Skip("cassette_suite_bench.py: "
                       + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["cassette_suite_vs_reserial_time_ratio"] = round(figures["ratio"], 3)
        self.notes["cassette_suite"] = (
            f"{figures['tests']} tests, whole pytest runs: wiretape {figures['wiretape_s']:.2f} s, "
            f"pytest-reserial {figures['reserial_s']:.2f} s (medians; ratio "
            f"{self.spread(figures['ratios'])})")

    def replay_as(self) -> None:
        """`replay --as PATH -- hokuyo-scan` vs hokuyo-scan on its simulator."""
        program = self.build / "bin" / "hokuyo-scan"
        if not program.exists():
            raise Skip(f"{program} not built")
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / "replay_as_bench.py"),
                               str(program), str(self.work / "replay-as"),
                               "5" if self.quick else "15"],
                              capture_output=True, text=True, timeout=1800, env=self.env)
        if proc.returncode != 0:
            raise Skip("replay_as_bench.py: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["replay_as_overhead_ratio"] = round(figures["ratio"], 3)
        self.notes["replay_as"] = (
            f"hokuyo-scan --json on the simulator {figures['simulator_s'] * 1e3:.0f} ms, "
            f"the whole `wiretape replay --as` {figures['replay_s'] * 1e3:.0f} ms (medians; "
            f"ratio {self.spread(figures['ratios'])}); the replayed conversation "
            f"{figures['conversation_s'] * 1e3:.0f} ms (the median of "
            f"{len(figures['conversations_s'])} recorded)")

    # --- --speed K: the Hokuyo campaign on a scaled clock ----------------
    def speed(self) -> None:
        """The Hokuyo campaign at --speed 10 against --speed 1 (hokuyo-scan's
        own 2 s timeouts, causal timing): time and outcomes."""
        program = self.build / "bin" / "hokuyo-scan"
        if not program.exists():
            raise Skip(f"{program} not built")
        runs = 40 if self.quick else 200
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / "speed_bench.py"),
                               str(program), str(runs)], capture_output=True, text=True,
                              timeout=3600, env=self.env)
        if proc.returncode != 0:
            raise Skip("speed_bench.py: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["speed_campaign_speedup"] = round(
            figures["speed1_s"] / figures["speed10_s"], 3)
        self.results["speed_campaign_same_outcomes"] = int(figures["same_outcomes"])
        differing = "; ".join(f"{a[0]}@{a[1]}: {a[2]} at K=1, {b[2]} at K=10"
                              for a, b in figures["differing"])
        self.notes["speed"] = (
            f"{figures['runs']} runs over {figures['sessions']} recordings: --speed 1 "
            f"{figures['speed1_s']:.1f} s, --speed 10 {figures['speed10_s']:.1f} s"
            + (f"; outcomes differ: {differing}" if differing else "; same outcomes")
            + f"; {os.cpu_count()} CPUs, shared")

    # --- fault campaigns ---------------------------------------------------
    def faults(self) -> None:
        """200 runs of hokuyo-scan against faulty replays: the campaign vs the
        same replays from a plain loop, vs clean replays, and --jobs 2."""
        program = self.build / "bin" / "hokuyo-scan"
        if not program.exists():
            raise Skip(f"{program} not built")
        runs = 50 if self.quick else 200
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / "faults_bench.py"),
                               str(program), str(runs)], capture_output=True, text=True,
                              timeout=3600, env=self.env)
        if proc.returncode != 0:
            raise Skip("faults_bench.py: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["faults_campaign_vs_loop_ratio"] = round(
            figures["campaign_s"] / figures["loop_s"], 3)
        self.results["faults_campaign_vs_clean_ratio"] = round(
            figures["campaign_s"] / figures["clean_s"], 3)
        self.results["faults_jobs2_speedup"] = round(
            figures["campaign_s"] / figures["campaign_jobs2_s"], 3)
        self.results["faults_inert_vs_clean_ratio"] = round(
            figures["inert_s"] / figures["clean_s"], 3)
        self.notes["faults"] = (
            f"{figures['runs']} runs over {figures['sessions']} recordings: campaign "
            f"{figures['campaign_s']:.1f} s (--jobs 2: {figures['campaign_jobs2_s']:.1f} s), "
            f"same faulty replays in a loop {figures['loop_s']:.1f} s, clean replays "
            f"{figures['clean_s']:.1f} s, with faults= firing none {figures['inert_s']:.1f} s; "
            f"faulty runs wait for the driver's timeouts, clean ones do not; "
            f"{os.cpu_count()} CPUs, shared")

    # --- wiretape view ------------------------------------------------------
    def view(self) -> None:
        """100,000 records, and 2.5M exchanges (not --quick), as view pages in Chromium."""
        if not (shutil.which("chromium") or shutil.which("chromium-browser")):
            raise Skip("chromium is not installed")
        notes = []
        for records, suffix in [(100_000, "100k")] + ([] if self.quick else [(5_000_000, "2_5M")]):
            proc = subprocess.run([str(self.python), str(ROOT / "bench" / "view_bench.py"),
                                   str(records)], capture_output=True, text=True, timeout=3600,
                                  env=dict(self.env, TMPDIR=str(self.work)))
            if proc.returncode != 0:
                raise Skip("view_bench.py: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
            figures = json.loads(proc.stdout.strip().splitlines()[-1])
            self.results.update({f"view_{name}_{suffix}": figures[name] for name in
                                 ("first_paint_ms", "write_s", "page_MB", "peak_rss_MB")})
            paints = ", ".join(f"{ms:.0f}" for ms in figures["paints_ms"])
            notes.append(f"{figures['records']} records ({figures['session_MB']} MB): "
                         f"{figures['write_s']:.1f} s, {figures['peak_rss_MB']:.0f} MB peak RSS, "
                         f"{figures['page_MB']} MB page, first paint {paints} ms (median kept)")
        self.notes["view"] = "; ".join(notes) + ("; --quick: no 2.5M case" if self.quick else "")

    def record_channels(self) -> None:
        """One `wiretape record` of 4 TCP channels vs 4 single-port records
        of the same streams: CPU per MB while the traffic flows."""
        size_mib = 16 if self.quick else 64
        need_disk(self.work, 2 * 4 * size_mib * MiB, "record_channels")
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / "record_channels_bench.py"),
                               str(size_mib), "3" if self.quick else "5"],
                              capture_output=True, text=True, timeout=1800,
                              env=dict(self.env, TMPDIR=str(self.work)))
        if proc.returncode != 0:
            raise Skip("record_channels_bench.py: "
                       + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["record_4_channels_vs_4_single_cpu_ratio"] = round(figures["ratio"], 3)
        self.notes["record_channels"] = (
            f"{figures['MB']:.0f} MB a round; 4 channels {figures['multi_ms_per_MB']:.2f} ms "
            f"CPU/MB, 4 single ports {figures['single_ms_per_MB']:.2f} ms CPU/MB (medians; "
            f"ratio {self.spread(figures['ratios'])})")

    def compress(self) -> None:
        """Compressed sessions (bench/compress_bench.py): sizes and costs."""
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / "compress_bench.py"),
                               str(self.work)] + (["--quick"] if self.quick else []),
                              capture_output=True, text=True, timeout=1800, env=self.env)
        if proc.returncode != 0:
            raise Skip("compress_bench.py: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["compress_ratio_hokuyo"] = round(figures["hokuyo_ratio"], 4)
        self.results["compress_ratio_nmea"] = round(figures["nmea_ratio"], 4)
        self.results["compressed_replay_vs_plain_ratio"] = round(figures["replay_ratio"], 3)
        self.results["compressed_write_MBps"] = round(figures["write_MBps"], 1)
        self.notes["compress"] = (f"replay throughput compressed/plain "
                                  f"{self.spread(figures['replay_ratios'])}; the replayed file "
                                  f"compressed to {figures['replay_file_ratio']:.3f}")
        # One channel of 4, compressed, beside the same pair uncompressed
        # measured in the same run (the anchor of channel_replay_time_ratio).
        self.results["compressed_channel_replay_time_ratio"] = round(figures["channel_ratio"], 3)
        self.results["compressed_channel_replay_plain_anchor_ratio"] = round(
            figures["plain_channel_ratio"], 3)
        self.notes["compressed_channel_replay"] = (
            f"c1 of 4 channels / c1 alone: compressed {self.spread(figures['channel_ratios'])}, "
            f"uncompressed {self.spread(figures['plain_channel_ratios'])}")
        # record --pty at 10 MB/s offered: received rate / offered rate, the
        # best round of each.
        self.results["record_pty_compressed_10MBps_ratio"] = round(figures["pty_zstd_ratio"], 3)
        self.results["record_pty_plain_10MBps_ratio"] = round(figures["pty_plain_ratio"], 3)
        self.notes["record_pty_10MBps"] = (
            f"{figures['pty_MB']:.0f} MB offered at 10 MB/s: compressed "
            f"{self.spread(figures['pty_zstd_ratios'])} (every byte recorded: "
            f"{figures['pty_zstd_recorded_all']}), uncompressed "
            f"{self.spread(figures['pty_plain_ratios'])} (every byte recorded: "
            f"{figures['pty_plain_recorded_all']})")

    # --- the --as shim -------------------------------------------------------
    def shim(self) -> None:
        """The shim's added cost per call: bench/shim_bench.c run with and
        without it, interleaved, each on a pty of its own; the best of the
        rounds (a shared machine only ever adds time)."""
        program = self.build / "bin" / "wiretape_shim_bench"
        if not program.exists():
            raise Skip(f"{program} not built")
        located = subprocess.run([str(self.python), "-c",
                                  "from wiretape import redirect; print(redirect.shim_path())"],
                                 capture_output=True, text=True, env=self.env)
        if located.returncode != 0:
            raise Skip("the shim: " + (located.stderr.strip().splitlines() or ["missing"])[-1])
        shim = located.stdout.strip()
        calls = 20_000 if self.quick else 200_000
        runs: dict[str, list[dict]] = {"with": [], "without": []}
        for _ in range(3 if self.quick else 7):
            for kind in ("without", "with"):
                master, terminal = os.openpty()
                try:
                    env = dict(self.env)
                    path = os.ttyname(terminal)
                    if kind == "with":
                        env.update(LD_PRELOAD=shim, WIRETAPE_REDIRECT_FROM="/dev/ttyBENCH0",
                                   WIRETAPE_REDIRECT_TO=path)
                        env.pop("WIRETAPE_LINE_CHANNEL", None)
                        path = "/dev/ttyBENCH0"
                    proc = subprocess.run([str(program), path, str(master), str(calls)],
                                          capture_output=True, text=True, timeout=600,
                                          env=env, pass_fds=(master,))
                finally:
                    os.close(master)
                    os.close(terminal)
                if proc.returncode != 0:
                    raise Skip("shim_bench: " + (proc.stderr.strip() or "failed"))
                runs[kind].append(json.loads(proc.stdout))
        best = {kind: {key: min(run[key] for run in runs[kind])
                         for key in runs[kind][0]} for kind in runs}
        added = {key: best["with"][key] - best["without"][key] for key in best["with"]}
        self.results["shim_redirected_write_added_ns"] = round(added["redirected_write"], 1)
        self.results["shim_redirected_read_added_ns"] = round(added["redirected_read"], 1)
        self.results["shim_unrelated_call_added_ns"] = round(
            max(added["unrelated_write"], added["unrelated_close"] / 2), 1)
        self.results["shim_redirected_write_ratio"] = round(
            best["with"]["redirected_write"] / best["without"]["redirected_write"], 3)
        self.notes["shim"] = ", ".join(
            f"{key} {best['without'][key]:.0f} -> {best['with'][key]:.0f} ns"
            for key in best["with"]) + (" (unrelated_close is a dup and a close: two "
                                          "wrapped calls)")

    def script_figures(self, script: str, timeout: int, *args: str) -> dict:
        """The JSON line bench/SCRIPT ARGS... WORKDIR prints last."""
        proc = subprocess.run([str(self.python), str(ROOT / "bench" / script), *args,
                               str(self.work)], capture_output=True, text=True,
                              timeout=timeout, env=self.env)
        if proc.returncode != 0:
            raise Skip(f"{script}: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        return json.loads(proc.stdout.strip().splitlines()[-1])

    def attach(self) -> None:
        """What attaching to a running program costs (bench/attach_bench.py)."""
        for key, value in self.script_figures("attach_bench.py", 900, str(self.build)).items():
            self.results["attach_" + key] = value

    def fuzz(self) -> None:
        """Fuzzing runs per second, in process and as processes, and the
        planted bugs found by `wiretape fuzz` and `wiretape faults` in one
        CPU budget (bench/fuzz_bench.py)."""
        runs, seconds = ("400", "60") if self.quick else ("2000", "300")
        for key, value in self.script_figures("fuzz_bench.py", 1800, str(self.build), runs,
                                              seconds).items():
            named = key.startswith(("fuzz_", "faults_"))
            self.results[key if named else "fuzz_" + key] = value

    def fuzz_coverage(self) -> None:
        """AFL++ coverage guidance against blind plans: seeds that reach the
        two-step crash of tests/python/fuzz/programs/two_step_driver.c
        (bench/fuzz_coverage_bench.py; skips without afl-clang-fast)."""
        seeds, runs = ("5", "50") if self.quick else ("20", "100")
        figures = self.script_figures("fuzz_coverage_bench.py", 1800, seeds, runs)
        if "skipped" in figures:
            raise Skip(figures["skipped"])
        for key in ("seeds", "runs", "afl_seeds_found", "none_seeds_found",
                    "afl_mean_first_crash_run", "none_mean_first_crash_run", "afl_mean_corpus"):
            self.results["fuzz_coverage_" + key] = figures[key]
        self.notes["fuzz_coverage"] = "first crashing run by seed: afl {}, blind {}".format(
            figures["afl_first_crash_run_by_seed"], figures["none_first_crash_run_by_seed"])

    # --- show ----------------------------------------------------------------
    def show(self) -> None:
        """`wiretape show` of 10 MB sessions with colour (bench/show_bench.py):
        the whole command line run (best of three), and show's loop against
        its loop before issue 26."""
        figures = self.script_figures("show_bench.py", 600)
        self.results["show_sensor_s"] = figures["sensor_show_s"]
        self.results["show_bulk_s"] = figures["bulk_show_s"]
        self.results["show_vs_anchor_ratio"] = round(
            figures["sensor_loop_s"] / figures["sensor_anchor_s"], 3)
        self.notes["show"] = (
            f"whole command line: sensor session ({figures['sensor_records']} records) "
            f"{figures['sensor_show_s']:.3f} s, bulk ({figures['bulk_records']} records) "
            f"{figures['bulk_show_s']:.3f} s; the loop alone {figures['sensor_loop_s']:.3f} s "
            f"and {figures['bulk_loop_s']:.3f} s, before issue 26 "
            f"{figures['sensor_anchor_s']:.3f} s and {figures['bulk_anchor_s']:.3f} s")

    def rfc2217(self) -> None:
        """The RFC 2217 client port against pyserial's rfc2217:// client on the
        same server (bench/rfc2217_bench.py): read throughput, CPU per MB
        and one-way latency, in alternating pairs."""
        proc = subprocess.run([str(self.python), "-W", "ignore",
                               str(ROOT / "bench" / "rfc2217_bench.py")]
                              + (["--quick"] if self.quick else []),
                              capture_output=True, text=True, timeout=900, env=self.env)
        if proc.returncode != 0:
            raise Skip("rfc2217_bench.py: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        f = json.loads(proc.stdout.strip().splitlines()[-1])
        self.results["rfc2217_read_cpu_vs_pyserial_ratio"] = f["read_cpu_s_per_MB_ratio"]
        self.results["rfc2217_read_vs_pyserial_ratio"] = f["read_MBps_ratio"]
        self.results["rfc2217_latency_p50_vs_pyserial_ratio"] = f["latency_p50_us_ratio"]
        self.results["rfc2217_latency_p99_vs_pyserial_ratio"] = f["latency_p99_us_ratio"]
        self.results["rfc2217_read_MBps"] = f["wiretape_read_MBps"]
        self.results["rfc2217_latency_p50_us"] = f["wiretape_latency_p50_us"]
        self.notes["rfc2217"] = "; ".join(
            f"{name} {f[name + '_read_MBps']:.2f} MB/s at {f[name + '_read_cpu_s_per_MB']:.3f} "
            f"CPU s/MB, one-way p50 {f[name + '_latency_p50_us']:.0f} µs "
            f"p99 {f[name + '_latency_p99_us']:.0f} µs" for name in ("wiretape", "pyserial")) + (
            f" (medians of {f['pairs']} pairs of {f['size_bytes']} bytes and {f['rounds']} "
            f"rounds; CPU ratio range {f['read_cpu_s_per_MB_ratio_range']})")

    def diff(self) -> None:
        """`wiretape diff` of two long sessions (bench/diff_bench.py): the
        exchanges aligned against the comparison by position before issue 38."""
        figures = self.script_figures("diff_bench.py", 900)
        self.results["diff_aligned_s"] = figures["aligned_s"]
        self.results["diff_worst_s"] = figures["worst_s"]
        self.results["diff_aligned_vs_anchor_ratio"] = round(
            figures["aligned_s"] / figures["anchor_s"], 3)
        self.notes["diff"] = (
            f"{figures['exchanges']} exchanges: by position {figures['anchor_s']:.3f} s "
            f"({figures['anchor_divergences']} divergences), aligned {figures['aligned_s']:.3f} s "
            f"({figures['aligned_divergences']}: {figures['aligned_summary']}); nothing "
            f"aligns {figures['worst_s']:.3f} s ({figures['worst_summary']})")

    def gbench(self) -> None:
        """The Google Benchmark program: the per-call view, and the request
        mode figures (GBENCH_FIGURES)."""
        if not self.gbench_path_ok():
            raise Skip("wiretape_bench not built (Google Benchmark missing: "
                       "apt-get install libbenchmark-dev)")
        out = self.work / "gbench.json"
        proc = subprocess.run([str(self.gbench_program), f"--benchmark_out={out}",
                               "--benchmark_out_format=json", "--benchmark_min_time=0.2"],
                              capture_output=True, text=True, timeout=900, env=self.env)
        if proc.returncode != 0:
            raise Skip("wiretape_bench: " + (proc.stderr.strip().splitlines() or ["failed"])[-1])
        figures = []
        for entry in json.loads(out.read_text()).get("benchmarks", []):
            for counter, key in GBENCH_FIGURES.get(entry["name"].split("/")[0], ()):
                if counter in entry:
                    self.results[key] = round(entry[counter], 3)
            rate = entry.get("bytes_per_second")
            figures.append(f"{entry['name'].replace('/real_time', '')} "
                           + (f"{rate / 1e6:.0f} MB/s" if rate else
                              f"{entry['real_time']:.1f} {entry['time_unit']}"))
        self.notes["gbench"] = f"{out}: " + "; ".join(figures)

    def gbench_path_ok(self) -> bool:
        return self.gbench_program.exists()


FIGURES = ["replay", "replay_1gib", "timing", "record", "record_1gib", "pty_proxy",
           "tcp_proxy", "udp_proxy", "relay_counts", "relay_instructions", "replay_ready",
           "cassette_suite", "replay_as", "reserial", "gbench", "faults", "speed", "view", "show",
           "diff", "shim", "channels", "record_channels", "rfc2217", "compress", "attach", "fuzz",
           "fuzz_coverage"]


def machine_note() -> dict:
    """Where and when the figures were taken, for README's table (bench/readme_table.py)."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    release = ".".join(platform.release().split(".")[:2])
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d"),
        "cpu": cpu,
        "cores": os.cpu_count(),
        "system": f"{platform.system()} {release}",
        "load_average": round(os.getloadavg()[0], 1),
    }


def build_programs(build: Path) -> None:
    subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build), "-DWIRETAPE_BENCH=ON"],
                   check=True, stdout=subprocess.DEVNULL)
    targets = ["wiretape_bench_tool", "wiretape_relay_bench", "wiretape_shim_bench",
               "traced_program", "planted-scan",
               "planted_scan_fuzz", "hokuyo_scan20_fuzz"]
    # wiretape_bench exists only when Google Benchmark was found.
    listing = subprocess.run(["cmake", "--build", str(build), "--target", "help"],
                             capture_output=True, text=True).stdout
    if "wiretape_bench:" in listing or "wiretape_bench " in listing:
        targets.append("wiretape_bench")
    subprocess.run(["cmake", "--build", str(build), "--target", *targets], check=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", required=True, type=Path, help="the CMake build tree")
    parser.add_argument("--only", help="comma-separated figure groups: " + ",".join(FIGURES))
    parser.add_argument("--quick", action="store_true", help="smaller sizes, fewer rounds")
    parser.add_argument("--no-build", action="store_true", help="use the programs as built")
    parser.add_argument("--udp-seconds", type=float, metavar="S",
                        help="how long each UDP proxy round floods (default 10, --quick 2)")
    args = parser.parse_args(argv)
    build = args.build.resolve()
    groups = FIGURES if not args.only else args.only.split(",")
    unknown = [g for g in groups if g not in FIGURES]
    if unknown:
        parser.error(f"unknown figure group(s) {', '.join(unknown)}; valid: {', '.join(FIGURES)}")
    if not args.no_build:
        build_programs(build)
    if args.udp_seconds is not None and args.udp_seconds <= 0:
        parser.error("--udp-seconds must be positive")
    bench = Bench(build, args.quick, args.udp_seconds)
    results_path = bench.work / "results.json"
    # --only updates the figures it measures and keeps the others.
    notes_path = bench.work / "notes.json"
    if args.only and results_path.exists():
        bench.results.update(json.loads(results_path.read_text()))
        if notes_path.exists():
            bench.notes.update(json.loads(notes_path.read_text()).get("notes", {}))
    skipped: dict[str, str] = {}
    machine = machine_note()
    for name in groups:
        print(f"bench: {name} ...", flush=True)
        started = time.perf_counter()
        try:
            getattr(bench, name)()
        except Skip as reason:
            skipped[name] = str(reason)
            print(f"bench: {name} skipped: {reason}", flush=True)
        except Exception as error:  # a broken figure must not hide the others
            skipped[name] = f"error: {error}"
            traceback.print_exc()
        else:
            print(f"bench: {name} done in {time.perf_counter() - started:.1f} s", flush=True)
    if bench_devices.USED_RUNNER:
        bench.notes["relays_run_by"] = (
            "wiretape.bridge through bench/bridge_runner.py (the CLI lacked: "
            + ", ".join(sorted(bench_devices.USED_RUNNER)) + ")")
    results_path.write_text(json.dumps(bench.results, indent=2, sort_keys=True) + "\n")
    notes_path.write_text(
        json.dumps({"notes": bench.notes, "skipped": skipped, "machine": machine},
                   indent=2, ensure_ascii=False) + "\n")
    print_table(bench.results, bench.notes, skipped)
    print(f"results: {results_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
