"""wiretape.fuzzing under atheris (DESIGN §27, in process): the example's
fuzz target runs its driver against mutated replays, and a driver with a
planted bug is found. Skips loudly where atheris is not installed (`make
fuzz` and `make test` install it into .venv from a wheel)."""

import os
import pathlib
import subprocess
import sys
import textwrap

import pytest

atheris = pytest.importorskip(
    "atheris", reason="atheris is not installed in this Python (make test installs it into "
                      ".venv where a wheel exists): the atheris fuzz tests did not run")

EXAMPLE = pathlib.Path(__file__).resolve().parents[3] / "examples" / "pyserial"
RECORDING = EXAMPLE / "recordings" / "test_thermometer" / "test_identify_and_read.wtape"


def test_example_target_runs_the_driver_against_mutated_replays():
    result = subprocess.run([sys.executable, str(EXAMPLE / "fuzz_thermometer.py"), "-runs=20",
                             "-seed=1"], capture_output=True, text=True, timeout=300,
                            cwd=EXAMPLE)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Done 20 runs" in result.stderr, result.stderr


# The thermometer's driver with a bug no recorded answer shows: it takes
# the model from the third word of the identity, which a shorter answer
# does not have (IndexError, not one of the driver's errors).
BUGGY_TARGET = textwrap.dedent("""
    import sys, atheris, serial
    from wiretape.fuzzing import DRIVER_ERRORS, FuzzedRecording

    recording = FuzzedRecording(sys.argv.pop(1))

    def model(port):
        port.write(b"*IDN?\\n")
        answer = port.read_until(b"\\n")
        if not answer.endswith(b"\\n"):
            raise TimeoutError("no answer")
        return answer.split()[2]

    def test_one_input(plan):
        with recording.serial(plan):
            try:
                model(serial.Serial("/dev/ttyUSB0", 115200, timeout=0.05))
            except (TimeoutError, ValueError) + DRIVER_ERRORS:
                pass

    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
""")


def test_planted_bug_is_found(tmp_path):
    target = tmp_path / "buggy_target.py"
    target.write_text(BUGGY_TARGET)
    result = subprocess.run([sys.executable, str(target), str(RECORDING), "-runs=20000",
                             "-seed=7", f"-artifact_prefix={tmp_path}/"],
                            capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert result.returncode != 0, result.stderr[-2000:]
    assert "IndexError" in result.stdout + result.stderr, result.stderr[-2000:]
    assert any(name.startswith("crash-") for name in os.listdir(tmp_path))
