"""The files the pytest plugin writes beside its cassettes (docs/testing.md):
a cassette that is a symbolic link is written through it, the link kept
(rewrite, and once with a dangling link); a recording left in progress by a
pytest that was killed (SIGKILL, SIGTERM) is removed by a later run, which
names it in its summary."""

import os
import signal
import subprocess
import sys

import wiretape
from devices import wait_until

pytest_plugins = ["pytester"]

LOOPBACK = "--wiretape-device=type=loopback"
ECHO_TEST = """
    def test_echo(wiretape_port):
        wiretape_port.write_all(b"hello\\n")
        assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"
"""


def cassette_of(pytester):
    return pytester.path / "recordings" / "test_echo" / "test_echo.wtape"


def tx_of(path):
    return b"".join(r.data for r in wiretape.SessionReader(str(path)) if r.kind == "tx")


def test_rewrite_writes_through_a_cassette_that_is_a_link(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    cassette = cassette_of(pytester)
    store = pytester.path / "store"
    store.mkdir()
    cassette.rename(store / "echo.wtape")
    cassette.symlink_to(os.path.relpath(store / "echo.wtape", cassette.parent))

    pytester.makepyfile(test_echo=ECHO_TEST.replace("hello", "howdy"))
    pytester.runpytest("--wiretape-record=rewrite", LOOPBACK).assert_outcomes(passed=1)
    assert cassette.is_symlink()
    assert tx_of(store / "echo.wtape") == b"howdy\n"
    # The header names the cassette the test knows, not the link's target.
    assert "log=test_echo.wtape" in wiretape.SessionReader(str(cassette)).header.port_options
    pytester.runpytest().assert_outcomes(passed=1)  # and it replays


def test_once_records_through_a_dangling_link(pytester):
    pytester.makepyfile(test_echo=ECHO_TEST)
    cassette = cassette_of(pytester)
    cassette.parent.mkdir(parents=True)
    store = pytester.path / "store"
    store.mkdir()
    cassette.symlink_to(store / "echo.wtape")
    assert not cassette.exists()

    pytester.runpytest("--wiretape-record=once", LOOPBACK).assert_outcomes(passed=1)
    assert cassette.is_symlink()
    assert tx_of(store / "echo.wtape") == b"hello\n"
    assert not [path for path in cassette.parent.iterdir() if path != cassette]


BLOCKING_TEST = """
    import pathlib

    def test_echo(wiretape_port):
        wiretape_port.write_all(b"hello\\n")
        assert wiretape_port.read_exactly(6, timeout=5) == b"hello\\n"
        pathlib.Path("recording.started").write_text("")
        wiretape_port.read_exactly(1, timeout=None)  # blocks until the process is killed
"""


def test_a_killed_runs_recording_in_progress_is_removed_and_named_later(pytester):
    pytester.makepyfile(test_echo=BLOCKING_TEST)
    started = pytester.path / "recording.started"
    for signum in (signal.SIGKILL, signal.SIGTERM):
        child = subprocess.Popen([sys.executable, "-m", "pytest", "-p", "no:cacheprovider",
                                  "--wiretape-record=rewrite", LOOPBACK, "test_echo.py"],
                                 cwd=pytester.path, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
        wait_until(lambda: started.exists() or child.poll() is not None,
                   what="the inner test recording")
        assert child.poll() is None, "the inner pytest ended before it was killed"
        os.kill(child.pid, signum)
        child.wait(timeout=60)
        started.unlink()
        partial = cassette_of(pytester).with_name(f"test_echo.wtape.recording-{child.pid}")
        assert partial.exists(), "nothing left behind: the test proves nothing"

        # A recording in progress of a live process (another pytest) is not touched.
        alive = cassette_of(pytester).with_name(f"other.wtape.recording-{os.getpid()}")
        alive.write_bytes(b"")
        pytester.makepyfile(test_echo=ECHO_TEST)
        result = pytester.runpytest("--wiretape-record=once", LOOPBACK)
        result.assert_outcomes(passed=1)
        assert not partial.exists()
        assert alive.exists()
        result.stdout.fnmatch_lines(["*removed 1 recording left in progress by a pytest that "
                                     "was killed*", f"*{partial}"])
        alive.unlink()
        pytester.makepyfile(test_echo=BLOCKING_TEST)
