"""wiretape.children.Child: the one way a command is run and ended (DESIGN
§17, "Child processes"): its own process group, ended as a whole, output
captured without waiting for the end of a pipe a grandchild holds."""

import io
import os
import signal
import sys
import textwrap

import pytest

from devices import DEADLINE_S, wait_until
from wiretape.children import Child, CommandNotStarted


def _alive(pid):
    """False once `pid` is gone (or a zombie nobody reaped yet)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _python(code):
    return [sys.executable, "-c", textwrap.dedent(code)]


# A child that starts a grandchild in its own group, says the grandchild's
# pid, and waits to be ended; with ignore_term both ignore SIGTERM.
PARENT_OF_A_SLEEPER = """
    import signal, subprocess, sys, time
    if sys.argv[1] == "ignore_term":
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sleeper = subprocess.Popen([sys.executable, "-c",
                                "import signal, sys, time\\n"
                                "if sys.argv[1] == 'ignore_term':\\n"
                                "    signal.signal(signal.SIGTERM, signal.SIG_IGN)\\n"
                                "print('ready', flush=True)\\n"
                                "time.sleep(1000)", sys.argv[1]], stdout=subprocess.PIPE)
    sleeper.stdout.readline()  # the grandchild has set its signals up
    print(sleeper.pid, flush=True)
    time.sleep(1000)
