"""``wiretape edit IN OUT``: cut a session down and scrub it before it is
shared (DESIGN §15, docs/cli.md "edit").

- ``cut``: keep the part from FROM to TO (seconds, or exchanges with an
  ``e`` suffix). What was in force at the cut point stays: every record
  before the client's first write (the open, the device's greeting, the
  first settings) is kept, and the settings, modem lines and connected
  client of the moment the cut begins follow it; the cut part is moved back
  in time to start right after the greeting.
- ``redact``: a regular expression over the rx and tx bytes; each match is
  overwritten (with ``*``, or REPLACEMENT repeated to the match's length,
  so lengths and framing stay) and marked by a ``redaction`` event, which
  replay treats as wildcards. A match may span records, up to ``MAX_SPAN``
  bytes. Redacting scrubs every place a value appears (DESIGN §23): it also
  clears the header's host, the device identity's serial number (and its
  part of the identity's by-id name) and the serial numbers of
  ``/dev/serial/by-id`` paths, and applies the patterns to the header's text (port options,
  device address, metadata values, import source) and to every string of
  every event (an open's description, a client's peer...). With a protocol
  profile, the checksums of each frame holding scrubbed bytes are
  recomputed (``Profile.recompute_checksums``), so that a scrubbed
  recording still replays to the driver that made it.
- ``drop_meta``: removes user metadata keys.
- ``channels``: a session of several ports (DESIGN §19) is edited channel
  by channel on its one clock: each channel's bytes are searched and framed
  apart, and its greeting and state are its own. ``--cut`` without
  ``channels`` cuts every channel by the one window and moves them back
  together; with ``channels`` only those channels are cut and redacted
  (the part kept stays at its time, so that the channels keep their order)
  and the others' records are kept as they are. The ``channels`` header
  member is kept.

The header's ``edits`` list says what was done (never the scrubbed text).
The input is never written over. The jobs live beside this module:
``edit_specs`` (the --cut and --redact specs), ``edit_cut`` (the window
and the cutter), ``edit_redact`` (the redactor and the resealer),
``edit_scrub`` (the header and the events) and ``edit_child`` (the process
edit_in_child() runs it in)."""

from __future__ import annotations

import dataclasses
import os
import pickle
import stat
import subprocess
import sys
from typing import Iterable, List, Optional, Tuple

from .. import _core
from ..children import Child
from ..session import (DIRECTIONS, SessionPath, chosen_profile, open_session, raise_damage,
                       refuse_same_file, session_files)
from .channels import UnknownChannel, choose_channels, several_channels
from .convert import session_writer
from .edit_cut import Cutter, cut_window
from .edit_redact import MAX_SPAN, Entry, Redactor, Resealer, merged_marks
from .edit_scrub import scrub_header, scrubbed_event
from .edit_specs import Cut, Redaction, parse_cut, parse_redaction

__all__ = ["edit", "edit_in_child", "EditResult", "Cut", "Redaction", "parse_cut",
           "parse_redaction", "MAX_SPAN"]


@dataclasses.dataclass(frozen=True)
class EditResult:
    """What edit() did."""

    records: int  # records written
    matches: int  # redacted matches
    redacted_records: int  # records with redacted bytes
    edits: Tuple[str, ...]  # what this edit added to the header's edits list
    profile: Optional[str] = None  # the profile whose checksums were recomputed
    resealed_frames: int = 0  # frames whose checksums it recomputed
    unsealed_frames: int = 0  # ... a byte of which was already written (HOLD_LIMIT)


def _profile(spec: str):
    """The profile `spec` names, or declares (``framing=...,checksum=...``),
    read as every --profile is (``_core.profile_from_spec``)."""
    try:
        return _core.profile_from_spec(spec)
    except _core.OptionError as error:
        raise ValueError(f"--profile {spec!r}: {error}") from None


def _remove_output(dst: str, before: Optional[os.stat_result]) -> None:
    """Removes what an interrupted edit wrote to `dst`: a regular file it
    created or wrote over (an output that is not a regular file, a FIFO or
    /dev/stdout, is written through and cannot be taken back)."""
    try:
        now = os.stat(dst)
    except OSError:
        return
    if not stat.S_ISREG(now.st_mode):
        return
    if before is not None and (before.st_ino, before.st_mtime_ns, before.st_size) == (
            now.st_ino, now.st_mtime_ns, now.st_size):
        return  # never opened: the file there is not ours
    try:
        os.unlink(dst)
    except OSError:
        pass


