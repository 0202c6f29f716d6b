"""``wiretape view``: a session as one self-contained HTML page (DESIGN §21).

The page holds everything it shows (no network access: the script, the
styles and the data are inline) and draws a zoomable, pannable timeline on
a canvas: per channel a tx, an rx and an events lane, the exchanges above
them (the one segmentation, ``_core.session_exchanges``, numbered as replay
numbers them), the frames of a protocol profile, and a hex/ASCII pane for
the record under the cursor or selected. A campaign's ``--json`` adds its
runs to the exchanges they faulted.

The data travels as one JSON object (``page_data``): per record its time,
kind and size in columns, and every payload's bytes in one base64 string,
so 100,000 records load in well under the 2 s first-paint budget
(bench/view_bench.py measures it). The records are streamed: the page holds
the first DETAIL_RECORDS in detail and every record in a binned summary,
so that memory and page stay bounded whatever the session's size. Only
this module knows the layout; the page's script (view_page/view.js) reads
it, and draws the record table, search, follow stream and cursors.
"""

from __future__ import annotations

import base64
import contextlib
import itertools
import json
import os
import re
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Tuple, cast

from .. import _core
from ..exports._common import replacing
from ..faults import Campaign, read_json
from ..options import join_options
from ..session import (FileRefused, SessionPath, chosen_profile, header_fields, is_stream,
                       open_session, refuse_same_file, session_files)

__all__ = ["view", "page_data", "default_output", "render_page", "decimation_note",
           "detail_limit", "PAGE_FORMAT", "MAX_RECORD_BYTES", "DETAIL_RECORDS", "DETAIL_BYTES"]

#: The version of page_data's layout, which view.js checks.
PAGE_FORMAT = 2

#: The bytes of one record the page holds: enough for any request and most
#: responses; the hex pane says when a record holds more.
MAX_RECORD_BYTES = 16384

#: The records a page holds in detail (their bytes, the record table, the
#: exchanges, frames and latencies): at most this many, holding at most
#: DETAIL_BYTES of bytes (detail_limit). A session past either is shown
#: whole in the summary timeline and in detail up to there; the page and
#: the command say so. Chosen so that the page opens to its first paint in
#: well under 2 s (docs/view.md, bench/view_bench.py).
DETAIL_RECORDS = 200_000
DETAIL_BYTES = 24 << 20

#: The bins of the summary timeline: a few per pixel of a wide screen.
SUMMARY_BINS = 4096

_PAGE_DIR = Path(__file__).with_name("view_page")


def default_output(session: SessionPath) -> str:
    """The page's path when -o is not given: the session's path with
    ``.html`` for its suffix (``scan.wtape`` -> ``scan.html``; a flexiport
    ``name.log`` -> ``name.html``)."""
    root, _ = os.path.splitext(os.fspath(session))
    return root + ".html"


# The replay keys that give a profile (_core.profile_from_spec reads them).
_PROFILE_KEYS = ("profile", "framing", "ignore", "echo", "checksum")


def _exchanges(path: str, profile: Optional[_core.Profile], options: str,
               channels: Optional[List[Tuple[int, str]]] = None) -> List[List[Any]]:
    """The exchanges as rows (view.js names the columns). A session of
    several ports (`channels`: (id, name)) has each channel's exchanges,
    numbered per channel, all in the order they begin; the eleventh column
    is the channel's id (0 in a session of one port)."""
    rows = []
    for channel, name in channels or [(None, "")]:
        keys = _core.parse_options(
            join_options(options, _core.option_string([("channel", name)]) if name else ""))
        if profile is not None:  # the profile given overrides the campaign's
            keys = [(key, value) for key, value in keys if key not in _PROFILE_KEYS]
        found = _core.session_exchanges(
            path, options=join_options(profile.options if profile is not None else "",
                                       _core.option_string(keys)))
        for exchange in found:
            row = [exchange.index, exchange.first_record, exchange.end_record,
                   exchange.request_first_t_ns, exchange.request_last_t_ns,
                   exchange.response_first_t_ns, exchange.response_last_t_ns,
                   exchange.request_bytes, exchange.response_bytes,
                   exchange.client_session]
            rows.append(row + [channel or 0])
    if channels:
        rows.sort(key=lambda row: next((t for t in (row[3], row[5]) if t is not None), 0))
    return rows


