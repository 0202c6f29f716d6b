"""Sessions made by other tools, read as wiretape sessions (``convert --from``).

``reserial``  pytest-reserial's cassettes: a JSON-lines file, one line per
              test, ``{"TEST": {"rx": ..., "tx": ..., "rx_encoding": "utf-8",
              "tx_encoding": "utf-8"}}`` (without an encoding, the bytes are
              base64). reserial keeps a test's received and sent bytes as two
              strings with no order between them: the rx becomes a greeting,
              released when the port opens, followed by the tx to check,
              which is how reserial itself replays them.
``umockdev``  umockdev's tty scripts (``umockdev-record --script``): one
              operation a line, ``r DELAY_MS DATA`` (the device sent),
              ``w DELAY_MS DATA`` (the client wrote), ``f PERCENT -`` (fuzz),
              ``d 0 DEVICE``, ``Q`` (stop), ``# comment``; in DATA a byte
              below 32 is ``^`` and the byte + 64, ``^`` itself is ``^```.

Each reader returns (SessionHeader, iterator of (kind, t_ns, data)) and raises
SessionError naming the file and the place (line, field) at bad input.
"""

from __future__ import annotations

import base64
import binascii
import json
import os
from typing import Dict, Iterator, List, Optional, Tuple

from .. import _core
from ..session import open_input

__all__ = ["reserial_records", "reserial_tests", "umockdev_records"]

Records = Iterator[Tuple[str, int, bytes]]


def _error(path: str, where, problem: str, offset: int = 0) -> _core.SessionError:
    place = f"{path}:{where}" if where is not None else path
    return _core.SessionError(f"{place}: {problem}", offset)


# --- pytest-reserial ----------------------------------------------------------

_RESERIAL_FIELDS = ("rx", "tx", "rx_encoding", "tx_encoding")


def _reserial_lines(path: str):
    """(line number, byte offset, test name, its entry) for every test."""
    with open_input(path) as handle:
        offset = 0
        for number, raw in enumerate(handle, start=1):
            line_offset, offset = offset, offset + len(raw)
            try:
                text = raw.decode("utf-8").strip()
            except UnicodeDecodeError as error:
                raise _error(path, number, f"not UTF-8 text ({error.reason} at column "
                                           f"{error.start + 1})", line_offset) from None
            if not text:
                continue
            try:
                item = json.loads(text)
            except RecursionError:
                raise _error(path, number, "not JSON: nested too deeply", line_offset) from None
            except ValueError as error:
                message = (f"{error.msg} at column {error.colno}"
                           if isinstance(error, json.JSONDecodeError) else str(error))
                raise _error(path, number, f"not JSON: {message}", line_offset) from None
            if not isinstance(item, dict) or not item:
                raise _error(path, number, "expected a JSON object {\"TEST NAME\": {\"rx\": ..., "
                                           "\"tx\": ...}}, as pytest-reserial writes", line_offset)
            for name, entry in item.items():
                try:
                    name.encode("utf-8")
                except UnicodeEncodeError:  # JSON's "\ud800": no session can hold it
                    raise _error(path, number, f"test {_shown(name)}: the name is not valid "
                                               "UTF-8 (a lone surrogate)", line_offset) from None
                yield number, line_offset, name, entry


def reserial_tests(path) -> List[str]:
    """The names of the tests a cassette holds, in file order."""
    path = os.fspath(path)
    names: Dict[str, None] = {}  # ordered, and linear in the number of tests
    for _, _, name, _ in _reserial_lines(path):
        names.setdefault(name, None)
    return list(names)


def _shown(name: str, limit: int = 80) -> str:
    """A test name as a message shows it: quoted, control characters
    (terminal escapes) escaped, cut at `limit` characters."""
    shown = repr(name[:limit])
    return shown + (f" (cut, {len(name)} characters)" if len(name) > limit else "")


