"""Fault injection from Python and the command line (docs/faults.md): faults=
through the Python API and the URL handler, --fault on virtual devices, the
campaign (`wiretape faults`), its outcomes, seeds and bad input, and the
cases wiretape.faults gives pytest."""

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

pytest_plugins = ["pytester"]

REPO = Path(__file__).resolve().parents[3]
WIRETAPE = [sys.executable, "-m", "wiretape.cli"]


def make_session(path: Path) -> Path:
    """Three line exchanges: Qn\\n answered by Rn...\\n."""
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(3):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}-abcdef\n".encode())
    return path


# A driver with the bugs fault campaigns find: it aborts (a crash) on an
# answer it did not expect and waits forever (a hang) for one that does not
# come; a clean "error" exit when the device goes away. Given "robust" after
# the path it checks and waits at most a second instead.
DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    robust = sys.argv[2:] == ["robust"]
    tty.setraw(fd)
    for n in range(3):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            if robust and not select.select([fd], [], [], 1.0)[0]:
                sys.exit(3)              # no answer in time: a clean error
            try:
                chunk = os.read(fd, 1)
            except OSError:
                sys.exit(3)          # hung up: a clean error
            if not chunk:
                sys.exit(3)
            line += chunk
        if line != f"R{n}-abcdef\\n".encode():
            if robust:
                sys.exit(3)
            os.abort()               # the bug: trusts the device
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


def run_cli(*args, timeout=120):
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True, timeout=timeout)


# --- faults= through the Python API and the URL handler ---------------------------------


def test_python_ports_take_faults(session):
    port = wiretape.open_port(f"type=replay,file={session},timing=none,"
                              "faults=truncate:2@exchange:1,seed=1,timeout=5")
    port.write(b"Q0\n")
    assert port.read_line() == b"R0-abcdef\n"
    port.write(b"Q1\n")
    assert port.read(100, timeout=0.3) == b"R1"
    port.close()


def test_bad_faults_are_option_errors_naming_the_key(session):
    with pytest.raises(wiretape.OptionError, match="faults.*unknown fault kind 'boom'"):
        wiretape.open_port(f"type=replay,file={session},faults=boom@exchange:0")


def test_the_url_handler_takes_faults(session):
    serial = pytest.importorskip("serial")
    port = serial.serial_for_url(f"wiretape://{session}?faults=duplicate@exchange:0",
                                 timeout=0.5)
    port.write(b"Q0\n")
    assert port.read(22) == b"R0-abcdef\nR0-abcdef\n"
    port.close()


# --- virtual devices ----------------------------------------------------------------------


def test_a_disconnect_hangs_up_the_pty(session, tmp_path):
    with faults.faulty_device(str(session), faults.FaultCase("disconnect", "exchange:1"),
                              "timing=none") as path:
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        try:
            import tty

            tty.setraw(fd)
            os.write(fd, b"Q0\n")
            got = b""
            while not got.endswith(b"\n"):
                got += os.read(fd, 64)
            assert got == b"R0-abcdef\n"
            os.write(fd, b"Q1\n")
            # The device is gone: the terminal hangs up (EOF or EIO).
            try:
                assert os.read(fd, 64) == b""
            except OSError as error:
                assert error.errno == 5
        finally:
            os.close(fd)


def test_replay_fault_on_the_command_line_is_reported(session, tmp_path):
    link = tmp_path / "port"
    process = subprocess.Popen([*WIRETAPE, "replay", str(session), "--pty", str(link),
                                "--timing", "none", "--fault", "corrupt@exchange:0",
                                "--seed", "9"], stderr=subprocess.PIPE, text=True)
    try:
        for line in process.stderr:  # the announcement: the pty exists
            if "clients use" in line:
                break
        fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
        import tty

        tty.setraw(fd)
        os.write(fd, b"Q0\n")
        got = b""
        while len(got) < 10:
            got += os.read(fd, 64)
        assert got != b"R0-abcdef\n" and len(got) == 10
        for line in process.stderr:
            if "fault corrupt@exchange:0" in line:
                assert "flipped bit" in line
                break
        os.close(fd)
    finally:
        process.terminate()
        process.wait(30)


def test_replay_fault_past_the_end_is_a_usage_error(session, tmp_path):
    result = run_cli("replay", str(session), "--pty", str(tmp_path / "p"),
                     "--fault", "drop@exchange:7")
    assert result.returncode == 2
    assert "exchange 7 is past its end" in result.stderr


