"""The driver of the importer fuzz targets (pcap_import_fuzz.py,
umockdev_import_fuzz.py): atheris when installed, otherwise random
mutations (truncation, bit flips, inserted tokens) of the corpus."""

from __future__ import annotations

import atexit
import os
import random
import shutil
import tempfile
import time

from import_check import check_input

_TOKENS = {
    "pcap": [b"\xff\xff\xff\xff", b"\x00\x00\x00\x00", b"\x0a\x0d\x0d\x0a", b"\xa1\xb2\xc3\xd4"],
    "umockdev": [b"r ", b"w ", b"f ", b"d 0 ", b"Q\n", b"^", b"^`", b"\n", b"99999999999999999999",
                 b"\x1b[31m"],
}


def _scratch() -> str:
    base = "/dev/shm" if os.access("/dev/shm", os.W_OK) else None
    scratch = tempfile.mkdtemp(prefix="wiretape-import-fuzz-", dir=base)
    atexit.register(shutil.rmtree, scratch, ignore_errors=True)
    return scratch


def _random_fuzz(fmt: str, argv: list, scratch: str) -> int:
    seconds = 60.0
    dirs = []
    if "-help=1" in argv:
        print(f"{fmt}_import_fuzz: random mutation (atheris is not installed); flags: "
              "-max_total_time=SECONDS, -runs=0, CORPUS_DIR...")
        return 0
    for arg in argv:
        if arg.startswith("-max_total_time="):
            seconds = float(arg.split("=", 1)[1])
        elif arg == "-runs=0":
            seconds = 0.0
        elif not arg.startswith("-"):
            dirs.append(arg)
    corpus = []
    for directory in dirs:
        for name in sorted(os.listdir(directory)):
            with open(os.path.join(directory, name), "rb") as handle:
                corpus.append(handle.read())
    for data in corpus:
        check_input(fmt, data, scratch)
    rng = random.Random(int(os.environ.get("FUZZ_SEED", time.time())))
    deadline = time.monotonic() + seconds
    runs = 0
    while time.monotonic() < deadline and corpus:
        data = bytearray(rng.choice(corpus))
        for _ in range(rng.randint(1, 3)):
            choice = rng.random()
            at = rng.randint(0, len(data))
            if choice < 0.3:
                del data[at:]
            elif choice < 0.7 and data:
                at = min(at, len(data) - 1)
                data[at] ^= 1 << rng.randint(0, 7)
            else:
                data[at:at] = rng.choice(_TOKENS[fmt])
        check_input(fmt, bytes(data), scratch)
        runs += 1
    print(f"{fmt}_import_fuzz: {len(corpus)} corpus inputs and {runs} mutations ran cleanly "
          f"(random mutation: atheris is not installed)")
    return 0


def main(fmt: str, argv: list) -> int:
    scratch = _scratch()
    try:
        import atheris
    except ImportError:
        return _random_fuzz(fmt, argv[1:], scratch)
    atheris.instrument_all()
    atheris.Setup(argv, lambda data: check_input(fmt, data, scratch))
    atheris.Fuzz()
    return 0
