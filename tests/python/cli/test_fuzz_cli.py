"""`wiretape fuzz SESSION -- CMD {port}` (DESIGN §27, docs/fuzzing.md):
plans run as replays to an unmodified program; its crashes are written as
minimized, deduplicated sessions listed in index.json, that replay; bad
input exits 2 naming the problem."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape
from wiretape import faults

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]


def make_session(path: Path) -> Path:
    """Three line exchanges: Qn\\n answered by Rn-abcdef\\n."""
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(3):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}-abcdef\n".encode())
    return path


# It aborts (a crash) on an answer it did not expect; "robust" after the path:
# a clean error exit instead, and no wait longer than half a second.
DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    robust = sys.argv[2:] == ["robust"]
    tty.setraw(fd)
    for n in range(3):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            if not select.select([fd], [], [], 0.5)[0]:
                sys.exit(3)              # no answer in time: a clean error
            try:
                chunk = os.read(fd, 1)
            except OSError:
                sys.exit(3)
            if not chunk:
                sys.exit(3)
            line += chunk
        if line != f"R{n}-abcdef\\n".encode():
            if robust:
                sys.exit(3)
            os.abort()                   # the bug: trusts the device
    sys.exit(0)
""")


@pytest.fixture()
def session(tmp_path: Path) -> Path:
    return make_session(tmp_path / "lines.wtape")


@pytest.fixture()
def driver(tmp_path: Path) -> list:
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    return [sys.executable, str(script), "{port}"]


def run_cli(*args, timeout=600):
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True, timeout=timeout)


def test_crashes_are_found_minimized_deduplicated_and_replay(tmp_path, session, driver):
    findings = tmp_path / "findings"
    result = run_cli("fuzz", str(session), "--runs", "12", "--seed", "3", "--timeout", "5",
                     "--findings", str(findings), "--", *driver)
    assert result.returncode == 1, result.stdout + result.stderr
    index = json.loads((findings / "index.json").read_text())
    crashes = [entry for entry in index["findings"] if entry["kind"] == "crash"]
    # Every abort has one cause (no stack to tell them apart): one finding.
    assert len(crashes) == 1, index
    crash = crashes[0]
    assert crash["signal"] == 6 and crash["signature"] == "signal SIGABRT"
    assert set(crash) >= {"kind", "signal", "signature", "session", "changed", "repro"}
    # Minimized: one change is enough to make this driver abort.
    assert len(crash["changed"]) == 1, crash
    assert crash["changed"][0].startswith("rx record "), crash
    finding = findings / crash["session"]
    assert list(wiretape.SessionReader(str(finding)).header.edits) == crash["changed"]
    # The reproduction line replays the finding to the driver: it aborts again.
    # (this wiretape on PATH, the line's fixed port moved under tmp_path)
    line = crash["repro"].replace(faults.REPRO_PORT, str(tmp_path / "repro-port"))
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    again = subprocess.run(["bash", "-c", line], capture_output=True, text=True, timeout=120,
                           env=env)
    assert again.returncode in (134, -6), again.stdout + again.stderr
    # --replay: the finding still reproduces (exit 1); fixed, it does not (exit 0).
    replayed = run_cli("fuzz", "--replay", str(findings), "--timeout", "5", "--", *driver)
    assert replayed.returncode == 1, replayed.stdout + replayed.stderr
    assert "still crash" in replayed.stdout
    fixed = run_cli("fuzz", "--replay", str(findings), "--timeout", "5", "--", *driver, "robust")
    assert fixed.returncode == 0, fixed.stdout + fixed.stderr


def test_a_robust_driver_leaves_nothing_found(tmp_path, session, driver):
    findings = tmp_path / "findings"
    junit = tmp_path / "fuzz.xml"
    result = run_cli("fuzz", str(session), "--runs", "8", "--seed", "3", "--timeout", "5",
                     "--findings", str(findings), "--junit", str(junit), "--", *driver, "robust")
    assert result.returncode == 0, result.stdout + result.stderr
    assert json.loads((findings / "index.json").read_text()) == {"findings": []}
    assert "8 runs" in result.stdout and "0 findings" in result.stdout
    assert junit.read_text().count("<testcase ") == 8


