"""A fault campaign says how far it is (issue 26): a line every few seconds
and one at the end on stderr when it is not a terminal (a CI log), one line
rewritten in place on a terminal; and its table says why a cell is blank."""

import io
import subprocess
import sys
from pathlib import Path

import wiretape
from wiretape import faults

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
# Answers every request the way the recording does; exits 3 on anything else.
DRIVER = """
import os, sys, tty
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd)
for n in range(3):
    os.write(fd, f"Q{n}\\n".encode())
    line = b""
    while not line.endswith(b"\\n"):
        try:
            chunk = os.read(fd, 1)
        except OSError:
            sys.exit(3)
        if not chunk:
            sys.exit(3)
        line += chunk
    if line != f"R{n}-ok\\n".encode():
        sys.exit(3)
"""


def make_session(path: Path) -> Path:
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(3):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}-ok\n".encode())
    return path


def test_not_on_a_terminal_progress_is_whole_lines_on_stderr(tmp_path):
    session = make_session(tmp_path / "s.wtape")
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    result = subprocess.run([*WIRETAPE, "faults", str(session), "--kinds", "garbage,disconnect",
                             "--timeout", "5", "--options", "timing=none", "--",
                             sys.executable, str(driver), "{port}"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stderr.splitlines()
    assert "wiretape faults: a clean run, then 6 runs with faults" in lines
    assert "\r" not in result.stderr
    assert any(line.startswith("wiretape faults: 6/6 runs (") and line.endswith(" s")
               for line in lines), result.stderr


def test_on_a_terminal_progress_is_one_line_rewritten(tmp_path):
    session = make_session(tmp_path / "s.wtape")
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    live = io.StringIO()
    faults.campaign(str(session), [sys.executable, str(driver), "{port}"],
                    kinds=["garbage"], timeout=5, replay_options="timing=none", progress=live)
    text = live.getvalue()
    assert text.count("\r") == 3 and text.endswith("\n")
    assert "\rwiretape faults: 3/3 runs (" in text and "error), " in text


def test_the_table_says_why_cells_are_blank(tmp_path):
    session = str(make_session(tmp_path / "s.wtape"))
    runs = [faults.Run(kind="drop", where=f"exchange:{n}", outcome="ok", exit=0, seconds=0.1)
            for n in (0, 2)]  # exchange 1 not run: a blank cell
    budgeted = faults.Campaign(session, 7, runs, planned=2, budget=2, cases=3)
    assert "blank: not run: left out by --budget 2 (sampled by --seed 7)" in \
        faults.table(budgeted)
    sharded = faults.Campaign(session, 0, runs, planned=2, cases=3,
                              shard=faults.Shard.parse("1/2"))
    assert "blank: not run: another shard's (this is 1/2)" in faults.table(sharded)
    whole = faults.Campaign(session, 0, runs[:1], planned=1, cases=1)
    assert "blank" not in faults.table(whole)
