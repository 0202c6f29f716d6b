"""The README's examples are real: the Python one runs, the C++ one is the
consumer program that ctest builds against an installed wiretape."""

import re
import subprocess
import sys
from pathlib import Path

import wiretape

ROOT = Path(__file__).resolve().parents[3]
README = (ROOT / "README.md").read_text()


def _block(language):
    match = re.search(rf"```{language}\n(.*?)```", README, re.S)
    assert match, f"README has no {language} example"
    return match.group(1)


def test_python_example_runs_and_replays_what_it_recorded(tmp_path):
    result = subprocess.run(
        [sys.executable, "-c", _block("python")],
        cwd=tmp_path, capture_output=True, text=True, timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == ["live:   b'PING\\n'", "replay: b'PING\\n'"]
    assert (tmp_path / "hello.wtape").stat().st_size > 0


def test_cpp_example_is_the_consumer_program():
    consumer = (ROOT / "tests/consumer/main.cpp").read_text()
    code = consumer[consumer.index("#include <wiretape/wiretape.hpp>"):]
    assert _block("cpp") == code


def test_version_is_defined_once():
    header = (ROOT / "include/wiretape/version.hpp").read_text()
    version = re.search(r'WIRETAPE_VERSION_STRING "([^"]+)"', header).group(1)
    package_xml = (ROOT / "package.xml").read_text()
    assert f"<version>{version}</version>" in package_xml
    assert wiretape.__version__ == version
