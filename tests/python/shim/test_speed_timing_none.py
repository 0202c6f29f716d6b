"""--speed K with timing=none (docs/replay.md "Faster than real time"): the
replay has no clock to scale, but CMD's clock and injected waits are still
K times faster, so `--timing none --speed K -- CMD` is accepted; a speed
that scales nothing at all (no CMD, no injected wait) is refused, saying
why. One rule, the replay's (`_core.replay_speed_applies`)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wiretape
from wiretape import _core

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the scaled-clock shim is Linux only")

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
DEVICE = "/dev/ttyWTNOCLOCK"
EXCHANGES = 3

# Asks each question (waiting 2 s on its clock for each answer), prints how
# many were answered and the clock speed it was started with (the shim's
# environment), exits 3 on a missing answer.
DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    answered = 0
    for n in range(int(sys.argv[2])):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n") and select.select([fd], [], [], 2)[0]:
            chunk = os.read(fd, 1)
            if not chunk:
                break
            line += chunk
        answered += line == f"R{n}\\n".encode()
    print("answered", answered)
    print("speed", os.environ.get("WIRETAPE_CLOCK_SPEED"))
    sys.exit(0 if answered == int(sys.argv[2]) else 3)
""")


def run_cli(*args):
    return subprocess.run([*WIRETAPE, *args], capture_output=True, text=True, timeout=120)


@pytest.fixture()
def session(tmp_path: Path) -> Path:
    path = tmp_path / "lines.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options=f"type=serial,device={DEVICE}") as writer:
        for n in range(EXCHANGES):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}\n".encode())
    return path


@pytest.fixture()
def driver(tmp_path: Path) -> Path:
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    return script


def test_timing_none_with_a_command_scales_the_commands_clock(session, driver):
    result = run_cli("replay", str(session), "--timing", "none", "--speed", "10", "--as", DEVICE,
                     "--", sys.executable, str(driver), DEVICE, str(EXCHANGES))
    assert result.returncode == 0, result.stderr
    assert f"answered {EXCHANGES}" in result.stdout
    assert "speed 10" in result.stdout, result.stdout


def test_timing_none_with_an_injected_delay_scales_it(session, driver):
    result = run_cli("replay", str(session), "--timing", "none", "--speed", "10",
                     "--fault", "delay:200@exchange:1", "--as", DEVICE,
                     "--", sys.executable, str(driver), DEVICE, str(EXCHANGES))
    assert result.returncode == 0, result.stderr
    assert f"answered {EXCHANGES}" in result.stdout


def test_a_speed_that_scales_nothing_is_refused_saying_why(session, tmp_path):
    result = run_cli("replay", str(session), "--timing", "none", "--speed", "10",
                     "--pty", str(tmp_path / "port"))
    assert result.returncode == 2, result.stderr
    assert "'speed' has no effect" in result.stderr and "scales nothing" in result.stderr
    assert not (tmp_path / "port").exists()


@pytest.mark.parametrize("keys, applies", [
    ("timing=none", False),
    ("ignoretimes", False),
    ("timing=none,faults=drop@exchange:0", False),
    ("timing=none,faults=delay:100@exchange:0", True),
    ("timing=none,faults=drop@exchange:0;trickle@exchange:1", True),
    ("timing=none,faults=stall:5@rx:1", True),
    ("timing=none,faults=reconnect:5@exchange:0", True),
    ("timing=session", True),
    ("", True),
])
def test_the_replays_rule_for_speed(session, keys, applies):
    options = f"type=replay,file={session}" + (f",{keys}" if keys else "")
    assert _core.replay_speed_applies(options) is applies
    if applies:
        _core.check_replay_options(options + ",speed=2")
    else:
        with pytest.raises(wiretape.OptionError, match="'speed' has no effect"):
            _core.check_replay_options(options + ",speed=2")


def test_a_campaign_at_speed_with_timing_none_runs(session, tmp_path):
    script = tmp_path / "campaign_driver.py"
    script.write_text(DRIVER)
    result = run_cli("faults", str(session), "--kinds", "drop,delay", "--options", "timing=none",
                     "--speed", "10", "--timeout", "20", "--json", str(tmp_path / "c.json"),
                     "--", sys.executable, str(script), "{port}", str(EXCHANGES))
    assert result.returncode == 0, result.stdout + result.stderr
    assert (tmp_path / "c.json").exists()
