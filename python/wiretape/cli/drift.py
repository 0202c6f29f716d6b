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
"""

from __future__ import annotations

import os
import shutil
import tempfile
from typing import Callable, Optional

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


def _device_type(args) -> str:
    """The port type of the one --device (``serial`` for a bare path)."""
    from .. import _core

    endpoints = collect(args, _ENDPOINT_DESTS)
    if not is_single(endpoints):
        raise UsageError("--against compares the recording of one device: give one "
                         "--device without NAME=")
    device = endpoints[0].get("device") if endpoints else None
    if device is None:
        raise UsageError("--against needs the --device the new recording is made from")
    return dict(_core.parse_options(_core.device_options(device))).get("type", "")


def _check_same_type(old: str, old_type: str, new_type: str, what: str) -> None:
    from ..options import has_line_settings

    def kind(port_type: str) -> str:
        # A serial device exported over RFC 2217 (DESIGN §28) is a serial line.
        return "serial line" if has_line_settings(port_type) else port_type

    if kind(old_type) != kind(new_type):
        raise UsageError(f"--against {old}: it is a recording of a device of type "
                         f"{old_type!r}, {what} is of type {new_type!r}: drift compares "
                         "recordings of one device")


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
    if header.channels:
        raise UsageError(f"--against {old}: it is a session of several channels; drift "
                         "compares the recording of one device")
    _check_same_type(old, header.port_type, _device_type(args), "--device")
    profile = session_profile(args.profile, [old], out)
    if args.output is None:
        args.output = default_output(old)
    if os.path.abspath(args.output) == os.path.abspath(old):
        raise UsageError(f"-o {args.output} is the --against file: the new recording goes "
                         "elsewhere (--update puts it in OLD's place once the run passed)")
    _keep_profile_meta(args, header)
    status = int(record(args, out) or 0)
    if not os.path.exists(args.output):
        out.note(f"wiretape record: nothing was recorded to {args.output}: no drift to report")
        return status if status else EXIT_CHECK_FAILED
    _check_same_type(old, header.port_type, _header(args.output).port_type,
                     f"the new recording {args.output}")
    result = diff(old, args.output, profile=profile, max_divergences=DIVERGENCES_SHOWN)
    drifted = not result.identical or result.damaged
    _report(result, old, args.output, profile, out)
    passed = status == EXIT_OK
    if args.update and passed:
        _replace_atomically(args.output, old)
        out.note(f"wiretape record: {old} updated with the new recording")
    elif args.update:
        out.note(f"wiretape record: {old} left as it was: the run failed (status {status})")
    if not passed:
        return status
    return EXIT_CHECK_FAILED if drifted else EXIT_OK


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