def _stat_or_none(path: str) -> Optional[os.stat_result]:
    try:
        return os.stat(path)
    except OSError:
        return None


def edit(src: SessionPath, dst: SessionPath, cut: Optional[Cut] = None,
         redact: Iterable[Redaction] = (), drop_meta: Iterable[str] = (),
         profile: Optional[str] = "", channels: Iterable[str] = (),
         compress: str = "none") -> EditResult:
    """Writes an edited copy of the session `src` to `dst` (a .wtape;
    ``compress="zstd"``: in compressed chunks, format 2.0).
    `profile`: the protocol profile whose checksums are recomputed over
    scrubbed bytes and by whose frames the exchanges of a ``Ne`` cut are
    numbered (as a replay with it numbers them), a name or a declared
    profile's keys
    (``framing=...,checksum=...``); "" (the default) for the one the
    session's metadata names (``profile=NAME``, by
    ``wiretape.session.chosen_profile``), None for none. Raises
    ValueError for an edit that does not fit the session (a metadata key it
    lacks, an exchange past its end) or an unknown profile; SessionError after
    writing what came before when `src` is damaged. Interrupted
    (KeyboardInterrupt), it removes the output it was writing.
    `channels`: names of channels of a session of several ports that
    `cut` and `redact` apply to (empty: every channel); the other
    channels' records are kept as they are (see the module's notes)."""
    src, dst = os.fspath(src), os.fspath(dst)
    redactions = list(redact)
    drop = list(drop_meta)
    channels = list(channels)
    if cut is None and not redactions and not drop:
        raise ValueError("nothing to edit: give --cut, --redact or --drop-meta")
    if channels and cut is None and not redactions:
        raise ValueError("--channel limits --cut and --redact: give one of them")
    refuse_same_file(session_files(src), [dst])
    reader = open_session(src)
    header = reader.header
    try:
        chosen = choose_channels(header, channels, src)
    except UnknownChannel as error:
        raise UnknownChannel(f"--channel: {error}") from None
    if cut is not None and cut.exchanges and several_channels(header) and len(channels) != 1:
        raise ValueError(f"--cut {cut.spec}: exchanges are numbered per channel in a session "
                         "of several channels: give one --channel NAME to count them on")
    if profile == "":
        # The one rule of a session's profile metadata as the default.
        profile = chosen_profile(None, header).spec
    counts_exchanges = cut is not None and cut.exchanges
    used_profile = (_profile(profile) if profile is not None and (redactions or counts_exchanges)
                    else None)
    # The profile recomputes checksums over scrubbed bytes, and numbers the
    # exchanges of --cut Ne as a replay with it does (frames, not records).
    framing = used_profile if redactions else None
    metadata = dict(header.metadata)
    for key in drop:
        if key not in metadata:
            known = ", ".join(sorted(metadata)) or "none"
            raise ValueError(f"--drop-meta {key!r}: {src} has no metadata key {key!r} "
                             f"(its keys: {known})")
        del metadata[key]
    header.metadata = metadata
    counted_on = channels[0] if counts_exchanges and channels else ""
    window = (cut_window(src, cut, counted_on, used_profile) if cut is not None
              else (None, None))

    earlier_edits = list(header.edits)
    edits: List[str] = []
    limited = "" if chosen is None else " of channel" + ("s " if len(channels) > 1 else " ") \
        + ", ".join(sorted(set(channels)))
    if cut is not None:
        edits.append(cut.describe() + limited)
    if redactions:
        scrub_header(header, redactions, chosen)
    edits += [f"dropped meta {key}" for key in drop]

    if redactions:
        # The header comes first, before any match is found: it names the
        # patterns' count; the redaction events say where each match was.
        count = len(redactions)
        sealed = f"; checksums recomputed ({framing.name})" if framing is not None else ""
        edits.append(f"redacted {count} pattern{'s' if count != 1 else ''}{limited}"
                     f" (host and by-id serial numbers cleared{sealed})")
    header.edits = earlier_edits + edits
    before = _stat_or_none(dst)
    counts = {"records": 0, "marked": 0}
    try:
        with session_writer(dst, header, compress) as writer:
            def emit(entry: Entry) -> None:
                marks = merged_marks(entry.marks)
                for offset, length in marks:
                    payload = _core.event_payload("redaction", {"offset": offset, "length": length})
                    writer.write("redaction", entry.t_ns, payload, channel=entry.channel)
                writer.write(entry.kind, entry.t_ns, bytes(entry.data), channel=entry.channel)
                counts["records"] += 1
                counts["marked"] += bool(marks)

            resealer = Resealer(framing, emit) if framing is not None else None
            redactor = Redactor(redactions, resealer.add if resealer is not None else emit)

            def keep(channel: int, kind: str, t_ns: int, data: bytes) -> None:
                if redactions and kind not in DIRECTIONS:
                    data = scrubbed_event(kind, data, redactions)
                redactor.add(Entry(kind, t_ns, data, channel))

            cutter = (Cutter(window[0], window[1], keep, move=chosen is None)
                      if cut is not None else None)
            for record in reader:
                channel = record.channel
                if chosen is not None and channel not in chosen:
                    redactor.add(Entry(record.kind, record.t_ns, record.data, channel),
                                 redact=False)
                elif cutter is not None:
                    cutter.add(record.kind, record.t_ns, record.data, channel)
                else:
                    keep(channel, record.kind, record.t_ns, record.data)
            if cutter is not None:
                cutter.finish()
            redactor.finish()
            if resealer is not None:
                resealer.finish()
    except KeyboardInterrupt:
        _remove_output(dst, before)
        raise
    raise_damage(reader)
    return EditResult(records=counts["records"], matches=redactor.matches,
                      redacted_records=counts["marked"], edits=tuple(edits),
                      profile=framing.name if framing is not None else None,
                      resealed_frames=resealer.frames if resealer is not None else 0,
                      unsealed_frames=resealer.missed if resealer is not None else 0)



