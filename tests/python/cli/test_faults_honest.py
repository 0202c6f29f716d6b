"""Honest outcomes of fault campaigns and of ``replay --fault ... -- CMD``
(DESIGN §23, issue 23): an interrupted campaign keeps the runs so far and
exits 130/143; its JSON never overwrites the session; CMD's own reaction to
an injected loss is seen and its status reported; a reproduction line
reproduces its run; a verdict never blames the client for an injected fault;
bad WHERE and --timeout are usage errors."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape
from wiretape import faults

from devices import wait_until

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
# Generous: a campaign starts Python, replays and CMDs on a loaded machine.
DEADLINE_S = 120.0
FIXED_PATH = "/dev/ttyWIRETAPEHONEST0"


def run_cli(*args, timeout=DEADLINE_S, **options):
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True, timeout=timeout,
                          **options)


@pytest.fixture()
def session(tmp_path: Path) -> Path:
    """Three line exchanges: Qn\\n answered by Rn-abcdef\\n, recorded on
    FIXED_PATH."""
    path = tmp_path / "lines.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options=f"type=serial,device={FIXED_PATH}") as writer:
        for n in range(3):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}-abcdef\n".encode())
    return path


def needs_shim():
    from wiretape.redirect import shim_path

    try:
        shim_path()
    except RuntimeError as missing:
        pytest.skip(f"device-redirecting shim not built: {missing}")


# A driver of the three exchanges. argv: PATH (the device), ON_LOSS, then
# options. ON_LOSS says what it does when the device hangs up: "exit7"
# (retries for half a second, says so, exits 7), "abort" (the same, then
# aborts), "ignore" (exits 0). An answer it did not expect: it aborts. A
# file after "--started" gets a line with its pid when it starts; "--ubsan"
# makes it print a UBSan report on a bad answer and exit 0 instead.
DRIVER = textwrap.dedent("""
    import os, sys, time, tty
    path, on_loss, options = sys.argv[1], sys.argv[2], sys.argv[3:]
    if "--started" in options:
        with open(options[options.index("--started") + 1], "a") as started:
            started.write(f"{os.getpid()}\\n")
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)

    def lost():
        if on_loss == "ignore":
            sys.exit(0)
        time.sleep(0.5)   # the driver's own reaction: it tries again a while
        print("driver: the device is gone", flush=True)
        if on_loss == "abort":
            os.abort()
        sys.exit(7)

    for n in range(3):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            try:
                chunk = os.read(fd, 1)
            except OSError:
                lost()
            if not chunk:
                lost()
            line += chunk
        if line != f"R{n}-abcdef\\n".encode():
            if "--ubsan" in options:
                sys.stderr.write("driver.c:12:7: runtime error: signed integer overflow\\n")
                sys.exit(0)
            os.abort()
    print("driver: done", flush=True)
