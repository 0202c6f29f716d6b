"""How soon `wiretape replay FILE --pty LINK` answers (issue 42): from the
start of the command to the first answer read on the pty, a request of the
recording written as soon as LINK exists. Beside it, where the start-up
goes: the interpreter alone, `import wiretape.cli`, and the slowest imports
of `-X importtime`.

Prints one JSON line: {"ready_ms": median, "runs_ms": [...], "linked_ms":
median time until LINK exists, "python_ms":
..., "import_cli_ms": ..., "slowest_imports": [[module, ms], ...],
"startup_instructions": the command line's start-up (imports, parser,
parse) in user-space instructions beyond the interpreter's, by valgrind,
or null without it}.

Usage: python replay_ready_bench.py WORKDIR ROUNDS
"""

from __future__ import annotations

import json
import os
import re
import select
import shutil
import signal
import statistics
import subprocess
import sys
import termios
import time
import tty
from pathlib import Path
from typing import Optional

import wiretape

REQUEST = b"PING\n"
ANSWER = b"PONG\n"
DEADLINE_S = 30.0
# As a user runs it: with compiled modules cached (here outside the source
# tree), where PYTHONDONTWRITEBYTECODE would make each run compile them all.
CHILD_ENV = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}


def write_recording(path: Path) -> None:
    with wiretape.SessionWriter(str(path), port_type="serial", capture="wire",
                                port_options="type=serial,device=/dev/ttyBENCH") as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 1_000_000, REQUEST)
        writer.write("rx", 2_000_000, ANSWER)


def wiretape_command() -> list[str]:
    script = Path(sys.executable).parent / "wiretape"
    return [str(script)] if script.exists() else [sys.executable, "-m", "wiretape.cli"]


def one_run(recording: Path, link: Path) -> tuple[float, float]:
    """Milliseconds from the start of the command to LINK, and to the answer."""
    link.unlink(missing_ok=True)
    start = time.perf_counter()
    child = subprocess.Popen([*wiretape_command(), "replay", str(recording), "--pty", str(link),
                              "--timing", "none", "-q"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=CHILD_ENV)
    try:
        while not link.exists():
            if child.poll() is not None:
                raise SystemExit("wiretape replay ended: " + child.stderr.read().decode())
            if time.perf_counter() - start > DEADLINE_S:
                raise SystemExit(f"{link} did not appear in {DEADLINE_S:.0f} s")
            time.sleep(0.0005)  # waiting for another process's link: 0.5 ms resolution
        linked = time.perf_counter() - start
        fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd, termios.TCSANOW)
            os.write(fd, REQUEST)
            got = b""
            while not got.endswith(ANSWER):
                left = DEADLINE_S - (time.perf_counter() - start)
                if left <= 0 or not select.select([fd], [], [], left)[0]:
                    raise SystemExit(f"no answer on {link} in {DEADLINE_S:.0f} s (got {got!r})")
                got += os.read(fd, 64)
            ready = time.perf_counter() - start
        finally:
            os.close(fd)
    finally:
        child.send_signal(signal.SIGINT)
        child.wait(DEADLINE_S)
    return linked * 1e3, ready * 1e3


def command_ms(args: list[str], rounds: int = 5) -> float:
    """The best of `rounds` runs (a shared machine only ever adds time)."""
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        subprocess.run(args, check=True, capture_output=True, env=CHILD_ENV)
        best = min(best, time.perf_counter() - start)
    return best * 1e3


def slowest_imports(count: int = 8) -> list[list]:
    """`-X importtime` of `import wiretape.cli`: the modules of largest
    cumulative time that are not inside one another's count already."""
    proc = subprocess.run([sys.executable, "-X", "importtime", "-c", "import wiretape.cli"],
                          capture_output=True, text=True, check=True, env=CHILD_ENV)
    rows = []
    for line in proc.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cumulative, name = (part.strip() for part in line[len("import time:"):].split("|"))
        depth = (len(name) - len(name.lstrip())) // 2
        if depth <= 1:  # top-level imports and their direct children
            rows.append([name.strip(), round(int(cumulative) / 1e3, 1)])
    return sorted(rows, key=lambda row: -row[1])[:count]


# The command line's start-up up to the replay's own work: its imports, its
# parser, the parse. Counted, not timed: a count does not move with the
# machine's load.
STARTUP = ("import sys\n"
           "from wiretape.cli.main import build_parser, command_run_alone, split_command\n"
           "import wiretape.cli.run\n"
           "own, _ = split_command(sys.argv[1:])\n"
           "build_parser(only=command_run_alone(own)).parse_args(own)\n")


def instructions(code: str, *args: str) -> Optional[int]:
    """User-space instructions of `python -c code args` (valgrind's lackey),
    or None without valgrind."""
    if shutil.which("valgrind") is None:
        return None
    proc = subprocess.run(["valgrind", "--tool=lackey", "--basic-counts=yes", sys.executable,
                           "-c", code, *args], capture_output=True, text=True, env=CHILD_ENV)
    found = re.search(r"guest instrs:\s+([\d,]+)", proc.stderr)
    if proc.returncode != 0 or found is None:
        return None
    return int(found.group(1).replace(",", ""))


def startup_instructions(recording: Path, link: Path) -> Optional[int]:
    """The start-up's instructions beyond the interpreter's own (`-c pass`)."""
    with_cli = instructions(STARTUP, "replay", str(recording), "--pty", str(link),
                            "--timing", "none", "-q")
    alone = instructions("pass")
    return None if with_cli is None or alone is None else with_cli - alone


def main() -> int:
    work = Path(sys.argv[1])
    rounds = int(sys.argv[2])
    work.mkdir(parents=True, exist_ok=True)
    recording = work / "ready.wtape"
    write_recording(recording)
    link = work / f"ready-{os.getpid()}.pty"
    CHILD_ENV["PYTHONPYCACHEPREFIX"] = str(work / "pycache")
    one_run(recording, link)  # fills the cache
    runs = [one_run(recording, link) for _ in range(rounds)]
    print(json.dumps({
        "ready_ms": statistics.median(run[1] for run in runs),
        "runs_ms": [round(run[1], 1) for run in runs],
        "linked_ms": statistics.median(run[0] for run in runs),
        "python_ms": command_ms([sys.executable, "-c", "pass"]),
        "import_cli_ms": command_ms([sys.executable, "-c", "import wiretape.cli"]),
        "slowest_imports": slowest_imports(),
        "startup_instructions": startup_instructions(recording, link)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
