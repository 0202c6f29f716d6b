#!/usr/bin/env python3
"""The RFC 2217 client's throughput, CPU and one-way latency (bench/run.py,
group "rfc2217"): wiretape's port (type=rfc2217, through the Python binding)
against pyserial's `rfc2217://` client, both on the same server, `wiretape
serve --protocol rfc2217` in a process of its own in front of a pty whose
master (in this process) plays the device. Prints one JSON line. Usage:
rfc2217_bench.py [--quick]

Each pair of runs measures both clients, in alternating order, so that the
machine's drift from run to run cancels out in the per-pair ratios:
- read_MBps: the device writes SIZE bytes (every byte value, so the server
  doubles each 255 and the client undoes it), the client reads them all;
  bounded by the server and the pty as much as by the client;
- read_cpu_s_per_MB: this process's CPU time over that read (the client's
  threads, and the device's writes, the same for both), per MB;
- latency_p50_us / latency_p99_us: the device writes one byte, the client's
  blocking read returns it; one clock (this process), ROUNDS rounds.
"""

import json
import os
import re
import signal
import statistics
import subprocess
import sys
import threading
import time
import tty

import serial

import wiretape
from wiretape import _core

QUICK = "--quick" in sys.argv
# pyserial's client parses each byte in Python: a few hundred kB/s at best.
SIZE = (256 if QUICK else 1024) * 1024
ROUNDS = 200 if QUICK else 1000
PAIRS = 1 if QUICK else 5
BAUD = 115200  # a pty moves bytes at its own speed; the rate is only set


class Device:
    """The pty's master side: the device behind the server."""

    def __init__(self):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        self.path = os.ttyname(self.slave)

    def write_all(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            view = view[os.write(self.master, view[:4096]):]

    def close(self):
        os.close(self.master)
        os.close(self.slave)


class WiretapeClient:
    name = "wiretape"

    def __init__(self, address: str):
        host, port = address.rsplit(":", 1)
        self.port = wiretape.open_port(_core.option_string(
            [("type", "rfc2217"), ("host", host), ("port", int(port)), ("baud", BAUD),
             ("timeout", 10)]))

    def read_some(self) -> int:
        return len(self.port.read(65536))

    def read_one(self) -> bytes:
        return self.port.read(1)

    def close(self):
        self.port.close()


class PyserialClient:
    name = "pyserial"

    def __init__(self, address: str):
        self.port = serial.serial_for_url("rfc2217://" + address, baudrate=BAUD, timeout=10)

    def read_some(self) -> int:
        return len(self.port.read(max(1, min(65536, self.port.in_waiting))))

    def read_one(self) -> bytes:
        return self.port.read(1)

    def close(self):
        self.port.close()


def timed_read(client, device: Device) -> tuple:
    payload = bytes(range(256)) * (SIZE // 256)
    writer = threading.Thread(target=device.write_all, args=(payload,))
    cpu = time.process_time()
    started = time.perf_counter()
    writer.start()
    got = 0
    while got < len(payload):
        got += client.read_some()
    elapsed = time.perf_counter() - started
    cpu = time.process_time() - cpu
    writer.join()
    return len(payload) / elapsed / 1e6, cpu / (len(payload) / 1e6)


def latencies(client, device: Device) -> list:
    samples = []
    for n in range(ROUNDS):
        byte = bytes([n % 251])
        started = time.perf_counter()
        os.write(device.master, byte)
        got = client.read_one()
        samples.append((time.perf_counter() - started) * 1e6)
        assert got == byte, (got, byte)
    return sorted(samples)


class Server:
    """`wiretape serve --protocol rfc2217` in front of the pty, as a child."""

    def __init__(self, device: Device):
        self.child = subprocess.Popen(
            [sys.executable, "-m", "wiretape.cli", "serve", "--device",
             f"type=serial,device={device.path},exclusive=false", "--listen", "127.0.0.1:0",
             "--protocol", "rfc2217", "-q"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        for _ in range(20):
            line = self.child.stderr.readline()
            match = re.search(r"clients use tcp (\S+:\d+)", line)
            if match:
                self.address = match.group(1)
                return
        self.child.kill()
        raise SystemExit("serve announced no address: " + self.child.stderr.read())

    def close(self):
        self.child.send_signal(signal.SIGINT)
        try:
            self.child.wait(10)
        except subprocess.TimeoutExpired:
            self.child.kill()
            self.child.wait()


def run(kind, device: Device, server: Server) -> dict:
    client = kind(server.address)
    try:
        read_MBps, cpu_s_per_MB = timed_read(client, device)
        samples = latencies(client, device)
    finally:
        client.close()
    return {"read_MBps": read_MBps, "read_cpu_s_per_MB": cpu_s_per_MB,
            "latency_p50_us": samples[len(samples) // 2],
            "latency_p99_us": samples[int(len(samples) * 0.99)]}


def main():
    device = Device()
    server = Server(device)
    runs = {WiretapeClient.name: [], PyserialClient.name: []}
    try:
        for index in range(PAIRS):
            order = (WiretapeClient, PyserialClient) if index % 2 == 0 else (
                PyserialClient, WiretapeClient)
            for kind in order:
                runs[kind.name].append(run(kind, device, server))
    finally:
        server.close()
        device.close()
    figures = {"size_bytes": SIZE, "rounds": ROUNDS, "pairs": PAIRS}
    for name, results in runs.items():
        for key in results[0]:
            figures[f"{name}_{key}"] = round(statistics.median(r[key] for r in results), 3)
    pairs = list(zip(runs["wiretape"], runs["pyserial"]))
    for key in ("read_MBps", "read_cpu_s_per_MB", "latency_p50_us", "latency_p99_us"):
        ratios = [ours[key] / theirs[key] for ours, theirs in pairs]
        figures[f"{key}_ratio"] = round(statistics.median(ratios), 3)
        figures[f"{key}_ratio_range"] = [round(min(ratios), 3), round(max(ratios), 3)]
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
