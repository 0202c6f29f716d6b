#!/usr/bin/env python3
"""Rewrites README.md's benchmark table from a bench run's results.

Usage: bench/readme_table.py RESULTS_JSON [README] [--notes NOTES_JSON]
       bench/readme_table.py --check [README]

`make bench` runs it after bench/run.py, so the README shows the latest run
and is never edited by hand. It replaces what lies between the markers
``<!-- bench-table:begin -->`` and ``<!-- bench-table:end -->``: a line
giving the run's date and machine, the table, and a comment holding the
figures the table was made from, so that a test can regenerate the section
from the README alone and see that nobody changed it by hand (--check).

The date and machine come from notes.json's ``machine`` (bench/run.py
records it); a run without it is dated by results.json's time and its
machine is "not recorded".
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

BEGIN = "<!-- bench-table:begin -->"
END = "<!-- bench-table:end -->"
_DATA_PREFIX = "<!-- bench-data: "
_DATA_SUFFIX = " -->"

ROOT = Path(__file__).resolve().parent.parent

Figures = Dict[str, float]


def _ratio(key: str) -> Callable[[Figures], Optional[str]]:
    return lambda r: f"{r[key]:.2f}" if key in r else None


def _pair(first: str, second: str, unit: str) -> Callable[[Figures], Optional[str]]:
    def text(r: Figures) -> Optional[str]:
        if first not in r and second not in r:
            return None
        return " / ".join(f"{r[k]:.3g}" if k in r else "–" for k in (first, second)) + unit
    return text


def _number(value: float) -> str:
    return f"{value:.3g}" if value >= 0.001 or value == 0 else "< 0.001"


# (figure, value, target text, keys whose targets the verdict checks, anchor)
ROWS: List[Tuple[str, Callable[[Figures], Optional[str]], str, Tuple[str, ...],
                 Callable[[Figures, Dict[str, str]], str]]] = [
    ("replay, timing=none, C++",
     lambda r: f"{r['replay_throughput_cpp_MBps']:.0f} MB/s" if "replay_throughput_cpp_MBps" in r else None,
     "", (), lambda r, n: ""),
    ("replay C++ / `cat` of the same file", _ratio("replay_vs_cat_ratio"), "≥ 0.8",
     ("replay_vs_cat_ratio",),
     lambda r, n: f"`cat` {n['cat_100MiB_MBps']}" if "cat_100MiB_MBps" in n else ""),
    ("replay Python / `cat`", _ratio("replay_python_vs_cat_ratio"), "≥ 0.25",
     ("replay_python_vs_cat_ratio",), lambda r, n: ""),
    ("replay peak RSS, 100 MiB / 1 GiB session",
     _pair("replay_rss_MB_100MiB", "replay_rss_MB_1GiB", " MiB"), "flat", (), lambda r, n: ""),
    ("timing=session lateness, median / p99",
     _pair("timing_session_p50_us", "timing_session_p99_us", " µs"), "≤ 20 / ≤ 200 µs",
     ("timing_session_p50_us", "timing_session_p99_us"), lambda r, n: ""),
    ("timing=session drift over 10 s",
     lambda r: f"{_number(abs(r['timing_session_drift_pct']))} %"
     if "timing_session_drift_pct" in r else None,
     "≤ 0.1 %", ("timing_session_drift_pct",),
     lambda r, n: f"naive sleep-per-record player: {r['naive_player_drift_pct']:.1f} %"
     if "naive_player_drift_pct" in r else ""),
    ("recording, 64 KiB writes over TCP, recorded / unrecorded",
     _ratio("record_throughput_ratio"), "≥ 0.9", ("record_throughput_ratio",), lambda r, n: ""),
    ("recording, 64-byte ping-pong RTT, recorded / unrecorded",
     _ratio("record_latency_ratio"), "≤ 1.1", ("record_latency_ratio",), lambda r, n: ""),
    ("recording 1 GiB, peak RSS",
     lambda r: f"{r['record_rss_MB_1GiB']:.1f} MiB" if "record_rss_MB_1GiB" in r else None,
     "bounded", (), lambda r, n: ""),
    ("`wiretape record --pty` / socat, CPU per MB relayed",
     _ratio("pty_proxy_vs_socat_cpu_ratio"), "≤ 1.0", ("pty_proxy_vs_socat_cpu_ratio",),
     lambda r, n: ""),
    ("`wiretape record --pty` / socat, one-way latency p99",
     _ratio("pty_proxy_vs_socat_latency_p99_ratio"), "≤ 1.0",
     ("pty_proxy_vs_socat_latency_p99_ratio",), lambda r, n: ""),
    ("`wiretape record --listen` / socat, CPU per MB relayed",
     _ratio("tcp_proxy_vs_socat_cpu_ratio"), "≤ 1.0", ("tcp_proxy_vs_socat_cpu_ratio",),
     lambda r, n: ""),
    ("`wiretape record --listen` / socat, one-way latency p99",
     _ratio("tcp_proxy_vs_socat_latency_p99_ratio"), "≤ 1.0",
     ("tcp_proxy_vs_socat_latency_p99_ratio",), lambda r, n: ""),
    ("`wiretape record --udp` / socat, datagrams lost at 100,000/s of 1,200 B",
     _pair("udp_proxy_loss_pct", "udp_socat_loss_pct", " %"), "≤ socat's",
     ("udp_proxy_vs_socat_delivered_ratio",),
     lambda r, n: f"delivered ratio {r['udp_proxy_vs_socat_delivered_ratio']:.4f}"
     if "udp_proxy_vs_socat_delivered_ratio" in r else ""),
    ("match=request / match=sequence, 100,000 exchanges",
     _ratio("request_vs_sequence_time_ratio"), "≤ 1.5", ("request_vs_sequence_time_ratio",),
     lambda r, n: ""),
    ("`profile=modbus-tcp`, a client reordering its polls / match=sequence",
     _ratio("modbus_reordering_vs_sequence_time_ratio"), "≤ 2",
     ("modbus_reordering_vs_sequence_time_ratio",), lambda r, n: ""),
    ("match=request, 1 GiB session, peak RSS",
     lambda r: f"{r['request_rss_MB_1GiB']:.1f} MiB" if "request_rss_MB_1GiB" in r else None,
     "≤ 64 MiB", ("request_rss_MB_1GiB",), lambda r, n: ""),
    ("fault campaign of 200 `hokuyo-scan` runs / the same faulty replays from a plain loop",
     _ratio("faults_campaign_vs_loop_ratio"), "≤ 1.3", ("faults_campaign_vs_loop_ratio",),
     lambda r, n: f"/ 200 clean replays: {r['faults_campaign_vs_clean_ratio']:.2f}"
     if "faults_campaign_vs_clean_ratio" in r else ""),
    ("fault campaign, `--jobs 2` speed-up over `--jobs 1`",
     _ratio("faults_jobs2_speedup"), "≥ 1.8", ("faults_jobs2_speedup",), lambda r, n: ""),
    ("replays with `faults=` that fire none / clean replays",
     _ratio("faults_inert_vs_clean_ratio"), "≤ 1.3", ("faults_inert_vs_clean_ratio",),
     lambda r, n: ""),
    ("recording 4 channels in one file / 4 single-port recordings, CPU per MB",
     _ratio("record_4_channels_vs_4_single_cpu_ratio"), "≤ 1.1",
     ("record_4_channels_vs_4_single_cpu_ratio",), lambda r, n: ""),
    ("10,000 exchanges through pyserial, wiretape / pytest-reserial",
     _ratio("wiretape_vs_reserial_time_ratio"), "≤ 0.5", ("wiretape_vs_reserial_time_ratio",),
     lambda r, n: f"reserial {r['reserial_replay_s']:.3f} s" if "reserial_replay_s" in r else ""),
]

sys.path.insert(0, str(Path(__file__).resolve().parent))
from targets import TARGETS  # noqa: E402  (key -> (target, better, what): one list of targets)


def missed(key: str, value: float) -> bool:
    target, better, _ = TARGETS[key]
    if target is None or better == "info":
        return False
    return value < target if better == "higher" else abs(value) > target


def render_section(results: Figures, notes: Dict[str, str], date: str, machine: str) -> str:
    """The README text between the markers (markers excluded)."""
    lines = [f"One run, {date}, on {machine}:", "",
             "| figure | value | target | anchor |", "|---|---|---|---|"]
    for figure, value, target, checked, anchor in ROWS:
        text = value(results)
        if text is None:
            text = "not measured"
        elif any(key in results and missed(key, results[key]) for key in checked):
            target += " — **missed**"
        cells = (figure, text, target, anchor(results, notes))
        lines.append("|" + "|".join(f" {cell} " if cell else " " for cell in cells) + "|")
    data = {"results": results, "notes": {k: v for k, v in notes.items() if k == "cat_100MiB_MBps"},
            "date": date, "machine": machine}
    lines += ["", _DATA_PREFIX + json.dumps(data, sort_keys=True, ensure_ascii=False) + _DATA_SUFFIX]
    return "\n" + "\n".join(lines) + "\n"


def machine_note(notes_file: dict) -> Optional[Tuple[str, str]]:
    """(date, machine) from notes.json's "machine", as bench/run.py writes it."""
    machine = notes_file.get("machine")
    if not machine:
        return None
    text = (f"a {machine['cores']}-core {machine['cpu']} machine ({machine['system']}), "
            f"load average {machine['load_average']:.1f} at the start")
    return machine["date"], text


