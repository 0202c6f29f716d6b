"""Who may open a pty wiretape creates (DESIGN §12, Permissions): mode 0660,
group dialout where it exists (else the process's group), like a real serial
device, so that a client that drops root (gpsd) opens it; --pty-mode and
--pty-group (pty_mode, pty_group in Python) change that; bad values are
usage errors naming the flag."""

import grp
import os
import pwd
import signal
import stat
import subprocess
import sys

import pytest

from wiretape import OptionError, _core, bridge

from devices import TcpDevice

DEADLINE = 10.0
SERIAL_GROUP = "dialout"


def expected_default_group():
    try:
        return grp.getgrnam(SERIAL_GROUP).gr_gid
    except KeyError:
        return os.getegid()


@pytest.fixture
def recording(tmp_path):
    path = tmp_path / "device.wtape"
    writer = _core.SessionWriter(str(path), capture="wire",
                                 port_options="type=serial,device=/dev/ttyX", port_type="serial")
    writer.write("open", 0, b"{}")
    writer.write("tx", 1_000_000, b"PING\n")
    writer.write("rx", 1_500_000, b"PONG\n")
    writer.close()
    return path


def start_cli(*argv):
    child = subprocess.Popen([sys.executable, "-m", "wiretape.cli", *argv],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = []
    # The announcement comes once the pty exists with its mode and group.
    while True:
        line = child.stderr.readline()
        if not line:
            stop_cli(child)
            raise AssertionError("no pty announced: " + "".join(seen))
        seen.append(line)
        if "clients use pty" in line:
            return child


def stop_cli(child):
    if child.poll() is None:
        child.send_signal(signal.SIGINT)
    try:
        return child.communicate(timeout=DEADLINE)
    except subprocess.TimeoutExpired:
        child.kill()
        return child.communicate()


def node_of(link):
    """Mode bits and group of the terminal the link points to."""
    info = os.stat(link)  # follows the link to /dev/pts/N
    assert stat.S_ISCHR(info.st_mode), info
    return stat.S_IMODE(info.st_mode), info.st_gid


def unprivileged_client():
    """(uid, gid of dialout) for a client that drops root into group
    dialout, or a skip saying why none can be used here. Nothing is created."""
    if os.geteuid() != 0:
        pytest.skip("LOUD SKIP: dropping to an unprivileged client needs root; "
                    "the unprivileged-open check did not run")
    try:
        gid = grp.getgrnam(SERIAL_GROUP).gr_gid
    except KeyError:
        pytest.skip(f"LOUD SKIP: no {SERIAL_GROUP} group on this system; "
                    "the unprivileged-open check did not run")
    for name in ("nobody", "daemon"):
        try:
            uid = pwd.getpwnam(name).pw_uid
        except KeyError:
            continue
        if uid != 0:
            return uid, gid
    pytest.skip("LOUD SKIP: no unprivileged user (nobody, daemon) on this system; "
                "the unprivileged-open check did not run")


def opens_as(uid, gid, path):
    """Whether a child running as `uid` in group `gid` only opens `path`
    for reading and writing."""
    child = subprocess.run(["/bin/sh", "-c", 'exec 3<>"$1"', "sh", path],
                           user=uid, group=gid, extra_groups=[],
                           stdin=subprocess.DEVNULL, capture_output=True, text=True,
                           timeout=DEADLINE)
    return child.returncode == 0


def test_replay_pty_is_0660_in_dialout_and_a_client_that_dropped_root_opens_it(
        recording, tmp_path):
    link = tmp_path / "ttyReplay"
    child = start_cli("replay", str(recording), "--pty", str(link), "--timing", "none")
    try:
        assert node_of(link) == (0o660, expected_default_group())
        uid, gid = unprivileged_client()
        assert opens_as(uid, gid, os.path.realpath(link))
    finally:
        stop_cli(child)


def test_pty_mode_takes_the_access_away_and_pty_group_changes_the_group(recording, tmp_path):
    link = tmp_path / "ttyReplay"
    child = start_cli("replay", str(recording), "--pty", str(link), "--timing", "none",
                      "--pty-mode", "0600", "--pty-group", "0")
    try:
        assert node_of(link) == (0o600, 0)
        uid, gid = unprivileged_client()
        assert not opens_as(uid, gid, os.path.realpath(link))
    finally:
        stop_cli(child)


def test_record_pty_has_the_default_and_takes_the_flags(tmp_path):
    with TcpDevice() as device:
        link = tmp_path / "ttyRecord"
        child = start_cli("record", "--device", device.options, "--pty", str(link),
                          "-o", str(tmp_path / "default.wtape"))
        try:
            assert node_of(link) == (0o660, expected_default_group())
        finally:
            stop_cli(child)
        group = grp.getgrgid(os.getegid()).gr_name
        child = start_cli("record", "--device", device.options, "--pty", str(link),
                          "-o", str(tmp_path / "flags.wtape"), "--pty-mode", "666",
                          "--pty-group", group)
        try:
            assert node_of(link) == (0o666, os.getegid())
        finally:
            stop_cli(child)


def test_python_api_takes_pty_mode_and_pty_group(recording, tmp_path):
    link = tmp_path / "ttyApi"
    with bridge.serve_replay(recording, pty=str(link), replay_options="timing=none",
                             pty_mode=0o640, pty_group=os.getegid(), quiet=True):
        assert node_of(link) == (0o640, os.getegid())
    with TcpDevice() as device:
        with bridge.record(device.options, tmp_path / "api.wtape", pty=str(link),
                           quiet=True) as handle:
            assert node_of(handle.pty_path) == (0o660, expected_default_group())


@pytest.mark.parametrize("flag, value, words", [
    ("--pty-mode", "999", "not an octal mode"),
    ("--pty-mode", "rw-rw----", "not an octal mode"),
    ("--pty-mode", "01777", "beyond the permission bits"),
    ("--pty-mode", "4755", "beyond the permission bits"),
    ("--pty-group", "no-such-group-wiretape", "no group"),
])
def test_bad_pty_access_values_are_usage_errors_naming_the_flag(
        recording, tmp_path, flag, value, words):
    for argv in (["replay", str(recording)],
                 ["record", "--device", "type=loopback", "-o", str(tmp_path / "x.wtape")]):
        child = subprocess.run([sys.executable, "-m", "wiretape.cli", *argv,
                                "--pty", str(tmp_path / "tty"), flag, value],
                               capture_output=True, text=True, timeout=DEADLINE)
        assert child.returncode == 2, child.stderr
        assert flag in child.stderr and words in child.stderr, child.stderr
        assert not (tmp_path / "tty").exists()


def test_pty_access_flags_need_a_pty(recording):
    child = subprocess.run([sys.executable, "-m", "wiretape.cli", "replay", str(recording),
                            "--listen", "127.0.0.1:0", "--pty-mode", "0666"],
                           capture_output=True, text=True, timeout=DEADLINE)
    assert child.returncode == 2, child.stderr
    assert "--pty-mode" in child.stderr


def test_bad_pty_access_values_in_python_are_option_errors(recording, tmp_path):
    for access, key in (({"pty_mode": 0o1000}, "pty_mode"), ({"pty_mode": -1}, "pty_mode"),
                        ({"pty_group": "no-such-group-wiretape"}, "pty_group")):
        with pytest.raises(OptionError, match=key):
            bridge.serve_replay(recording, pty=str(tmp_path / "tty"), quiet=True, **access)
    with pytest.raises(ValueError, match="pty"):
        bridge.serve_replay(recording, listen="127.0.0.1:0", pty_mode=0o666, quiet=True)
