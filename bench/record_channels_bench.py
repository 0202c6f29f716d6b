"""Recording several channels at once (issue 25): one `wiretape record` of 4
channels (4 TCP devices, `--device cN=... --listen cN=...`) against 4
single-port `wiretape record`s of the same traffic, in alternating order.
The figure is the CPU seconds per MB the recorder processes spend while the
traffic flows (read from /proc before and after it, so that start-up and
interpreter import cost nothing), 4 channels / 4 single ports.

Prints one JSON line: {"ratio": median, "ratios": [...], "multi_ms_per_MB":
..., "single_ms_per_MB": ..., "MB": ...}.

Usage: python record_channels_bench.py MIB_PER_CHANNEL ROUNDS
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import threading
from typing import List, Tuple

CHANNELS = 4
CHUNK = 64 * 1024
TICKS = os.sysconf("SC_CLK_TCK")
DEADLINE_S = 120.0


class StreamingDevice:
    """A TCP device that sends `size` bytes to each connection, then closes it."""

    def __init__(self, size: int):
        self.size = size
        self.server = socket.socket()
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(4)
        self.options = f"type=tcp,host=127.0.0.1,port={self.server.getsockname()[1]}"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        block = bytes(range(256)) * (CHUNK // 256)
        while True:
            try:
                connection, _ = self.server.accept()
            except OSError:
                return
            with connection:
                left = self.size
                while left > 0:
                    connection.sendall(block[:min(left, CHUNK)])
                    left -= min(left, CHUNK)

    def close(self) -> None:
        self.server.close()


def cpu_seconds(pid: int) -> float:
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS  # utime, stime


def start_recorder(args: List[str]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "wiretape.cli", "record", "-q", *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def addresses(child: subprocess.Popen, count: int) -> List[Tuple[str, int]]:
    found = []
    while len(found) < count:
        line = child.stderr.readline()
        if not line:
            raise SystemExit("wiretape record ended: " + child.stderr.read())
        match = re.search(r"clients use tcp (\S+):(\d+)", line)
        if match:
            found.append((match.group(1), int(match.group(2))))
    return found


def drain(address: Tuple[str, int], size: int) -> None:
    with socket.create_connection(address, timeout=DEADLINE_S) as client:
        got = 0
        while got < size:
            chunk = client.recv(1 << 20)
            if not chunk:
                raise SystemExit(f"the stream through {address} ended after {got} bytes")
            got += len(chunk)


def traffic_cpu(children: List[subprocess.Popen], targets: List[Tuple[str, int]],
                size: int) -> float:
    """CPU seconds the recorders spent while every stream was drained."""
    before = sum(cpu_seconds(child.pid) for child in children)
    readers = [threading.Thread(target=drain, args=(address, size)) for address in targets]
    for reader in readers:
        reader.start()
    for reader in readers:
        reader.join()
    after = sum(cpu_seconds(child.pid) for child in children)
    return after - before


def stop(children: List[subprocess.Popen]) -> None:
    for child in children:
        child.send_signal(signal.SIGINT)
    for child in children:
        child.wait(DEADLINE_S)


def one_round(size: int, work: str, index: int, multi: bool) -> float:
    devices = [StreamingDevice(size) for _ in range(CHANNELS)]
    outputs = [os.path.join(work, f"channels-{index}-{n}.wtape") for n in range(CHANNELS)]
    try:
        if multi:
            args = ["-o", outputs[0]]
            for n, device in enumerate(devices):
                args += ["--device", f"c{n}={device.options}", "--listen", f"c{n}=127.0.0.1:0"]
            children = [start_recorder(args)]
            targets = addresses(children[0], CHANNELS)
        else:
            children = [start_recorder(["--device", device.options, "--listen", "127.0.0.1:0",
                                        "-o", output])
                        for device, output in zip(devices, outputs)]
            targets = [addresses(child, 1)[0] for child in children]
        try:
            return traffic_cpu(children, targets, size)
        finally:
            stop(children)
    finally:
        for device in devices:
            device.close()
        for output in outputs:
            if os.path.exists(output):
                os.unlink(output)


def main() -> int:
    size = int(sys.argv[1]) << 20
    rounds = int(sys.argv[2])
    work = os.environ.get("TMPDIR", "/tmp")
    megabytes = CHANNELS * size / 1e6
    multi, single = [], []
    for index in range(rounds):
        order = (True, False) if index % 2 == 0 else (False, True)
        for is_multi in order:
            cpu = one_round(size, work, index, is_multi)
            (multi if is_multi else single).append(cpu / megabytes)
    ratios = [m / s for m, s in zip(multi, single)]
    print(json.dumps({"ratio": statistics.median(ratios), "ratios": ratios,
                      "multi_ms_per_MB": statistics.median(multi) * 1e3,
                      "single_ms_per_MB": statistics.median(single) * 1e3,
                      "MB": megabytes}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