def split_readme(text: str) -> Tuple[str, str, str]:
    """(before, section, after); ValueError if the markers are not there once each."""
    if text.count(BEGIN) != 1 or text.count(END) != 1 or text.index(BEGIN) > text.index(END):
        raise ValueError(f"README must hold {BEGIN} and then {END}, once each")
    before, rest = text.split(BEGIN)
    section, after = rest.split(END)
    return before, section, after


def embedded_data(section: str) -> dict:
    for line in section.splitlines():
        if line.startswith(_DATA_PREFIX) and line.endswith(_DATA_SUFFIX):
            return json.loads(line[len(_DATA_PREFIX):-len(_DATA_SUFFIX)])
    raise ValueError("the benchmark section holds no bench-data comment")


def regenerate(section: str) -> str:
    """The section the generator makes from the figures the section holds."""
    data = embedded_data(section)
    return render_section(data["results"], data["notes"], data["date"], data["machine"])


def update_readme(readme: Path, results_path: Path, notes_path: Optional[Path],
                  machine: Optional[str] = None) -> None:
    results = json.loads(results_path.read_text())
    notes_file = json.loads(notes_path.read_text()) if notes_path and notes_path.exists() else {}
    note = machine_note(notes_file)
    if note is None:
        mtime = datetime.datetime.fromtimestamp(results_path.stat().st_mtime, datetime.timezone.utc)
        note = (mtime.strftime("%Y-%m-%d"), "a machine not recorded (notes.json has no machine)")
    if machine:
        note = (note[0], machine)
    before, _, after = split_readme(readme.read_text())
    section = render_section(results, notes_file.get("notes", {}), *note)
    readme.write_text(before + BEGIN + section + END + after)


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", nargs="?", type=Path, help="build/bench/results.json")
    parser.add_argument("readme", nargs="?", type=Path, default=ROOT / "README.md")
    parser.add_argument("--notes", type=Path,
                        help="notes.json (default: beside the results)")
    parser.add_argument("--machine", help="describe the machine (for a run whose notes.json "
                        "does not), e.g. 'a 2-core AMD EPYC virtual machine (Linux 6.18)'")
    parser.add_argument("--check", action="store_true",
                        help="only check that README's section is what its figures make")
    args = parser.parse_args(argv)
    if args.check:
        readme = args.results or args.readme  # `--check README` reads naturally
        _, section, _ = split_readme(readme.read_text())
        if regenerate(section) != section:
            print(f"{readme}: the benchmark table differs from what its figures make; "
                  "run make bench (or bench/readme_table.py RESULTS)", file=sys.stderr)
            return 1
        return 0
    if args.results is None:
        parser.error("RESULTS_JSON is required")
    notes = args.notes or args.results.with_name("notes.json")
    update_readme(args.readme, args.results, notes, args.machine)
    print(f"{args.readme}: benchmark table rewritten from {args.results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
