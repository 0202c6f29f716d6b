"""A campaign's results: a run and a campaign, the table people read, the
``--json`` written and read back, and shards merged into one campaign."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import stat
import tempfile
from typing import Dict, List, Optional, Sequence

from .. import _core
from ..session import session_files
from .cases import OUTCOMES, FaultInputError, Shard


@dataclasses.dataclass
class Run:
    kind: str
    where: str
    outcome: str
    exit: Optional[int]
    seconds: float
    repro: str = ""
    output: str = ""
    #: The case's index among the campaign's cases (all shards).
    case: int = 0

    @property
    def spec(self) -> str:
        return f"{self.kind}@{self.where}"

    def as_json(self) -> Dict[str, object]:
        return {"case": self.case, "kind": self.kind, "where": self.where,
                "outcome": self.outcome, "exit": self.exit, "seconds": round(self.seconds, 3),
                "repro": self.repro}


@dataclasses.dataclass
class Campaign:
    session: str
    seed: int
    runs: List[Run]
    #: SIGINT or SIGTERM ended it early: ``runs`` are those that ended by
    #: themselves before (the run it stopped has no outcome).
    interrupted: bool = False
    #: How many cases were to run (in this shard).
    planned: int = 0
    #: What makes the cases: shards of one campaign agree on all of these
    #: (``merge`` checks it).
    kinds: Optional[List[str]] = None
    budget: Optional[int] = None
    options: str = ""
    session_sha256: str = ""
    #: The campaign's cases in all shards, and this one's shard (None: all).
    cases: int = 0
    shard: Optional[Shard] = None
    #: --speed: CMD's clock ran this many times faster than real time.
    speed: float = 1.0

    @property
    def summary(self) -> Dict[str, int]:
        counts = {outcome: 0 for outcome in OUTCOMES}
        for run in self.runs:
            counts[run.outcome] += 1
        return counts

    @property
    def failed(self) -> bool:
        summary = self.summary
        return summary["crash"] > 0 or summary["hang"] > 0

    def as_json(self) -> Dict[str, object]:
        return {"session": self.session, "session_sha256": self.session_sha256,
                "seed": self.seed, "kinds": self.kinds, "budget": self.budget,
                "options": self.options, "cases": self.cases,
                "shard": str(self.shard) if self.shard else None, "speed": self.speed,
                "runs": [run.as_json() for run in self.runs], "summary": self.summary,
                "interrupted": self.interrupted}



def session_digest(session: str) -> str:
    """SHA-256 of the session's bytes (every file of a flexiport pair): what
    tells shards run on other machines, under other paths, that they
    replayed the same recording."""
    digest = hashlib.sha256()
    for path in session_files(session):
        with open(path, "rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


_LETTERS = {"ok": ".", "error": "E", "crash": "C", "hang": "H"}


def table(result: Campaign) -> str:
    """A line per kind, a column per exchange: . ok, E error, C crash,
    H hang (blank: not run); then other places and the totals."""
    by_kind: Dict[str, Dict[int, str]] = {}
    others: List[Run] = []
    width = 0
    for run in result.runs:
        place = _core.parse_faults(run.spec)[0]
        if place.where == "exchange" and place.number is not None:
            exchange = place.number
            # a session of several ports: a line per channel and kind
            channel = place.channel
            row = f"{channel} {run.kind}" if channel else run.kind
            by_kind.setdefault(row, {})[exchange] = run.outcome
            width = max(width, exchange + 1)
        else:
            others.append(run)
    lines = []
    if by_kind:
        channelled = any(_core.parse_faults(run.spec)[0].channel for run in result.runs)
        corner = "channel kind \\ exchange" if channelled else "kind \\ exchange"
        name_width = max(len(corner), *(len(kind) for kind in by_kind))
        header = "".join(str(n % 10) for n in range(width))
        lines.append(f"{corner:<{name_width}}  {header}")
        for kind, outcomes in by_kind.items():
            cells = "".join(_LETTERS[outcomes[n]] if n in outcomes else " " for n in range(width))
            counts = {outcome: list(outcomes.values()).count(outcome) for outcome in OUTCOMES}
            figures = " ".join(f"{outcome} {count}" for outcome, count in counts.items() if count)
            lines.append(f"{kind:<{name_width}}  {cells}  {figures}")
    for run in others:
        lines.append(f"{run.kind}@{run.where}: {run.outcome}")
    summary = result.summary
    blank = any(n not in outcomes for outcomes in by_kind.values() for n in range(width))
    lines.append(f"{len(result.runs)} runs: " + ", ".join(f"{summary[o]} {o}" for o in OUTCOMES)
                 + "  (. ok  E error  C crash  H hang" + (f"  blank: {_not_run(result)}"
                                                          if blank else "") + ")")
    return "\n".join(lines)


def _not_run(result: Campaign) -> str:
    """Why a cell of the table is blank: the case was not run, because..."""
    reasons = []
    if result.interrupted:
        reasons.append("the campaign was interrupted")
    if result.shard is not None:
        reasons.append(f"another shard's (this is {result.shard})")
    if result.budget is not None and result.budget < result.cases:
        reasons.append(f"left out by --budget {result.budget} (sampled by --seed {result.seed})")
    return "not run: " + ("; or ".join(reasons) if reasons else "no such fault there")


def write_json(result: Campaign, path: str) -> None:
    """Writes the campaign's JSON whole or not at all (a file beside it,
    renamed over `path`); to a FIFO, a device or /dev/stdout, directly."""
    try:
        special = not stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        special = False
    if special:
        with open(path, "w", encoding="utf-8") as output:
            json.dump(result.as_json(), output, indent=1)
            output.write("\n")
        return
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(prefix=".wiretape-faults-", suffix=".json",
                                         dir=folder)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as output:
            json.dump(result.as_json(), output, indent=1)
            output.write("\n")
        umask = os.umask(0o022)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)  # as open() would have made it
        os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise


# --------------------------------------------------------------------------
# shards of one campaign, merged


def _member(document: Dict[str, object], name: str, types, where: str):
    if name not in document:
        raise FaultInputError(f"{where}: no {name!r}: not the --json of a wiretape faults run "
                              "with --shard (run it again with this wiretape)")
    value = document[name]
    allowed = types if isinstance(types, tuple) else (types,)
    # A JSON true is a Python bool, which is an int too: not a count.
    if not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed):
        raise FaultInputError(f"{where}: {name!r} is {json.dumps(value)[:60]}: not what a "
                              "campaign writes")
    return value


def read_json(path: str) -> Campaign:
    """A campaign's ``--json`` file read back (for ``merge``); FaultInputError
    names the file and what is wrong in it."""
    try:
        with open(path, encoding="utf-8") as stream:
            document = json.load(stream)
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise FaultInputError(f"{path}: not a campaign's JSON: {error}") from None
    if not isinstance(document, dict):
        raise FaultInputError(f"{path}: not a campaign's JSON: not an object")
    shard_text = _member(document, "shard", (str, type(None)), path)
    kinds = _member(document, "kinds", (list, type(None)), path)
    if kinds is not None and not all(isinstance(kind, str) for kind in kinds):
        raise FaultInputError(f"{path}: 'kinds' holds something that is not a kind")
    runs = []
    for number, item in enumerate(_member(document, "runs", list, path)):
        where = f"{path}: runs[{number}]"
        if not isinstance(item, dict):
            raise FaultInputError(f"{where}: not an object")
        outcome = _member(item, "outcome", str, where)
        if outcome not in OUTCOMES:
            raise FaultInputError(f"{where}: outcome {outcome!r} is not one of "
                                  + ", ".join(OUTCOMES))
        runs.append(Run(_member(item, "kind", str, where), _member(item, "where", str, where),
                        outcome, _member(item, "exit", (int, type(None)), where),
                        float(_member(item, "seconds", (int, float), where)),
                        repro=_member(item, "repro", str, where),
                        case=_member(item, "case", int, where)))
    try:
        shard = Shard.parse(shard_text) if shard_text is not None else None
    except FaultInputError as error:
        raise FaultInputError(f"{path}: {error}") from None
    return Campaign(_member(document, "session", str, path), _member(document, "seed", int, path),
                    runs, interrupted=_member(document, "interrupted", bool, path),
                    kinds=kinds, budget=_member(document, "budget", (int, type(None)), path),
                    options=_member(document, "options", str, path),
                    session_sha256=_member(document, "session_sha256", str, path),
                    cases=_member(document, "cases", int, path), shard=shard,
                    planned=len(runs), speed=_speed_member(document, path))


def _speed_member(document: Dict[str, object], path: str) -> float:
    """``speed`` (written since --speed: 1 when absent)."""
    value = document.get("speed", 1.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value > 0):
        raise FaultInputError(f"{path}: 'speed' is {json.dumps(value)[:60]}: not what a "
                              "campaign writes")
    return float(value)


# What shards of one campaign agree on, and the flag that sets each.
_CAMPAIGN_IDENTITY = (("session_sha256", "SESSION (its bytes differ)"), ("seed", "--seed"),
                      ("kinds", "--kinds"), ("budget", "--budget"), ("options", "--options"),
                      ("speed", "--speed"), ("cases", "the cases (a different wiretape?)"))


def merge(paths: Sequence[str]) -> Campaign:
    """One campaign from the ``--json`` of its shards (``--shard K/N``, every
    K once): the runs in the cases' order, as one unsharded run gives them.
    Refuses (FaultInputError) files of different sessions, seeds, kinds,
    budgets or replay keys, a shard missing or given twice, and an
    interrupted shard."""
    if not paths:
        raise FaultInputError("give the --json files of every shard")
    shards = [(path, read_json(path)) for path in paths]
    first_path, first = shards[0]
    by_number: Dict[int, str] = {}
    for path, part in shards:
        if part.shard is None:
            raise FaultInputError(f"{path}: a whole campaign (run without --shard): nothing to "
                                  "merge")
        if part.interrupted:
            raise FaultInputError(f"{path}: shard {part.shard} was interrupted after "
                                  f"{len(part.runs)} runs: run it again")
        for member, flag in _CAMPAIGN_IDENTITY:
            if getattr(part, member) != getattr(first, member):
                raise FaultInputError(
                    f"{path}: {member} {json.dumps(getattr(part, member))} but {first_path}: "
                    f"{json.dumps(getattr(first, member))}: shards of one campaign share {flag}")
        if part.shard.count != first.shard.count:
            raise FaultInputError(f"{path}: --shard {part.shard} but {first_path}: --shard "
                                  f"{first.shard}: shards of one campaign share N")
        if part.shard.number in by_number:
            raise FaultInputError(f"{path}: shard {part.shard} is also {by_number[part.shard.number]}")
        by_number[part.shard.number] = path
        expected = [index for index in range(part.cases) if part.shard.owns(index)]
        if sorted(run.case for run in part.runs) != expected:
            raise FaultInputError(f"{path}: its runs are not the cases of shard {part.shard} "
                                  f"({len(part.runs)} runs, {len(expected)} cases)")
    missing = [f"{number}/{first.shard.count}" for number in range(1, first.shard.count + 1)
               if number not in by_number]
    if missing:
        raise FaultInputError("missing shard " + ", ".join(missing) + " of the campaign")
    runs = sorted((run for _, part in shards for run in part.runs), key=lambda run: run.case)
    return dataclasses.replace(first, runs=runs, planned=first.cases, shard=None)
