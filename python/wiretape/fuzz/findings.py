"""What a fuzzing run found (DESIGN §27): a run's verdict (crash, hang, or a
non-zero exit on an inert plan), its signature for deduplication, and the
findings directory (``DIR/index.json`` and the sessions beside it)."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import signal as signals
from typing import Dict, List, Optional

from ..children import sanitizer_report
from ..faults.cases import FaultInputError
from ..faults.report import Run, write_whole

INDEX = "index.json"

# A sanitizer's one-line summary ("SUMMARY: AddressSanitizer: heap-buffer-
# overflow scip.cpp:120 in f"): the same cause gives the same line.
_SUMMARY = re.compile(r"SUMMARY: \w+Sanitizer: .*")
# The first frame of a stack trace that names a function ("#0 0x... in f").
_FRAME = re.compile(r"#\d+ 0x[0-9a-f]+ in (\S+)")
# A whole frame line, for the finding's stack.
_FRAME_LINE = re.compile(r"^\s*(#\d+ 0x[0-9a-f]+ in .*)$", re.MULTILINE)
#: Frames of a finding's stack kept in index.json.
STACK_FRAMES = 16
# What differs between two runs of one cause in the last line CMD wrote:
# addresses, then any other number, its sign with it (pids, sizes, counts,
# byte values).
_ADDRESS = re.compile(r"0x[0-9a-fA-F]+")
_NUMBER = re.compile(r"-?\d+")
#: Characters of CMD's last line kept in a signature.
LAST_LINE_CHARS = 160


class PlanFileError(FaultInputError):
    """A --plan file that is not a plan (exit 2)."""


def finding_kind(run: Run, inert: bool) -> Optional[str]:
    """The kind of finding `run` is: crash or hang; error (a non-zero exit)
    only for an inert plan, since rejecting a malformed answer is a
    driver's right answer. None: not a finding."""
    if run.outcome in ("crash", "hang"):
        return run.outcome
    if run.outcome == "error" and inert:
        return "error"
    return None


def run_signal(run: Run) -> Optional[int]:
    """The signal that ended CMD, if one did."""
    return -run.exit if run.exit is not None and run.exit < 0 else None


def last_line(output: str) -> str:
    """The last line CMD wrote, normalised so that one cause gives one text:
    addresses become ``ADDR``, other numbers ``N``, spaces one space."""
    lines = [line for line in output.splitlines() if line.strip()]
    if not lines:
        return ""
    text = _NUMBER.sub("N", _ADDRESS.sub("ADDR", lines[-1]))
    return " ".join(text.split())[:LAST_LINE_CHARS]


def signature(kind: str, run: Run) -> str:
    """What two findings of one cause share: a sanitizer's summary line and
    the first named frames of its stack, else the signal and the first
    named frames CMD printed, else (no stack printed: every abort would be
    one finding) the signal and CMD's last line normalised, else the kind
    and exit status."""
    output = run.output or ""
    frames = _FRAME.findall(output)[:3]
    summary = _SUMMARY.search(output)
    if summary:
        return " | ".join([summary.group(0).strip()] + frames)
    report = sanitizer_report(output)
    if report:
        return " | ".join([report] + frames)
    number = run_signal(run)
    if number is not None:
        name = signals.Signals(number).name if number in signals.valid_signals() else str(number)
        said = [] if frames else [last_line(output)]
        return " | ".join([f"signal {name}"] + frames + [line for line in said if line])
    if kind == "hang":
        return "hang"
    return f"exit {run.exit}"


def stack(run: Run) -> List[str]:
    """The (symbolized, where CMD's sanitizer did so) frames of the first
    stack trace CMD printed."""
    frames: List[str] = []
    for line in _FRAME_LINE.findall(run.output or ""):
        if frames and line.startswith("#0 "):
            break  # the next trace (where the memory was allocated, freed...)
        frames.append(line.strip())
    return frames[:STACK_FRAMES]


# gdb's word that CMD stopped on a signal, and a frame of its `bt` after it
# ("#1  0x000055d4 in decode (line=...) at scip.cpp:120", frame 0 often
# without its address).
_DEBUGGER_STOPPED = "Program received signal "
_DEBUGGER_FRAME = re.compile(r"^#\d+\s+\S.*$", re.MULTILINE)


def debugger_command(argv: List[str]) -> List[str]:
    """CMD run under gdb in batch mode: run to the signal, print the
    backtrace, end (gdb kills CMD when it exits)."""
    return ["gdb", "-q", "-nx", "-batch", "-ex", "set startup-with-shell off",
            "-ex", "run", "-ex", "bt", "--args", *argv]


def debugger_stack(output: str) -> List[str]:
    """The frames of gdb's backtrace in `output` (debugger_command's run),
    after CMD stopped on a signal; none when it did not."""
    at = output.rfind(_DEBUGGER_STOPPED)
    if at < 0:
        return []
    frames = [" ".join(line.split()) for line in _DEBUGGER_FRAME.findall(output[at:])]
    return frames[:STACK_FRAMES]


@dataclasses.dataclass
class Finding:
    kind: str
    signal: Optional[int]
    signature: str
    session: str  # relative to the findings directory
    changed: List[str]
    repro: str
    plan: str  # hex, the plan that the session holds the result of
    stack: List[str] = dataclasses.field(default_factory=list)

    def as_json(self) -> Dict[str, object]:
        return dataclasses.asdict(self)


def plan_from_text(text: str, where: str) -> bytes:
    """A plan written as hex (``wiretape fuzz --plan FILE``, index.json's
    ``plan``): whitespace between the digits is allowed."""
    digits = "".join(text.split())
    bad = next((i for i, c in enumerate(digits) if c not in "0123456789abcdefABCDEF"), None)
    if bad is not None:
        raise PlanFileError(f"{where}: not a plan: a plan file holds the plan's bytes in hex "
                            f"(e.g. 01011e05), and this has {digits[bad:bad + 8]!r} at hex "
                            f"digit {bad}")
    if len(digits) % 2:
        raise PlanFileError(f"{where}: not a plan: an odd number of hex digits ({len(digits)}); "
                            "each byte of a plan is two")
    return bytes.fromhex(digits)


def read_plan_file(path: str) -> bytes:
    try:
        with open(path, "rb") as handle:
            raw = handle.read()
    except OSError as error:
        raise PlanFileError(f"--plan {path}: {error.strerror}") from None
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        raise PlanFileError(f"--plan {path}: not a plan: a plan file holds the plan's bytes "
                            "in hex (e.g. 01011e05), and this is not text") from None
    return plan_from_text(text, f"--plan {path}")


def write_index(directory: str, findings: List[Finding]) -> str:
    path = os.path.join(directory, INDEX)

    def write(output) -> None:
        json.dump({"findings": [finding.as_json() for finding in findings]}, output, indent=1,
                  ensure_ascii=False)
        output.write("\n")
    write_whole(path, write, suffix=".json")
    return path


def read_index(directory: str) -> List[Finding]:
    path = os.path.join(directory, INDEX)
    try:
        with open(path, encoding="utf-8") as handle:
            document = json.load(handle)
        return [Finding(**entry) for entry in document["findings"]]
    except OSError as error:
        raise FaultInputError(f"--replay {directory}: no findings there ({path}: "
                              f"{error.strerror})") from None
    except (ValueError, KeyError, TypeError) as error:
        raise FaultInputError(f"--replay {directory}: {path} is not a findings index: "
                              f"{error}") from None
