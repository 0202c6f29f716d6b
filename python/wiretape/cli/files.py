"""The commands on session files: show, stats, verify, convert, diff, edit,
view (the work is in wiretape.tools)."""

from __future__ import annotations

import os
import sys

from .. import SessionError
from .console import Output, silence_stdout
from .errors import EXIT_CHECK_FAILED, EXIT_OK, CheckFailed, RuntimeFailure, UsageError


def require_input(path: str) -> None:
    """A session file given to read must be there (exit 3 otherwise); a
    flexiport ``name.log`` stands for ``name.logr`` + ``name.logw``."""
    if os.path.exists(path):
        if os.path.isdir(path):
            raise RuntimeFailure(f"{path}: is a directory, not a session file")
        return
    if path.endswith(".log") and (os.path.exists(path + "r") or os.path.exists(path + "w")):
        return
    raise RuntimeFailure(f"{path}: no such file")


def _starts_as_a_session(path: str) -> bool:
    """A regular file starting with a session's magic (a pipe is not read:
    that would consume it)."""
    from .._core import SESSION_MAGIC

    try:
        if not os.path.isfile(path):
            return False
        with open(path, "rb") as handle:
            return handle.read(len(SESSION_MAGIC)) == SESSION_MAGIC
    except OSError:
        return False


def require_session(path: str) -> None:
    """require_input(), and a file wiretape imports but does not read as it
    is (a capture, a pytest-reserial cassette) named with the command that
    converts it (exit 1, as any file that is not a session)."""
    require_input(path)
    if _starts_as_a_session(path):  # the usual case, without importing the importers
        return
    from ..tools.convert import unconverted_format

    found = unconverted_format(path)
    if found is not None:
        what, command = found
        raise CheckFailed(f"{path}: not a wiretape session but {what}: convert it first: "
                          f"{command}")


def session_profile(given, paths, out: Output):
    """The profile spec a command reads `paths` with, or None: the one rule
    of wiretape.session.chosen_profile (--profile given, else the sessions'
    ``profile`` metadata; ``none``: none), its note printed. A session read
    from a pipe gives no default: reading its header here would consume it."""
    from ..session import NO_PROFILE, chosen_profile, is_stream, open_session

    if given is None and any(is_stream(path) or not os.path.isfile(path) for path in paths):
        return None
    headers = []
    if given is None:
        try:
            for path in paths:
                with open_session(path) as reader:
                    headers.append(reader.header)
        except (OSError, SessionError):  # the command itself reports it, in its place
            return None
    try:
        choice = chosen_profile(given, *headers)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if choice.note is not None:
        out.note(f"wiretape: {choice.note}")
    return choice.spec if choice.spec != NO_PROFILE else None


def cmd_show(args, out: Output) -> int:
    from ..tools.channels import UnknownChannel
    from ..tools.show import Selection, color_wanted, show_reporting_damage

    require_session(args.file)
    if args.textconv or args.no_start or args.no_times:
        return _show_textconv(args)
    profile = args.profile or args.decode
    if args.profile and args.decode and args.profile != args.decode:
        raise UsageError(f"--profile {args.profile} and --decode {args.decode} disagree: give one")
    if profile and profile != "none" and args.format != "text":
        option = "--profile" if args.profile else "--decode"
        raise UsageError(f"{option} works with --format text only")
    if args.format == "text":
        profile = session_profile(profile, [args.file], out)
    else:
        profile = None
    try:
        select = Selection(kinds=frozenset(args.kind) if args.kind else None,
                           start_s=args.start_s, end_s=args.end_s,
                           grep=args.grep.encode("utf-8", "surrogateescape")
                           if args.grep is not None else None,
                           channels=frozenset(args.channel) if args.channel else None)
    except ValueError as error:
        raise UsageError(str(error)) from None
    try:
        _, damage = show_reporting_damage(args.file, fmt=args.format, profile=profile,
                                          select=select, full=args.full,
                                          color=color_wanted(args.color, sys.stdout))
    except UnknownChannel as error:
        raise UsageError(f"--channel: {error}") from None
    except BrokenPipeError:  # `wiretape show big.wtape | head`
        silence_stdout()
        return EXIT_OK
    # show reports damage itself and shows everything before it.
    return EXIT_OK if damage is None else EXIT_CHECK_FAILED


def _show_textconv(args) -> int:
    """show --textconv: the text git's diff.textconv runs (tools/textconv)."""
    from ..tools.textconv import textconv

    if args.format == "jsonl" or args.profile or args.decode:
        raise UsageError("--textconv, --no-start and --no-times work with --format text or "
                         "hex, without --profile")
    chosen = [flag for flag, given in (("--kind", args.kind), ("--from", args.start_s is not None),
                                       ("--to", args.end_s is not None),
                                       ("--grep", args.grep is not None), ("--full", args.full),
                                       ("--channel", args.channel))
              if given]
    if chosen:
        raise UsageError(f"{chosen[0]} does not go with --textconv (which shows every record "
                         "and every byte)")
    try:
        textconv(args.file, fmt=args.format, start=not args.no_start, times=not args.no_times)
    except BrokenPipeError:
        silence_stdout()
    # A damaged file is a line of the text: git shows the diff all the same.
    return EXIT_OK


def _print_stats(stats, out: Output) -> None:
    rows = stats.text_rows()
    width = max([len("wiretape_version")] + [len(name) for name, _ in rows
                                             if not name.startswith("latency ")])
    for name, value in rows:
        out.print(f"{name:<{width}}  {value}", style="bold red" if name == "damaged" else None)


