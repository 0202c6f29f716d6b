"""``wiretape show``: a session's timeline for people (text, hex) and
programs (jsonl).

Streams the session (a ``.wtape`` file or a flexiport ``name.log``): memory
does not grow with the file's size.
"""

from __future__ import annotations

import dataclasses
import difflib
import heapq
import json
import os
import re
import sys
from typing import IO, Callable, FrozenSet, Iterable, Iterator, Optional, Tuple

from .. import _core
from ..session import DIRECTIONS as _DIRECTIONS
from ..session import NO_PROFILE, SessionPath, event_of, event_payload, header_text, open_session
from ..session import warn_if_unfinished
from ..session import printable as _printable
from .channels import (capture_text, channel_label, channel_names, choose_channels,
                       several_channels)

__all__ = ["show", "show_reporting_damage", "Selection", "check_kinds", "record_kinds",
           "color_wanted"]


# The time and Δt columns are as wide as a day and more of session time
# (+99999.999999s): the columns after them do not move when times pass 10 s
# or 100 s. The time is left-aligned, so that a record's line still starts
# with its signed time.
TIME_WIDTH = 14
STEP_WIDTH = 13


def _seconds(t_ns: int) -> str:
    return f"{f'{t_ns / 1e9:+.6f}s':<{TIME_WIDTH}}"


def _header_lines(reader: _core.SessionReader, path: SessionPath) -> Iterator[str]:
    """The header for people; every field from the file goes through
    header_text() (the file may hold terminal escape sequences)."""
    header = reader.header
    yield f"session {os.fspath(path)}"
    if header.version_major == 0:
        yield "  format       flexiport log (name.logr + name.logw)"
    else:
        yield f"  format       wiretape {header.version_major}.{header.version_minor}"
    if header.source_format != "wiretape":
        files = ", ".join(header_text(name) for name in header.source_files)
        details = ", ".join(f"{header_text(key)}: {header_text(value)}"
                            for key, value in sorted(header.source_details.items()))
        yield (f"  imported     from {header_text(header.source_format)}"
               + (f" ({files})" if files else "") + (f"; {details}" if details else ""))
    if header.port_type or header.port_options:
        yield f"  port         {header_text(header.port_type or '?')}: {header_text(header.port_options)}"
    if header.device_address:
        yield f"  device       {header_text(header.device_address)}"
    # The members as the header names them, in its order; those not known
    # left out.
    identity = ", ".join(f"{name}={header_text(value)}"
                         for name, value in header.device_identity.items() if value)
    if identity:
        yield f"  identity     {identity}"
    yield f"  capture      {header_text(header.capture)}"
    attached = header.attached
    if attached:
        fds = ", ".join(str(fd) for fd in attached["descriptors"])
        yield (f"  attached     to process {attached['pid']} "
               f"({header_text(attached['command'])}) at {header_text(attached['utc'])}, "
               f"descriptors {fds}: {header_text(attached['device'])}")
        for warning in attached["warnings"]:
            yield f"  warning      {header_text(warning)}"
    started = header_text(header.start_utc) if header.start_utc else "at a time not recorded"
    host = f" on {header_text(header.host)}" if header.host else ""
    yield f"  started      {started}{host}"
    if header.wiretape_version:
        yield f"  written by   wiretape {header_text(header.wiretape_version)}"
    for channel in header.channels:
        port = (f" {header_text(channel.port_type or '?')}: {header_text(channel.port_options)}"
                if channel.port_type or channel.port_options else "")
        device = f", device {header_text(channel.device_address)}" if channel.device_address else ""
        yield (f"  channel      {channel.id} {header_text(channel.name)}:{port} "
               f"(capture {header_text(capture_text(channel.capture))}{device})")
    for edit in header.edits:
        yield f"  edited       {header_text(edit)}"
    for key, value in sorted(header.metadata.items()):
        yield f"  meta         {header_text(key)}={header_text(value)}"


def _hexdump(data: bytes) -> Iterator[str]:
    for offset in range(0, len(data), 16):
        chunk = data[offset:offset + 16]
        hex_part = " ".join(f"{b:02x}" for b in chunk)
        text = "".join(chr(b) if 0x20 <= b < 0x7F else "." for b in chunk)
        yield f"    {offset:08x}  {hex_part:<47}  |{text}|"


