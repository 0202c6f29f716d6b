"""wiretape convert --from umockdev: an umockdev tty script (made by
umockdev-record --script) becomes a session that the recorded program
replays against through ``wiretape://``, printing what it printed when it
was recorded; a script with a bad line is one clean error naming the file
and the line, exit 1."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import wiretape
from wiretape import cli
from wiretape.tools import importers

DATA = Path(__file__).resolve().parents[2] / "data" / "umockdev"
SCRIPT = DATA / "talk.script"
TALK = DATA / "talk.py"
sys.path.insert(0, str(DATA))
import talk  # noqa: E402  (the recorded program: its device and answers)

sys.path.remove(str(DATA))

EXPECTED_OUTPUT = "".join(repr(talk.answer(request)) + "\n" for request in talk.REQUESTS)


def run_cli(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def replay_program(capsys, tmp_path, script):
    session = tmp_path / "talk.wtape"
    code, _, err = run_cli(capsys, "convert", script, session, "--from", "umockdev", "-q")
    assert code == 0, err
    proc = subprocess.run([sys.executable, str(TALK),
                           f"wiretape://{session}?timing=none&unused=error"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_checked_in_script_replays_to_its_program(capsys, tmp_path):
    assert replay_program(capsys, tmp_path, SCRIPT) == EXPECTED_OUTPUT


def test_fresh_script_from_umockdev_record_replays_to_its_program(capsys, tmp_path):
    if shutil.which("umockdev-record") is None:
        pytest.skip("umockdev-record not installed: apt-get install umockdev")
    device = talk.Device()
    script = tmp_path / "fresh.script"
    proc = subprocess.run(["umockdev-record", f"--script={device.path}={script}", "--",
                           sys.executable, str(TALK), device.path],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == EXPECTED_OUTPUT
    assert replay_program(capsys, tmp_path, script) == EXPECTED_OUTPUT


def test_delays_become_times_and_escapes_bytes(tmp_path):
    script = tmp_path / "s.script"
    script.write_bytes(b"# made by hand\nd 0 /dev/ttyS0\nw 5 AT^M\nf 10 -\nr 20 ^@^`\xff^J\n"
                       b"w 0  lead space\nQ 0 -\nr 0 never\n")
    header, records = importers.umockdev_records(script)
    assert list(records) == [("tx", 5_000_000, b"AT\r"), ("rx", 25_000_000, b"\x00^\xff\n"),
                             ("tx", 25_000_000, b" lead space")]
    assert header.metadata == {"umockdev.device": "/dev/ttyS0", "umockdev.fuzz_percent": "10"}
    assert (header.source_format, header.source_files) == ("umockdev", ["s.script"])


# (the script, the bad line's number, what the message must say)
BAD = {
    "unknown_operation": (b"w 0 A\nx 0 B\n", 2, "unknown operation 'x'"),
    "no_space": (b"w0 A\n", 1, "a space after the operation"),
    "value_not_a_number": (b"r 0 A\nr soon A\n", 2, "value: expected a whole number"),
    "negative_value": (b"r -5 A\n", 1, "value: expected a whole number"),
    "no_data": (b"w 5\n", 1, "no data after the delay"),
    "bad_escape": (b"r 0 A^!B\n", 1, "data: bad escape '^!' at column 2"),
    "lone_caret": (b"w 0 AB^\n", 1, "data: a lone '^' at the end"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_line_is_one_clean_error(capsys, tmp_path, case):
    content, line, message = BAD[case]
    script = tmp_path / "bad.script"
    script.write_bytes(content)
    output = tmp_path / "out.wtape"
    code, _, err = run_cli(capsys, "convert", script, output, "--from", "umockdev")
    assert code == 1
    assert f"{script}:{line}: " in err and message in err, err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    assert not output.exists()


def test_session_holds_the_script_bytes(capsys, tmp_path):
    session = tmp_path / "s.wtape"
    assert run_cli(capsys, "convert", SCRIPT, session, "--from", "umockdev", "-q")[0] == 0
    received = b"".join(r.data for r in wiretape.SessionReader(str(session)) if r.kind == "rx")
    assert received == b"".join(talk.answer(request) for request in talk.REQUESTS)
    assert os.path.getsize(session) > 0
