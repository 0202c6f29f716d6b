"""What the tools (show, stats, verify, convert, diff, edit) and the exports
(jsonl, pcapng, mcap) share: reading a session (opening it, its header, its
events, its bytes as text) and opening the files they read and write
themselves. Every tool and export reads and writes through here, so a
session is opened and described the same way everywhere.

Files follow DESIGN §6, "Special files": an input is a regular file, or a
pipe or FIFO read as a stream (waiting for its writer, interruptibly); an
output that is not a regular file (a FIFO, a device, through a symbolic link
too) is written through, never renamed over; nothing is written over the
input. The C++ library applies the same rules, in the same words, to the
.wtape files and flexiport logs it opens (src/posix/file_checks.cpp), where
replay and the session writer keep to regular files.

Every refusal is a :class:`FileRefused`, an OSError: the command line exits
3 (a file that cannot be opened, read or written)."""

from __future__ import annotations

import errno
import os
import select
import stat
import sys
from typing import IO, Any, Callable, Dict, Iterable, List, NamedTuple, Optional, Union

from . import _core

__all__ = ["SessionPath", "DIRECTIONS", "open_session", "raise_damage", "warn_if_unfinished", "header_fields",
           "event_of", "event_payload", "escape_bytes", "header_text", "printable",
           "FileRefused", "open_input", "open_output", "check_output",
           "is_stream", "is_written_through", "open_regular_output",
           "check_regular_output", "session_files", "refuse_same_file",
           "not_regular_file_problem"]


# --------------------------------------------------------------------------
# reading a session

#: A session file: a ``.wtape`` or a flexiport ``name.log`` (for
#: ``name.logr`` + ``name.logw``).
SessionPath = Union[str, "os.PathLike[str]"]

#: The record kinds that carry bytes (rx, tx); every other kind is an event.
DIRECTIONS = tuple(kind["name"] for kind in _core.RECORD_KINDS if not kind["is_event"])


def open_session(path: SessionPath) -> _core.SessionReader:
    """A reader streaming the session's records.

    The rule for damaged input, the same in every command (docs/cli.md):
    a file that cannot be opened or read (missing, permission denied, neither
    a regular file nor a pipe or FIFO, which is read as a stream) raises
    PortError here, an OSError: exit 3. A file that is
    not a session, or is damaged, is read up to the damage, every record
    before it is used (shown, counted, compared, converted), and then
    raise_damage() raises the damage, a SessionError: exit 1
    (cli.exit_code_for maps both)."""
    return _core.SessionReader(os.fspath(path))


#: The metadata key by which a session names its protocol profile
#: (``wiretape record --meta profile=NAME``).
PROFILE_META_KEY = "profile"
#: The --profile value that says: no profile, not even the session's.
NO_PROFILE = "none"


class ProfileChoice(NamedTuple):
    """The profile a command reads sessions with: ``spec`` for
    _core.profile_from_spec (a name or a declared profile), or None for
    none; ``note``, when a session's ``profile`` metadata was left out, says
    why (for the user: the command runs without it). A NamedTuple, not a
    dataclass: dataclasses imports inspect, a sixth of the wiretape
    command's start-up."""

    spec: Optional[str] = None
    note: Optional[str] = None