#: ANSI colours of show's text on a terminal (rich's per-line rendering
#: would cost ten times the time of show itself on a big session).
_RESET = "\x1b[0m"
_STYLES = {"time": "\x1b[2m", "tx": "\x1b[36m", "rx": "\x1b[32m", "event": "\x1b[33m",
           "problem": "\x1b[1;31m", "heading": "\x1b[1m"}
#: Event kinds that mean something was lost or broken: shown in red.
_PROBLEM_KINDS = frozenset({"capture_gap", "device_lost", "fault"})


def record_kinds() -> Tuple[str, ...]:
    """Every record kind a session may hold (what ``--kind`` accepts)."""
    return tuple(kind["name"] for kind in _core.RECORD_KINDS)


def check_kinds(kinds: Iterable[str]) -> None:
    """Raises ValueError naming the first unknown kind and the closest known one."""
    import difflib

    known = record_kinds()
    kinds = list(kinds)
    if not kinds:
        raise ValueError("no record kind given: use " + ", ".join(known))
    for kind in kinds:
        if kind not in known:
            close = difflib.get_close_matches(kind, known, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise ValueError(f"unknown record kind {kind!r}{hint}: use " + ", ".join(known))


@dataclasses.dataclass(frozen=True)
class Selection:
    """Which records show prints: all of them by default.

    ``kinds``: record kinds (``record_kinds()``), None for every kind.
    ``channels``: channel names (``--channel``), None for every channel;
    checked against the file when it is shown.
    ``start_s``/``end_s``: seconds of session time (the first column), both
    ends included. ``grep``: a bytes regular expression searched in the
    payloads of tx and rx records (events have none, so they are left out).
    """

    kinds: Optional[FrozenSet[str]] = None
    start_s: Optional[float] = None
    end_s: Optional[float] = None
    grep: Optional[bytes] = None
    channels: Optional[FrozenSet[str]] = None

    def __post_init__(self) -> None:
        if self.kinds is not None:
            check_kinds(self.kinds)
        if self.start_s is not None and self.end_s is not None and self.start_s > self.end_s:
            raise ValueError(f"the time range ends ({self.end_s} s) before it starts "
                             f"({self.start_s} s)")
        if self.grep is not None:
            try:
                re.compile(self.grep)
            except re.error as error:
                raise ValueError(f"bad --grep pattern {self.grep!r}: {error}") from None

    @property
    def everything(self) -> bool:
        return self == Selection()

    @property
    def every_record_of_the_channels(self) -> bool:
        """Whether only the channel choice (if any) leaves records out."""
        return dataclasses.replace(self, channels=None) == Selection()

    def matcher(self) -> Callable[[int, str, bytes], bool]:
        """A test of (t_ns, kind, payload) for the records to show."""
        kinds = self.kinds
        start = None if self.start_s is None else round(self.start_s * 1e9)
        end = None if self.end_s is None else round(self.end_s * 1e9)
        search = re.compile(self.grep).search if self.grep is not None else None

        def wanted(t_ns: int, kind: str, data: bytes) -> bool:
            if kinds is not None and kind not in kinds:
                return False
            if start is not None and t_ns < start:
                return False
            if end is not None and t_ns > end:
                return False
            if search is not None:
                return kind in _DIRECTIONS and search(data) is not None
            return True

        return wanted


def show(path: SessionPath, fmt: str = "text", profile: Optional[str] = None,
         out: Optional[IO[str]] = None, decode: Optional[str] = None,
         select: Optional[Selection] = None, full: bool = False, color: bool = False) -> int:
    """Prints the session's timeline to ``out`` (default stdout).

    ``fmt``: ``text`` (one line per record), ``hex`` (a hex dump of each
    record) or ``jsonl`` (one JSON object per record: ``t_ns``, ``kind``,
    ``size``, ``data_hex``, and ``event`` for events). ``profile`` (text
    format) names a protocol profile (``_core.profile_names()``; ``scip`` for
    Hokuyo SCIP 2.0): the byte streams are cut into the protocol's frames,
    however the recording split them, and each frame is named. ``decode`` is
    the older name of ``profile``. ``select`` picks records (kinds, a time
    range, a pattern); ``full`` shows every byte of each payload instead of
    its first 64; ``color`` writes ANSI colours. Text and hex have a Δt
    column: the time since the previous record shown. Returns the number of
    records shown; a damaged file is reported at the end (on stderr for
    jsonl) and everything before the damage is shown.
    """
    return show_reporting_damage(path, fmt, profile, out, decode, select=select, full=full,
                                 color=color)[0]


def show_reporting_damage(path: SessionPath, fmt: str = "text", profile: Optional[str] = None,
                          out: Optional[IO[str]] = None, decode: Optional[str] = None,
                          wrap: Optional[int] = None, select: Optional[Selection] = None,
                          full: bool = False, color: bool = False
                          ) -> Tuple[int, Optional[_core.SessionError]]:
    """show(), and the damage reading stopped at (None for an intact
    session): what the command line's exit code needs, without a second
    reading, which a pipe or FIFO would not allow. With `wrap` (text format,
    for textconv), every byte of a payload is shown, `wrap` bytes a line,
    the lines after the first indented under it, and there is no Δt column
    (a changed time would show as two changed lines in a diff)."""
    if fmt not in ("text", "hex", "jsonl"):
        raise ValueError(f"unknown format {fmt!r}: use text, hex or jsonl")
    if profile is not None and decode is not None and profile != decode:
        raise ValueError(f"profile={profile!r} and decode={decode!r} disagree: give one")
    profile = profile if profile is not None else decode
    # A name or a declared profile, read by the replay's rule; "none": none.
    framing = (_core.profile_from_spec(profile)
               if profile is not None and profile != NO_PROFILE else None)
    out = out if out is not None else sys.stdout
    select = select if select is not None else Selection()
    wanted = None if select.every_record_of_the_channels else select.matcher()
    reader = open_session(path)
    header = reader.header
    chosen = choose_channels(header, select.channels, path)
    names = channel_names(header)
    several = several_channels(header)
    shown = 0
    if fmt == "jsonl":
        from ..exports.jsonl import json_line, record_to_json

        for record in reader:
            if chosen is not None and record.channel not in chosen:
                continue
            if wanted is None or wanted(record.t_ns, record.kind, record.data):
                line = record_to_json(record)
                if several:
                    line.setdefault("channel", names.get(record.channel, f"#{record.channel}"))
                out.write(json_line(line))
                shown += 1
        if reader.damage is not None:
            print(f"wiretape show: damaged: {header_text(reader.damage.message)}",
                  file=sys.stderr)
        warn_if_unfinished(reader)
        return shown, reader.damage
    paint = _painter(color)
    for line in _header_lines(reader, path):
        out.write(line + "\n")
    out.write("\n")
    delta = wrap is None
    limit = 64 if not full else None
    # Several channels: a column names each record's channel.
    width = max([len("channel")] + [len(channel_label(names, id)) for id in names]) \
        if several else 0
    labels: dict = {}

    def channel_column(channel: int) -> str:
        if not several:
            return ""
        if channel not in labels:
            labels[channel] = f"{channel_label(names, channel):<{width}} "
        return labels[channel]

    if delta:
        heading = f"{'channel':<{width}} " if several else ""
        out.write(paint("heading", f"{'time':<{TIME_WIDTH}}  {'Δt':>{STEP_WIDTH}}  {heading}{'kind':<17} "
                                   f"{'size':>8}  data") + "\n")
    previous: Optional[int] = None
    if framing is not None and fmt == "text":
        if several:
            # Each channel is its own byte stream: cut into frames apart,
            # then shown together in time order.
            records = _counting(reader)
            for _ in records:
                pass
            decoded = heapq.merge(*(_decoded(framing, path, id) for id in sorted(names)
                                    if chosen is None or id in chosen),
                                  key=lambda item: item[0])
        else:
            records = _counting(reader)
            decoded = ((t_ns, kind, data, description, 0) for t_ns, kind, data, description
                       in framing.decode_session(records))
        for t_ns, kind, data, description, channel in decoded:
            if chosen is not None and channel not in chosen:
                continue
            if wanted is not None and not wanted(t_ns, kind, data):
                continue
            shown += 1
            if description is None:
                event = event_payload(data)
                description = json.dumps(event, separators=(",", ":")) if event else ""
            # Frames and events line up with the plain timeline's columns.
            size = f"{len(data):>6} B" if kind in _DIRECTIONS else ""
            line = _stamp(paint, t_ns, previous if delta else None, delta) + channel_column(channel)
            style = kind if kind in _DIRECTIONS else _event_style(kind)
            out.write(f"{line}{paint(style, f'{kind:<17}')} {size:>8}  {description}"
                      .rstrip() + "\n")
            previous = t_ns
        count = records.count
    elif fmt == "text" and wrap is None and not several and chosen is None:
        # the fast timeline of a session of one port
        count, shown = _timeline(reader, out, paint, wanted, full)
    else:
        count = 0
        columns: dict = {}

        def kind_column(kind: str) -> str:
            # painted once per kind: a big session has millions of lines, few kinds
            if kind not in columns:
                style = kind if kind in _DIRECTIONS else _event_style(kind)
                columns[kind] = paint(style, f"{kind:<17}")
            return columns[kind]

        for record in reader:
            count += 1
            t_ns, kind, data = record.t_ns, record.kind, record.data
            if chosen is not None and record.channel not in chosen:
                continue
            if wanted is not None and not wanted(t_ns, kind, data):
                continue
            shown += 1
            line = _stamp(paint, t_ns, previous, delta) + channel_column(record.channel)
            previous = t_ns
            if kind in _DIRECTIONS:
                size = f"{len(data):>6} B"
                arrow = "<-" if kind == "rx" else "->"
                if wrap is not None:
                    text = _printable(data[:wrap], wrap)
                else:
                    text = _printable(data, len(data) if full else limit)
                summary = f"{arrow} {text}" if fmt == "text" else ""
                head = f"{line}{kind_column(kind)} {size}  "
                out.write(f"{head}{summary}\n".rstrip() + "\n")
                if fmt == "text" and wrap is not None:
                    indent = " " * (len(_stamp(_plain, t_ns, None, False))
                                    + len(channel_column(record.channel)) + 17 + 1 + 8 + 2 + 3)
                    for at in range(wrap, len(data), wrap):
                        more = data[at:at + wrap]
                        out.write(indent + _printable(more, len(more)) + "\n")
                if fmt == "hex":
                    for dump in _hexdump(data):
                        out.write(dump + "\n")
            else:
                event = event_of(record)
                text = (json.dumps(event, separators=(",", ":")) if event is not None
                        else _printable(data, len(data) if full else limit))
                out.write(f"{line}{kind_column(kind)} {'':>8}  {text}"
                          .rstrip() + "\n")
    if reader.damage is not None:
        out.write("\n" + paint("problem", f"DAMAGED at byte {reader.damage.offset}: "
                                           f"{header_text(reader.damage.message)}") + "\n")
    elif shown == count:
        out.write(f"\n{count} {_plural(count, 'record')}\n")
    else:
        out.write(f"\n{shown} of {count} {_plural(count, 'record')} shown\n")
    warn_if_unfinished(reader)
    return shown, reader.damage


# Lines the timeline gathers before one write: a write per line costs a
# tenth of show's time on a big session.
_LINES_PER_WRITE = 512
# How many Δt and size columns the timeline keeps formatted: a device's
# traffic repeats its gaps and sizes, and formatting them is most of the
# loop's time. Bounded, so memory does not grow with the session.
_COLUMNS_KEPT = 4096


def _timeline(reader, out: IO[str], paint: Callable[[str, str], str],
              wanted: Optional[Callable[[int, str, bytes], bool]], full: bool
              ) -> Tuple[int, int]:
    """The text format's lines with their Δt column: (records read, records
    shown). The same columns as _stamp() and the hex loop give, built in one
    f-string a line (show of a 10 MB session is bound by this loop)."""
    time_on, time_off = (_STYLES["time"], _RESET) if paint is not _plain else ("", "")
    heads: dict = {}  # kind -> {size -> "kind  size B  arrow "}
    steps: dict = {}  # Δt in ns -> the Δt column
    escape = _core.escape_bytes
    limit = 64
    lines: list = []
    count = shown = 0
    previous: Optional[int] = None
    first_step = f"{time_on}{'':>{STEP_WIDTH}}{time_off}  "
    for record in reader:
        count += 1
        t_ns, kind, data = record.t_ns, record.kind, record.data
        if wanted is not None and not wanted(t_ns, kind, data):
            continue
        shown += 1
        if previous is None:
            step = first_step
        else:
            step = steps.get(t_ns - previous)
            if step is None:
                if len(steps) >= _COLUMNS_KEPT:
                    steps.clear()
                gap = f"{(t_ns - previous) / 1e9:.6f}s"
                step = steps[t_ns - previous] = f"{time_on}{gap:>{STEP_WIDTH}}{time_off}  "
        previous = t_ns
        sizes = heads.get(kind)
        if sizes is None:
            style = kind if kind in _DIRECTIONS else _event_style(kind)
            sizes = heads[kind] = {"column": paint(style, f"{kind:<17}")}
        if kind == "rx" or kind == "tx":
            size = len(data)
            head = sizes.get(size)
            if head is None:
                if len(sizes) >= _COLUMNS_KEPT:
                    sizes.clear()
                    sizes["column"] = paint(kind, f"{kind:<17}")
                head = sizes[size] = (f"{sizes['column']} {size:>6} B  "
                                      f"{'<-' if kind == 'rx' else '->'} ")
            text = escape(data, size if full else limit)
            lines.append(f"{time_on}{_seconds(t_ns)}{time_off}  {step}{head}{text}".rstrip())
        else:
            event = event_of(record)
            text = (json.dumps(event, separators=(",", ":")) if event is not None
                    else escape(data, len(data) if full else limit))
            lines.append(f"{time_on}{_seconds(t_ns)}{time_off}  {step}{sizes['column']} "
                         f"{'':>8}  {text}".rstrip())
        if len(lines) >= _LINES_PER_WRITE:
            lines.append("")
            out.write("\n".join(lines))
            lines.clear()
    if lines:
        lines.append("")
        out.write("\n".join(lines))
    return count, shown


def _plural(count: int, word: str) -> str:
    return word if count == 1 else word + "s"


def _event_style(kind: str) -> str:
    return "problem" if kind in _PROBLEM_KINDS else "event"


def _plain(style: str, text: str) -> str:
    return text


def _painter(color: bool) -> Callable[[str, str], str]:
    if not color:
        return _plain

    def paint(style: str, text: str) -> str:
        return f"{_STYLES[style]}{text}{_RESET}"

    return paint


def _stamp(paint: Callable[[str, str], str], t_ns: int, previous: Optional[int],
           delta: bool) -> str:
    """The time column and, with `delta`, the Δt column (blank on the first
    line shown)."""
    time = paint("time", _seconds(t_ns))
    if not delta:
        return f"{time}  "
    step = "" if previous is None else f"{(t_ns - previous) / 1e9:.6f}s"
    return f"{time}  {paint('time', f'{step:>{STEP_WIDTH}}')}  "


def color_wanted(choice: str, stream: IO[str]) -> bool:
    """``--color auto|always|never``: auto is colour on a terminal, unless
    NO_COLOR is set (https://no-color.org) or TERM is dumb."""
    if choice == "always":
        return True
    if choice == "never":
        return False
    if os.environ.get("NO_COLOR"):
        return False
    if os.environ.get("TERM") == "dumb":
        return False
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


def _decoded(framing, path: SessionPath, channel: int) -> Iterator[tuple]:
    """One channel's records cut into the profile's frames, each item
    tagged with the channel."""
    reader = _core.SessionReader(os.fspath(path), channel=channel)
    for t_ns, kind, data, description in framing.decode_session(reader):
        yield t_ns, kind, data, description, channel


class _counting:
    """Iterates records and counts them."""

    def __init__(self, records):
        self._records = records
        self.count = 0

    def __iter__(self):
        for record in self._records:
            self.count += 1
            yield record