"""


def _started_parent(mode, **options):
    child = Child(_python(PARENT_OF_A_SLEEPER) + [mode], **options)
    assert child.wait_for_output(lambda out: out.endswith(b"\n"), DEADLINE_S), child.stdout
    return child, int(child.stdout)


def test_output_is_captured_with_the_exit_status():
    outcome = Child(["sh", "-c", "echo out; echo err >&2; exit 3"]).run(DEADLINE_S)
    assert (outcome.returncode, outcome.exit_status, outcome.signal) == (3, 3, None)
    assert not outcome.timed_out
    assert sorted(outcome.stdout.splitlines()) == [b"err", b"out"]
    assert outcome.stderr == b""


def test_stderr_apart_and_text():
    outcome = Child(["sh", "-c", "echo out; echo err >&2"], separate_stderr=True,
                    text=True).run(DEADLINE_S)
    assert (outcome.returncode, outcome.stdout, outcome.stderr) == (0, "out\n", "err\n")


def test_a_death_by_signal_is_reported():
    outcome = Child(["sh", "-c", "kill -SEGV $$"]).run(DEADLINE_S)
    assert outcome.returncode == -signal.SIGSEGV
    assert outcome.signal == signal.SIGSEGV
    assert outcome.exit_status == 128 + signal.SIGSEGV
    assert not outcome.timed_out


def test_captured_output_is_relayed_as_it_comes():
    relay = io.BytesIO()
    outcome = Child(["sh", "-c", "echo one; echo two"], relay=relay).run(DEADLINE_S)
    assert relay.getvalue() == outcome.stdout == b"one\ntwo\n"


def test_stdout_and_stderr_are_relayed_apart():
    out, err = io.BytesIO(), io.BytesIO()
    outcome = Child(["sh", "-c", "echo out; echo err >&2"], separate_stderr=True, relay=out,
                    relay_stderr=err).run(DEADLINE_S)
    assert (out.getvalue(), err.getvalue()) == (b"out\n", b"err\n")
    assert (outcome.stdout, outcome.stderr) == (b"out\n", b"err\n")


def test_a_stop_event_ends_the_child_and_its_grandchild_at_once():
    import threading

    child, grandchild = _started_parent("plain")
    stop = threading.Event()
    stop.set()  # as an interrupted campaign sets it for each running case
    outcome = child.run(timeout=DEADLINE_S * 10, stop=stop)
    assert outcome.stopped and not outcome.timed_out
    assert outcome.signal == signal.SIGTERM
    wait_until(lambda: not _alive(grandchild), DEADLINE_S, "the grandchild to be gone")


def test_a_child_that_exits_is_not_stopped():
    import threading

    outcome = Child(["sh", "-c", "exit 4"]).run(DEADLINE_S, stop=threading.Event())
    assert (outcome.returncode, outcome.stopped, outcome.timed_out) == (4, False, False)


def test_a_sanitizer_report_is_found_in_output():
    from wiretape.children import sanitizer_report

    assert sanitizer_report(b"ok\nx.c:3:5: runtime error: shift\n") == \
        "x.c:3:5: runtime error: shift"
    assert sanitizer_report("==1==ERROR: AddressSanitizer: heap-use-after-free") is not None
    assert sanitizer_report("WARNING: ThreadSanitizer: data race") is not None
    assert sanitizer_report("all is well\n") is None


def test_output_passed_through_is_not_captured(capfd):
    child = Child(["sh", "-c", "echo through"], capture=False)
    outcome = child.run(DEADLINE_S)
    assert outcome.returncode == 0 and outcome.stdout == b""
    assert capfd.readouterr().out == "through\n"


def test_a_timeout_ends_the_child_and_its_grandchild():
    child, grandchild = _started_parent("plain")
    assert _alive(grandchild)
    outcome = child.run(timeout=0.1)
    assert outcome.timed_out
    assert outcome.signal == signal.SIGTERM
    wait_until(lambda: not _alive(grandchild), DEADLINE_S, "the grandchild to be gone")


def test_what_ignores_sigterm_is_killed_after_the_grace_period():
    child, grandchild = _started_parent("ignore_term", grace=0.2)
    returncode = child.end()
    assert returncode == -signal.SIGKILL
    wait_until(lambda: not _alive(grandchild), DEADLINE_S, "the grandchild to be gone")


def test_ending_after_the_child_exited_ends_what_it_left_in_its_group():
    child = Child(_python("""
        import subprocess, sys
        sleeper = subprocess.Popen(["sleep", "1000"])
        print(sleeper.pid, flush=True)
    """))
    assert child.wait(DEADLINE_S) == 0
    grandchild = int(child.stdout)
    assert _alive(grandchild)
    assert child.end() == 0
    wait_until(lambda: not _alive(grandchild), DEADLINE_S, "the grandchild to be gone")


def test_a_grandchild_of_another_session_holding_stdout_does_not_stall_it():
    child = Child(_python("""
        import subprocess
        sleeper = subprocess.Popen(["sleep", "1000"], start_new_session=True)
        print(sleeper.pid, flush=True)
    """))
    outcome = child.run(DEADLINE_S)
    grandchild = int(outcome.stdout)
    try:
        assert (outcome.returncode, outcome.timed_out) == (0, False)
        # It returned while the grandchild still holds the pipe open.
        assert _alive(grandchild)
    finally:
        os.kill(grandchild, signal.SIGKILL)


def test_a_grandchild_of_another_session_writing_on_does_not_stall_it():
    child = Child(_python("""
        import subprocess
        import sys
        writer = subprocess.Popen(["yes"], start_new_session=True)
        # One write (print writes each part apart under PYTHONUNBUFFERED):
        # yes's lines cannot split it.
        sys.stdout.write(f"writer {writer.pid}\\n")
        sys.stdout.flush()
    """))
    outcome = child.run(DEADLINE_S)
    # yes may have written before the line with its pid.
    writer = int(next(line for line in outcome.stdout.split(b"\n")
                      if line.startswith(b"writer ")).split()[1])
    try:
        assert (outcome.returncode, outcome.timed_out) == (0, False)
        # Our end of the pipe is closed: the writer gets SIGPIPE.
        wait_until(lambda: not _alive(writer), DEADLINE_S, "the writer to be gone")
    finally:
        if _alive(writer):
            os.kill(writer, signal.SIGKILL)


def test_waiting_for_output_that_never_comes_ends_with_the_output():
    child = Child(["sh", "-c", "echo nothing"])
    assert not child.wait_for_output(lambda out: b"ready" in out, DEADLINE_S)
    assert child.run().stdout == b"nothing\n"


def test_a_command_that_cannot_be_started_is_named(tmp_path):
    with pytest.raises(CommandNotStarted, match="no-such-program: command not found") as error:
        Child([str(tmp_path / "no-such-program")])
    assert error.value.exit_code == 127
    script = tmp_path / "not-executable"
    script.write_text("#!/bin/sh\n")
    with pytest.raises(CommandNotStarted, match="permission denied") as error:
        Child([str(script)])
    assert error.value.exit_code == 126


def test_a_child_used_as_a_context_is_ended():
    with Child(["sleep", "1000"]) as child:
        pid = child.pid
    assert child.returncode == -signal.SIGTERM
    assert not _alive(pid)


def test_a_sanitizer_watch_relays_and_finds_a_report_among_much_output():
    from wiretape.children import SanitizerWatch

    relay = io.BytesIO()
    watch = SanitizerWatch(relay)
    chunks = [b"x" * 100_000 + b"\n", b"a.c:1:2: runtime ", b"error: overflow\nmore\n",
              b"ERROR: AddressSanitizer: later\n"]
    for chunk in chunks:
        watch.write(chunk)
    assert relay.getvalue() == b"".join(chunks)
    assert watch.finish() == "a.c:1:2: runtime error: overflow"
    unended = SanitizerWatch()
    unended.write(b"WARNING: ThreadSanitizer: data race")
    assert unended.finish() == "WARNING: ThreadSanitizer: data race"


def test_keep_holds_only_the_end_of_the_output():
    outcome = Child(["sh", "-c", "seq 1 100000"], keep=16).run(DEADLINE_S)
    assert outcome.stdout == b"\n".join(b"%d" % n for n in range(99997, 100001))[-15:] + b"\n"


def test_a_wait_ends_when_its_wake_descriptor_is_readable_and_the_child_runs_on():
    read_fd, write_fd = os.pipe()
    try:
        with Child([sys.executable, "-c", "import time; time.sleep(600)"]) as child:
            os.write(write_fd, b"x")  # another event, as a bridge's end
            # Without the wake descriptor this wait would last its whole timeout.
            assert child.wait(600, read_fd) is None
            assert child.running
    finally:
        os.close(read_fd)
        os.close(write_fd)


def test_a_wait_with_a_wake_descriptor_still_ends_at_the_childs_exit():
    read_fd, write_fd = os.pipe()
    try:
        child = Child(["sh", "-c", "exit 3"])
        assert child.wait(600, read_fd) == 3  # nothing written: the exit woke it
        child.end()
    finally:
        os.close(read_fd)
        os.close(write_fd)