def _frames(path: str, framing: _core.Profile,
            channels: Optional[List[Tuple[int, str]]] = None) -> List[List[Any]]:
    """The profile's frames: [t_ns, direction, size, name]; in a session of
    several ports each channel's bytes framed apart, with its id fifth."""
    frames = []
    for channel, _ in channels or [(None, "")]:
        source = path if channel is None else _core.SessionReader(path, channel=channel)
        # The stub says object: its items are (t_ns, kind, bytes, description).
        decoded = cast(Iterable[Tuple[int, str, bytes, Optional[str]]],
                       framing.decode_session(source))
        for t_ns, kind, data, description in decoded:
            if description is None:  # an event
                continue
            frames.append([t_ns, kind, len(data), description]
                          + ([] if channel is None else [channel]))
    if channels:
        frames.sort(key=lambda frame: frame[0])
    return frames


def _campaign(path: str, result: Campaign, session: str,
              exchanges: List[List[Any]], channel_ids: Optional[Dict[str, int]] = None
              ) -> Dict[str, Any]:
    """The campaign read from `path` (its --json), its runs placed on the
    exchange (exchange:N, its row in `exchanges`; in a session of several
    ports exchange:N@channel:NAME) or the time (t:SECONDS) they faulted; the
    others (rx:N, every:K, p:P) are listed without a place."""
    from ..faults import FaultInputError, session_digest

    rows = {(row[0], row[10] if channel_ids else None): position
            for position, row in enumerate(exchanges)}
    runs = []
    for run in result.runs:
        place: Dict[str, Any] = {}
        try:
            fault = _core.parse_faults(run.spec)[0]  # the replay's own reading of the place
        except _core.OptionError as error:
            raise FaultInputError(f"{path}: run {run.case}: {error}") from None
        if fault.where == "exchange" and fault.number is not None:
            index, name = fault.number, fault.channel or None
            channel = (channel_ids or {}).get(name) if name else None
            if name and channel is None:
                raise FaultInputError(
                    f"{path}: run {run.case} ({run.spec}) is on channel {name}, which the "
                    "session does not have: the campaign ran on another session")
            if (index, channel) not in rows:
                whose = f"channel {name} of the session" if name else "the session"
                count = sum(1 for key in rows if key[1] == channel)
                raise FaultInputError(
                    f"{path}: run {run.case} ({run.spec}) is at exchange {index}, but "
                    f"{whose} has {count} exchanges: the campaign ran on another session")
            place["exchange"] = rows[(index, channel)]
        if fault.where == "t" and fault.value is not None:
            place["t_ns"] = int(fault.value * 1e9)
        runs.append({"case": run.case, "kind": run.kind, "where": run.where,
                     "outcome": run.outcome, "exit": run.exit, "seconds": run.seconds,
                     "repro": run.repro, **place})
    same = not result.session_sha256 or result.session_sha256 == session_digest(session)
    return {"path": os.fspath(path), "session": result.session, "seed": result.seed,
            "options": result.options, "same_session": same, "runs": runs,
            "summary": result.summary, "interrupted": result.interrupted}


def page_data(session: SessionPath, profile: Optional[str] = None,
              campaign: Optional[str] = None) -> Dict[str, Any]:
    """Everything the page shows, as one JSON-able object (see _page_data)."""
    return _page_data(os.fspath(session), profile, campaign)[0]


def detail_limit(records: int, payload_bytes: int) -> bool:
    """Whether a record, after `records` records holding `payload_bytes` of
    bytes, is still in the page's detail (its bytes, the tables, the
    exchanges): the first DETAIL_RECORDS records, up to DETAIL_BYTES of
    their bytes. The records past it are in the summary timeline only."""
    return records < DETAIL_RECORDS and payload_bytes < DETAIL_BYTES


