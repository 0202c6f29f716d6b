"""examples/pyserial (docs/testing.md, "Drivers that build their own
serial.Serial") runs as the docs say: it replays its committed cassette with
no device, and records it again from its simulator."""

import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import wiretape

pytest.importorskip("serial", reason="pyserial is not installed")

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "pyserial"
CASSETTE = Path("recordings") / "test_thermometer" / "test_identify_and_read.wtape"


def run_pytest(directory, *args):
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           *args, "test_thermometer.py"],
                          cwd=directory, capture_output=True, text=True, timeout=300)


@pytest.fixture
def example(tmp_path):
    copy = tmp_path / "pyserial"
    shutil.copytree(EXAMPLE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    return copy


def streams(path):
    records = list(wiretape.SessionReader(str(path)))
    return (b"".join(r.data for r in records if r.kind == "tx"),
            b"".join(r.data for r in records if r.kind == "rx"))


def test_the_example_replays_its_cassette_without_the_device(example):
    result = run_pytest(example)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "1 passed" in result.stdout


def test_the_example_records_again_from_its_simulator(example, tmp_path):
    link = tmp_path / "ttyTHERMO"
    simulator = subprocess.Popen([sys.executable, "fake_thermometer.py", str(link)],
                                 cwd=example, stdout=subprocess.PIPE, text=True)
    try:
        assert simulator.stdout.readline().startswith("thermometer on")  # the pty is there
        result = run_pytest(example, "--wiretape-record=rewrite", f"--wiretape-device={link}")
        assert result.returncode == 0, result.stdout + result.stderr
    finally:
        simulator.send_signal(signal.SIGTERM)
        simulator.wait(30)
    assert not link.exists()  # the simulator ended and removed its link
    assert streams(example / CASSETTE) == streams(EXAMPLE / CASSETTE)
    result = run_pytest(example)  # and the new cassette replays
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("name", ["thermometer.py", "test_thermometer.py"])
def test_the_docs_show_the_example_as_it_is(name):
    docs = (EXAMPLE.parents[1] / "docs" / "testing.md").read_text()
    start = docs.index(f"# examples/pyserial/{name}\n") + len(f"# examples/pyserial/{name}\n")
    shown = docs[start:docs.index("```", start)]
    assert shown.strip() and shown in (EXAMPLE / name).read_text()