def chosen_profile(given: Optional[str], *headers: Any) -> ProfileChoice:
    """The one rule of every command's --profile (docs/cli.md "Protocol
    profiles"): a given profile is the one (``none``: no profile at all);
    without one, the profile the sessions name in their ``profile``
    metadata, read as --profile is read (``_core.profile_from_spec``), is
    the default. Metadata that names no profile wiretape knows is left out,
    with a note; sessions naming different profiles are a ValueError (give
    --profile). `headers`: the sessions' SessionHeaders."""
    if given is not None:
        return ProfileChoice(None if given.strip() == NO_PROFILE else given)
    named: Dict[str, List[Any]] = {}
    notes: List[str] = []
    for header in headers:
        spec = (header.metadata.get(PROFILE_META_KEY) or "").strip()
        if not spec or spec == NO_PROFILE:
            continue
        try:
            _core.profile_from_spec(spec)
        except _core.OptionError as error:
            notes.append(f"the session's metadata {PROFILE_META_KEY}={spec!r} is not a "
                         f"profile ({error}): read without one")
            continue
        named.setdefault(spec, []).append(header)
    if len(named) > 1:
        raise ValueError("the sessions name different profiles in their metadata ("
                         + ", ".join(f"{PROFILE_META_KEY}={spec}" for spec in named)
                         + "): give --profile NAME, or --profile none")
    spec = next(iter(named), None)
    return ProfileChoice(spec, "; ".join(notes) or None)


def raise_damage(reader: _core.SessionReader) -> None:
    """Raises the session's damage (SessionError, exit 1), if reading it
    stopped at some; call it once the records before the damage are used.
    A file still being written (a recorder has it open) is not damaged: its
    unfinished end is a warning on stderr, and the command goes on."""
    damage = reader.damage
    if damage is not None:
        raise damage
    warn_if_unfinished(reader)


def warn_if_unfinished(reader: _core.SessionReader) -> None:
    """Says on stderr, once reading ended, that it ended at the unfinished
    end of a file still being written (a recorder has it open): a warning,
    not damage."""
    unfinished = reader.unfinished
    if unfinished is not None:
        print(f"wiretape: warning: {unfinished.message}", file=sys.stderr, flush=True)


def header_fields(reader: _core.SessionReader) -> Dict[str, Any]:
    """The session header as the file holds it (its JSON layout,
    ``SessionHeader.to_dict()``), a dict the caller may change, for output
    as JSON (exports, jsonl, view); read ``reader.header``'s attributes
    otherwise."""
    return reader.header.to_dict()


def event_of(record: _core.Record) -> Optional[Dict[str, Any]]:
    """The event's JSON object, or None for rx/tx and unparsable payloads."""
    if record.kind in DIRECTIONS:
        return None
    return event_payload(record.data)


def event_payload(data: bytes) -> Optional[Dict[str, Any]]:
    """An event record's payload as a JSON object ({} when empty), or None
    when it is not one."""
    if not data:
        return {}
    try:
        value = _json_loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    return value if isinstance(value, dict) else None


_loads: Optional[Callable[[str], Any]] = None


def _json_loads(text: str) -> Any:
    """json.loads, imported at the first event read: json is not on the
    start-up of a command that reads none (replay_as_overhead_ratio)."""
    global _loads
    if _loads is None:
        import json

        _loads = json.loads
    return _loads(text)


def escape_bytes(data: bytes) -> str:
    """Printable ASCII kept, the rest as escapes (\\r, \\n, \\xNN): safe on a
    terminal (C++'s escape_bytes, as in mismatch reports)."""
    return _core.escape_bytes(bytes(data), len(data))


def header_text(value: object) -> str:
    """A session header's text (port options, host, metadata keys and
    values...) as it may reach a terminal: the only way header text is
    printed. The file is anyone's, so every character that is not printable
    (control characters such as ESC, DEL, C1 controls, bidirectional
    overrides, line separators) and the backslash are escaped as payload
    bytes are (escape_bytes of their UTF-8: ``\\x1b``, ``\\n``, ``\\\\``);
    printable letters of any script are kept."""
    text = value if isinstance(value, str) else str(value)
    if text.isprintable() and "\\" not in text:
        return text
    return "".join(
        char if char.isprintable() and char != "\\"
        else escape_bytes(char.encode("utf-8", "surrogatepass"))
        for char in text
    )


def printable(data: bytes, limit: int = 64) -> str:
    """The first `limit` bytes as escape_bytes() text, and how many more there are."""
    return _core.escape_bytes(bytes(data), limit)