class _Summary:
    """The whole session binned in time for the summary timeline: per
    channel and lane (tx, rx, events) the records of each of SUMMARY_BINS
    bins of equal width, counted, with the largest size. One pass, memory
    fixed: when a record falls past the last bin the bins are merged by
    pairs and their width doubles."""

    def __init__(self) -> None:
        self.width_ns = 1000
        self._lanes: Dict[Tuple[int, str], Tuple[List[int], List[int]]] = {}

    def add(self, channel: int, lane: str, t_ns: int, size: int) -> None:
        at = t_ns // self.width_ns
        while at >= SUMMARY_BINS:
            self._merge()
            at = t_ns // self.width_ns
        counts, largest = self._lanes.get((channel, lane)) or self._new(channel, lane)
        counts[at] += 1
        if size > largest[at]:
            largest[at] = size

    def _new(self, channel: int, lane: str) -> Tuple[List[int], List[int]]:
        bins = self._lanes[(channel, lane)] = ([0] * SUMMARY_BINS, [0] * SUMMARY_BINS)
        return bins

    def _merge(self) -> None:
        half = SUMMARY_BINS // 2
        for counts, largest in self._lanes.values():
            counts[:half] = [counts[2 * n] + counts[2 * n + 1] for n in range(half)]
            largest[:half] = [max(largest[2 * n], largest[2 * n + 1]) for n in range(half)]
            counts[half:] = [0] * half
            largest[half:] = [0] * half
        self.width_ns *= 2

    def to_page(self) -> Dict[str, Any]:
        """Sparse: per lane [bin, count, largest] of the bins holding records."""
        return {"bin_ns": self.width_ns, "lanes": [
            {"channel": channel, "lane": lane,
             "bins": [[n, count, largest[n]] for n, count in enumerate(counts) if count]}
            for (channel, lane), (counts, largest) in sorted(self._lanes.items())]}


