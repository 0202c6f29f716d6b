"""The recording proxies' wall-clock and CPU figures (bench/run.py's
`pty_proxy`, `tcp_proxy`, `udp_proxy`): wiretape record --pty, --listen and
--udp against socat doing the same relay, on wiretape_relay_bench's devices
(bench/relay_bench.cpp, commands from bench_devices.py)."""

from __future__ import annotations

import statistics

import bench_devices
from bench_devices import need_disk

MiB = 1 << 20
# The UDP proxy's load: datagrams a second, and their size (relay_bench.cpp).
UDP_RATE = 100_000
UDP_DATAGRAM = 1200


class RelayJobs:
    """Mixed into run.py's Bench: uses its quick, udp_seconds, work, python,
    relay_program, results and notes."""

    def relay_rounds(self, client: str, first: int, second: int, rounds: int) -> dict[str, list]:
        """wiretape and socat as the same relay on the same kind of device,
        interleaved in alternating order; per-pair ratios, so that the
        machine's drift from round to round cancels out."""
        figures: dict[str, list] = {"wiretape": [], "socat": []}
        for index in range(rounds):
            order = ("wiretape", "socat") if index % 2 == 0 else ("socat", "wiretape")
            for kind in order:
                figures[kind].append(bench_devices.relay_figures(
                    self.relay_program, kind, client, first, second, self.work, self.python))
        return figures

    @staticmethod
    def pair_ratios(figures: dict[str, list], key: str) -> list[float]:
        return [ours[key] / theirs[key]
                for ours, theirs in zip(figures["wiretape"], figures["socat"])]

    @staticmethod
    def spread(values: list[float]) -> str:
        return f"range {min(values):.2f}–{max(values):.2f} over {len(values)} pairs"

    def stream_proxy(self, client: str, prefix: str) -> None:
        """wiretape record (--pty or --listen) vs socat relaying the same pty
        device: the relay's CPU seconds per MB while the device streams to
        the client, and the one-way latency p99 of single messages."""
        size = (16 if self.quick else 64) * MiB
        # 15 pairs: a p99 of 2000 messages on a shared machine moves ±30 %
        # from run to run for socat and wiretape alike.
        figures = self.relay_rounds(client, size, 500 if self.quick else 2000,
                                    3 if self.quick else 15)
        cpu = self.pair_ratios(figures, "cpu_s_per_MB")
        latency = self.pair_ratios(figures, "one_way_p99_us")
        self.results[f"{prefix}_vs_socat_cpu_ratio"] = round(statistics.median(cpu), 3)
        self.results[f"{prefix}_vs_socat_latency_p99_ratio"] = round(statistics.median(latency), 3)
        best = {kind: {key: statistics.median(f[key] for f in runs)
                         for key in ("bytes_per_s", "cpu_s_per_MB", "one_way_p50_us",
                                     "one_way_p99_us", "to_client_p50_us", "to_device_p50_us",
                                     "message_cpu_us")}
                  for kind, runs in figures.items()}
        self.notes[prefix] = "; ".join(
            f"{kind} {m['cpu_s_per_MB'] * 1e3:.2f} ms CPU/MB at {m['bytes_per_s'] / 1e6:.0f} MB/s, "
            f"one-way p50 {m['one_way_p50_us']:.0f} µs p99 {m['one_way_p99_us']:.0f} µs "
            f"(p50 to the client {m['to_client_p50_us']:.0f}, to the device "
            f"{m['to_device_p50_us']:.0f}; {m['message_cpu_us']:.1f} µs of CPU a message)"
            for kind, m in best.items()) + (
            f" (medians of {len(cpu)} pairs; CPU ratio {self.spread(cpu)}, "
            f"p99 ratio {self.spread(latency)})")

    def pty_proxy(self) -> None:
        """wiretape record --pty vs socat PTY ... FILE:device."""
        self.stream_proxy("pty", "pty_proxy")

    def tcp_proxy(self) -> None:
        """wiretape record --listen vs socat TCP-LISTEN ... FILE:device."""
        self.stream_proxy("tcp", "tcp_proxy")

    def udp_proxy(self) -> None:
        """wiretape record --udp vs socat UDP-LISTEN ... UDP:device: 100,000
        datagrams/s of 1,200 bytes for udp_seconds, what reaches the device."""
        seconds = self.udp_seconds if self.udp_seconds else (2.0 if self.quick else 10.0)
        need_disk(self.work, int(2 * UDP_RATE * UDP_DATAGRAM * seconds),
                  "udp_proxy (the recording of the flood)")
        # Two rounds: each relay once first and once second.
        figures = self.relay_rounds("udp", UDP_RATE, int(seconds * 1000), 2)
        totals = {kind: {key: sum(f[key] for f in runs) for key in ("offered", "received", "lost")}
                  for kind, runs in figures.items()}
        loss = {kind: 100.0 * t["lost"] / t["offered"] for kind, t in totals.items()}
        for kind, prefix in (("wiretape", "udp_proxy"), ("socat", "udp_socat")):
            self.results[f"{prefix}_datagrams_sent"] = totals[kind]["offered"]
            self.results[f"{prefix}_datagrams_received"] = totals[kind]["received"]
            self.results[f"{prefix}_datagrams_lost"] = totals[kind]["lost"]
        self.results["udp_proxy_loss_pct"] = round(loss["wiretape"], 4)
        self.results["udp_socat_loss_pct"] = round(loss["socat"], 4)
        delivered = {kind: t["received"] / t["offered"] for kind, t in totals.items()}
        self.results["udp_proxy_vs_socat_delivered_ratio"] = round(
            delivered["wiretape"] / delivered["socat"], 5)
        rates = {kind: statistics.median(f["send_rate"] for f in runs)
                 for kind, runs in figures.items()}
        cpu = {kind: statistics.median(f["cpu_s"] / f["seconds"] for f in runs)
               for kind, runs in figures.items()}
        self.notes["udp_proxy"] = "; ".join(
            f"{kind} sent {t['offered']}, received {t['received']}, lost {t['lost']} "
            f"({loss[kind]:.3f} %) at {rates[kind]:.0f} datagrams/s, "
            f"relay CPU {cpu[kind]:.2f} s/s"
            for kind, t in totals.items()) + (
            f" ({len(figures['socat'])} rounds of {seconds:g} s each, "
            f"{UDP_DATAGRAM}-byte datagrams)")
