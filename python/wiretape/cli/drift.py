"""Drift (DESIGN §28): ``wiretape record … --against OLD [--profile P]
[--update]`` records as ever, then compares the new recording with the
stored one OLD by exchange (tools/diff.py: the exchanges aligned as
``diff -u`` aligns lines, through the profile's match key, so a field the
profile leaves out, a masked one, never drifts) and reports every place
the device now answers differently.

Exit 1 on drift (a damaged new recording included), 0 when the device
answers as OLD recorded; when the run itself failed (-- CMD exited non-zero,
the bridge failed) its status, after the comparison. ``--update`` writes
the new recording in OLD's place, atomically (a copy next to OLD renamed
over it), only when the run passed: the recording and any -- CMD succeeded.
Drift does not stop it: the point of updating is to take what the device
now answers; the exit status still says there was drift.

A recording of several devices (channels, DESIGN §19) is compared channel
by channel: each of OLD's channels with the live device of its name
(``--device NAME=…``); a channel only one side has is a usage error naming
it, before anything runs. ``--json`` prints one JSON document instead of
the report (drift_document), the run's own output going to stderr.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
import tempfile
from typing import Callable, Dict, Iterator, List, Optional

from .console import Output
from .endpoints import collect, is_single
from .errors import EXIT_CHECK_FAILED, EXIT_OK, UsageError
from .files import require_session, session_profile

#: Divergences the report shows one by one (all are counted).
DIVERGENCES_SHOWN = 20

_ENDPOINT_DESTS = ("device", "pty", "listen", "udp", "peer", "redirect_path")


def default_output(old: str) -> str:
    """Where the new recording goes without -o: next to OLD, ``.new`` before
    its ``.wtape`` (``scan.wtape`` -> ``scan.new.wtape``)."""
    stem = old[:-len(".wtape")] if old.endswith(".wtape") else old
    return stem + ".new.wtape"


def _header(path: str):
    from ..session import open_session

    with open_session(path) as reader:
        return reader.header


def _channel_types(header) -> Dict[str, str]:
    """A recording's port types by channel name ('' for the one unnamed)."""
    return {channel.name: channel.port_type for channel in header.channel_list()}


def _device_types(args, old: str, stored: Dict[str, str]) -> Dict[str, str]:
    """The port type of each --device by channel name (``serial`` for a bare
    path), the names those of OLD's channels: a channel only one side has
    is a usage error naming it."""
    from .. import _core

    endpoints = collect(args, _ENDPOINT_DESTS)
    if list(stored) == [""]:
        if not is_single(endpoints):
            raise UsageError(f"--against {old}: it is the recording of one device: give "
                             "one --device without NAME=")
    else:
        given = [endpoint.name for endpoint in endpoints]
        for name in stored:
            if name not in given:
                raise UsageError(
                    f"--against {old}: its channel {name!r} has no live device here: give "
                    f"--device {name}=DEVICE (its channels: {', '.join(stored)})")
        for name in given:
            if name not in stored:
                shown = f"--device {name}=…" if name else "the unnamed --device"
                raise UsageError(f"--against {old}: it has no channel {name!r} to compare "
                                 f"{shown} with (its channels: {', '.join(stored)})")
    types = {}
    for endpoint in endpoints:
        device = endpoint.get("device")
        if device is None:
            what = f"channel {endpoint.name!r}" if endpoint.name else "the new recording"
            raise UsageError(f"--against needs the --device {what} is made from")
        options = _core.device_options(device)
        types[endpoint.name] = dict(_core.parse_options(options)).get("type", "")
    if not types:
        raise UsageError("--against needs the --device the new recording is made from")
    return types


def _check_same_types(old: str, stored: Dict[str, str], live: Dict[str, str],
                      what: str) -> None:
    """Each channel of OLD and the live one of its name reach one kind of device."""
    from ..options import has_line_settings

    def kind(port_type: str) -> str:
        # A serial device exported over RFC 2217 (DESIGN §28) is a serial line.
        return "serial line" if has_line_settings(port_type) else port_type

    for name, old_type in stored.items():
        if name not in live:
            raise UsageError(f"--against {old}: {what} has no channel {name!r}")
        new_type = live[name]
        if kind(old_type) != kind(new_type):
            channel = f"channel {name!r} of " if name else ""
            raise UsageError(f"--against {old}: {channel}it is a recording of a device of "
                             f"type {old_type!r}, {what} is of type {new_type!r}: drift "
                             "compares recordings of one device")
    for name in live:
        if name not in stored:
            raise UsageError(f"--against {old}: it has no channel {name!r}, which {what} has")


def _keep_profile_meta(args, header) -> None:
    """The new recording keeps OLD's ``profile`` metadata (unless --meta
    gives one), so that an updated recording replays through the same masks."""
    from ..session import PROFILE_META_KEY

    spec = header.metadata.get(PROFILE_META_KEY)
    given = [pair.split("=", 1)[0] for pair in (args.meta or [])]
    if spec and PROFILE_META_KEY not in given:
        args.meta = list(args.meta or []) + [f"{PROFILE_META_KEY}={spec}"]


def _replace_atomically(new: str, old: str) -> None:
    """OLD replaced by a copy of NEW in one rename: a reader sees the old
    file or the new one, never a part."""
    folder = os.path.dirname(os.path.abspath(old))
    handle, partial = tempfile.mkstemp(prefix=os.path.basename(old) + ".", suffix=".update",
                                       dir=folder)
    try:
        with os.fdopen(handle, "wb") as target, open(new, "rb") as source:
            shutil.copyfileobj(source, target)
            target.flush()
            os.fsync(target.fileno())
        shutil.copymode(old, partial)
        os.replace(partial, old)
    except BaseException:
        if os.path.exists(partial):
            os.unlink(partial)
        raise


