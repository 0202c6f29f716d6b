"""Device-level benchmarks run.py drives: the recording proxies (wiretape
record --pty, --listen and --udp against socat doing the same relay) and the
pyserial replay comparison with pytest-reserial.

The relays are measured by wiretape_relay_bench (bench/relay_bench.cpp),
which holds the pseudo-terminal device, starts the relay, feeds, reads and
echoes on native threads; this module only says which relay to start.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


class Skip(Exception):
    """A figure that cannot be measured here; the message says why."""


GiB = 1 << 30


def free_bytes(path: Path) -> int:
    stat = os.statvfs(path)
    return stat.f_bavail * stat.f_frsize


def need_disk(path: Path, needed: int, what: str) -> None:
    free = free_bytes(path)
    if free < needed:
        raise Skip(f"{what}: needs {needed / GiB:.1f} GiB free in {path}, "
                   f"only {free / GiB:.1f} GiB")


# --- relays: wiretape record --pty / --listen / --udp against socat -----------
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


DEVICE = "type=serial,device={device},baud=115200"
UDP_DEVICE = "type=udp,host=127.0.0.1,port={device_port}"


def relay_command(kind: str, client: str, python: Path, work: Path) -> list[str]:
    """The relay's command line, with wiretape_relay_bench's placeholders
    ({device}, {device_port}, {port}, {link}). client: "pty" (wiretape record
    --pty vs socat PTY), "tcp" (wiretape record --listen vs socat TCP-LISTEN)
    or "udp" (wiretape record --udp vs socat UDP-LISTEN, which takes the
    first sender as its peer and relays without forking)."""
    if kind == "socat":
        if shutil.which("socat") is None:
            raise Skip("socat is not installed (apt-get install socat)")
        if client == "udp":
            return ["socat", "-b65536", "UDP-LISTEN:{port},bind=127.0.0.1,reuseaddr",
                    "UDP:127.0.0.1:{device_port}"]
        side = ("PTY,link={link},raw,echo=0" if client == "pty"
                else "TCP-LISTEN:{port},bind=127.0.0.1,reuseaddr")
        return ["socat", "-b65536", side, "FILE:{device},raw,echo=0"]
    output = ["-o", str(work / "relay.wtape")]
    record = wiretape_command("record", python) + ["record"]
    if client == "pty":
        return record + ["--device", DEVICE, "--pty", "{link}", *output]
    if client == "tcp":
        return record + ["--device", DEVICE, "--listen", "127.0.0.1:{port}", *output]
    return record + ["--device", UDP_DEVICE, "--udp", "127.0.0.1:{port}", *output]


def relay_figures(program: Path, kind: str, client: str, first: int, second: int,
                  work: Path, python: Path) -> dict:
    """One run of one relay. pty/tcp: first = bytes, second = messages;
    {"bytes_per_s", "cpu_s_per_MB", "one_way_p99_us", ...}. udp: first =
    datagrams a second, second = milliseconds; {"sent", "received", "lost",
    ...}."""
    return run_relay(program, client, first, second, work,
                     relay_command(kind, client, python, work), kind)


def run_relay(program: Path, client: str, first: int, second: int, work: Path,
              relay: list[str], kind: str, env: dict | None = None) -> dict:
    """wiretape_relay_bench running `relay` (a relay_command, perhaps
    wrapped) in `env` (default: this process's); see relay_figures."""
    command = [str(program), client, str(first), str(second), str(work), "--", *relay]
    try:
        proc = subprocess.run(command, capture_output=True, text=True, timeout=1800, env=env)
    finally:
        (work / "relay.wtape").unlink(missing_ok=True)
    if proc.returncode != 0:
        message = proc.stderr.strip() or f"exit status {proc.returncode}"
        raise Skip(f"{kind} relay: {message.splitlines()[0]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


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


def reserial_comparison(work: Path, tool: Path, python: Path, count: int,
                        rounds: int) -> list[dict]:
    """`rounds` interleaved pairs of pytest runs (reserial, wiretape, then
    wiretape, reserial, ...): one run of 10,000 exchanges takes 20-50 ms,
    where one pair alone moves by half on a shared machine."""
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
    pairs = []
    for index in range(rounds):
        order = ("reserial", "wiretape") if index % 2 == 0 else ("wiretape", "reserial")
        out.unlink(missing_ok=True)
        wall = {}
        for key in order:
            start = time.perf_counter()
            proc = subprocess.run([str(venv_python), "-m", "pytest", "-q", "-p",
                                   "no:cacheprovider", "-k", f"test_{key}",
                                   str(where / "test_exchanges.py")],
                                  cwd=where, env=env, capture_output=True, text=True,
                                  timeout=600)
            wall[key] = time.perf_counter() - start
            if proc.returncode != 0:
                raise Skip(f"{key} replay through pyserial failed: "
                           + " | ".join(proc.stdout.strip().splitlines()[-3:]))
        loops = {}
        for line in out.read_text().splitlines():
            loops.update(json.loads(line))
        pairs.append({"reserial": loops["reserial_loop"], "wiretape": loops["wiretape_loop"],
                      "reserial_wall": wall["reserial"], "wiretape_wall": wall["wiretape"]})
    return pairs
