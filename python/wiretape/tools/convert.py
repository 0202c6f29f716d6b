"""Conversions between session formats.

Formats:
  ``wiretape``  a ``.wtape`` file (docs/session-format.md);
  ``flexiport`` flexiport's two-file log: ``name.log`` stands for
                ``name.logr`` + ``name.logw`` (read: both of its formats;
                written: the new format, events dropped; one port, so a
                session of several channels is refused);
  ``jsonl``     one JSON object per line: first ``{"header": {...}}``, then
                one record per line as ``wiretape show --format jsonl``
                prints it (``t_ns``, ``kind``, ``data_hex``, ``event``...;
                in a session of named channels ``channel``, the name);
  ``pcapng``, ``mcap``  exports for Wireshark and Foxglove (written only);
  ``pcap``      a packet capture (pcap or pcapng; read only): one TCP
                conversation or UDP flow becomes a session, or several
                named ones its channels (pcap_import).
  ``reserial``, ``umockdev``  pytest-reserial cassettes (one test of one:
                ``test``) and umockdev tty scripts (read only; importers.py).

A format not given is taken from the file name: ``.wtape``; ``.log``,
``.logr``, ``.logw``; ``.jsonl``; ``.pcapng``; ``.mcap``. A source with
another name is sniffed (a ``.wtape`` file starts with its magic number),
unless it is a pipe or FIFO: that is read as a ``.wtape`` stream (its bytes
cannot be looked at twice), or as ``--from jsonl``. A source named ``.pcap``,
``.pcapng`` or ``.cap``, or starting as a capture does, is a ``pcap``.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shlex
import tempfile
import time
from typing import Dict, List, Optional, Sequence, Tuple, Union

from .. import _core, exports
from ..exports import jsonl
from . import importers
from ..session import (FileRefused, SessionPath, is_stream, is_written_through,
                       open_input, open_session,
                       raise_damage, refuse_same_file, session_files)
from . import pcap_import

__all__ = ["convert", "detect_format", "ConvertResult", "FORMATS"]

FORMATS = ("wiretape", "flexiport", "jsonl", "pcapng", "mcap")
_IMPORTED = ("reserial", "umockdev", "pcap")
_READABLE = ("wiretape", "flexiport", "jsonl") + _IMPORTED
_CAPTURE_SUFFIXES = (".pcap", ".pcapng", ".cap")
# The readable formats that are not sessions: written to a scratch session
# first when the target is made from one (pcapng, mcap, flexiport).
_RECORD_SOURCES = ("jsonl",) + _IMPORTED
_SUFFIXES = {
    ".wtape": "wiretape",
    ".log": "flexiport",
    ".logr": "flexiport",
    ".logw": "flexiport",
    ".jsonl": "jsonl",
    ".pcapng": "pcapng",
    ".mcap": "mcap",
}


def detect_format(path, reading: bool) -> str:
    """The format `path` names by its suffix (or, for a source, its magic)."""
    path = os.fspath(path)
    suffix = os.path.splitext(path)[1].lower()
    if reading and suffix in _CAPTURE_SUFFIXES:
        return "pcap"
    if suffix in _SUFFIXES:
        return _SUFFIXES[suffix]
    if reading:
        if is_stream(path):
            return "wiretape"
        try:
            with open_input(path) as handle:
                if handle.read(len(_core.SESSION_MAGIC)) == _core.SESSION_MAGIC:
                    return "wiretape"
        except FileRefused:
            raise
        except OSError:
            pass
        if _core.flexiport_prefix(path) is not None:
            return "flexiport"
        if pcap_import.is_capture(path):
            return "pcap"
    known = ", ".join(sorted(_SUFFIXES))
    raise ValueError(
        f"{path}: cannot tell the format from the name (known suffixes: {known}); "
        f"say it with --{'from' if reading else 'to'} "
        f"({'|'.join(_READABLE if reading else FORMATS)})"
    )


def unconverted_format(path) -> Optional[Tuple[str, str]]:
    """What a file that is not a session is, when wiretape can import it:
    (what it is, the convert command), or None. Reads only the start of a
    regular file (a pipe is left alone: reading would consume it)."""
    path = os.fspath(path)
    try:
        if not os.path.isfile(path):
            return None
        with open(path, "rb") as handle:
            start = handle.read(4096)
    except OSError:
        return None
    if start.startswith(_core.SESSION_MAGIC):
        return None
    quoted = shlex.quote(path)
    output = shlex.quote(os.path.splitext(os.path.basename(path))[0] + ".wtape")
    if pcap_import.is_capture(path):
        return ("a packet capture (pcap/pcapng)",
                f"wiretape convert --from pcap {quoted} {output}")
    first = start.split(b"\n", 1)[0]
    try:
        item = json.loads(first)
    except ValueError:
        return None
    if jsonl.looks_like_reserial(item):
        return ("a pytest-reserial cassette",
                f"wiretape convert --from reserial {quoted} {output} (--test NAME picks a test)")
    return None


def _check_format(name: str, allowed) -> str:
    if name not in allowed:
        raise ValueError(f"unknown format {name!r}: one of {', '.join(allowed)}")
    return name


# --- progress ----------------------------------------------------------------

class _Progress:
    """Progress on a terminal's stderr (rich): a bar of the source's share
    read (estimated from record sizes), records so far, time left. Shown
    from the start, so that a capture's reading before its first record
    shows too; gone when the conversion ends. Disabled: nothing at all."""

    def __init__(self, enabled: bool, total_bytes: int):
        self.total = max(total_bytes, 1)
        self.done = 0
        self.records = 0
        self.last = 0.0
        self._bar = None
        if enabled:
            import rich.console
            import rich.progress

            self._bar = rich.progress.Progress(
                rich.progress.TextColumn("converting"), rich.progress.BarColumn(),
                rich.progress.TaskProgressColumn(),
                rich.progress.TextColumn("{task.fields[records]}"),
                rich.progress.TimeRemainingColumn(),
                console=rich.console.Console(stderr=True), transient=True)
            self._task = self._bar.add_task("convert", total=self.total, records="")
            self._bar.start()

    def step(self, size: int) -> None:
        self.records += 1
        self.done += size + 20  # a record's header and CRC
        if self._bar is not None and time.monotonic() - self.last > 0.1:
            self.last = time.monotonic()
            self._bar.update(self._task, completed=min(self.done, self.total),
                             records=f"{self.records} records")

    def finish(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def __enter__(self) -> "_Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.finish()


def _source_size(path: str, fmt: str) -> int:
    if fmt == "flexiport":
        prefix = _core.flexiport_prefix(path) or path
        return sum(os.path.getsize(prefix + s) for s in "rw" if os.path.exists(prefix + s))
    return os.path.getsize(path) if os.path.exists(path) else 0


# --- the conversion ----------------------------------------------------------

def _output_files(dst: str, fmt: str):
    """The files writing `dst` as `fmt` creates."""
    if fmt == "flexiport":
        prefix = _core.flexiport_prefix(dst) or dst
        return [prefix + "r", prefix + "w"]
    return [dst]


def _records_of(src: str, fmt: str, choice: Optional[dict] = None):
    """(SessionHeader, record iterator of (kind, t_ns, data, channel id), a function that
    raises the damage the records stopped at, if any). `choice`: what to
    take of a source holding several sessions (a capture's stream and device
    address, a cassette's test)."""
    choice = choice or {}
    if fmt == "pcap" and choice.get("channels"):
        header, records = pcap_import.read_capture_channels(
            src, choice["channels"], device_addrs=choice.get("device_addrs"),
            allow_gaps=bool(choice.get("allow_gaps")))
        return header, iter(records), lambda: None
    if fmt == "pcap":
        header, captured = pcap_import.read_capture(
            src, stream=choice.get("stream"), device_addr=choice.get("device_addr"),
            allow_gaps=bool(choice.get("allow_gaps")))
        return header, iter([(*record, 0) for record in captured]), lambda: None
    if fmt == "reserial":
        header, records = importers.reserial_records(src, choice.get("test"))
        # checked whole before writing
        return header, iter([(*record, 0) for record in records]), lambda: None
    if fmt == "umockdev":
        header, records = importers.umockdev_records(src)
        return header, iter([(*record, 0) for record in records]), lambda: None
    if fmt == "jsonl":
        items = jsonl.read_records(src)
        _, header = next(items)

        def records():
            for _, record in items:
                yield record

        return header or _core.SessionHeader(), records(), lambda: None
    reader = open_session(src)

    def records():
        for record in reader:
            yield record.kind, record.t_ns, record.data, record.channel

    return reader.header, records(), lambda: raise_damage(reader)


def session_writer(dst: str, header: _core.SessionHeader,
                   compress: str = "none") -> _core.SessionWriter:
    """A SessionWriter for `dst` writing `header` as it is: a time or host
    the source does not know stays unknown (an import never invents them
    from the converting machine). ``compress="zstd"``: in compressed
    chunks (format 2.0)."""
    return _core.SessionWriter(dst, header, flush_ms=1000, compress=compress)


def _write_wiretape(dst: str, header: _core.SessionHeader, records, progress: _Progress,
                    compress: str = "none") -> int:
    with session_writer(dst, header, compress) as writer:
        for kind, t_ns, data, channel in records:
            writer.write(kind, t_ns, data, channel=channel)
            progress.step(len(data))
    return progress.records


def _write_jsonl(dst: str, header: _core.SessionHeader, records, progress: _Progress) -> int:
    def counted():
        for kind, t_ns, data, channel in records:
            yield _core.Record(t_ns, kind, data, channel)
            progress.step(len(data))

    jsonl.write_records(dst, header.to_dict(), counted())
    return progress.records


@dataclasses.dataclass(frozen=True)
class ConvertResult:
    """What convert() did: how many records it wrote, from which format to which."""

    records: int
    from_format: str
    to_format: str


def _as_list(value: Union[None, str, Sequence[str]]) -> List[str]:
    if value is None:
        return []
    return [value] if isinstance(value, str) else list(value)


def _named_streams(streams: List[str], device_addrs: List[str]
                   ) -> Optional[Tuple[List[Tuple[str, str]], Dict[str, str]]]:
    """--stream NAME=FILTER (repeatable) and --device-addr NAME=IP:PORT as
    ([(NAME, FILTER)...], {NAME: IP:PORT}); None for today's form (one
    --stream FILTER, one --device-addr IP:PORT, no names). ValueError
    (a usage error) naming the flag for what cannot be."""
    split = [(text, *pcap_import.split_name(text)) for text in streams]
    named = [text for text, name, _ in split if name is not None]
    if not named:
        if len(streams) > 1:
            raise ValueError(f"--stream is given {len(streams)} times without names: name each "
                             f"conversation's channel (--stream NAME=FILTER) to import them "
                             f"into one session")
        for text in device_addrs:
            if pcap_import.split_name(text)[0] is not None:
                raise ValueError(f"--device-addr {text}: names a channel, but no --stream "
                                 f"does (--stream NAME=FILTER)")
        if len(device_addrs) > 1:
            raise ValueError(f"--device-addr is given {len(device_addrs)} times for one "
                             f"conversation")
        return None
    channels: List[Tuple[str, str]] = []
    for text, name, stream in split:
        if name is None:
            raise ValueError(f"--stream {text}: no NAME= while --stream {named[0]} has one: "
                             f"name every stream (--stream NAME=FILTER)")
        problem = _core.channel_name_problem(name)
        if problem is not None:
            raise ValueError(f"--stream {text}: {problem}")
        earlier = next((f"{n}={f}" for n, f in channels if n == name), None)
        if earlier is not None:
            raise ValueError(f"--stream {text}: the channel name {name!r} is given twice "
                             f"(also --stream {earlier})")
        if not stream.strip():
            raise ValueError(f"--stream {text}: no conversation after {name}= (tcp:N, udp:N "
                             f"or a tshark display filter)")
        channels.append((name, stream))
    names = [name for name, _ in channels]
    addresses: Dict[str, str] = {}
    for text in device_addrs:
        name, address = pcap_import.split_name(text)
        if name is None:
            raise ValueError(f"--device-addr {text}: with named streams, say whose device it "
                             f"is: --device-addr NAME=IP:PORT (NAME: {', '.join(names)})")
        if name not in names:
            raise ValueError(f"--device-addr {text}: no --stream names {name!r} (the streams "
                             f"are {', '.join(names)})")
        if name in addresses:
            raise ValueError(f"--device-addr {text}: {name!r} is given twice (also "
                             f"--device-addr {name}={addresses[name]})")
        addresses[name] = address
    return channels, addresses


def convert(src: SessionPath, dst: SessionPath, from_format: Optional[str] = None,
            to_format: Optional[str] = None, progress: bool = False,
            flexiport_format: str = "new",
            stream: Union[None, str, Sequence[str]] = None,
            device_addr: Union[None, str, Sequence[str]] = None, test: Optional[str] = None,
            allow_gaps: bool = False, compress: str = "none") -> ConvertResult:
    """Converts the session `src` into `dst`.

    Returns the number of records written and both formats. A damaged
    source is converted up to the damage, then its SessionError is raised
    (``dst`` keeps everything before the damage). Header fields (start time,
    host, capture, metadata...) are carried over where the target format
    has them. ``flexiport_format``: ``new`` (flexiport from 2008-07) or
    ``old``, for a flexiport output.

    A ``pcap`` source (a packet capture) gives one conversation: `stream`
    chooses it (``tcp:N``, ``udp:N``, ``N`` or a tshark display filter) and
    `device_addr` (``IP:PORT``) says which side is the device
    (pcap_import's text has the rules); a capture of several conversations
    and none chosen raises pcap_import.CaptureError listing them.
    Several conversations go into channels of one session when `stream`
    is a list of ``NAME=FILTER`` (``["gps=tcp:0", "rtk=udp:1"]``, the
    channels in that order, on the capture's clock); then `device_addr`
    may be a list of ``NAME=IP:PORT``. A name given twice, a stream
    without a name among named ones, raise ValueError naming the flag.
    A capture that lost bytes raises pcap_import.CaptureError naming the
    stream, direction and offset, unless `allow_gaps` (a ``capture_gap``
    event stands there, and no bytes).
    `test` chooses the test of a pytest-reserial cassette.
    """
    if flexiport_format not in ("new", "old"):
        raise ValueError(f"flexiport format {flexiport_format!r}: expected new or old")
    src = os.fspath(src)
    dst = os.fspath(dst)
    source_format = _check_format(from_format, _READABLE) if from_format else detect_format(src, True)
    if source_format not in _READABLE:
        raise ValueError(f"{src}: {source_format} files cannot be read, only written")
    target_format = _check_format(to_format, FORMATS) if to_format else detect_format(dst, False)
    if test is not None and source_format != "reserial":
        raise ValueError(f"--test chooses a test of a pytest-reserial cassette (--from reserial); "
                         f"{src} is read as {source_format}")
    if source_format == "flexiport":
        src = _core.flexiport_prefix(src) or src
    refuse_same_file(session_files(src), _output_files(dst, target_format))
    streams, device_addrs = _as_list(stream), _as_list(device_addr)
    if source_format != "pcap" and (streams or device_addrs or allow_gaps):
        raise ValueError("--stream, --device-addr and --allow-gaps are about a packet "
                         "capture: they need --from pcap")
    choice = {"stream": streams[0] if streams else None,
              "device_addr": device_addrs[0] if device_addrs else None, "test": test,
              "allow_gaps": allow_gaps, "compress": compress}
    named = _named_streams(streams, device_addrs)
    if named is not None:
        choice["channels"], choice["device_addrs"] = named
    with tempfile.TemporaryDirectory(prefix="wiretape-convert-") as scratch:
        readable = src
        if source_format in _NEEDS_A_FILE and is_stream(src):
            readable = _spool(src, scratch)
        outputs = _output_files(dst, target_format)
        try:
            # The folders outside: a failure removes the output, then them.
            with _parent_folders(outputs), \
                    _removed_unless_done(outputs, keep_on_damage=source_format not in _IMPORTED):
                return _convert(readable, dst, source_format, target_format, progress,
                                flexiport_format, choice, scratch)
        except _core.SessionError as error:
            if readable == src:
                raise
            # Name the stream given, not the scratch copy of it.
            raise type(error)(str(error).replace(readable, src), error.offset) from None


# Formats another program reads (tshark reads a capture twice): a pipe or
# FIFO is copied to a scratch file first.
_NEEDS_A_FILE = ("pcap",)
_SPOOL_CHUNK = 1 << 16


def _spool(src: str, scratch: str) -> str:
    """The stream `src` copied to a file in `scratch`, named as it is (the
    import's header names its source file). Interruptible: open_input waits
    for a writer in poll(), reads are restarted after a signal handler
    (PEP 475) unless it raises. An empty stream is a SessionError."""
    folder = os.path.join(scratch, "input")
    os.mkdir(folder)
    copy = os.path.join(folder, os.path.basename(src) or "stream")
    size = 0
    with open_input(src) as stream, open(copy, "wb") as out:
        while True:
            chunk = stream.read(_SPOOL_CHUNK)
            if not chunk:
                break
            out.write(chunk)
            size += len(chunk)
    if size == 0:
        raise _core.SessionError(f"{src}: an empty stream: no capture was written to it", 0)
    return copy


class _removed_unless_done:
    """Removes the regular files among `outputs` that the block wrote, when
    it does not complete: an interrupted conversion (SIGINT, SIGTERM) and a
    failed import leave nothing under the name asked for (DESIGN §23). A
    damaged session or jsonl source keeps what came before the damage
    (`keep_on_damage`), as docs/cli.md says. Outputs written through (a
    FIFO, a device) are left alone."""

    def __init__(self, outputs, keep_on_damage: bool):
        # What was there before: a file the block never wrote is left alone.
        self.before = {path: _identity(path) for path in outputs
                       if not is_written_through(path)}
        self.keep_on_damage = keep_on_damage

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        if kind is None:
            return False
        if self.keep_on_damage and issubclass(kind, _core.SessionError):
            return False
        for path, before in self.before.items():
            now = _identity(path)
            if now is not None and now != before:
                try:
                    os.unlink(path)
                except OSError:
                    pass
        return False


class _parent_folders:
    """Creates the missing folders of the outputs' paths (a recording goes
    where the pytest plugin looks for it: tests/recordings/MODULE/TEST.wtape,
    docs/cli.md); removes those it created, if still empty, when the block
    fails."""

    def __init__(self, outputs):
        self.created: List[str] = []
        for output in outputs:
            folder = os.path.dirname(os.path.abspath(output))
            missing = []
            while folder and not os.path.lexists(folder):
                missing.append(folder)
                folder = os.path.dirname(folder)
            for folder in reversed(missing):
                os.mkdir(folder)
                self.created.append(folder)

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        if kind is not None:
            for folder in reversed(self.created):
                try:
                    os.rmdir(folder)
                except OSError:
                    break
        return False


def _identity(path: str):
    """(inode, size, mtime) of the regular file at `path`, or None."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    if not os.path.isfile(path):
        return None
    return info.st_ino, info.st_size, info.st_mtime_ns


def _refuse_several_channels(src: str, header: _core.SessionHeader) -> None:
    """A flexiport log holds one port: a session of several channels is
    refused (ValueError naming them), never merged into one port's log."""
    channels = header.channel_list()
    if len(channels) > 1:
        names = ", ".join(channel.name for channel in channels)
        raise ValueError(f"{src}: a session of {len(channels)} channels ({names}); a flexiport "
                         f"log holds one port: convert it to wiretape, jsonl, pcapng or mcap, "
                         f"which keep its channels")


def _convert(src: str, dst: str, source_format: str, target_format: str, progress: bool,
             flexiport_format: str, choice: dict, scratch: str) -> ConvertResult:
    with _Progress(progress, _source_size(src, source_format)) as report:
        return _convert_reporting(src, dst, source_format, target_format, report,
                                  flexiport_format, choice, scratch)


def _convert_reporting(src: str, dst: str, source_format: str, target_format: str,
                       report: _Progress, flexiport_format: str, choice: dict,
                       scratch: str) -> ConvertResult:
    if target_format in ("pcapng", "mcap"):
        session = src
        if source_format in _RECORD_SOURCES:
            session = os.path.join(scratch, "session.wtape")
            header, records, _ = _records_of(src, source_format, choice)
            _write_wiretape(session, header, records, _Progress(False, 0))
        writer = exports.write_pcapng if target_format == "pcapng" else exports.write_mcap
        # Raises the damage once dst is written. Its counts, not a second
        # reading: a pipe or FIFO can be read only once.
        written = sum(writer(session, dst).values())
        return ConvertResult(written, source_format, target_format)

    if target_format == "flexiport":
        prefix = _core.flexiport_prefix(dst) or dst
        # A stream's header cannot be looked at before the export reads it:
        # it goes through a scratch session, whose header can.
        through_scratch = source_format in _RECORD_SOURCES or (
            source_format == "wiretape" and is_stream(src))
        if through_scratch:
            session = os.path.join(scratch, "session.wtape")
            header, records, raise_source_damage = _records_of(src, source_format, choice)
            _refuse_several_channels(src, header)
            written = _write_wiretape(session, header, records, report)
            exported = _core.export_flexiport(session, prefix, flexiport_format)
            if source_format == "wiretape":
                written = exported  # what the same file gives when not a stream
            raise_source_damage()
        else:
            if source_format == "wiretape":
                _refuse_several_channels(src, open_session(src).header)
            # Its count, not a reading of the output, which may be a FIFO or
            # /dev/null written through.
            written = _core.export_flexiport(src, prefix, flexiport_format)
        report.finish()
        return ConvertResult(written, source_format, target_format)

    header, records, raise_source_damage = _records_of(src, source_format, choice)
    if target_format == "wiretape":
        written = _write_wiretape(dst, header, records, report, choice.get("compress", "none"))
    else:
        written = _write_jsonl(dst, header, records, report)
    report.finish()
    raise_source_damage()
    return ConvertResult(written, source_format, target_format)
