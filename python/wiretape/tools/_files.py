"""Opening the files the tools read and write themselves (jsonl, pcapng,
mcap): regular files only, never blocking in ``open()``, never writing
through a symbolic link or over the input. The C++ library applies the same
rules, in the same words, to the .wtape files and flexiport logs it opens
(src/posix/file_checks.cpp).

Every refusal is a :class:`FileRefused`, an OSError: the command line exits
3 (a file that cannot be opened, read or written)."""

from __future__ import annotations

import errno
import os
import stat
from typing import IO, Iterable, List, Optional

from .. import _core

__all__ = ["FileRefused", "open_input", "open_output", "check_output",
           "session_files", "refuse_same_file"]


class FileRefused(OSError):
    """A file wiretape will not read or write, and why."""


_KINDS = (
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISLNK, "a symbolic link"),
)


def not_regular_file_problem(path: str, mode: int) -> Optional[str]:
    """``"PATH is a FIFO, not a regular file"`` and the like; None for a
    regular file."""
    if stat.S_ISREG(mode):
        return None
    for test, kind in _KINDS:
        if test(mode):
            return f"{path} is {kind}, not a regular file"
    return f"{path} is not a regular file"


def _refuse_unless_regular(path: str, mode: int) -> None:
    problem = not_regular_file_problem(path, mode)
    if problem is not None:
        raise FileRefused(problem)


def open_input(path, text: bool = False) -> IO:
    """`path` opened to read (binary, or UTF-8 text). Never blocks: it is
    opened non-blocking and refused unless it is a regular file, so a FIFO
    cannot hang the command. Symbolic links are followed."""
    path = os.fspath(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        _refuse_unless_regular(path, os.fstat(fd).st_mode)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "r", encoding="utf-8") if text else os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def check_output(path) -> None:
    """Refuses an output path that exists and is not a regular file: a
    symbolic link (never written through), a FIFO, a device, a directory."""
    path = os.fspath(path)
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    _refuse_unless_regular(path, mode)


def open_output(path, text: bool = False) -> IO:
    """`path` created, or emptied if it is a regular file, to write (binary,
    or UTF-8 text). Refuses what check_output() refuses, without touching it
    and without blocking."""
    path = os.fspath(path)
    check_output(path)  # before opening: opening a device can do things
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK
                     | os.O_CLOEXEC, 0o644)
    except OSError as error:
        if error.errno in (errno.ELOOP, errno.ENXIO):  # replaced since the check
            check_output(path)
        raise
    try:
        # Again on the descriptor: what was checked is what is written.
        _refuse_unless_regular(path, os.fstat(fd).st_mode)
        os.ftruncate(fd, 0)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "w", encoding="utf-8") if text else os.fdopen(fd, "wb")
    except BaseException:
        os.close(fd)
        raise


def session_files(path) -> List[str]:
    """Every file reading the session `path` may read: itself and, when it
    names a flexiport log, ``name.logr`` and ``name.logw``."""
    path = os.fspath(path)
    files = [path]
    prefix = _core.flexiport_prefix(path)
    if prefix is not None:
        files += [prefix + suffix for suffix in "rw"]
    return files


def refuse_same_file(inputs: Iterable, outputs: Iterable) -> None:
    """Refuses to write any of `outputs` when it is one of `inputs`: the same
    device and inode, so hard links and symbolic links to an input count."""
    identities = []
    for name in inputs:
        try:
            info = os.stat(name)
        except OSError:
            continue  # opening it reports that
        identities.append((info.st_dev, info.st_ino, os.fspath(name)))
    for output in outputs:
        try:
            info = os.stat(output)
        except OSError:
            continue
        for device, inode, name in identities:
            if (info.st_dev, info.st_ino) == (device, inode):
                raise FileRefused(f"{os.fspath(output)} is the same file as {name}: "
                                  "refusing to overwrite the input")