# --------------------------------------------------------------------------
# the files the tools and exports open themselves


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


def is_stream(path) -> bool:
    """Whether `path` is a pipe or FIFO (following symbolic links), found
    without opening it: opening and closing a FIFO a writer is using would
    cost the writer its reader."""
    try:
        return stat.S_ISFIFO(os.stat(path).st_mode)
    except OSError:
        return False


def _wait_for_writer(fd: int) -> None:
    # Until a writer first connects a read reports the end at once, so wait in
    # poll(), which Python restarts after running signal handlers (PEP 475):
    # Ctrl-C and SIGTERM end the wait.
    poller = select.poll()
    poller.register(fd, select.POLLIN)
    while not poller.poll():
        pass


def open_input(path, text: bool = False) -> IO:
    """`path` opened to read (binary, or UTF-8 text), following symbolic
    links: a regular file, or a pipe or FIFO read as a stream, once a writer
    has come (the wait is interruptible). Anything else (a device, a
    directory, a socket) is refused. Opening itself never blocks."""
    path = os.fspath(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISFIFO(mode):
            _wait_for_writer(fd)
        else:
            _refuse_unless_regular(path, mode)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "r", encoding="utf-8") if text else os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _never_an_output(path: str, mode: int) -> None:
    # Nothing can be written into a directory or a socket as into a file.
    if stat.S_ISDIR(mode) or stat.S_ISSOCK(mode):
        raise FileRefused(not_regular_file_problem(path, mode))


def _mode_of(path: str, follow_links: bool) -> Optional[int]:
    """What is at `path` (st_mode), or None when nothing is."""
    try:
        return (os.stat if follow_links else os.lstat)(path).st_mode
    except FileNotFoundError:
        return None


def check_output(path) -> None:
    """Refuses an output path that cannot be written through, following
    symbolic links: a directory, a socket. A FIFO or a device is fine:
    open_output() writes through it."""
    path = os.fspath(path)
    mode = _mode_of(path, follow_links=True)
    if mode is not None:
        _never_an_output(path, mode)


def is_written_through(path) -> bool:
    """Whether an output at `path` is written in place because it is not a
    regular file (a FIFO, a device; through a symbolic link too), rather
    than replaced by renaming a finished file over it."""
    mode = _mode_of(os.fspath(path), follow_links=True)
    return mode is not None and not stat.S_ISREG(mode)


def open_output(path, text: bool = False) -> IO:
    """`path` opened to write (binary, or UTF-8 text), following symbolic
    links: created, or emptied if it is a regular file; a FIFO or a device
    is written through as it is (a FIFO waits for its reader, interruptibly:
    Python restarts the open after running signal handlers). Refuses what
    check_output() refuses."""
    path = os.fspath(path)
    check_output(path)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        info = os.fstat(fd)
        _never_an_output(path, info.st_mode)
        if stat.S_ISREG(info.st_mode):
            os.ftruncate(fd, 0)
        return os.fdopen(fd, "w", encoding="utf-8") if text else os.fdopen(fd, "wb")
    except BaseException:
        os.close(fd)
        raise


def check_regular_output(path) -> None:
    """Refuses an output path that exists and is not a regular file, a
    symbolic link included: for a file that is renamed over another."""
    path = os.fspath(path)
    mode = _mode_of(path, follow_links=False)
    if mode is not None:
        _refuse_unless_regular(path, mode)


def open_regular_output(path, text: bool = False) -> IO:
    """`path` created, or emptied if it is a regular file, to write (binary,
    or UTF-8 text): the temporary file an export renames at the end. Refuses
    what check_regular_output() refuses, without touching it and without
    blocking."""
    path = os.fspath(path)
    check_regular_output(path)  # before opening: opening a device can do things
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK
                     | os.O_CLOEXEC, 0o644)
    except OSError as error:
        if error.errno in (errno.ELOOP, errno.ENXIO):  # replaced since the check
            check_regular_output(path)
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