def test_a_plan_file_that_is_not_a_plan_exits_2(tmp_path, session, driver):
    plan = tmp_path / "plan.txt"
    plan.write_text("01 01 zz 05\n")
    result = run_cli("fuzz", str(session), "--plan", str(plan), "--", *driver)
    assert result.returncode == 2, result.stdout + result.stderr
    assert f"--plan {plan}: not a plan" in result.stderr


def test_a_profile_that_does_not_fit_exits_2(session, driver):
    result = run_cli("fuzz", str(session), "--profile", "modbus-rtu", "--", *driver)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "'modbus-rtu' does not fit" in result.stderr


def test_a_session_without_device_bytes_exits_2(tmp_path, driver):
    quiet = tmp_path / "quiet.wtape"
    with wiretape.SessionWriter(str(quiet), port_type="serial") as writer:
        writer.write("tx", 0, b"Q0\n")
    result = run_cli("fuzz", str(quiet), "--", *driver)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "no device bytes" in result.stderr


# Waits at most 0.3 s for each answer, then exits with an error: a delay
# within the replay's tolerance (an inert plan) must not make it fail.
IMPATIENT_DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    for n in range(3):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            if not select.select([fd], [], [], 0.3)[0]:
                sys.exit(3)
            line += os.read(fd, 100)
    sys.exit(0)
""")


def test_an_error_exit_on_an_inert_plan_is_a_finding(tmp_path, session):
    script = tmp_path / "impatient.py"
    script.write_text(IMPATIENT_DRIVER)
    plan = tmp_path / "delay.txt"
    plan.write_text("08 01 00 31\n")  # rx record 1 delayed by 500 ms
    findings = tmp_path / "findings"
    # A tolerance of one second makes the delay inert.
    result = run_cli("fuzz", str(session), "--plan", str(plan), "--runs", "1", "--timeout", "5",
                     "--options", "check=timing,tolerance=1000", "--findings", str(findings), "--",
                     sys.executable, str(script), "{port}")
    assert result.returncode == 1, result.stdout + result.stderr
    [finding] = json.loads((findings / "index.json").read_text())["findings"]
    assert finding["kind"] == "error" and finding["signature"] == "exit 3"
    assert finding["changed"] == ["rx record 1 delayed by 500 ms"]
    # Within the default tolerance (100 ms) the same delay is the driver's
    # right to refuse: nothing found.
    result = run_cli("fuzz", str(session), "--plan", str(plan), "--runs", "1", "--timeout", "5",
                     "--findings", str(tmp_path / "none"), "--",
                     sys.executable, str(script), "{port}")
    assert result.returncode == 0, result.stdout + result.stderr


# Waits for each answer's end without a timeout: an answer cut short hangs it.
PATIENT_DRIVER = textwrap.dedent("""
    import os, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    for n in range(3):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            line += os.read(fd, 100)
    sys.exit(0)
