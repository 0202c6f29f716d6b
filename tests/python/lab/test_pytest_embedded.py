"""pytest-embedded's serial DUT on a wiretape replay (DESIGN §28): the
example test of examples/lab runs under pytest-embedded's own plugin, its
port a `wiretape://` URL or the pty of `wiretape replay --pty`; a DUT that
sends what the device was never sent fails with the replay's mismatch; and
the project's own pytest runs carry none of pytest-embedded's options."""

import subprocess
import sys

import pytest

from console_device import console_session
from devices import interrupt, start_cli
from lab_runs import EXAMPLES, ROOT, run_pytest, wait_for_line

try:
    import pytest_embedded  # noqa: F401
    import pytest_embedded_serial  # noqa: F401
except ImportError as missing:
    pytest.skip(f"pytest-embedded is not installed ({missing}); the test extra pins it: "
                "make python, or pip install -e '.[test]'", allow_module_level=True)

EXAMPLE = EXAMPLES / "test_console_embedded.py"


def embedded_run(tmp_path, port, test_file=EXAMPLE):
    return run_pytest(sys.executable, tmp_path / "run", test_file,
                      "-p", "wiretape", "-p", "pytest_embedded",
                      "--embedded-services", "serial", "--port", port,
                      "--root-logdir", str(tmp_path / "logs"))


def test_the_serial_dut_runs_on_a_wiretape_url(tmp_path):
    recording = console_session(tmp_path / "console.wtape")
    status, output = embedded_run(tmp_path, f"wiretape://{recording}?timing=none")
    assert status == 0 and "1 passed" in output, output


def test_the_serial_dut_runs_on_a_replayed_pty(tmp_path):
    recording = console_session(tmp_path / "console.wtape")
    pty = tmp_path / "console"
    child = start_cli("replay", recording, "--pty", str(pty), "--timing", "none")
    try:
        wait_for_line(child, "clients use pty")
        status, output = embedded_run(tmp_path, str(pty))
    finally:
        code, _, err = interrupt(child)
    assert status == 0 and "1 passed" in output, output
    # The replay's own verdict: every recorded byte was asked for and served.
    assert code == 0, err


def test_a_dut_that_sends_another_command_fails_with_the_replay_mismatch(tmp_path):
    recording = console_session(tmp_path / "console.wtape")
    wrong = tmp_path / "wrong" / EXAMPLE.name
    wrong.parent.mkdir()
    wrong.write_text(EXAMPLE.read_text().replace('dut.write("version")', 'dut.write("verzion")'))
    status, output = embedded_run(tmp_path, f"wiretape://{recording}?timing=none", wrong)
    assert status == 1 and "1 failed" in output, output
    assert "replay mismatch" in output and "exchange 1" in output, output


def test_the_projects_pytest_runs_leave_pytest_embedded_out():
    # pyproject's addopts disable it: its options would be in every run's --help.
    project = subprocess.run([sys.executable, "-m", "pytest", "--help"], cwd=ROOT, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=60)
    assert project.returncode == 0, project.stdout
    assert "--wiretape-record" in project.stdout, "the run did not load the project's config"
    assert "--embedded-services" not in project.stdout, "pytest-embedded is on in the project's runs"
