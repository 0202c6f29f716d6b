#!/usr/bin/env python3
"""Fuzzes what `wiretape faults merge` reads (wiretape.faults.report): any
bytes as the second shard's --json of a campaign, merged with a first shard
as a campaign writes it, must either merge (exit 0 or 1, the merged --json
strict JSON) or be refused with exit 2 by one line naming the file, holding
no control character a terminal would act on, and writing nothing. Any
other outcome (exit 3, a traceback, an escape echoed) is a finding.

Usage: faults_merge_fuzz.py [libFuzzer flags] [CORPUS_DIR...]

With atheris (installed into .venv by `make fuzz`) a coverage-guided
libFuzzer run; without it, random mutations of the corpus for
-max_total_time seconds. In the corpus, ``@SHA256@`` stands for the digest
of the session the target writes (so that a shard can name it), and the
session is ``lines.wtape`` beside the shards.
tests/python/cli/test_faults_merge_input.py runs every corpus file through
check_input().
"""

from __future__ import annotations

import atexit
import contextlib
import io
import json
import os
import random
import shutil
import sys
import tempfile
import time

import wiretape
from wiretape import faults
from wiretape.cli import main as cli_main

KINDS = ["drop", "corrupt"]
OPTIONS = "timing=none"
SHA256_MARK = b"@SHA256@"


def prepare(scratch: str) -> dict:
    """The session (three exchanges) and the first of two shards, written once."""
    session = os.path.join(scratch, "lines.wtape")
    if not os.path.exists(session):
        with wiretape.SessionWriter(session, port_type="serial") as writer:
            for n in range(3):
                writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
                writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}\n".encode())
    digest = faults.session_digest(session)
    first = os.path.join(scratch, "shard1.json")
    if not os.path.exists(first):
        cases = faults.cases(session, kinds=KINDS, options=OPTIONS)
        runs = [{"case": index, "kind": case.kind, "where": case.where, "outcome": "ok",
                 "exit": 0, "seconds": 0.25, "repro": ""}
                for index, case in enumerate(cases) if index % 2 == 0]
        with open(first, "w", encoding="utf-8") as stream:
            json.dump({"session": "lines.wtape", "session_sha256": digest, "seed": 0,
                       "kinds": KINDS, "budget": None, "options": OPTIONS,
                       "cases": len(cases), "shard": "1/2", "speed": 1.0, "runs": runs,
                       "interrupted": False}, stream)
    return {"first": first, "digest": digest}


def _refuse_constant(name: str):
    raise ValueError(f"{name} in the merged --json")


def check_input(data: bytes, scratch: str) -> str:
    """Merges `data` as shard 2/2; "merged" or "refused", or AssertionError
    when the contract is broken."""
    files = prepare(scratch)
    bad = os.path.join(scratch, "shard2.json")
    out = os.path.join(scratch, "merged.json")
    with open(bad, "wb") as handle:
        handle.write(data.replace(SHA256_MARK, files["digest"].encode()))
    if os.path.exists(out):
        os.unlink(out)
    stdout, stderr = io.StringIO(), io.StringIO()
    started = time.monotonic()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = cli_main(["faults", "merge", files["first"], bad, "--json", out])
    if time.monotonic() - started > 60:
        raise AssertionError("took more than 60 s (a hang?)")
    printed = stdout.getvalue() + stderr.getvalue()
    shown = printed.replace("\n", "")
    if not shown.isprintable():
        raise AssertionError(f"a control character reached the terminal: {printed!r}")
    if "Traceback" in printed:
        raise AssertionError(f"a traceback: {printed!r}")
    if status == 2:
        message = stderr.getvalue().strip()
        if "\n" in message or bad not in message:
            raise AssertionError(f"not one line naming the file: {message!r}")
        if os.path.exists(out):
            raise AssertionError(f"--json written before the refusal {message!r}")
        return "refused"
    if status not in (0, 1):
        raise AssertionError(f"exit {status}: {printed!r}")
    with open(out, encoding="utf-8") as stream:
        merged = json.load(stream, parse_constant=_refuse_constant)
    if len(merged["runs"]) != merged["cases"]:
        raise AssertionError(f"merged {len(merged['runs'])} runs of {merged['cases']} cases")
    return "merged"


def _random_fuzz(argv: list, scratch: str) -> int:
    """Without atheris: random token mutations of the corpus."""
    seconds = 60.0
    dirs = []
    for arg in argv:
        if arg.startswith("-max_total_time="):
            seconds = float(arg.split("=", 1)[1])
        elif arg == "-runs=0":
            seconds = 0.0
        elif arg == "-help=1":
            print("faults_merge_fuzz: random mutation (atheris is not installed); flags: "
                  "-max_total_time=SECONDS, -runs=0, CORPUS_DIR...")
            return 0
        elif not arg.startswith("-"):
            dirs.append(arg)
    corpus = []
    for directory in dirs:
        for name in sorted(os.listdir(directory)):
            with open(os.path.join(directory, name), "rb") as handle:
                corpus.append(handle.read())
    for data in corpus:
        check_input(data, scratch)
    tokens = [b"NaN", b"Infinity", b"-1", b"0", b"null", b"true", b'"\x1b[31m"', b'"drop"',
              b'"exchange:99"', b'"hang"', b'"crash"', b"[[[[[[[[", b"1e999", b'"2/2"',
              b'"1/2"', b"{", b"}", b",", b'"\\u001b"']
    rng = random.Random(int(os.environ.get("FUZZ_SEED", time.time())))
    deadline = time.monotonic() + seconds
    runs = 0
    while time.monotonic() < deadline and corpus:
        data = bytearray(rng.choice(corpus))
        for _ in range(rng.randint(1, 4)):
            at = rng.randint(0, len(data))
            if rng.random() < 0.6:
                data[at:at] = rng.choice(tokens)
            elif data:
                del data[at:at + rng.randint(1, 8)]
        check_input(bytes(data), scratch)
        runs += 1
    print(f"faults_merge_fuzz: {len(corpus)} corpus inputs and {runs} mutations ran cleanly "
          "(random mutation: atheris is not installed)")
    return 0


def main() -> int:
    base = "/dev/shm" if os.access("/dev/shm", os.W_OK) else None
    scratch = tempfile.mkdtemp(prefix="wiretape-merge-fuzz-", dir=base)
    atexit.register(shutil.rmtree, scratch, ignore_errors=True)
    try:
        import atheris
    except ImportError:
        return _random_fuzz(sys.argv[1:], scratch)
    atheris.instrument_all()
    atheris.Setup(sys.argv, lambda data: check_input(data, scratch))
    atheris.Fuzz()
    return 0


if __name__ == "__main__":
    sys.exit(main())
