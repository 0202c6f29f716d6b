"""labgrid against a recording with no lab (DESIGN §28): labgrid's own
pytest plugin and SerialDriver, in their venv (`make labgrid-venv`),
drive examples/lab's test through the environment's NetworkSerialPort,
which is `wiretape replay --listen ... --protocol rfc2217` instead of the
exporter's ser2net; the replay's verdict shows it served the whole
recording, and a driver that sends another command is named by it."""

import subprocess

import pytest
import yaml

from console_device import console_session
from devices import announced_address, interrupt, start_cli
from lab_runs import EXAMPLES, ROOT, run_pytest

EXAMPLE = EXAMPLES / "test_console_labgrid.py"
ENVIRONMENT = EXAMPLES / "labgrid_env.yaml"
VENV = ROOT / "build" / "labgrid-venv"
# pip over the network: minutes when PyPI is slow, a skip when it is away.
VENV_DEADLINE_S = 900.0


@pytest.fixture(scope="module")
def labgrid_python():
    try:
        made = subprocess.run(["make", "-C", str(ROOT), "labgrid-venv"], text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              timeout=VENV_DEADLINE_S)
    except (OSError, subprocess.TimeoutExpired) as error:
        pytest.skip(f"SKIPPED LOUDLY: make labgrid-venv could not build {VENV}: {error}")
    # A Makefile without the target is this project's fault, not the network's.
    assert "No rule to make target" not in made.stdout, made.stdout
    if made.returncode != 0:
        pytest.skip(f"SKIPPED LOUDLY: make labgrid-venv could not build {VENV} (offline? "
                    f"it installs labgrid from PyPI): {made.stdout[-1500:]}")
    return VENV / "bin" / "python"


def environment_for(tmp_path, address):
    """examples/lab's environment with its NetworkSerialPort at `address`
    (the port the replay announced), the rest as the example has it."""
    environment = yaml.safe_load(ENVIRONMENT.read_text())
    port = environment["targets"]["main"]["resources"]["NetworkSerialPort"]
    port["host"], port["port"] = address
    path = tmp_path / "env.yaml"
    path.write_text(yaml.safe_dump(environment))
    return path


def labgrid_run(labgrid_python, tmp_path, test_file=EXAMPLE):
    """Serves the console's recording over RFC 2217 and runs `test_file`
    under labgrid's plugin: (pytest's status and output, the replay's
    status and stderr)."""
    recording = console_session(tmp_path / "console.wtape")
    replay = start_cli("replay", recording, "--listen", "127.0.0.1:0",
                       "--protocol", "rfc2217", "--timing", "none")
    try:
        environment = environment_for(tmp_path, announced_address(replay, "tcp"))
        status, output = run_pytest(labgrid_python, tmp_path / "run", test_file,
                                    "-p", "labgrid", "--lg-env", str(environment),
                                    "-W", "ignore::DeprecationWarning")
    finally:
        code, _, err = interrupt(replay)
    return status, output, code, err


def test_labgrids_serial_driver_runs_against_a_recording(labgrid_python, tmp_path):
    status, output, code, err = labgrid_run(labgrid_python, tmp_path)
    assert status == 0 and "1 passed" in output, output
    # The replay's own verdict: every recorded byte was asked for and served.
    assert code == 0, err
    assert "set to 115200 8N1" in err, err


def test_a_driver_that_sends_another_command_is_named_by_the_replay(labgrid_python, tmp_path):
    wrong = tmp_path / "wrong" / EXAMPLE.name
    wrong.parent.mkdir()
    wrong.write_text(EXAMPLE.read_text().replace('sendline("version")', 'sendline("verzion")'))
    status, output, code, err = labgrid_run(labgrid_python, tmp_path, wrong)
    assert status == 1 and "1 failed" in output, output
    assert code == 1, err
    assert "replay mismatch" in err and "exchange 1" in err, err
