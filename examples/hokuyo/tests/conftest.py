"""Fixtures for the Hokuyo example tests: the repository, the hokuyo-scan
program, the shared real recordings, and simulators on a pty or TCP."""
import os
import pathlib
import select
import subprocess
import sys
import time

import pytest

HERE = pathlib.Path(__file__).resolve().parent
EXAMPLE = HERE.parent
REPO = EXAMPLE.parent.parent
sys.path.insert(0, str(EXAMPLE / "sim"))


def bin_dir():
    # WIRETAPE_BIN_DIR points the tests at another build tree's programs.
    return pathlib.Path(os.environ.get("WIRETAPE_BIN_DIR", REPO / "build" / "bin"))


@pytest.fixture(scope="session")
def repo():
    return REPO


@pytest.fixture(scope="session")
def hokuyo_scan():
    program = bin_dir() / "hokuyo-scan"
    if not program.exists():
        pytest.skip(f"SKIPPED LOUDLY: {program} is not built (run `make`)")
    return program


@pytest.fixture(scope="session")
def shared_data():
    data = REPO.parent / "shared" / "data" / "flexiport"
    if not (data / "urg04lx_2011.logr").exists():
        pytest.skip(f"SKIPPED LOUDLY: the real recordings are not in {data}")
    return data


class Simulator:
    def __init__(self, process, where):
        self.process = process
        self.where = where  # a pty link path or "HOST:PORT"

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def start_simulator(*args, deadline_s=15.0):
    """Starts the simulator and waits for its ready line (no sleeping)."""
    process = subprocess.Popen(
        [sys.executable, str(EXAMPLE / "sim"), *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + deadline_s
    while True:
        left = end - time.monotonic()
        ready, _, _ = select.select([process.stdout], [], [], max(left, 0))
        if not ready:
            process.kill()
            raise AssertionError(f"simulator {args} printed no ready line in {deadline_s} s")
        line = process.stdout.readline()
        if not line:
            raise AssertionError(f"simulator {args} exited: {process.stderr.read()}")
        if line.startswith("ready "):
            fields = dict(f.split("=", 1) for f in line.split()[1:])
            return Simulator(process, fields.get("link") or fields.get("tcp"))


@pytest.fixture
def simulator(tmp_path):
    """simulator(*args): a started simulator on a pty link in tmp_path
    (or TCP when args hold --listen); stopped at the end of the test."""
    started = []

    def start(*args):
        if "--listen" not in args:
            args = ("--pty", str(tmp_path / f"sim{len(started)}"), *args)
        sim = start_simulator(*args)
        started.append(sim)
        return sim

    yield start
    for sim in started:
        sim.stop()


def run_scan(program, port, *args, timeout=60):
    return subprocess.run([str(program), "--port", port, *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)