def cmd_stats(args, out: Output) -> int:
    from ..tools.stats import stats as session_stats

    require_session(args.file)
    result = session_stats(args.file, profile=session_profile(args.profile, [args.file], out))
    if args.json:
        import json  # for --json only: not on every command's start-up

        print(json.dumps(result.to_json(), indent=2, sort_keys=True, default=str))
    else:
        _print_stats(result, out)
    return EXIT_CHECK_FAILED if result.damaged else EXIT_OK


def cmd_verify(args, out: Output) -> int:
    from ..tools.verify import verify

    require_session(args.file)
    result = verify(args.file)
    if args.repair and result.ok and result.index in ("absent", "stale") \
            and result.unfinished is None:
        from ..tools.verify import repair_index

        appended = repair_index(args.file)
        result = verify(args.file)
        if not args.json:
            out.print(f"{args.file}: index {appended}")
    if args.json:
        import json  # for --json only: not on every command's start-up

        print(json.dumps(result.to_json(), indent=2, sort_keys=True, default=str))
    elif result.ok:
        out.print(f"{args.file}: ok, {result.records} records{_per_channel(result)}",
                  style="green")
        if result.unfinished is not None:
            # Not damage: a recorder is writing the file; its end is checked once it closed.
            out.print(f"{result.unfinished} (checked up to there; verify again once it "
                      f"is closed)")
        if result.index in ("absent", "stale"):
            # Not damage: a recorder that did not close its file leaves none.
            out.print(f"{args.file}: index {result.index} ({result.index_detail}): a reader of "
                      f"one channel reads every record; `wiretape verify --repair` appends it")
    elif result.unlisted_channel is not None:
        out.print(f"{args.file}: BAD {result.message}{_per_channel(result)}", style="bold red")
    else:
        out.print(f"{args.file}: DAMAGED at byte {result.offset} after "
                  f"{result.records} good records: {result.message}{_per_channel(result)}",
                  style="bold red")
    return EXIT_OK if result.ok else EXIT_CHECK_FAILED


def _per_channel(result) -> str:
    """`` (gps 4, rtk 6)``: the records of each channel of a session of several."""
    from ..session import header_text

    if not result.channel_records:
        return ""
    return " (" + ", ".join(f"{header_text(name)} {count}"
                            for name, count in result.channel_records.items()) + ")"


def cmd_convert(args, out: Output) -> int:
    from ..tools.convert import convert

    require_input(args.input)
    progress = sys.stderr.isatty() and not args.quiet
    result = convert(args.input, args.output, from_format=args.from_format,
                     to_format=args.to_format, progress=progress,
                     flexiport_format=args.flexiport_format,
                     stream=args.stream, device_addr=args.device_addr, test=args.test,
                     allow_gaps=args.allow_gaps, compress=args.compress)
    if not args.quiet:
        out.note(f"converted {result.records} records: {args.input} "
                 f"({result.from_format}) -> {args.output} ({result.to_format})")
    return EXIT_OK


def cmd_diff(args, out: Output) -> int:
    from ..tools.diff import diff

    require_session(args.a)
    require_session(args.b)
    result = diff(args.a, args.b, profile=session_profile(args.profile, [args.a, args.b], out),
                  max_divergences=args.max_divergences)
    if args.json:
        import json  # for --json only: not on every command's start-up

        print(json.dumps(result.to_json(), indent=2, sort_keys=True))
        return EXIT_OK if result.identical and not result.damaged else EXIT_CHECK_FAILED
    for line in result.report().splitlines():
        style = None
        if line == "sessions are identical":
            style = "green"
        elif line == "sessions differ" or "damaged" in line:
            style = "bold red"
        out.print(line, style=style)
    return EXIT_OK if result.identical and not result.damaged else EXIT_CHECK_FAILED


def cmd_edit(args, out: Output) -> int:
    from ..tools.edit import edit_in_child, parse_cut, parse_redaction

    require_input(args.input)
    cut = parse_cut(args.cut) if args.cut is not None else None
    redactions = [parse_redaction(spec) for spec in args.redact]
    profile = {None: "", "none": None}.get(args.profile, args.profile)
    # In a child process: a signal ends a catastrophic pattern's matching too.
    result = edit_in_child(args.input, args.output, cut=cut, redact=redactions,
                           drop_meta=args.drop_meta, profile=profile, channels=args.channel,
                           compress=args.compress)
    if not args.quiet:
        done = "; ".join(result.edits)
        matches = (f", {result.matches} matches redacted in {result.redacted_records} records"
                   if redactions else "")
        if redactions and result.profile is not None:
            matches += f", checksums recomputed in {result.resealed_frames} {result.profile} frames"
        elif redactions and result.matches:
            matches += " (no --profile: checksums over scrubbed bytes are left as they were)"
        out.note(f"edited {args.input} -> {args.output}: {result.records} records{matches} ({done})")
        if result.unsealed_frames:
            out.note(f"{result.unsealed_frames} {result.profile} frames keep part of their "
                     "recorded checksums: the records holding them were written before the "
                     "frame was complete (more than 8 MiB waited behind them)")
    return EXIT_OK


def cmd_view(args, out: Output) -> int:
    from ..tools.view import default_output, view

    require_input(args.file)
    if args.campaign is not None:
        require_input(args.campaign)
    if args.output == "":
        raise UsageError("-o needs a file name (FILE.html)")
    output = args.output if args.output is not None else default_output(args.file)
    default = "" if args.output is not None else " (the default: SESSION with .html; -o to choose)"
    try:
        view(args.file, output, profile=session_profile(args.profile, [args.file], out) or "none",
             campaign=args.campaign)
    except SessionError:  # the page shows what came before the damage
        if not args.quiet:
            out.note(f"wrote {output}{default}, up to the damage:")
        raise
    if not args.quiet:
        out.note(f"wrote {output}{default}: open it in a browser")
    return EXIT_OK