class _StderrRelay:
    """The child's stderr, passed on to this process's (a warning of
    Python's, a sanitizer's report)."""

    def write(self, data: bytes) -> None:
        sys.stderr.write(data.decode("utf-8", "replace"))

    def flush(self) -> None:
        sys.stderr.flush()


def edit_in_child(src: SessionPath, dst: SessionPath, **options) -> EditResult:
    """edit() in a child process (``wiretape.tools.edit_child``, run as a
    :class:`~wiretape.children.Child`) while this process only waits for it.

    Python's ``re`` does not look at signals while it matches, so a
    catastrophic pattern (``(a+)+$`` over a long ``aaa...b``) would hold
    SIGINT and SIGTERM off for as long as it runs, and the command could
    neither end nor remove its partial output. Waiting on the child, this
    process takes the signal at once (its handler raises
    KeyboardInterrupt): it ends the child, removes the output and lets the
    command exit 130/143. Running the matching in a thread would not help
    (``re`` holds the GIL throughout). The request goes to the child
    pickled on its stdin; its outcome, a result or an exception, comes back
    pickled on its stdout. Like every Child, it ends with this process, even
    one killed by SIGKILL: a catastrophic match cannot outlive the command
    as an orphan holding its output."""
    src, dst = os.fspath(src), os.fspath(dst)
    before = _stat_or_none(dst)
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    # The child imports this very package, wherever it was imported from.
    package_root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [package_root] + [part for part in env.get("PYTHONPATH", "").split(os.pathsep) if part])
    # Not the current directory first (python -m would put it there): a
    # ``wiretape`` folder where the command runs must not stand in for it.
    env["PYTHONSAFEPATH"] = "1"
    child = Child([sys.executable, "-m", "wiretape.tools.edit_child"], separate_stderr=True,
                  relay_stderr=_StderrRelay(), stdin=subprocess.PIPE, env=env)
    try:
        try:
            with child.process.stdin as request:
                request.write(pickle.dumps((src, dst, options)))
        except BrokenPipeError:
            pass  # the child ended at once: its outcome says how
        outcome = child.run()
    except BaseException:
        child.end(grace=0)
        _remove_output(dst, before)
        raise
    if not outcome.stdout:
        _remove_output(dst, before)
        ended = (f"killed by signal {outcome.signal}" if outcome.signal is not None
                 else f"exit status {outcome.exit_status}")
        raise RuntimeError(f"edit {src} -> {dst}: the editing process ended without a result "
                           f"({ended})")
    kind, value = pickle.loads(outcome.stdout)
    if kind == "error":
        raise value
    return value
