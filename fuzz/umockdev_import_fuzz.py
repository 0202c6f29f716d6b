#!/usr/bin/env python3
"""Fuzzes the umockdev importer (``wiretape convert X.script OUT --from umockdev``):
any bytes either convert to records whose bytes are in the script, or fail
with a SessionError naming the file, leaving no output (fuzz/import_check.py).

Usage: umockdev_import_fuzz.py [libFuzzer flags] [CORPUS_DIR...]
With atheris (installed by `make fuzz`) a coverage-guided run; without it,
random mutations of the corpus for -max_total_time seconds."""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from import_fuzz_main import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main("umockdev", sys.argv))
