#!/usr/bin/env python3
"""Fuzzes the jsonl importer (``wiretape convert X.jsonl OUT --from jsonl``,
wiretape.exports.jsonl): any bytes must either convert, or fail with a
SessionError whose one-line message names the file and the line (exit 1 from
the CLI, as a damaged session file). Any other exception is a finding.

Usage: jsonl_import_fuzz.py [libFuzzer flags] [CORPUS_DIR...]

With atheris (installed into .venv by `make fuzz`) this is a coverage-guided
libFuzzer run, taking libFuzzer's flags (-max_total_time=N, -runs=0, ...).
Without it, it mutates the corpus at random for -max_total_time seconds.
tests/python/exports/test_jsonl.py runs every corpus file through
check_input().
"""

from __future__ import annotations

import atexit
import os
import random
import re
import shutil
import sys
import tempfile
import time

import wiretape
from wiretape.cli import EXIT_CHECK_FAILED, exit_code_for
from wiretape.tools import convert as convert_module


def check_input(data: bytes, scratch: str) -> None:
    """Converts `data` as a jsonl session; raises AssertionError (or the
    unexpected exception) if the outcome breaks the importer's contract."""
    src = os.path.join(scratch, "in.jsonl")
    dst = os.path.join(scratch, "out.wtape")
    with open(src, "wb") as handle:
        handle.write(data)
    if os.path.exists(dst):
        os.unlink(dst)
    try:
        result = convert_module.convert(src, dst, from_format="jsonl", to_format="wiretape")
    except wiretape.SessionError as error:
        message = str(error)
        if not re.match(re.escape(src) + r":[1-9][0-9]*: \S", message):
            raise AssertionError(f"the message does not name the line: {message!r}") from error
        if "\n" in message or "Traceback" in message:
            raise AssertionError(f"not a one-line message: {message!r}") from error
        if exit_code_for(error) != EXIT_CHECK_FAILED:
            raise AssertionError(f"exit code {exit_code_for(error)} for {message!r}") from error
        if not 0 <= error.offset <= len(data):
            raise AssertionError(f"offset {error.offset} outside the input") from error
        return
    # Records of kinds this version does not name are written but skipped
    # when read (docs/session-format.md), so fewer may come back.
    with wiretape.SessionReader(dst) as reader:
        count = sum(1 for _ in reader)
        if reader.damage is not None or count > result.records:
            raise AssertionError(f"wrote {result.records} records, read back {count}")


def _scratch() -> str:
    base = "/dev/shm" if os.access("/dev/shm", os.W_OK) else None
    return tempfile.mkdtemp(prefix="wiretape-jsonl-fuzz-", dir=base)


def _random_fuzz(argv: list[str], scratch: str) -> int:
    """Without atheris: random byte and token mutations of the corpus."""
    seconds = 60.0
    dirs = []
    for arg in argv:
        if arg.startswith("-max_total_time="):
            seconds = float(arg.split("=", 1)[1])
        elif arg.startswith("-runs="):
            seconds = 0.0 if arg == "-runs=0" else seconds
        elif not arg.startswith("-"):
            dirs.append(arg)
    corpus = []
    for directory in dirs:
        for name in sorted(os.listdir(directory)):
            with open(os.path.join(directory, name), "rb") as handle:
                corpus.append(handle.read())
    for data in corpus:
        check_input(data, scratch)
    tokens = [b"{", b"}", b"[", b"]", b'"t_ns":', b'"kind":', b'"data_hex":', b'"header":',
              b'"event":', b"1e999", b"-1", b"18446744073709551616", b"null", b"\n", b'"zz"']
    rng = random.Random(int(os.environ.get("FUZZ_SEED", time.time())))
    deadline = time.monotonic() + seconds
    runs = 0
    while time.monotonic() < deadline and corpus:
        data = bytearray(rng.choice(corpus))
        for _ in range(rng.randint(1, 4)):
            at = rng.randint(0, len(data))
            if rng.random() < 0.5:
                data[at:at] = rng.choice(tokens)
            elif data:
                del data[at:at + rng.randint(1, 8)]
        check_input(bytes(data), scratch)
        runs += 1
    print(f"jsonl_import_fuzz: {len(corpus)} corpus inputs and {runs} mutations ran cleanly "
          f"(random mutation: atheris is not installed)")
    return 0


def main() -> int:
    scratch = _scratch()
    atexit.register(shutil.rmtree, scratch, ignore_errors=True)
    try:
        import atheris
    except ImportError:
        return _random_fuzz(sys.argv[1:], scratch)
    # Every function loaded so far, the importer's included: the editable
    # install loads wiretape through its own finder, which
    # atheris.instrument_imports() does not see into.
    atheris.instrument_all()
    atheris.Setup(sys.argv, lambda data: check_input(data, scratch))
    atheris.Fuzz()
    return 0


if __name__ == "__main__":
    sys.exit(main())
