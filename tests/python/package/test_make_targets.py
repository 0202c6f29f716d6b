"""What the Makefile's entry points build, read from `make -n` (nothing is
run): `make demo` builds only the targets the demo runs, `make install`
installs the C++ package into PREFIX."""

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="no make")


def dry_run(*arguments):
    result = subprocess.run(["make", "-n", "-C", str(ROOT), *arguments, "BUILD=build-dry-run"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return [line.strip() for line in result.stdout.splitlines()]


def builds(lines):
    return [line for line in lines if line.startswith("cmake --build")]


def test_make_demo_builds_only_what_the_demo_runs():
    lines = dry_run("demo")
    build = builds(lines)
    assert len(build) == 1, lines
    targets = build[0].split("--target", 1)[1].split()
    assert {"_core", "hokuyo-scan"} <= set(targets)
    assert not any("test" in target or "fuzz" in target for target in targets), targets
    assert any("WIRETAPE_BIN_DIR=" in line and "build-dry-run/bin" in line
               and line.endswith("wiretape demo") for line in lines), lines


def test_make_test_still_builds_everything():
    assert "cmake --build build-dry-run" in builds(dry_run("test"))


def test_make_install_installs_the_cpp_package_into_prefix():
    lines = dry_run("install", "PREFIX=/opt/wiretape")
    assert "cmake --build build-dry-run --target wiretape" in lines
    assert "cmake --install build-dry-run --prefix /opt/wiretape --component cpp" in lines


def pip_installs(lines):
    """The packages of every `pip install` line make would run."""
    commands = "\n".join(lines).replace("\\\n", " ").splitlines()
    return {word.strip('"').split(">")[0].split("=")[0] for line in commands
            if " -m pip install" in line for word in line.split() if word.startswith('"')}


def test_make_demo_installs_only_what_the_demo_runs_and_make_test_the_test_tools(tmp_path):
    # A venv that does not exist yet: make must install everything it needs.
    fresh = f"VENV={tmp_path}/venv"
    demo = pip_installs(dry_run("demo", fresh))
    assert {"scikit-build-core", "nanobind", "pyserial", "rich", "mcap"} <= demo
    assert not demo & {"pytest", "mypy", "pymavlink", "pymodbus", "hypothesis"}, demo
    test = pip_installs(dry_run("test", fresh))
    assert {"pytest", "mypy", "pymavlink", "pymodbus", "hypothesis", "nanobind"} <= test


def test_make_demo_installs_libzstd_before_it_configures():
    lines = dry_run("demo")
    installs = [n for n, line in enumerate(lines) if line.startswith("bench/install-tools.sh")
                and "libzstd-dev" in line.split()]
    configures = [n for n, line in enumerate(lines) if line.startswith("cmake -S . -B")]
    assert installs and configures, lines
    assert installs[0] < configures[0]
