"""Running a lab tool's own pytest on a test of examples/lab: in a folder
of its own (its own pytest.ini, so this project's options and conftest stay
out), with plugin autoloading off and only the plugins named enabled (`-p`):
the project's runs disable them (pyproject's addopts), their tests enable
them here."""

import os
import pathlib
import shutil
import subprocess

from devices import DEADLINE_S

ROOT = pathlib.Path(__file__).resolve().parents[3]
EXAMPLES = ROOT / "examples" / "lab"
# The lab tool's run: a replay it talks to and the pytest it is, generous.
RUN_DEADLINE_S = 120.0


def run_pytest(python, folder, test_file, *argv):
    """(exit status, output) of `python -m pytest` on `test_file` (copied
    into `folder`, a new rootdir) with `argv`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "pytest.ini").write_text("[pytest]\n")
    shutil.copy(test_file, folder / test_file.name)
    env = dict(os.environ, PYTEST_DISABLE_PLUGIN_AUTOLOAD="1")
    done = subprocess.run([str(python), "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           *argv, test_file.name], cwd=folder, env=env, text=True,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          timeout=RUN_DEADLINE_S)
    return done.returncode, done.stdout


def wait_for_line(child, text, deadline_lines=20):
    """Reads the child's stderr until a line holding `text`; the child is
    killed and the test fails with what it said if none comes."""
    lines = []
    for _ in range(deadline_lines):
        line = child.stderr.readline()
        if not line:
            break
        lines.append(line)
        if text in line:
            return line
    child.kill()
    raise AssertionError(f"no {text!r} from the replay: " + "".join(lines) + child.stderr.read())


__all__ = ["DEADLINE_S", "EXAMPLES", "ROOT", "run_pytest", "wait_for_line"]