def test_replay_fault_places_count_exchanges_as_the_replay_does(tmp_path):
    # Two tx runs but one request line: with --profile lines exchange 1 is
    # past the end.
    path = tmp_path / "split.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        writer.write("tx", 1, b"A")
        writer.write("rx", 2, b"x")
        writer.write("tx", 3, b"B\n")
        writer.write("rx", 4, b"y")
    assert faults.session_shape(str(path)).exchanges == 2
    result = run_cli("replay", str(path), "--pty", str(tmp_path / "p"), "--profile", "lines",
                     "--fault", "drop@exchange:1", timeout=60)
    assert result.returncode == 2
    assert "exchange 1 is past its end" in result.stderr


# --- the campaign -------------------------------------------------------------------------


def test_a_campaign_sorts_runs_into_outcomes(session, driver, tmp_path):
    report = tmp_path / "campaign.json"
    result = run_cli("faults", str(session), "--kinds", "drop,corrupt,disconnect,delay:50",
                     "--timeout", "3", "--jobs", "2", "--json", str(report),
                     "--options", "timing=none", "--", *driver)
    assert result.returncode == 1, result.stdout + result.stderr
    data = json.loads(report.read_text())
    outcomes = {(run["kind"], run["where"]): run["outcome"] for run in data["runs"]}
    assert outcomes[("corrupt", "exchange:0")] == "crash"
    assert outcomes[("drop", "exchange:1")] == "hang"
    assert outcomes[("disconnect", "exchange:2")] == "error"
    assert outcomes[("delay:50", "exchange:0")] == "ok"
    assert data["summary"] == {"ok": 3, "error": 3, "crash": 3, "hang": 3}
    assert data["session"] == str(session) and data["seed"] == 0
    crash = next(run for run in data["runs"] if run["outcome"] == "crash")
    assert crash["repro"].startswith("(wiretape replay ")  # a subshell: CMD's status
    assert "--fault corrupt@exchange:" in crash["repro"]
    assert "corrupt   " in result.stdout or "corrupt" in result.stdout
    assert crash["repro"] in result.stdout


def test_the_same_seed_gives_the_same_campaign(session, driver, tmp_path):
    def campaign(name):
        report = tmp_path / name
        run_cli("faults", str(session), "--budget", "6", "--seed", "42", "--kinds",
                "corrupt,garbage,truncate,duplicate", "--timeout", "3", "--json", str(report),
                "--options", "timing=none", "--", *driver)
        return [(run["kind"], run["where"], run["outcome"])
                for run in json.loads(report.read_text())["runs"]]

    first = campaign("a.json")
    assert len(first) == 6
    assert campaign("b.json") == first


def test_a_robust_driver_has_no_crash_and_no_hang(session, driver, tmp_path):
    report = tmp_path / "robust.json"
    result = run_cli("faults", str(session), "--kinds", "drop,garbage,silence", "--timeout",
                     "10", "--jobs", "2", "--json", str(report), "--options", "timing=none",
                     "--", *driver, "robust")
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(report.read_text())["summary"]
    assert summary["crash"] == 0 and summary["hang"] == 0
    assert summary["error"] > 0


@pytest.mark.parametrize("args, message", [
    (["--kinds", "explode"], "unknown fault kind 'explode'"),
    (["--kinds", "drop@exchange:3"], "past its end"),
])
def test_bad_campaign_input_exits_2(session, driver, args, message):
    result = run_cli("faults", str(session), *args, "--", *driver)
    assert result.returncode == 2
    assert message in result.stderr


def test_a_command_without_port_exits_2(session):
    result = run_cli("faults", str(session), "--", sys.executable, "-c", "pass")
    assert result.returncode == 2
    assert "{port}" in result.stderr


def test_no_command_exits_2(session):
    result = run_cli("faults", str(session))
    assert result.returncode == 2


def test_a_command_that_fails_clean_stops_the_campaign(session, tmp_path):
    result = run_cli("faults", str(session), "--options", "timing=none", "--",
                     sys.executable, "-c", "import sys; print('broken driver'); sys.exit(4)",
                     "{port}")
    assert result.returncode == 1
    assert "fails on the clean replay" in result.stderr
    assert "broken driver" in result.stderr


# --- pytest parametrization ------------------------------------------------------------


HOKUYO_GD = REPO / "examples/hokuyo/recordings/urg04lx_gd.wtape"


@pytest.mark.parametrize("case", faults.cases(str(HOKUYO_GD), kinds=["truncate:0"], budget=3,
                                              seed=1),
                         ids=lambda case: case.id)
