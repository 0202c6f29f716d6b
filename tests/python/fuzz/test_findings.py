"""A finding's signature (DESIGN §27): two causes are two findings, one
cause reached by two plans is one, also when CMD prints no stack (each
abort told apart by the last line CMD wrote, its numbers stripped)."""

import sys
import textwrap

import pytest

import wiretape
from wiretape import fuzz
from wiretape.faults.report import Run
from wiretape.fuzz.findings import last_line, signature

# Aborts when an answer is not what it asked for, saying which answer in
# words and, as real programs do, numbers that differ run to run.
DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    for n, name in enumerate(["greeting", "reading"]):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            if not select.select([fd], [], [], 2)[0]:
                sys.exit(3)
            line += os.read(fd, 1)
        if line != f"R{n}-abcdef\\n".encode():
            bad = next(i for i, b in enumerate(line) if b != f"R{n}-abcdef\\n".encode()[i])
            sys.stderr.write(f"driver[{os.getpid()}]: the {name} is corrupt at byte {bad} "
                             f"(buffer {id(line):#x})\\n")
            sys.stderr.flush()
            os.abort()
    sys.exit(0)
""")


@pytest.fixture()
def session(tmp_path):
    path = tmp_path / "lines.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(2):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}-abcdef\n".encode())
    return path


def test_aborts_of_two_causes_are_two_findings_and_one_cause_is_one(tmp_path, session):
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    target = fuzz.Target([sys.executable, str(script), "{port}"], timeout=10)
    # flip [op 0, record, offset, bit]: the greeting at two bytes, the reading once
    plans = [bytes([0, 0, 4, 0]), bytes([0, 0, 6, 1]), bytes([0, 1, 5, 0])]
    result = fuzz.search(str(session), target, str(tmp_path / "findings"), plans=plans,
                         runs=len(plans))
    assert [run.outcome for run in result.runs] == ["crash"] * 3
    signatures = sorted(finding.signature for finding in result.findings)
    assert signatures == ["signal SIGABRT | driver[N]: the greeting is corrupt at byte N "
                          "(buffer ADDR)",
                          "signal SIGABRT | driver[N]: the reading is corrupt at byte N "
                          "(buffer ADDR)"], signatures
    assert result.duplicates == 1


def test_a_stack_or_a_sanitizer_report_wins_over_the_last_line():
    with_frames = Run("fuzz", "", "crash", -6, 0.1,
                      output="#0 0x4011 in decode_scan scip.cpp:12\nAborted (pid 77)\n")
    assert signature("crash", with_frames) == "signal SIGABRT | decode_scan"
    silent = Run("fuzz", "", "crash", -8, 0.1, output="")
    assert signature("crash", silent) == "signal SIGFPE"


def test_the_last_line_is_normalised():
    assert last_line("scan 1\n  planted bug x: range 70000 at 0xdeadbeef  \n\n") == \
        "planted bug x: range N at ADDR"
    assert last_line("planted bug y: index -490\n") == last_line("planted bug y: index 120\n")
    assert last_line("") == ""


# Crashes on a bad first byte of the greeting's answer, printing nothing: the
# stack comes from gdb, run once more on the minimized plan.
SILENT_CRASH = textwrap.dedent("""
    #include <fcntl.h>
    #include <stdlib.h>
    #include <termios.h>
    #include <unistd.h>

    static int decode_reply(const char* field) { return field[0] == 'R' ? 0 : *(volatile int*)0; }

    int main(int argc, char** argv) {
      int fd = open(argv[1], O_RDWR | O_NOCTTY);
      struct termios raw;
      if (fd < 0 || tcgetattr(fd, &raw) != 0) return 3;
      cfmakeraw(&raw);
      tcsetattr(fd, TCSANOW, &raw);
      char reply[16];
      if (write(fd, "Q0\\n", 3) != 3 || read(fd, reply, 1) != 1) return 3;
      return decode_reply(reply);
    }
""")


def test_a_crash_that_prints_no_stack_gets_one_from_the_debugger(tmp_path, session):
    import shutil
    import subprocess
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None or shutil.which("gdb") is None:
        pytest.skip("needs a C compiler and gdb (Debian packages gcc, gdb)")
    from wiretape.fuzz.findings import debugger_command
    probe = subprocess.run(debugger_command(["true"]), capture_output=True, text=True,
                           timeout=120)
    if "exited normally" not in probe.stdout + probe.stderr:
        pytest.skip("gdb cannot run a program here (ptrace refused?): "
                    + (probe.stdout + probe.stderr).strip()[-200:])
    source = tmp_path / "silent_crash.c"
    source.write_text(SILENT_CRASH)
    program = tmp_path / "silent_crash"
    subprocess.run([compiler, "-g", "-O0", "-o", str(program), str(source)], check=True)
    target = fuzz.Target([str(program), "{port}"], timeout=10)
    result = fuzz.search(str(session), target, str(tmp_path / "findings"),
                         plans=[bytes([0, 0, 0, 1])], runs=1)
    assert [run.outcome for run in result.runs] == ["crash"]
    (finding,) = result.findings
    assert finding.signature == "signal SIGSEGV"  # CMD printed nothing to tell it by
    assert finding.stack, "gdb gave no backtrace"
    assert "decode_reply" in finding.stack[0] and "silent_crash.c" in finding.stack[0]
    assert any("main" in frame for frame in finding.stack[1:])
    # index.json carries it, for whoever reads the finding without wiretape
    import json
    index = json.loads((tmp_path / "findings" / "index.json").read_text())
    assert index["findings"][0]["stack"] == finding.stack