def _page_data(path: str, profile: Optional[str], campaign: Optional[str]
               ) -> Tuple[Dict[str, Any], Optional[_core.SessionError]]:
    """Everything the page shows, as one JSON-able object. ``profile`` (a
    name or a declared profile; by default the session's ``profile``
    metadata, wiretape.session.chosen_profile; ``none``: none) names the frames; a
    ``campaign`` (a ``wiretape faults --json`` file) adds its runs. A
    damaged session is shown up to the damage, which the page names; the
    damage is returned with the data. The records are streamed once, with
    memory bounded whatever the session's size: the first records (while
    detail_limit allows) are held in detail, every record is binned in the
    summary."""
    reader = open_session(path)
    header = header_fields(reader)
    spec = chosen_profile(profile, reader.header).spec
    # An unknown profile is an OptionError, before any work.
    framing = _core.profile_from_spec(spec) if spec is not None else None
    kinds = [kind["name"] for kind in _core.RECORD_KINDS]
    kind_code = {name: code for code, name in enumerate(kinds)}
    lane_of_kind = {name: name if name in ("tx", "rx") else "events" for name in kinds}
    times: List[int] = []
    kind_of: List[int] = []
    sizes: List[int] = []
    kept: List[int] = []
    channels: List[int] = []
    payload = bytearray()
    summary = _Summary()
    meters: Dict[int, _core.LatencyMeter] = {}
    total = 0
    last_t_ns = 0
    for record in reader:
        content = record.data
        channel, kind, t_ns = record.channel, record.kind, record.t_ns
        total += 1
        last_t_ns = t_ns
        summary.add(channel, lane_of_kind.get(kind, "events"), t_ns, len(content))
        if not detail_limit(len(times), len(payload)):
            continue
        meter = meters.get(channel)
        if meter is None:
            meter = meters[channel] = _core.LatencyMeter(reader.header, channel=channel,
                                                         profile=spec)
        meter.feed(kind, t_ns, content)
        channels.append(channel)
        times.append(t_ns)
        code = kind_code.get(kind)
        if code is None:
            code = kind_code[kind] = len(kinds)
            kinds.append(kind)
        kind_of.append(code)
        sizes.append(len(content))
        piece = content[:MAX_RECORD_BYTES]
        kept.append(len(piece))
        payload += piece
    damage = reader.damage.message if reader.damage is not None else None
    names = {channel.id: channel.name for channel in reader.header.channel_list()}
    # A campaign's exchanges are numbered under its replay keys.
    campaign_runs = read_json(campaign) if campaign is not None else None
    options = campaign_runs.options if campaign_runs is not None else ""
    listed = reader.header.channel_list()
    several = [(channel.id, channel.name) for channel in listed] if len(listed) > 1 else None
    with _detail_part(path, reader.damage is None and len(times) == total,
                      len(times)) as detailed:
        exchanges = _exchanges(detailed, framing, options, several)
        frames = _frames(detailed, framing, several) if framing is not None else []
    latencies = {(channel, answered.exchange): answered.wait_ns
                 for channel, meter in meters.items() for answered in meter.answered}
    for row in exchanges:
        row.append(latencies.get((row[10], row[0])))
    if several:
        _to_page_records(exchanges, channels)
    campaign_data = None
    if campaign is not None and campaign_runs is not None:
        campaign_data = _campaign(campaign, campaign_runs, path, exchanges,
                                  {name: id for id, name in several or []})
    decimated: Optional[Dict[str, Any]] = None
    if len(times) < total:
        decimated = {"records": total, "shown": len(times),
                     "shown_until_t_ns": times[-1] if times else 0,
                     "limit_records": DETAIL_RECORDS, "limit_bytes": DETAIL_BYTES}
    data = {
        "format": PAGE_FORMAT,
        "session": {"path": path, "name": os.path.basename(path), "header": header,
                    "damage": damage, "profile": framing.name if framing is not None else None,
                    "records": total, "last_t_ns": last_t_ns},
        # A group of lanes per channel: a session of several ports (DESIGN
        # §19) has one per port, and "channel" is then a column, one number
        # per record, rather than one number for all.
        "channels": [{"id": channel,
                      "name": names.get(channel) or header.get("port_type") or "port"}
                     for channel in sorted(set(channels) | set(names) | {0})],
        "kinds": kinds,
        "records": {"t_ns": times, "kind": kind_of, "size": sizes, "kept": kept,
                    "channel": channels if any(channels) else 0,
                    "bytes": base64.b64encode(bytes(payload)).decode("ascii")},
        "decimated": decimated,
        "summary": summary.to_page(),
        "exchanges": exchanges,
        "frames": frames,
        "campaign": campaign_data,
        "mismatch": _mismatch(header, path),
    }
    if decimated is not None:
        decimated["message"] = decimation_note(data)
    return data, reader.damage


def _to_page_records(exchanges: List[List[Any]], channels: List[int]) -> None:
    """A channel's exchanges number its own records (first, end): made the
    page's, which are every channel's in recorded order."""
    positions: Dict[int, List[int]] = {}
    for index, channel in enumerate(channels):
        positions.setdefault(channel, []).append(index)
    for row in exchanges:
        own = positions.get(row[10], [])
        first, end = row[1], row[2]
        row[1] = own[first] if first < len(own) else len(channels)
        row[2] = own[end - 1] + 1 if 0 < end <= len(own) else (row[1] if end <= 0 else len(channels))


@contextlib.contextmanager
def _detail_part(path: str, whole: bool, records: int) -> Iterator[str]:
    """`path`, or a temporary copy of its first `records` records when the
    page holds fewer than the whole (a damaged session: those before the
    damage; a large one: those in detail): exchanges and frames are found in
    what the page shows, by the one segmentation."""
    if whole:
        yield path
        return
    with tempfile.TemporaryDirectory(prefix="wiretape-view-") as directory:
        copy = os.path.join(directory, "detail.wtape")
        reader = open_session(path)
        with _core.SessionWriter(copy, reader.header) as writer:
            for record in itertools.islice(reader, records):
                writer.write(record.kind, record.t_ns, record.data, channel=record.channel)
        yield copy