""")


def test_a_hang_past_the_timeout_is_a_finding(tmp_path, session):
    script = tmp_path / "patient.py"
    script.write_text(PATIENT_DRIVER)
    plan = tmp_path / "truncate.txt"
    plan.write_text("02020400")  # rx record 2 truncated to 4 bytes
    findings = tmp_path / "findings"
    result = run_cli("fuzz", str(session), "--plan", str(plan), "--runs", "1", "--timeout", "1",
                     "--findings", str(findings), "--", sys.executable, str(script), "{port}")
    assert result.returncode == 1, result.stdout + result.stderr
    [finding] = json.loads((findings / "index.json").read_text())["findings"]
    assert finding["kind"] == "hang" and finding["signal"] is None
    assert finding["changed"] == ["rx record 2 truncated: 10 → 4 bytes"]
    assert finding["repro"].startswith("(wiretape replay ") and "timeout -k 5 1 " in finding["repro"]


# A C driver that copies whatever one read gave into an 11-byte buffer: an
# answer longer than recorded overflows it, which AddressSanitizer reports.
OVERFLOWING_DRIVER = r"""
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>
#include <sys/select.h>
int main(int argc, char** argv) {
  int fd = open(argv[1], O_RDWR | O_NOCTTY);
  struct termios raw;
  tcgetattr(fd, &raw); cfmakeraw(&raw); tcsetattr(fd, TCSANOW, &raw);
  for (int n = 0; n < 3; ++n) {
    char question[4] = {'Q', (char)('0' + n), '\n', 0};
    write(fd, question, 3);
    char got[100];
    size_t size = 0;
    while (!memchr(got, '\n', size)) {
      fd_set readable; FD_ZERO(&readable); FD_SET(fd, &readable);
      struct timeval wait = {0, 300000};
      if (select(fd + 1, &readable, 0, 0, &wait) <= 0) return 3;
      usleep(20000);  /* let the whole answer arrive */
      ssize_t count = read(fd, got + size, sizeof got - size);
      if (count <= 0) return 3;
      size += (size_t)count;
    }
    char* answer = malloc(11);
    memcpy(answer, got, size);  /* the bug: trusts the answer's length */
    free(answer);
  }
  return 0;
}
"""


def test_sanitizer_reports_of_one_cause_are_one_finding(tmp_path, session):
    source = tmp_path / "overflow.c"
    source.write_text(OVERFLOWING_DRIVER)
    program = tmp_path / "overflow"
    built = subprocess.run(["cc", "-g", "-fsanitize=address", "-o", str(program), str(source)],
                           capture_output=True, text=True)
    if built.returncode != 0:
        pytest.skip(f"no C compiler with AddressSanitizer here: {built.stderr.strip()[:200]}")
    plans = []
    for name, text in (("five", "03000441"), ("nine", "03000842")):
        plans += ["--plan", str(tmp_path / name)]
        (tmp_path / name).write_text(text)  # rx record 0 extended by 5 (9) bytes
    findings = tmp_path / "findings"
    result = run_cli("fuzz", str(session), *plans, "--runs", "2", "--timeout", "10",
                     "--findings", str(findings), "--", str(program), "{port}")
    assert result.returncode == 1, result.stdout + result.stderr
    [finding] = json.loads((findings / "index.json").read_text())["findings"]
    assert finding["kind"] == "crash" and finding["signal"] is None
    assert finding["signature"].startswith("SUMMARY: AddressSanitizer: heap-buffer-overflow")
    assert "1 duplicate" in result.stdout
    assert any(" in main " in frame for frame in finding["stack"]), finding["stack"]
    assert [frame.split()[0] for frame in finding["stack"]][:2] == ["#0", "#1"]
    assert sum(frame.startswith("#0 ") for frame in finding["stack"]) == 1  # the first trace


FIXED_PATH = "/dev/ttyWIRETAPEFUZZ0"


def test_a_driver_with_a_fixed_path_is_fuzzed_and_its_finding_replays_with_as(tmp_path,
                                                                              session, driver):
    """CMD opens its device itself: --as redirects it, and the finding's
    reproduction is `wiretape replay FINDING --as PATH -- CMD`."""
    from wiretape.redirect import shim_path

    try:
        shim_path()
    except RuntimeError as missing:
        pytest.skip(f"device-redirecting shim not built: {missing}")
    plan = tmp_path / "boundary.txt"
    plan.write_text("01010005")  # rx record 1 byte 0: 0x52 → 0xff
    findings = tmp_path / "findings"
    fixed = [arg.replace("{port}", FIXED_PATH) for arg in driver]
    result = run_cli("fuzz", str(session), "--plan", str(plan), "--runs", "1", "--timeout", "10",
                     "--as", FIXED_PATH, "--findings", str(findings), "--", *fixed)
    assert result.returncode == 1, result.stdout + result.stderr
    [finding] = json.loads((findings / "index.json").read_text())["findings"]
    assert finding["kind"] == "crash" and finding["changed"] == ["rx record 1 byte 0: 0x52 → 0xff"]
    session_path = str(findings / finding["session"])
    assert finding["repro"].startswith(f"wiretape replay {session_path} -q --as {FIXED_PATH} --")
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    again = subprocess.run(["bash", "-c", finding["repro"]], capture_output=True, text=True,
                           timeout=120, env=env)
    assert again.returncode == 128 + 6, again.stdout + again.stderr