def record_against(args, out: Output, record: Callable[[object, Output], int]) -> int:
    """``record`` (cli/run.py's recording) run, then its recording compared
    with ``args.against``."""
    from ..tools.diff import diff

    old = args.against
    require_session(old)
    header = _header(old)
    stored = _channel_types(header)
    _check_same_types(old, stored, _device_types(args, old, stored), "--device")
    profile = session_profile(args.profile, [old], out)
    if args.output is None:
        args.output = default_output(old)
    if os.path.abspath(args.output) == os.path.abspath(old):
        raise UsageError(f"-o {args.output} is the --against file: the new recording goes "
                         "elsewhere (--update puts it in OLD's place once the run passed)")
    _keep_profile_meta(args, header)
    as_json = bool(getattr(args, "json", False))
    with _stdout_on_stderr(as_json):
        status = int(record(args, out) or 0)
    if not os.path.exists(args.output):
        out.note(f"wiretape record: nothing was recorded to {args.output}: no drift to report")
        status = status if status else EXIT_CHECK_FAILED
        if as_json:
            _print_json({"stored": old, "now": None, "profile": profile, "drift": None,
                         "status": status, "count": 0, "places": []})
        return status
    _check_same_types(old, stored, _channel_types(_header(args.output)),
                      f"the new recording {args.output}")
    result = diff(old, args.output, profile=profile,
                  max_divergences=sys.maxsize if as_json else DIVERGENCES_SHOWN)
    drifted = not result.identical or result.damaged
    if not as_json:
        _report(result, old, args.output, profile, out)
    passed = status == EXIT_OK
    updated = bool(args.update and passed)
    if updated:
        _replace_atomically(args.output, old)
        out.note(f"wiretape record: {old} updated with the new recording")
    elif args.update:
        out.note(f"wiretape record: {old} left as it was: the run failed (status {status})")
    exit_status = status if not passed else EXIT_CHECK_FAILED if drifted else EXIT_OK
    if as_json:
        document = drift_document(result, old, args.output, profile)
        document.update(status=exit_status, updated=updated)
        _print_json(document)
    return exit_status


@contextlib.contextmanager
def _stdout_on_stderr(moved: bool) -> Iterator[None]:
    """With --json, stdout is the document's alone: what the run prints
    (its messages, a -- CMD's output, which inherits the descriptor) goes
    to stderr meanwhile."""
    if not moved:
        yield
        return
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def _print_json(document: dict) -> None:
    print(json.dumps(document, indent=2), flush=True)


def _bytes_json(data: Optional[bytes]) -> Optional[dict]:
    """Bytes for a program and for a person: hex, and text (UTF-8, other
    bytes as \\xNN escapes)."""
    if data is None:
        return None
    data = bytes(data)
    return {"hex": data.hex(), "text": data.decode("utf-8", "backslashreplace")}


def _frame_at(framing, direction: str, data: Optional[bytes], offset: int) -> Optional[bytes]:
    """The profile's frame of `data` that holds byte `offset` (the last one
    when `data` ends before it)."""
    if not data:
        return None
    frames = framing.frames(direction, bytes(data))
    start = 0
    for frame in frames:
        if offset < start + len(frame):
            return bytes(frame)
        start += len(frame)
    return bytes(frames[-1]) if frames else None


def _field_json(framing, divergence) -> Optional[dict]:
    """What the profile calls the frame that drifted (its name, and each
    side's description); None without a profile."""
    if framing is None:
        return None
    frames = [_frame_at(framing, divergence.direction, data, divergence.offset)
              for data in (divergence.bytes_a, divergence.bytes_b)]
    described = [framing.describe(divergence.direction, frame) if frame is not None else None
                 for frame in frames]
    named = next((frame for frame in frames if frame is not None), None)
    return {"name": framing.frame_name(divergence.direction, named) if named else None,
            "expected": described[0], "got": described[1]}


def drift_document(result, old: str, new: str, profile: Optional[str]) -> dict:
    """``record --against --json``'s document: every place the device now
    answers differently from OLD (``expected``: OLD's bytes, ``got``: the
    new recording's), by channel and exchange. The exit status and whether
    OLD was updated are added by the caller."""
    from .. import _core

    framing = _core.profile_from_spec(profile) if profile else None
    places: List[dict] = []
    for divergence in result.divergences:
        places.append({
            "channel": divergence.channel,
            "exchange": divergence.exchange,
            "exchange_stored": divergence.exchange_a,
            "exchange_now": divergence.exchange_b,
            "direction": divergence.direction,
            "part": "request" if divergence.direction == "tx" else "response",
            "offset": divergence.offset,
            "expected": _bytes_json(divergence.bytes_a),
            "got": _bytes_json(divergence.bytes_b),
            "field": _field_json(framing, divergence),
        })
    return {"stored": old, "now": new, "profile": profile,
            "drift": not result.identical or result.damaged,
            "damage": {"stored": result.damage_a, "now": result.damage_b},
            "count": result.divergence_count, "places": places}


def _report(result, old: str, new: str, profile: Optional[str], out: Output) -> None:
    through = f" through profile {profile}" if profile else ""
    if result.identical and not result.damaged:
        out.print(f"wiretape record: no drift: the device answers as {old} recorded{through}",
                  style="green")
        return
    out.print(f"wiretape record: drift: the device now answers differently from {old}"
              f"{through}", style="bold red")
    for line in result.report().splitlines():
        if line in ("sessions differ", "sessions are identical"):
            continue
        out.print(line.replace("A: ", "A (stored): ", 1) if line.startswith("A: ")
                  else line.replace("B: ", "B (now): ", 1) if line.startswith("B: ") else line)
