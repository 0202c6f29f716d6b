"""`wiretape convert` shows rich's progress bar on a terminal's stderr, and
nothing of it when stderr is not a terminal (issue 26)."""

import os
import subprocess
import sys

import wiretape


def _session(path):
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(2000):
            writer.write("rx", n * 1000, b"x" * 100)


def _read_all(master: int) -> bytes:
    chunks = []
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    return b"".join(chunks)


def test_on_a_terminal_convert_shows_a_progress_bar(tmp_path):
    source = tmp_path / "s.wtape"
    _session(source)
    master, slave = os.openpty()
    child = subprocess.Popen([sys.executable, "-m", "wiretape.cli", "convert", str(source),
                              str(tmp_path / "s.jsonl")],
                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave,
                             env={**os.environ, "TERM": "xterm", "COLUMNS": "100"})
    os.close(slave)
    try:
        shown = _read_all(master).decode("utf-8", "replace")
        assert child.wait(60) == 0, shown
    finally:
        if child.poll() is None:
            child.kill()
        os.close(master)
    assert "converting" in shown, shown
    assert "converted 2000 records" in shown, shown


def test_off_a_terminal_convert_prints_its_summary_only(tmp_path):
    source = tmp_path / "s.wtape"
    _session(source)
    done = subprocess.run([sys.executable, "-m", "wiretape.cli", "convert", str(source),
                           str(tmp_path / "s.jsonl")], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines() == [
        f"converted 2000 records: {source} (wiretape) -> {tmp_path / 's.jsonl'} (jsonl)"], \
        done.stderr