""")


@pytest.fixture()
def driver(tmp_path: Path) -> list:
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    return [sys.executable, str(script)]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


# --- an interrupted campaign --------------------------------------------------------------


@pytest.mark.parametrize("signum, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_an_interrupted_campaign_stops_and_keeps_the_runs_so_far(session, driver, tmp_path,
                                                                 signum, status):
    started = tmp_path / "started"
    report = tmp_path / "campaign.json"
    # The clean run and three delay runs pass; then silence leaves the
    # driver waiting for ever (a hang only after 600 s).
    campaign = subprocess.Popen(
        [*WIRETAPE, "faults", str(session), "--kinds", "delay:1,silence", "--timeout", "600",
         "--json", str(report), "--options", "timing=none", "--",
         *driver, "{port}", "exit7", "--started", str(started)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        def runs_started():
            assert campaign.poll() is None, campaign.communicate()
            return started.exists() and len(started.read_text().split()) == 5

        wait_until(runs_started, DEADLINE_S, "the first silence run to start")
        hanging = int(started.read_text().split()[-1])
        campaign.send_signal(signum)
        out, err = campaign.communicate(timeout=DEADLINE_S)
    finally:
        if campaign.poll() is None:
            campaign.kill()
            campaign.communicate()
    assert campaign.returncode == status, out + err
    wait_until(lambda: not _alive(hanging), DEADLINE_S, "the running case's CMD to be ended")
    data = json.loads(report.read_text())
    assert data["interrupted"] is True
    assert [(run["kind"], run["where"], run["outcome"]) for run in data["runs"]] == [
        ("delay:1", f"exchange:{n}", "ok") for n in range(3)]
    assert "3 runs: 3 ok" in out
    assert "interrupted after 3 of 6 runs" in err
    assert "Traceback" not in err


def test_a_finished_campaign_says_it_was_not_interrupted(session, driver, tmp_path):
    report = tmp_path / "campaign.json"
    result = run_cli("faults", str(session), "--kinds", "delay:1", "--json", str(report),
                     "--options", "timing=none", "--", *driver, "{port}", "exit7")
    assert result.returncode == 0, result.stdout + result.stderr
    assert json.loads(report.read_text())["interrupted"] is False


# --- bad input ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["same", "hard link", "symbolic link"])
def test_the_json_is_never_the_session(session, driver, tmp_path, name):
    before = session.read_bytes()
    target = session
    if name == "hard link":
        target = tmp_path / "linked.wtape"
        os.link(session, target)
    elif name == "symbolic link":
        target = tmp_path / "symlinked.json"
        target.symlink_to(session)
    result = run_cli("faults", str(session), "--kinds", "delay:1", "--json", str(target),
                     "--options", "timing=none", "--", *driver, "{port}", "exit7")
    assert result.returncode == 3, result.stdout + result.stderr
    assert "refusing to overwrite the input" in result.stderr
    assert session.read_bytes() == before


@pytest.mark.parametrize("value", ["inf", "1e300", "1000001"])
def test_a_timeout_that_is_not_a_finite_bounded_number_is_a_usage_error(session, driver,
                                                                        value):
    result = run_cli("faults", str(session), "--timeout", value, "--", *driver, "{port}",
                     "exit7")
    assert result.returncode == 2, result.stdout + result.stderr
    assert "--timeout" in result.stderr and "finite" in result.stderr
    with pytest.raises(faults.FaultInputError, match="--timeout"):
        faults.campaign(str(session), [*driver, "{port}"], timeout=float(value))


def test_a_fault_past_the_end_with_a_command_is_a_usage_error_before_it_runs(session,
                                                                             tmp_path):
    marker = tmp_path / "ran"
    result = run_cli("replay", str(session), "--fault", "truncate@exchange:99", "--as",
                     FIXED_PATH, "--", "touch", str(marker))
    assert result.returncode == 2, result.stdout + result.stderr
    assert "exchange 99 is past its end" in result.stderr
    assert not marker.exists()


# --- CMD's own reaction to an injected loss -----------------------------------------------


def test_cmd_outlives_an_injected_loss_and_its_status_is_returned(session, driver):
    needs_shim()
    result = run_cli("replay", str(session), "--timing", "none", "--fault",
                     "disconnect@exchange:1", "--as", FIXED_PATH, "--", *driver, FIXED_PATH,
                     "exit7")
    assert result.returncode == 7, result.stdout + result.stderr
    assert "driver: the device is gone" in result.stdout
    assert "exited with status 7" in result.stderr


def test_a_loss_before_any_answer_does_not_blame_the_client(session, driver):
    needs_shim()
    result = run_cli("replay", str(session), "--timing", "none", "--fault",
                     "disconnect@exchange:0", "--as", FIXED_PATH, "--", *driver, FIXED_PATH,
                     "ignore")
    # The driver exits 0, but it was served nothing: the replay's verdict.
    assert result.returncode == 1, result.stdout + result.stderr
    assert "nothing the client sent matched" not in result.stderr
    assert "an injected fault ended the replay" in result.stderr
    assert "disconnect@exchange:0" in result.stderr


def test_cmd_output_is_relayed_and_a_sanitizer_report_fails_it(session, driver):
    needs_shim()
    result = run_cli("replay", str(session), "--timing", "none", "--fault",
                     "corrupt@exchange:1", "--seed", "1", "--as", FIXED_PATH, "--", *driver,
                     FIXED_PATH, "exit7", "--ubsan")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "runtime error: signed integer overflow" in result.stderr
    assert "runtime error" not in result.stdout
    assert "printed a sanitizer report" in result.stderr


# --- the campaign's outcomes with --as ----------------------------------------------------


def test_with_as_a_sanitizer_report_is_a_crash_and_is_shown(session, driver, tmp_path):
    needs_shim()
    report = tmp_path / "as.json"
    result = run_cli("faults", str(session), "--kinds", "corrupt@exchange:1", "--timeout",
                     "60", "--json", str(report), "--options", "timing=none", "--as",
                     FIXED_PATH, "--", *driver, FIXED_PATH, "exit7", "--ubsan")
    assert result.returncode == 1, result.stdout + result.stderr
    runs = json.loads(report.read_text())["runs"]
    assert [(run["outcome"], run["exit"]) for run in runs] == [("crash", 0)]
    assert "| driver.c:12:7: runtime error: signed integer overflow" in result.stdout


# A driver that leaves two helpers and exits 0: one in its own process
# group (ended with the driver's group), one in a session of its own
# holding the driver's output (not waited for). It prints their pids. With
# "hang" it then waits for ever instead of exiting.
LEAVES_HELPERS = textwrap.dedent("""
    import os, subprocess, sys, time
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    grouped = subprocess.Popen(["sleep", "1000"])
    daemon = subprocess.Popen(["sleep", "1000"], start_new_session=True)
    print(grouped.pid, daemon.pid, flush=True)
    if sys.argv[2:] == ["hang"]:
        while True:
            time.sleep(1000)
