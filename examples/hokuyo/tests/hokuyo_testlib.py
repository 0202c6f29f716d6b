"""Helpers of the Hokuyo example tests (a module of its own name, so that
it never collides with another folder's conftest)."""
import os
import pathlib
import select
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
EXAMPLE = HERE.parent
REPO = EXAMPLE.parent.parent
sys.path.insert(0, str(EXAMPLE / "sim"))
# The shared test data is located in one place, the Python tests' helper.
sys.path.insert(0, str(REPO / "tests" / "python" / "support"))

from real_recordings import flexiport_log  # noqa: E402,F401 (for conftest.py)


def bin_dir():
    # WIRETAPE_BIN_DIR points the tests at another build tree's programs.
    return pathlib.Path(os.environ.get("WIRETAPE_BIN_DIR", REPO / "build" / "bin"))


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


def run_scan(program, port, *args, timeout=60):
    return subprocess.run([str(program), "--port", port, *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)
