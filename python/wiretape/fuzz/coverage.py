"""Coverage from AFL++'s instrumentation (DESIGN §27, docs/fuzzing.md
"Coverage from AFL++"): a program built with afl-clang-fast / afl-cc
writes its edge hit counts into a SysV shared-memory map whose id it finds
in ``__AFL_SHM_ID``. The search makes one map per job, clears it before
each run and reads it after; a plan whose run lit an edge (or a hit-count
bucket of one, as AFL counts them) never seen before joins the corpus."""

from __future__ import annotations

import ctypes
import mmap
import os
import shutil
import subprocess
from typing import Optional, Sequence

#: Strings every AFL++-instrumented program holds (its runtime's).
AFL_MARKERS = (b"__AFL_SHM_ID", b"__afl_area_ptr")
#: The map's size when the program does not say (AFL++'s default).
DEFAULT_MAP_SIZE = 65536

_IPC_PRIVATE = 0
_IPC_CREAT = 0o1000
_IPC_EXCL = 0o2000
_IPC_RMID = 0


def _bucket(count: int) -> int:
    """AFL's hit-count classes: 1, 2, 3, 4-7, 8-15, 16-31, 32-127, 128+."""
    if count == 0:
        return 0
    for bit, upper in enumerate((1, 2, 3, 7, 15, 31, 127)):
        if count <= upper:
            return 1 << bit
    return 128


_BUCKETS = bytes(_bucket(count) for count in range(256))


class CoverageError(Exception):
    """The map could not be made (no SysV shared memory here)."""


def executable_of(argv: Sequence[str]) -> Optional[str]:
    """The program file CMD runs, found as the shell would (None when not)."""
    if not argv:
        return None
    found = shutil.which(argv[0])
    return os.path.realpath(found) if found else None


def instrumented(argv: Sequence[str]) -> bool:
    """Whether CMD's program was built with AFL++'s compiler: its file holds
    AFL++'s runtime (the markers above). A script run by an interpreter,
    or a program that only loads an instrumented library, is not seen."""
    path = executable_of(argv)
    if path is None:
        return False
    try:
        with open(path, "rb") as file, mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ) as data:
            return any(data.find(marker) >= 0 for marker in AFL_MARKERS)
    except (OSError, ValueError):  # unreadable, or empty (mmap refuses)
        return False


def map_size(argv: Sequence[str]) -> int:
    """The map CMD's program needs: what it says when asked
    (AFL_DUMP_MAP_SIZE=1, AFL++ 4), else AFL_MAP_SIZE, else 65536."""
    path = executable_of(argv)
    if path is not None:
        env = dict(os.environ, AFL_DUMP_MAP_SIZE="1")
        try:
            told = subprocess.run([path], env=env, capture_output=True, timeout=10,
                                  stdin=subprocess.DEVNULL).stdout.split()
            if told and told[0].isdigit() and int(told[0]) > 0:
                return max(int(told[0]), 64)
        except (OSError, subprocess.TimeoutExpired):
            pass
    try:
        return max(int(os.environ.get("AFL_MAP_SIZE", "")), 64)
    except ValueError:
        return DEFAULT_MAP_SIZE


def _libc() -> ctypes.CDLL:
    libc = ctypes.CDLL(None, use_errno=True)
    libc.shmget.argtypes = [ctypes.c_int, ctypes.c_size_t, ctypes.c_int]
    libc.shmget.restype = ctypes.c_int
    libc.shmat.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_int]
    libc.shmat.restype = ctypes.c_void_p
    libc.shmdt.argtypes = [ctypes.c_void_p]
    libc.shmdt.restype = ctypes.c_int
    libc.shmctl.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_void_p]
    libc.shmctl.restype = ctypes.c_int
    return libc


class AflMap:
    """One SysV shared-memory map for the runs of one job. It is marked for
    removal as soon as it is made (Linux still lets the program attach it
    by id), so it goes when the last user detaches: at close, or when this
    process dies, never left behind."""

    def __init__(self, size: int):
        self.size = size
        self._libc = _libc()
        self.id = self._libc.shmget(_IPC_PRIVATE, size, _IPC_CREAT | _IPC_EXCL | 0o600)
        if self.id < 0:
            raise CoverageError(f"AFL++ coverage: shmget of a {size}-byte map failed: "
                                f"{os.strerror(ctypes.get_errno())}")
        address = self._libc.shmat(self.id, None, 0)
        if address in (None, ctypes.c_void_p(-1).value):
            error = ctypes.get_errno()
            self._libc.shmctl(self.id, _IPC_RMID, None)
            raise CoverageError(f"AFL++ coverage: shmat failed: {os.strerror(error)}")
        self._libc.shmctl(self.id, _IPC_RMID, None)
        self._address: Optional[int] = address

    def environment(self) -> Sequence[str]:
        """What CMD's environment gets (as `env` takes it) to write here."""
        return [f"__AFL_SHM_ID={self.id}", f"AFL_MAP_SIZE={self.size}"]

    def clear(self) -> None:
        assert self._address is not None
        ctypes.memset(self._address, 0, self.size)

    def trace(self) -> bytes:
        """The run's hit counts, bucketed as AFL buckets them."""
        assert self._address is not None
        return ctypes.string_at(self._address, self.size).translate(_BUCKETS)

    def close(self) -> None:
        if self._address is not None:
            self._libc.shmdt(self._address)
            self._address = None

    def __enter__(self) -> "AflMap":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Coverage:
    """Every (edge, hit-count bucket) the runs lit so far."""

    def __init__(self) -> None:
        self._seen = 0

    def add(self, trace: bytes) -> int:
        """Adds one run's bucketed trace; returns how many of its (edge,
        bucket) bits are new."""
        bits = int.from_bytes(trace, "little")
        new = bits & ~self._seen
        self._seen |= new
        return bin(new).count("1")

    @property
    def edges(self) -> int:
        """Edges lit so far (each counted once, whatever its buckets)."""
        seen = self._seen.to_bytes((self._seen.bit_length() + 7) // 8 or 1, "little")
        return len(seen) - seen.count(0)
