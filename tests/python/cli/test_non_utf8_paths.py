"""A session path that is not valid UTF-8 (b"n\\xff.wtape", which Linux
allows) works for every command: Python holds it as surrogateescape text
(os.fsdecode), and the bindings pass it to C++ as the bytes it names
(src/python/text_caster.hpp), as an argument and inside an option string.
Before, every command exited 3 with std::bad_cast."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

import wiretape

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
DEVICE = "/dev/ttyWTNOTUTF8"

DRIVER = textwrap.dedent("""
    import os, select, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    os.write(fd, b"PING\\n")
    line = b""
    while not line.endswith(b"\\n") and select.select([fd], [], [], 10)[0]:
        line += os.read(fd, 1)
    sys.exit(0 if line == b"PONG\\n" else 3)
""")


def run_cli(*args: bytes | str, timeout: float = 120):
    argv = [*WIRETAPE, *(os.fsencode(arg) if isinstance(arg, str) else arg for arg in args)]
    return subprocess.run(argv, capture_output=True, timeout=timeout)


def text(result) -> str:
    return (result.stdout + result.stderr).decode("utf-8", "backslashreplace")


@pytest.fixture
def folder(tmp_path) -> bytes:
    return os.fsencode(tmp_path)


@pytest.fixture
def session(folder) -> bytes:
    path = folder + b"/n\xff.wtape"
    # The bindings take the bytes, and the surrogateescape text of them.
    with wiretape.SessionWriter(os.fsdecode(path), port_type="serial",
                                port_options=f"type=serial,device={DEVICE}") as writer:
        writer.write("tx", 1_000_000, b"PING\n")
        writer.write("rx", 2_000_000, b"PONG\n")
    assert os.path.exists(path)
    with wiretape.SessionReader(path) as reader:
        assert [record.data for record in reader] == [b"PING\n", b"PONG\n"]
    return path


def test_show_and_verify_read_it(session):
    shown = run_cli("show", session)
    assert shown.returncode == 0, text(shown)
    assert b"PONG" in shown.stdout
    verified = run_cli("verify", session)
    assert verified.returncode == 0, text(verified)
    assert "bad_cast" not in text(verified)


@pytest.mark.parametrize("suffix", [b".jsonl", b".pcapng", b".mcap", b".wtape"])
def test_convert_reads_and_writes_it(session, folder, suffix):
    out = folder + b"/out\xfe" + suffix
    result = run_cli("convert", session, out)
    assert result.returncode == 0, text(result)
    assert os.path.getsize(out) > 0
    if suffix in (b".jsonl", b".wtape"):
        back = folder + b"/back\xfd.wtape"
        again = run_cli("convert", out, back)
        assert again.returncode == 0, text(again)
        with wiretape.SessionReader(back) as reader:
            assert [record.data for record in reader] == [b"PING\n", b"PONG\n"]


def test_replay_serves_it_to_a_command(session, tmp_path):
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    result = run_cli("replay", session, "--timing", "none", "--as", DEVICE, "--",
                     sys.executable, str(driver), DEVICE)
    assert result.returncode == 0, text(result)


def test_record_writes_it(folder):
    output = folder + b"/rec\xff.wtape"
    result = run_cli("record", "--device", "type=loopback", "--listen", "127.0.0.1:0", "-o",
                     output, "--duration", "0.2", "--quiet")
    assert result.returncode == 0, text(result)
    with wiretape.SessionReader(output) as reader:
        assert reader.header.port_type == "loopback"


@pytest.mark.parametrize("command", ["show", "verify", "stats"])
def test_its_name_prints_with_the_bytes_escaped_on_a_strict_terminal(session, command):
    """A UTF-8 locale's strict stdout cannot print the name as Python holds
    it: the command prints those bytes as \\xNN instead of failing."""
    env = dict(os.environ, PYTHONIOENCODING="utf-8:strict")
    result = subprocess.run([*WIRETAPE, command, session], capture_output=True, timeout=120,
                            env=env)
    assert result.returncode == 0, text(result)
    assert b"n\\xff.wtape" in result.stdout
    missing = subprocess.run([*WIRETAPE, command, session + b".gone"], capture_output=True,
                             timeout=120, env=env)
    assert missing.returncode == 3 and b"n\\xff.wtape.gone" in missing.stderr, text(missing)
