"""``wiretape record --attach PID``: the session of a program that is already
running, recorded through ptrace without restarting it (DESIGN §26; the
work is the C++ core's wiretape.attach)."""

from __future__ import annotations

import argparse
import time

from .bridges import POLL_S, meta_pairs, plural
from .console import Output
from .errors import EXIT_OK, UsageError

# The record arguments that name a device or a client side: an attached
# program has its own.
_NOT_WITH_ATTACH = (("device", "--device"), ("pty", "--pty"), ("listen", "--listen"),
                    ("udp", "--udp"), ("peer", "--peer"), ("redirect_path", "--redirect-path"))


def _pid(text: str) -> int:
    try:
        pid = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a process id is a number, not {text!r}") from None
    if pid <= 0:
        raise argparse.ArgumentTypeError(f"a process id is positive, not {pid}")
    return pid


def add_attach_arguments(record: argparse.ArgumentParser) -> None:
    group = record.add_argument_group(
        "attaching to a running program (Linux x86_64; docs/recording.md)")
    group.add_argument("--attach", metavar="PID", type=_pid,
                       help="record the running program PID's session with its device "
                            "through ptrace, without restarting it; detached as it was at "
                            "Ctrl-C, SIGTERM, --duration or its exit")
    which = group.add_mutually_exclusive_group()
    which.add_argument("--path", metavar="DEV",
                       help="with --attach: the device it holds open, matched by device "
                            "number (default: its only tty or socket)")
    which.add_argument("--fd", metavar="N", type=int,
                       help="with --attach: its descriptor N (and the duplicates of it)")


def refuse_attach_options(args) -> None:
    """--path and --fd belong to --attach."""
    for name in ("path", "fd"):
        if getattr(args, name, None) is not None:
            raise UsageError(f"--{name} says which descriptor of an --attach PID to record: "
                             "give --attach too")


def _ended(summary) -> str:
    if summary.ended_by == "exited":
        status = summary.exit_status
        if status is not None and status & 0x7f == 0:
            return f"the program exited with status {status >> 8}"
        return "the program ended"
    if summary.ended_by == "execed":
        return "the program executed another program (not followed)"
    return "detached"


def cmd_record_attached(args, out: Output) -> int:
    import wiretape

    for name, flag in _NOT_WITH_ATTACH:
        if getattr(args, name, None):
            raise UsageError(f"{flag} cannot be given with --attach: the program's own "
                             "device is recorded (say which with --path or --fd)")
    if getattr(args, "command_argv", None) is not None:
        raise UsageError("-- CMD cannot be given with --attach: the program runs already")
    attachment = wiretape.attach(args.attach, args.output, path=args.path or "", fd=args.fd,
                                 meta=meta_pairs(args.meta))
    attached = attachment.header.attached or {}
    out.note(f"wiretape record: attached to process {args.attach} "
             f"({attached.get('command', '?')}), recording {attached.get('device', '?')} "
             f"to {args.output}")
    deadline = None if args.duration is None else time.monotonic() + args.duration
    try:
        while not attachment.wait(POLL_S):
            if deadline is not None and time.monotonic() >= deadline:
                break
    except KeyboardInterrupt:
        out.note("wiretape record: detaching")
    attachment.stop()
    summary = attachment.summary()
    for warning in summary.warnings:
        out.note(f"wiretape record: warning: {warning}")
    out.note(f"wiretape record: {_ended(summary)}: {plural(summary.records, 'record')} "
             f"written, {plural(summary.rx_bytes, 'byte')} read by the program, "
             f"{plural(summary.tx_bytes, 'byte')} written by it")
    return EXIT_OK
