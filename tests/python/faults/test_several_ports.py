"""Fault campaigns over a session of several ports (issue 25): every
channel's exchanges are cases (``KIND@exchange:N@channel:NAME``), CMD names
each channel's device ``{port:NAME}``, a WHERE is checked against its
channel, and the table has a line per channel and kind."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import pytest

from wiretape import faults

from channel_sessions import write_channel_session

CHANNELS = [("gps", "serial"), ("rtk", "serial")]
ROUNDS = {"gps": 3, "rtk": 2}


def line_records():
    """gps: Gn? answered by gn!; rtk: Rn? answered by rn!; interleaved on one clock."""
    records = []
    for name, rounds in ROUNDS.items():
        for n in range(rounds):
            t = n * 20_000_000 + (0 if name == "gps" else 5_000_000)
            ask = f"{name[0].upper()}{n}?\n".encode()
            answer = f"{name[0]}{n}!\n".encode()
            records += [(name, "tx", t, ask), (name, "rx", t + 2_000_000, answer)]
    return sorted(records, key=lambda record: record[2])


@pytest.fixture()
def session(tmp_path: Path) -> str:
    return write_channel_session(tmp_path / "two.wtape", CHANNELS, line_records()).path


def test_cases_are_every_channels_exchanges(session):
    cases = faults.cases(session, kinds=["drop"])
    assert [case.spec for case in cases] == (
        [f"drop@exchange:{n}@channel:gps" for n in range(ROUNDS["gps"])]
        + [f"drop@exchange:{n}@channel:rtk" for n in range(ROUNDS["rtk"])])


def test_where_is_checked_against_its_channel(session):
    faults.check_where(session, "drop@exchange:2@channel:gps")
    with pytest.raises(faults.FaultInputError, match=r"channel rtk has 2 exchanges"):
        faults.check_where(session, "drop@exchange:2@channel:rtk")
    with pytest.raises(faults.FaultInputError,
                       match=r"no channel 'imu' \(its channels: gps, rtk\)"):
        faults.check_where(session, "drop@exchange:0@channel:imu")
    # without @channel a fault applies to every channel: past the end of all
    faults.check_where(session, "drop@exchange:2")
    with pytest.raises(faults.FaultInputError, match="every channel has 3 exchanges"):
        faults.check_where(session, "drop@exchange:3")


def test_command_names_each_channels_device(session):
    with pytest.raises(faults.FaultInputError, match=r"\{port:NAME\}"):
        faults.check_command(["driver", "{port}"], None, faults.session_channels(session))
    with pytest.raises(faults.FaultInputError, match=r"\{port:imu\}: the session has no channel"):
        faults.check_command(["driver", "{port:gps}", "{port:imu}"], None, ["gps", "rtk"])
    faults.check_command(["driver", "{port:gps}", "--rtk={port:rtk}"], None, ["gps", "rtk"])


DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    ports = {name: os.open(path, os.O_RDWR | os.O_NOCTTY)
             for name, path in (("gps", sys.argv[1]), ("rtk", sys.argv[2]))}
    for fd in ports.values():
        tty.setraw(fd)
    rounds = {"gps": 3, "rtk": 2}
    for n in range(3):
        for name, fd in ports.items():
            if n >= rounds[name]:
                continue
            os.write(fd, f"{name[0].upper()}{n}?\\n".encode())
            line = b""
            while not line.endswith(b"\\n"):
                if not select.select([fd], [], [], 2.0)[0]:
                    sys.exit(3)          # no answer in time: a clean error
                line += os.read(fd, 1)
            if line != f"{name[0]}{n}!\\n".encode():
                sys.exit(3)
    sys.exit(0)
""")


def test_campaign_over_two_channels_faults_each_on_its_own(session, tmp_path):
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    result = faults.campaign(session, [sys.executable, str(script), "{port:gps}", "{port:rtk}"],
                             kinds=["drop"], timeout=30)
    specs = [run.spec for run in result.runs]
    assert specs == [case.spec for case in faults.cases(session, kinds=["drop"])]
    # a dropped answer on either channel is noticed by the driver
    assert [run.outcome for run in result.runs] == ["error"] * len(specs)
    table = faults.table(result).splitlines()
    assert table[0].startswith("channel kind \\ exchange")
    rows = {line.split("  ")[0].strip(): line for line in table[1:3]}
    assert set(rows) == {"gps drop", "rtk drop"}
    assert "EEE" in rows["gps drop"] and "error 3" in rows["gps drop"]
    assert "EE " in rows["rtk drop"] and "error 2" in rows["rtk drop"]


def test_t_is_checked_on_the_sessions_clock_in_each_channel(session):
    # rtk's last rx is recorded at 27 ms of the session's one clock (its
    # first record at 5 ms): t:0.026 fires there, as the replay fires it.
    faults.check_where(session, "drop@t:0.026@channel:rtk")
    with pytest.raises(faults.FaultInputError,
                       match=r"channel rtk lasts 0.027 s; t:0.028 is past its end"):
        faults.check_where(session, "drop@t:0.028@channel:rtk")