""")


@pytest.mark.parametrize("as_path", [None, FIXED_PATH])
@pytest.mark.parametrize("behaviour", ["exit", "hang"])
def test_what_cmd_leaves_is_ended_or_abandoned_never_waited_for(session, tmp_path, as_path,
                                                                 behaviour):
    if as_path:
        needs_shim()
    script = tmp_path / "helpers.py"
    script.write_text(LEAVES_HELPERS)
    argv = [sys.executable, str(script), as_path or "{port}", behaviour]
    timeout = 3.0 if behaviour == "hang" else DEADLINE_S
    run = faults.run_case(str(session), None, argv, timeout=timeout,
                          replay_options="timing=none", as_path=as_path)
    grouped, daemon = (int(pid) for pid in run.output.split()[:2])
    try:
        expected = ("hang", None) if behaviour == "hang" else ("ok", 0)
        assert (run.outcome, run.exit) == expected, run.output
        # The run ended with the driver (or at its timeout), not with the
        # daemon's copy of its output; the helper of its group was ended.
        assert run.seconds < DEADLINE_S / 2
        wait_until(lambda: not _alive(grouped), DEADLINE_S, "the grouped helper to be ended")
        assert _alive(daemon)
    finally:
        for pid in (grouped, daemon):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


# --- reproduction lines -------------------------------------------------------------------


def _run_repro(line: str, tmp_path: Path) -> subprocess.CompletedProcess:
    """Runs a printed reproduction line in a shell, with this wiretape on
    PATH and the fixed port of the line moved under tmp_path (tests run
    side by side)."""
    line = line.replace(faults.REPRO_PORT, str(tmp_path / "repro-port"))
    env = dict(os.environ)
    env["PATH"] = os.path.dirname(sys.executable) + os.pathsep + env.get("PATH", "")
    return subprocess.run(["bash", "-c", line], capture_output=True, text=True,
                          timeout=DEADLINE_S, env=env, cwd=tmp_path)


@pytest.mark.parametrize("as_path", [None, FIXED_PATH])
def test_a_reproduction_line_reproduces_its_run(session, driver, tmp_path, as_path):
    """The driver aborts half a second after the device is lost: a crash
    that only shows when CMD outlives the replay."""
    if as_path:
        needs_shim()
    report = tmp_path / "repro.json"
    path = as_path or "{port}"
    as_arguments = ["--as", as_path] if as_path else []
    result = run_cli("faults", str(session), "--kinds", "disconnect@exchange:1", "--timeout",
                     "60", "--json", str(report), "--options", "timing=none", *as_arguments,
                     "--", *driver, path, "abort")
    assert result.returncode == 1, result.stdout + result.stderr
    (run,) = json.loads(report.read_text())["runs"]
    assert (run["outcome"], run["exit"]) == ("crash", -signal.SIGABRT)
    assert run["repro"] in result.stdout
    again = _run_repro(run["repro"], tmp_path)
    assert again.returncode == 128 + signal.SIGABRT, again.stdout + again.stderr
    assert "driver: the device is gone" in again.stdout


# --- the bridge's verdict -----------------------------------------------------------------


@pytest.mark.parametrize("fault, ended_by_fault", [("disconnect@exchange:0", True),
                                                   ("drop@exchange:0", False)])
def test_the_bridge_says_an_injected_loss_ended_it(session, fault, ended_by_fault):
    import tty

    from wiretape import bridge

    handle = bridge.serve_replay(str(session), pty=True,
                                 replay_options=f"timing=none,faults={fault}", quiet=True)
    try:
        fd = os.open(handle.pty_path, os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd)
            os.write(fd, b"Q0\n")
            if ended_by_fault:
                wait_until(lambda: handle.wait(0.05), DEADLINE_S, "the injected loss to end it")
        finally:
            os.close(fd)
    finally:
        handle.stop()
        handle.wait()
    result = handle.result()
    assert result.ended_by_fault is ended_by_fault, result
    if ended_by_fault:
        assert result.outcome == "device_closed"
        assert "an injected fault ended the replay before any was served" in \
            result.nothing_served
        assert "nothing the client sent matched" not in result.nothing_served
