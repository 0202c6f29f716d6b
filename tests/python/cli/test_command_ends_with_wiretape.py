"""``record/replay ... -- CMD``: CMD ends with its wiretape, however
wiretape ends. A CI job's timeout kills wiretape with SIGKILL, which no
handler sees; CMD runs in a session of its own (so that ending it reaches
what it started), and so nothing ended it: drivers were found running 90
minutes later (issue 37). Linux's parent-death signal ends it now
(wiretape.children, docs/replay.md "Running a program against the
replay")."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape

pytestmark = pytest.mark.skipif(not hasattr(os, "pidfd_open"),
                                reason="SKIPPED LOUDLY: no pidfd_open (Linux 5.3 and "
                                       "Python 3.9 or later) to wait for CMD's end")

# Generous: a loaded machine starts a Python CMD slowly, and the kernel
# delivers the parent-death signal at once.
DEADLINE_S = 60.0
DEVICE = "/dev/ttyWTLIFETIME"

# A long-running CMD: says its pid on stdout (relayed by wiretape), then
# waits for ever, SIGTERM included.
LONG_RUNNING = textwrap.dedent("""
    import os, signal
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    print(os.getpid(), flush=True)
    while True:
        signal.pause()
""")


def _session(path: Path) -> Path:
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options=f"type=serial,device={DEVICE}") as writer:
        writer.write("tx", 1_000_000, b"Q\n")
        writer.write("rx", 2_000_000, b"R\n")
    return path


def _ended_within(pid: int, seconds: float) -> bool:
    """Whether process `pid` (not our child) ends within `seconds`: its
    pidfd becomes readable when it exits."""
    try:
        pidfd = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    try:
        poller = select.poll()
        poller.register(pidfd, select.POLLIN)
        return bool(poller.poll(seconds * 1000))
    finally:
        os.close(pidfd)


@pytest.mark.parametrize("command", ["replay", "record"])
def test_cmd_ends_when_wiretape_is_killed(tmp_path, command):
    script = tmp_path / "long_running.py"
    script.write_text(LONG_RUNNING)
    if command == "replay":
        arguments = ["replay", str(_session(tmp_path / "s.wtape")), "--as", DEVICE]
    else:
        arguments = ["record", "--device", "type=loopback", "--as", DEVICE,
                     "-o", str(tmp_path / "r.wtape")]
    started = subprocess.Popen([sys.executable, "-m", "wiretape.cli", *arguments, "--",
                                sys.executable, str(script)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               start_new_session=True)
    cmd_pid = None
    try:
        line = started.stdout.readline()  # CMD's pid, relayed once CMD runs
        assert line.strip().isdigit(), (line, started.stderr.read() if started.poll() else "")
        cmd_pid = int(line)
        started.kill()
        started.wait(DEADLINE_S)
        assert _ended_within(cmd_pid, DEADLINE_S), \
            f"CMD (pid {cmd_pid}) still runs {DEADLINE_S:.0f} s after wiretape was killed"
    finally:
        if started.poll() is None:
            os.killpg(started.pid, signal.SIGKILL)
            started.wait()
        if cmd_pid is not None and not _ended_within(cmd_pid, 0):
            os.kill(cmd_pid, signal.SIGKILL)
        started.stdout.close()
        started.stderr.close()


def test_a_child_whose_parent_ended_before_it_ran_does_not_run():
    """The race the parent-death signal leaves open: wiretape killed between
    fork and the call that sets it. The child sees its parent gone and ends
    before CMD runs. Forced here: the preexec kills the starting process and
    waits for its end (on its pidfd) before the check runs."""
    starter = textwrap.dedent("""
        import os, select, signal
        from wiretape import children
        parent = os.getpid()
        checked = children._ending_with_parent

        def killing_the_parent_first(then=None):
            check = checked(then)

            def preexec():
                pidfd = os.pidfd_open(parent)
                os.kill(parent, signal.SIGKILL)
                select.select([pidfd], [], [])  # the parent has ended
                check()
            return preexec

        children._ending_with_parent = killing_the_parent_first
        children.Child(["echo", "CMD ran"], capture=False)
    """)
    # The starter's stdout is this pipe, and so is the orphan's: it ends once
    # both are gone, having carried "CMD ran" had CMD been run.
    ran = subprocess.run([sys.executable, "-c", starter], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, timeout=DEADLINE_S)
    assert ran.returncode == -signal.SIGKILL, ran.stderr
    assert ran.stdout == b""
