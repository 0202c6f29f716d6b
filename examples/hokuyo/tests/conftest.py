"""Fixtures for the Hokuyo example tests: the repository, the hokuyo-scan
program, the shared real recordings, and simulators on a pty or TCP."""
import pytest

from hokuyo_testlib import REPO, bin_dir, flexiport_log, start_simulator


@pytest.fixture(scope="session")
def repo():
    return REPO


@pytest.fixture(scope="session")
def hokuyo_scan():
    program = bin_dir() / "hokuyo-scan"
    if not program.exists():
        pytest.fail(f"{program} is not built: run `make` (or point WIRETAPE_BIN_DIR "
                    "at the build's bin folder)", pytrace=False)
    return program


@pytest.fixture(scope="session")
def shared_data():
    """The folder of the real flexiport recordings (tests/python/support/real_recordings.py)."""
    return flexiport_log("urg04lx_2011").parent


@pytest.fixture
def simulator(tmp_path):
    """simulator(*args): a started simulator on a pty link in tmp_path
    (or TCP when args hold --listen); stopped at the end of the test."""
    started = []

    def start(*args):
        if "--listen" not in args:
            args = ("--pty", str(tmp_path / f"sim{len(started)}"), *args)
        sim = start_simulator(*args)
        started.append(sim)
        return sim

    yield start
    for sim in started:
        sim.stop()