def _script_json(value: Any) -> str:
    """JSON that cannot end the <script> element holding it."""
    text = json.dumps(value, separators=(",", ":"), default=str)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def render_page(data: Dict[str, Any]) -> str:
    """The HTML page of ``page_data``: the template with its style, script
    and data inline."""
    template = (_PAGE_DIR / "view.html").read_text(encoding="utf-8")
    style = (_PAGE_DIR / "view.css").read_text(encoding="utf-8")
    script = (_PAGE_DIR / "view.js").read_text(encoding="utf-8")
    title = data["session"]["name"]
    pieces = {"@TITLE@": _html_text(title), "@STYLE@": style,
              "@DATA@": _script_json(data), "@SCRIPT@": script}
    return re.sub("@(TITLE|STYLE|DATA|SCRIPT)@", lambda match: pieces[match.group(0)], template)


def _html_text(text: str) -> str:
    return (text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;"))


def _replayed_session(header: Dict[str, Any], path: str) -> Optional[Dict[str, str]]:
    """A replay's ``-o`` recording names the session it replayed in its
    port options (``type=replay,file=...``): that file and the replay's
    match key, when the file is still there."""
    if header.get("port_type") != "replay":
        return None
    options = dict(_core.parse_options(header.get("port_options") or ""))
    original = options.get("file")
    if not original:
        return None
    if not os.path.isabs(original) and not os.path.exists(original):
        original = os.path.join(os.path.dirname(path), original)
    if not os.path.isfile(original):
        return None
    return {"path": original, "match": options.get("match", "sequence")}


def _mismatch(header: Dict[str, Any], path: str) -> Optional[Dict[str, Any]]:
    """Where the client of a replay's ``-o`` recording wrote bytes the
    replayed session does not hold (replay's mismatch, under match=sequence:
    its tx stream compared with the session's, as ``wiretape diff`` compares
    them). None when the client kept to the session, stopped early, or the
    replay matched requests in any order (match=request)."""
    from .diff import DirectionDiff, diff

    original = _replayed_session(header, path)
    if original is None or original["match"] != "sequence":
        return None
    tx = diff(original["path"], path)["tx"]
    if not isinstance(tx, DirectionDiff) or tx.identical or tx.offset is None or not tx.at_b:
        return None
    return {"original": original["path"], "tx_offset": tx.offset,
            "expected": _core.hex_ascii(bytes(tx.at_a)), "actual": _core.hex_ascii(bytes(tx.at_b))}


def decimation_note(data: Dict[str, Any]) -> Optional[str]:
    """What the page says when it holds only part of the session in detail
    (the command prints it too), or None when it holds all of it."""
    cut = data.get("decimated")
    if not cut:
        return None
    return (f"{data['session']['name']}: {cut['records']:,} records, more than a page holds "
            f"in detail ({DETAIL_RECORDS:,} records or {DETAIL_BYTES >> 20} MiB of bytes): "
            f"the first {cut['shown']:,} (to +{cut['shown_until_t_ns'] / 1e9:.6f} s) are in "
            "detail, the whole session in the summary timeline; `wiretape edit SESSION PART "
            "--cut FROM:TO` makes a session of a later part (docs/view.md, \"Large sessions\")")


def view(session: SessionPath, output: Optional[SessionPath] = None,
         profile: Optional[str] = None, campaign: Optional[str] = None,
         note: Optional[Callable[[str], None]] = None) -> str:
    """Writes the page of ``session`` to ``output`` (default:
    default_output(session)) and returns its path. Nothing is written over
    the session or the campaign's file; the page appears whole or not at all
    (an interrupted view leaves nothing). A damaged session is shown up to
    the damage, then its SessionError is raised. A session larger than the
    page's detail (detail_limit) is said so to `note` (default: stderr)."""
    path = os.fspath(session)
    output = os.fspath(output) if output is not None else default_output(path)
    if is_stream(path):
        raise FileRefused(f"{path}: a pipe or FIFO: view reads the session more than once "
                          "(records, exchanges, frames); give it a file")
    inputs = session_files(path) + ([campaign] if campaign is not None else [])
    refuse_same_file(inputs, [output])
    data, damage = _page_data(path, profile, campaign)
    told = decimation_note(data)
    if told is not None:
        (note or (lambda text: print(f"wiretape view: {text}", file=sys.stderr)))(told)
    page = render_page(data).encode("utf-8")
    with replacing(output) as out:
        out.write(page)
    if damage is not None:
        raise damage
    return output
