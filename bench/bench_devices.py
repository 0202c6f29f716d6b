"""Device-level benchmarks run.py drives: relays over a pseudo-terminal device
(wiretape record --pty and wiretape serve against socat) and the pyserial
replay comparison with pytest-reserial.

The "device" is a pseudo-terminal this process holds: bytes written to its
master side come out of the serial device the relay opened, and what the relay
writes to the device can be read from the master.
"""

from __future__ import annotations

import os
import select
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CHUNK = 64 * 1024


class Skip(Exception):
    """A figure that cannot be measured here; the message says why."""


# --- processes --------------------------------------------------------------
USED_RUNNER: set[str] = set()


def wiretape_command(subcommand: str, python: Path) -> list[str]:
    """The wiretape CLI, once it is checked that `subcommand` exists in it;
    else the same engine through wiretape.bridge (bench/bridge_runner.py)."""
    script = Path(python).parent / "wiretape"
    command = [str(script)] if script.exists() else [str(python), "-m", "wiretape.cli"]
    probe = subprocess.run(command + [subcommand, "--help"], capture_output=True, text=True,
                           timeout=60)
    if probe.returncode == 0 and "--device" in probe.stdout:
        return command
    check = subprocess.run([str(python), "-c", "import wiretape.bridge as b; b.record, b.serve"],
                           capture_output=True, text=True, timeout=60)
    if check.returncode != 0:
        raise Skip(f"neither `wiretape {subcommand}` nor wiretape.bridge is available")
    USED_RUNNER.add(subcommand)
    return [str(python), str(Path(__file__).resolve().parent / "bridge_runner.py")]


def need_socat() -> None:
    if shutil.which("socat") is None:
        raise Skip("socat is not installed (apt-get install socat)")


def spawn(command: list[str]) -> subprocess.Popen:
    return subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, start_new_session=True)