def test_cases_parametrize_tests(case):
    """Each case's options open a replay with that fault: truncate:0 leaves
    its exchange without an answer."""
    port = wiretape.open_port(f"type=replay,file={HOKUYO_GD},match=request,repeat=last,"
                              f"timing=none,timeout=0.3,unused=ignore,{case.options}")
    exchange = int(case.where.split(":")[1])
    reader = wiretape.SessionReader(str(HOKUYO_GD))
    requests = []
    for record in reader:
        if record.kind == "tx" and record.data:
            requests.append(record.data)
    answered = []
    for request in requests[:exchange + 1]:
        port.write(request)
        answered.append(port.read(4096) != b"")
    port.close()
    assert answered[exchange] is False
    assert all(answered[:exchange])


def test_a_recorded_faulty_replay_holds_fault_events(session, tmp_path):
    log = tmp_path / "faulty.wtape"
    port = wiretape.open_port(f"type=replay,file={session},timing=none,timeout=1,"
                              f"faults=garbage:4@exchange:1,seed=2,log={log}")
    for n in range(3):
        port.write(f"Q{n}\n".encode())
        port.read(64)
    port.close()
    events = [record for record in wiretape.SessionReader(str(log)) if record.kind == "fault"]
    assert len(events) == 1
    payload = json.loads(events[0].data)
    assert payload["kind"] == "garbage:4" and payload["where"] == "exchange:1"
    assert "inserted 4 random bytes" in payload["detail"]


def test_a_disconnect_resets_a_tcp_client(session):
    import socket

    with faults.faulty_device(str(session), faults.FaultCase("disconnect", "exchange:1"),
                              "timing=none", listen=True) as address:
        host, port = address.rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=10) as client:
            client.sendall(b"Q0\n")
            got = b""
            while not got.endswith(b"\n"):
                got += client.recv(64)
            assert got == b"R0-abcdef\n"
            client.sendall(b"Q1\n")
            with pytest.raises(ConnectionResetError):
                while client.recv(64):
                    pass


def test_the_pytest_marker_takes_faults(pytester):
    pytester.makepyfile(test_echo="""
        def test_echo(wiretape_port):
            wiretape_port.write_all(b"hello\\n")
            assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"
    """)
    pytester.runpytest("--wiretape-record=once", "--wiretape-device=type=loopback"
                       ).assert_outcomes(passed=1)
    pytester.makepyfile(test_echo="""
        import pytest

        @pytest.mark.wiretape(faults="truncate:2@exchange:0;drop@p:0", seed=3)
        def test_echo(wiretape_port):
            wiretape_port.write_all(b"hello\\n")
            assert wiretape_port.read(64, timeout=0.5) == b"he"
    """)
    pytester.runpytest().assert_outcomes(passed=1)


def test_as_redirects_a_fixed_device_path(session, driver, tmp_path):
    from wiretape.redirect import shim_path

    try:
        shim_path()
    except RuntimeError as missing:
        pytest.skip(f"device-redirecting shim not built: {missing}")
    fixed = "/dev/ttyWIRETAPEFAULTS0"
    report = tmp_path / "as.json"
    result = run_cli("faults", str(session), "--kinds", "disconnect", "--budget", "2",
                     "--timeout", "10", "--json", str(report), "--options", "timing=none",
                     "--as", fixed, "--", driver[0], driver[1], fixed, "robust")
    assert result.returncode == 0, result.stdout + result.stderr
    runs = json.loads(report.read_text())["runs"]
    assert [run["outcome"] for run in runs] == ["error", "error"]


# A driver that starts a helper in a session of its own, holding the
# driver's output open, says the helper's pid and exits 0.
LEAVES_A_DAEMON = textwrap.dedent("""
    import subprocess, sys
    helper = subprocess.Popen(["sleep", "1000"], start_new_session=True)
    print(helper.pid, flush=True)
""")


def test_a_driver_that_leaves_a_daemon_holding_its_output_is_not_a_hang(session, tmp_path):
    script = tmp_path / "daemonizing.py"
    script.write_text(LEAVES_A_DAEMON)
    run = faults.run_case(str(session), None, [sys.executable, str(script), "{port}"],
                          timeout=60, replay_options="timing=none")
    daemon = int(run.output.split()[0]) if run.output.strip() else None
    try:
        # The run ended with the driver, not when the helper's copy of the
        # output closed.
        assert (run.outcome, run.exit) == ("ok", 0), run.output
    finally:
        if daemon is not None:
            os.kill(daemon, signal.SIGKILL)
