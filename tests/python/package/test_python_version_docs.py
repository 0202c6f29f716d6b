"""README and docs/python.md say the oldest Python wiretape installs on, as
pyproject.toml's requires-python has it: on an older one pip says only "No
matching distribution" (issue 38)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def test_the_docs_name_the_python_that_pyproject_requires():
    pyproject = (ROOT / "pyproject.toml").read_text()
    required = re.search(r'^requires-python = ">=(\d+\.\d+)"', pyproject, re.M).group(1)
    for doc in ("README.md", "docs/python.md"):
        said = re.findall(r"requires Python ≥ (\d+\.\d+)", (ROOT / doc).read_text())
        assert said, f"{doc} does not say which Python wiretape requires"
        assert set(said) == {required}, (doc, said, required)