def stop(process: subprocess.Popen) -> None:
    """Ctrl-C first (wiretape ends cleanly on it), then harder."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(10)
    if process.stderr:
        process.stderr.close()


def failure(process: subprocess.Popen, what: str) -> Skip:
    err = process.stderr.read().decode(errors="replace").strip() if process.stderr else ""
    return Skip(f"{what}: exited with {process.returncode}: {err.splitlines()[-1:] or ''}")


# --- the device -------------------------------------------------------------
class PtyDevice:
    """A pseudo-terminal standing in for a serial device."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._echo: threading.Thread | None = None
        self._stop = threading.Event()

    def options(self) -> str:
        return f"type=serial,device={self.path},baud=115200"

    def feed(self, size: int) -> threading.Thread:
        """Writes `size` bytes as the device's output, on a thread."""
        def run() -> None:
            block = bytes(range(256)) * (CHUNK // 256)
            sent = 0
            while sent < size:
                try:
                    sent += os.write(self.master, block[: min(CHUNK, size - sent)])
                except OSError:
                    return
        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        return thread

    def echo(self) -> None:
        """Sends back everything written to the device, until close()."""
        def run() -> None:
            while not self._stop.is_set():
                ready, _, _ = select.select([self.master], [], [], 0.2)
                if not ready:
                    continue
                try:
                    data = os.read(self.master, CHUNK)
                    while data:
                        data = data[os.write(self.master, data):]
                except OSError:
                    return
        self._echo = threading.Thread(target=run, daemon=True)
        self._echo.start()

    def close(self) -> None:
        self._stop.set()
        if self._echo:
            self._echo.join(5)
        os.close(self.master)
        os.close(self.slave)


def wait_for(predicate, process: subprocess.Popen, what: str, seconds: float = 15.0):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        result = predicate()
        if result:
            return result
        if process.poll() is not None:
            raise failure(process, what)
        time.sleep(0.02)  # polling another process's readiness, not a test
    raise Skip(f"{what}: not ready after {seconds:.0f} s")


def read_exactly(read, size: int, seconds: float = 120.0) -> None:
    deadline = time.monotonic() + seconds
    got = 0
    while got < size:
        if time.monotonic() > deadline:
            raise Skip(f"relay delivered {got} of {size} bytes in {seconds:.0f} s")
        data = read(min(CHUNK, size - got))
        if not data:
            raise Skip(f"relay closed after {got} of {size} bytes")
        got += len(data)


# --- pty relays: wiretape record --pty vs socat --------------------------------
def pty_relay_throughput(kind: str, size: int, work: Path, python: Path) -> float:
    """Bytes per second from the device to a client of the relay's pty."""
    device = PtyDevice()
    link = work / f"relay-{kind}.pty"
    link.unlink(missing_ok=True)
    if kind == "wiretape":
        command = wiretape_command("record", python) + [
            "record", "--device", device.options(), "--pty", str(link),
            "-o", str(work / "relay.wtape")]
    else:
        need_socat()
        command = ["socat", "-b65536", f"PTY,link={link},raw,echo=0",
                   f"FILE:{device.path},raw,echo=0"]
    process = spawn(command)
    client = -1
    try:
        wait_for(link.exists, process, f"{kind} pty relay")
        client = os.open(link, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(client)

        def read(n: int) -> bytes:
            ready, _, _ = select.select([client], [], [], 10)
            return os.read(client, n) if ready else b""
        start = time.perf_counter()
        feeder = device.feed(size)
        read_exactly(read, size)
        seconds = time.perf_counter() - start
        feeder.join(10)
        return size / seconds
    finally:
        if client >= 0:
            os.close(client)
        stop(process)
        device.close()
        (work / "relay.wtape").unlink(missing_ok=True)


# --- TCP relays: wiretape serve vs socat TCP-LISTEN ---------------------------------
def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def tcp_relay_figures(kind: str, size: int, roundtrips: int, work: Path,
                      python: Path) -> tuple[float, float]:
    """(bytes/s device->client, median µs of a 64-byte round trip)."""
    device = PtyDevice()
    port = free_port()
    if kind == "wiretape":
        command = wiretape_command("serve", python) + [
            "serve", "--device", device.options(), "--listen", f"127.0.0.1:{port}"]
    else:
        need_socat()
        command = ["socat", "-b65536", f"TCP-LISTEN:{port},bind=127.0.0.1,reuseaddr",
                   f"FILE:{device.path},raw,echo=0"]
    process = spawn(command)
    client = None
    try:
        def connect():
            try:
                return socket.create_connection(("127.0.0.1", port), timeout=10)
            except OSError:
                return None
        client = wait_for(connect, process, f"{kind} TCP relay")
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client.settimeout(10)

        start = time.perf_counter()
        feeder = device.feed(size)
        read_exactly(client.recv, size)
        bps = size / (time.perf_counter() - start)
        feeder.join(10)

        device.echo()
        message = b"p" * 64
        rtts = []
        for _ in range(roundtrips):
            begin = time.perf_counter()
            client.sendall(message)
            read_exactly(client.recv, len(message), 10)
            rtts.append((time.perf_counter() - begin) * 1e6)
        return bps, statistics.median(rtts)
    finally:
        if client is not None:
            client.close()
        stop(process)
        device.close()


# --- pyserial replay: wiretape:// vs pytest-reserial ------------------------------
TEST_FILE = '''\
import json, os, time

import serial

N = int(os.environ["BENCH_EXCHANGES"])
OUT = os.environ["BENCH_OUT"]
SESSION = os.environ["BENCH_SESSION"]


def exchange_all(port):
    start = time.perf_counter()
    for i in range(N):
        port.write(b"REQ%05d\\n" % i)
        expected = b"RSP%05d,OK\\n" % i
        answer = port.read(len(expected))
        assert answer == expected, (i, answer)
    return time.perf_counter() - start


def save(key, seconds):
    with open(OUT, "a") as out:
        out.write(json.dumps({key: seconds}) + "\\n")


def test_reserial(reserial):
    port = serial.Serial("/dev/reserial-bench", 115200, timeout=1)
    save("reserial_loop", exchange_all(port))
    port.close()


def test_wiretape():
    import wiretape.urlhandler

    wiretape.urlhandler.register()  # the wiretape:// URL scheme, for pyserial

    port = serial.serial_for_url("wiretape://" + SESSION + "?timing=none", timeout=1)
    save("wiretape_loop", exchange_all(port))
    port.close()
'''


def bench_venv(work: Path) -> Path:
    """build/bench/venv with pytest-reserial and pyserial; wiretape by path."""
    venv = work / "venv"
    python = venv / "bin" / "python"
    if not (venv / ".ready").exists():
        subprocess.run([sys.executable, "-m", "venv", "--clear", str(venv)], check=True)
        proc = subprocess.run([str(python), "-m", "pip", "install", "-q", "pytest-reserial",
                               "pyserial", "pytest"], capture_output=True, text=True)
        if proc.returncode != 0:
            raise Skip("cannot install pytest-reserial from PyPI: "
                       + (proc.stderr.strip().splitlines() or ["pip failed"])[-1])
        site = next((venv / "lib").glob("python3*/site-packages"))
        (site / "wiretape-source.pth").write_text(str(ROOT / "python") + "\n")
        (venv / ".ready").write_text("")
    return python


def reserial_comparison(work: Path, tool: Path, python: Path, count: int) -> dict:
    import json

    venv_python = bench_venv(work)
    where = work / "reserial"
    where.mkdir(exist_ok=True)
    (where / "test_exchanges.py").write_text(TEST_FILE)
    session = where / "exchanges.wtape"
    subprocess.run([str(tool), "make-exchanges", str(session), str(count)], check=True,
                   stdout=subprocess.DEVNULL)
    tx = "".join("REQ%05d\n" % i for i in range(count))
    rx = "".join("RSP%05d,OK\n" % i for i in range(count))
    (where / "test_exchanges.jsonl").write_text(json.dumps(
        {"test_reserial": {"rx_encoding": "utf-8", "tx_encoding": "utf-8", "rx": rx, "tx": tx}})
        + "\n")
    out = where / "times.jsonl"
    out.unlink(missing_ok=True)
    env = dict(os.environ, BENCH_EXCHANGES=str(count), BENCH_OUT=str(out),
               BENCH_SESSION=str(session), PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTEST_ADDOPTS", None)
    wall = {}
    for key in ("reserial", "wiretape"):
        start = time.perf_counter()
        proc = subprocess.run([str(venv_python), "-m", "pytest", "-q", "-p", "no:cacheprovider",
                               "-k", f"test_{key}", str(where / "test_exchanges.py")],
                              cwd=where, env=env, capture_output=True, text=True, timeout=600)
        wall[key] = time.perf_counter() - start
        if proc.returncode != 0:
            raise Skip(f"{key} replay through pyserial failed: "
                       + " | ".join(proc.stdout.strip().splitlines()[-3:]))
    loops = {}
    for line in out.read_text().splitlines():
        loops.update(json.loads(line))
    return {"reserial": loops["reserial_loop"], "wiretape": loops["wiretape_loop"],
            "reserial_wall": wall["reserial"], "wiretape_wall": wall["wiretape"]}