def _listing(names: List[str], limit: int = 20) -> str:
    shown = ", ".join(_shown(name) for name in names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def _reserial_bytes(path: str, number: int, offset: int, name: str, entry: dict,
                    direction: str) -> bytes:
    field = f"test {_shown(name)}: {direction}"
    text = entry.get(direction, "")
    if not isinstance(text, str):
        raise _error(path, number, f"{field}: expected a string, got {type(text).__name__}", offset)
    encoding = entry.get(f"{direction}_encoding")
    if encoding is None:
        try:
            return base64.b64decode(text.encode("ascii"), validate=True)
        except (UnicodeEncodeError, binascii.Error) as error:
            raise _error(path, number, f"{field}: not base64 (no {direction}_encoding, so "
                                       f"pytest-reserial wrote base64): {error}", offset) from None
    if encoding != "utf-8":
        raise _error(path, number, f"test {_shown(name)}: {direction}_encoding: expected "
                                   f"\"utf-8\" (or none: base64), got {_shown(str(encoding), 40)}",
                     offset)
    try:
        return text.encode("utf-8")
    except UnicodeEncodeError as error:
        raise _error(path, number, f"{field}: not valid UTF-8: {error.reason}", offset) from None


def reserial_records(path, test: Optional[str] = None):
    """(header, records) of one test of a pytest-reserial cassette.

    `test` may be omitted when the cassette holds one test; otherwise the
    SessionError lists the tests it holds."""
    path = os.fspath(path)
    found = None
    names: Dict[str, None] = {}  # ordered, and linear in the number of tests
    for number, offset, name, entry in _reserial_lines(path):
        if not isinstance(entry, dict):
            raise _error(path, number, f"test {_shown(name)}: expected a JSON object with rx "
                                       "and tx", offset)
        unknown = [key for key in entry if key not in _RESERIAL_FIELDS]
        if unknown:
            raise _error(path, number, f"test {_shown(name)}: unknown field "
                                       f"{_shown(unknown[0], 40)} (pytest-reserial writes "
                                       f"{', '.join(_RESERIAL_FIELDS)})", offset)
        names.setdefault(name, None)
        # The first line of a name, as pytest-reserial itself replays.
        if found is None and (test is None or name == test):
            found = (number, offset, name, entry)
    listing = _listing(list(names))
    if test is None and len(names) > 1:
        raise _error(path, None, f"a pytest-reserial cassette of {len(names)} tests: choose one "
                                 f"with --test NAME ({listing})")
    if found is None:
        if test is None:
            raise _error(path, None, "no test in this pytest-reserial cassette (an empty file)")
        raise _error(path, None, f"no test {_shown(test)} in this pytest-reserial cassette: it holds "
                                 f"{listing or 'none'}")
    number, offset, name, entry = found
    rx = _reserial_bytes(path, number, offset, name, entry, "rx")
    tx = _reserial_bytes(path, number, offset, name, entry, "tx")
    header = _core.SessionHeader(port_type="serial", source_format="reserial",
                                 source_files=[os.path.basename(path)],
                                 source_details={"test": name})

    def records() -> Records:
        # The greeting first, then what the client must write: every rx is
        # there to read from the open on, as under pytest-reserial.
        if rx:
            yield "rx", 0, rx
        if tx:
            yield "tx", 0, tx

    return header, records()


# --- umockdev -----------------------------------------------------------------

_UMOCKDEV_OPS = {b"r": "rx", b"w": "tx"}
_UMOCKDEV_KNOWN = "r (read), w (write), f (fuzz), d (device), Q (stop), # (comment)"


def _escaped(data: bytes) -> str:
    """Bytes as a message shows them: control bytes and non-ASCII escaped."""
    return data.decode("latin-1").encode("unicode_escape").decode("ascii")


def _umockdev_data(text: bytes) -> bytes:
    """DATA unescaped: ``^`` + chr(b + 64) is the byte b < 32, ``^``` is ``^``;
    ValueError naming the column of a bad escape."""
    if b"^" not in text:
        return text
    out = bytearray()
    index = 0
    while index < len(text):
        byte = text[index]
        if byte != 0x5E:  # '^'
            out.append(byte)
            index += 1
            continue
        if index + 1 == len(text):
            raise ValueError(f"a lone '^' at the end (column {index + 1}): an escape needs "
                             "a second character")
        code = text[index + 1]
        if code == 0x60:  # '`'
            out.append(0x5E)
        elif 0x40 <= code <= 0x5F:
            out.append(code - 0x40)
        else:
            raise ValueError(f"bad escape '^{_escaped(bytes([code]))}' at column {index + 1}: "
                             "'^' is followed "
                             "by one of @ A..Z [ \\ ] ^ _ (bytes 0..31) or ` (the '^' itself)")
        index += 2
    return bytes(out)


def _umockdev_lines(path: str):
    """(line number, byte offset, op, value, data) for every operation."""
    with open_input(path) as handle:
        content = handle.read()
    offset = 0
    for number, line in enumerate(content.split(b"\n"), start=1):
        line_offset, offset = offset, offset + len(line) + 1
        if not line or line.startswith(b"#"):
            continue
        op = line[:1]
        if op == b"Q":
            return
        if op not in (b"r", b"w", b"f", b"d"):
            shown = _escaped(op)
            raise _error(path, number, f"unknown operation {shown!r}: one of {_UMOCKDEV_KNOWN}",
                         line_offset)
        if line[1:2] != b" ":
            raise _error(path, number, f"expected '{op.decode()} VALUE DATA': a space after the "
                                       "operation", line_offset)
        value_text, space, data = line[2:].partition(b" ")
        if not value_text.isdigit() or len(value_text) > 20:
            shown = _escaped(value_text[:20])
            if value_text.isdigit():
                shown = f"a number of {len(value_text)} digits"
            raise _error(path, number, f"value: expected a whole number (milliseconds, or the "
                                       f"fuzz percentage) of at most 20 digits, got {shown!r}",
                         line_offset)
        if op in _UMOCKDEV_OPS and not space:
            raise _error(path, number, f"expected '{op.decode()} DELAY_MS DATA': no data after "
                                       "the delay", line_offset)
        yield number, line_offset, op, int(value_text), data


def umockdev_records(path):
    """(header, records) of an umockdev tty script (``umockdev-record --script``).

    Delays add up into the records' times. umockdev's fuzz (``f``) lets
    written bytes differ by a percentage; a replay checks them exactly, so
    the last fuzz percentage is only kept in the metadata."""
    path = os.fspath(path)
    # Read whole before anything is written: a bad line is reported before
    # an output exists, and the device line (first) reaches the header.
    operations = []
    device = None
    fuzz = None
    for number, offset, op, value, data in _umockdev_lines(path):
        if op == b"d":
            if device is None:
                device = data.decode("utf-8", "replace")
            continue
        if op == b"f":
            fuzz = value
            continue
        try:
            payload = _umockdev_data(data)
        except ValueError as error:
            raise _error(path, number, f"data: {error}", offset) from None
        operations.append((_UMOCKDEV_OPS[op], value, payload, number, offset))
    if not operations and device is None and fuzz is None:
        raise _error(path, None, "no operation: an empty file, or only comments (an umockdev "
                                 "script has r, w, f or d lines)")
    metadata = {}
    if device:
        metadata["umockdev.device"] = device
    if fuzz:
        metadata["umockdev.fuzz_percent"] = str(fuzz)
    header = _core.SessionHeader(port_type="serial", metadata=metadata,
                                 source_format="umockdev",
                                 source_files=[os.path.basename(path)])

    def records() -> Records:
        t_ms = 0
        for kind, delay_ms, payload, number, offset in operations:
            t_ms += delay_ms
            t_ns = t_ms * 1_000_000
            if t_ns > _core.MAX_RECORD_T_NS:
                raise _error(path, number, f"delay: the delays add up to {t_ms} ms here, beyond "
                                           f"the {_core.MAX_RECORD_T_NS // 1_000_000} ms a "
                                           "session can hold", offset)
            if not payload:
                continue
            problem = _core.record_content_problem(kind, t_ns, payload)
            if problem is not None:
                raise _error(path, number, problem, offset)
            yield kind, t_ns, payload

    return header, records()
