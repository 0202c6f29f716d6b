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
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from .. import _core
from ..session import header_text, session_files
from .cases import (KIND_NAMES, KINDS, OUTCOMES, FaultInputError, Shard, _kind_spec,
                    all_cases, check_where)
from .shard import ENGINES

ENGINE_NAMES = tuple(engine[0] for engine in ENGINES)


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
                "shard": str(self.shard) if self.shard else None,
                "shard_from": self.shard.engine if self.shard else None, "speed": self.speed,
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
    """Writes the campaign's JSON whole or not at all (write_whole)."""
    def dump(output) -> None:
        json.dump(result.as_json(), output, indent=1, allow_nan=False)
        output.write("\n")
    write_whole(path, dump, suffix=".json")


def write_whole(path: str, write: Callable[[object], None], suffix: str) -> None:
    """Writes a report whole or not at all: `write(stream)` into a file
    beside `path`, renamed over it; to a FIFO, a device or /dev/stdout,
    directly."""
    try:
        special = not stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        special = False
    if special:
        with open(path, "w", encoding="utf-8") as output:
            write(output)
        return
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(prefix=".wiretape-faults-", suffix=suffix, dir=folder)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as output:
            write(output)
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


def _shown(value: object) -> str:
    """A value of a file anyone may have written, as a message shows it: its
    JSON (control characters escaped), cut to 60 characters, and safe on a
    terminal (header_text)."""
    text = json.dumps(value)
    return header_text(text if len(text) <= 60 else text[:57] + "...")


def _member(document: Dict[str, object], name: str, types, where: str):
    if name not in document:
        raise FaultInputError(f"{where}: no {name!r}: not the --json of a wiretape faults run "
                              "with --shard (run it again with this wiretape)")
    value = document[name]
    allowed = types if isinstance(types, tuple) else (types,)
    # A JSON true is a Python bool, which is an int too: not a count.
    if not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed):
        raise FaultInputError(f"{where}: {name!r} is {_shown(value)}: not what a "
                              "campaign writes")
    return value


def _refused(where: str, name: str, value: object, why: str) -> FaultInputError:
    return FaultInputError(f"{where}: {name!r} is {_shown(value)}: {why}")


def _count_member(document: Dict[str, object], name: str, where: str, least: int,
                  optional: bool = False) -> Optional[int]:
    """A whole number of at least `least` (or null when `optional`)."""
    value = _member(document, name, (int, type(None)) if optional else int, where)
    if value is not None and value < least:
        raise _refused(where, name, value, f"a campaign writes {least} or more")
    return value


def _kind_member(item: Dict[str, object], where: str) -> str:
    kind = _member(item, "kind", str, where)
    try:
        if _core.normal_fault_kind(kind) == kind:
            return kind
    except _core.OptionError:
        pass
    raise _refused(where, "kind", kind, "not a fault kind as a campaign writes it "
                   "(" + ", ".join(KINDS) + ")")


def _where_member(item: Dict[str, object], kind: str, where: str) -> str:
    place = _member(item, "where", str, where)
    try:
        parsed = _core.parse_faults(f"{kind}@{place}")
        if len(parsed) == 1 and parsed[0].where_text == place:
            return place
    except _core.OptionError:
        pass
    raise _refused(where, "where", place, "not a place as a campaign writes it "
                   "(exchange:N, rx:N, t:SECONDS, every:K or p:P, @channel:NAME)")


# What a run's outcome says of CMD's exit status (run.py sorts them so): a
# hang has none, ok is 0, an error a status of its own; a crash is a signal
# (minus its number) or a sanitizer's report, whatever the status.
_EXITS = {"ok": "0", "error": "a status from 1 to 255", "crash": "a status or minus a signal",
          "hang": "null (CMD was ended)"}
_LOWEST_EXIT = -64  # minus the highest signal number (SIGRTMAX)


def _exit_fits(outcome: str, status: Optional[int]) -> bool:
    if outcome == "hang":
        return status is None
    if status is None or not _LOWEST_EXIT <= status <= 255:
        return False
    return {"ok": status == 0, "error": status > 0}.get(outcome, True)


def _run_member(item: object, where: str) -> Run:
    if not isinstance(item, dict):
        raise FaultInputError(f"{where}: not an object")
    outcome = _member(item, "outcome", str, where)
    if outcome not in OUTCOMES:
        raise _refused(where, "outcome", outcome, "not one of " + ", ".join(OUTCOMES))
    status = _member(item, "exit", (int, type(None)), where)
    if not _exit_fits(outcome, status):
        raise _refused(where, "exit", status, f"a run whose outcome is {outcome} exited with "
                       + _EXITS[outcome])
    seconds = _member(item, "seconds", (int, float), where)
    if not (math.isfinite(seconds) and seconds >= 0):
        raise _refused(where, "seconds", seconds, "a run lasts a finite time, 0 or more")
    repro = _member(item, "repro", str, where)
    if not repro.isprintable():  # merge prints it as it is, for a shell
        raise _refused(where, "repro", repro, "a reproduction line is one line of printable "
                       "text")
    kind = _kind_member(item, where)
    return Run(kind, _where_member(item, kind, where), outcome, status, float(seconds),
               repro=repro, case=_count_member(item, "case", where, 0))


def _is_kinds_item(text: object) -> bool:
    """An item of --kinds: a kind (delay, corrupt:4) or a fault at a place
    (drop@rx:100), as the replay's parser reads them."""
    if not isinstance(text, str):
        return False
    try:
        if "@" in text:
            _core.parse_faults(text)
        elif text not in KIND_NAMES:
            _core.normal_fault_kind(text)
    except _core.OptionError:
        return False
    return True


def _kinds_member(document: Dict[str, object], path: str) -> Optional[List[str]]:
    """``kinds``: null (all), or --kinds's items."""
    kinds = _member(document, "kinds", (list, type(None)), path)
    for number, text in enumerate(kinds or []):
        if not _is_kinds_item(text):
            raise _refused(path, f"kinds[{number}]", text, "not a fault kind (KIND or "
                           "KIND@WHERE, as --kinds takes them)")
    return kinds


def read_json(path: str) -> Campaign:
    """A campaign's ``--json`` file read back (for ``merge``); FaultInputError
    names the file, the member and what is wrong with it, every value
    escaped for a terminal."""
    shown_path = header_text(path)
    try:
        with open(path, encoding="utf-8") as stream:
            document = json.load(stream)  # NaN and Infinity: refused where they stand
    except RecursionError:
        raise FaultInputError(f"{shown_path}: not a campaign's JSON: nested too deeply (a "
                              "campaign's JSON nests 3 levels)") from None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise FaultInputError(f"{shown_path}: not a campaign's JSON: "
                              f"{header_text(str(error))}") from None
    if not isinstance(document, dict):
        raise FaultInputError(f"{shown_path}: not a campaign's JSON: not an object")
    shard_text = _member(document, "shard", (str, type(None)), shown_path)
    kinds = _kinds_member(document, shown_path)
    runs = [_run_member(item, f"{shown_path}: runs[{number}]")
            for number, item in enumerate(_member(document, "runs", list, shown_path))]
    # written since --shard auto: absent in older files
    shard_from = document.get("shard_from")
    if shard_from is not None and (shard_text is None or shard_from not in ENGINE_NAMES):
        raise _refused(shown_path, "shard_from", shard_from,
                       "not a CI engine --shard auto knows (" + ", ".join(ENGINE_NAMES) + ")")
    try:
        shard = Shard.parse(shard_text) if shard_text is not None else None
    except FaultInputError as error:
        raise FaultInputError(f"{shown_path}: {header_text(str(error))}") from None
    if shard is not None:
        shard = dataclasses.replace(shard, engine=shard_from)
    options = _member(document, "options", str, shown_path)
    try:
        _core.check_replay_options(_core.option_string(
            [("type", "replay"), ("file", "x")] + _core.parse_options(options)))
    except _core.OptionError as error:
        raise _refused(shown_path, "options", options,
                       f"not replay keys ({header_text(str(error))})") from None
    cases = _count_member(document, "cases", shown_path, 1)
    for number, run in enumerate(runs):
        if run.case >= cases:
            raise _refused(f"{shown_path}: runs[{number}]", "case", run.case,
                           f"past the campaign's {cases} cases")
    return Campaign(_member(document, "session", str, shown_path),
                    _count_member(document, "seed", shown_path, 0),
                    runs, interrupted=_member(document, "interrupted", bool, shown_path),
                    kinds=kinds, budget=_count_member(document, "budget", shown_path, 1,
                                                      optional=True),
                    options=options, session_sha256=_member(document, "session_sha256", str, shown_path),
                    cases=cases, shard=shard,
                    planned=len(runs), speed=_speed_member(document, shown_path))


def _speed_member(document: Dict[str, object], path: str) -> float:
    """``speed`` (written since --speed: 1 when absent)."""
    value = document.get("speed", 1.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value > 0):
        raise FaultInputError(f"{path}: 'speed' is {_shown(value)}: not what a "
                              "campaign writes")
    return float(value)


# What shards of one campaign agree on, and the flag that sets each.
_CAMPAIGN_IDENTITY = (("session_sha256", "SESSION (its bytes differ)"), ("seed", "--seed"),
                      ("kinds", "--kinds"), ("budget", "--budget"), ("options", "--options"),
                      ("speed", "--speed"), ("cases", "the cases (a different wiretape?)"))


def merge(paths: Sequence[str], note: Optional[Callable[[str], None]] = None) -> Campaign:
    """One campaign from the ``--json`` of its shards (``--shard K/N``, every
    K once): the runs in the cases' order, as one unsharded run gives them.
    Refuses (FaultInputError) files of different sessions, seeds, kinds,
    budgets or replay keys, a shard missing or given twice, an interrupted
    shard, a case run twice, a kind the campaign does not inject and, when
    the session is here (the path a shard names, from the current folder or
    the shard's own; the same bytes), a run that is not the case of its
    index: a place past the session's end among them. `note` hears that the
    session is not here, so the places went unchecked."""
    if not paths:
        raise FaultInputError("give the --json files of every shard")
    shards = [(path, read_json(path)) for path in paths]
    first_path, first = shards[0]
    by_number: Dict[int, str] = {}
    for path, part in shards:
        shown = header_text(path)
        if part.shard is None:
            raise FaultInputError(f"{shown}: a whole campaign (run without --shard): nothing to "
                                  "merge")
        if part.interrupted:
            raise FaultInputError(f"{shown}: shard {part.shard} was interrupted after "
                                  f"{len(part.runs)} runs: run it again")
        for member, flag in _CAMPAIGN_IDENTITY:
            if getattr(part, member) != getattr(first, member):
                raise FaultInputError(
                    f"{shown}: {member} {_shown(getattr(part, member))} but "
                    f"{header_text(first_path)}: {_shown(getattr(first, member))}: shards of "
                    f"one campaign share {flag}")
        if part.shard.count != first.shard.count:
            raise FaultInputError(f"{shown}: --shard {part.shard} but {header_text(first_path)}: "
                                  f"--shard {first.shard}: shards of one campaign share N")
        if part.shard.number in by_number:
            raise FaultInputError(f"{shown}: shard {part.shard} is also "
                                  f"{header_text(by_number[part.shard.number])}")
        by_number[part.shard.number] = path
        expected = [index for index in range(part.cases) if part.shard.owns(index)]
        if sorted(run.case for run in part.runs) != expected:
            raise FaultInputError(f"{shown}: its runs are not the cases of shard {part.shard} "
                                  f"({len(part.runs)} runs, {len(expected)} cases)")
    missing = [f"{number}/{first.shard.count}" for number in range(1, first.shard.count + 1)
               if number not in by_number]
    if missing:
        raise FaultInputError("missing shard " + ", ".join(missing) + " of the campaign")
    _check_runs(shards, note)
    runs = sorted((run for _, part in shards for run in part.runs), key=lambda run: run.case)
    return dataclasses.replace(first, runs=runs, planned=first.cases, shard=None)


def _campaign_kinds(campaign: Campaign) -> List[str]:
    """The kinds a campaign injects, as its runs name them (delay:500)."""
    kinds = []
    for text in campaign.kinds or KIND_NAMES:
        if "@" in text:
            kinds += [fault.kind_text for fault in _core.parse_faults(text)]
        else:
            kinds.append(_kind_spec(text))
    return kinds


def _check_runs(shards: Sequence[Tuple[str, Campaign]],
                note: Optional[Callable[[str], None]]) -> None:
    """Each run once, of a kind its campaign injects, and the case of its
    index (when the session is here)."""
    first_path, first = shards[0]
    kinds = _campaign_kinds(first)
    session, cases = _session_cases(first_path, first)
    if cases is None and note is not None:
        note(f"{header_text(first.session)} is not here (or not the session the shards ran): "
             "the runs' places are not checked against it")
    seen: Dict[str, str] = {}
    for path, part in shards:
        for number, run in enumerate(part.runs):
            here = f"{header_text(path)}: runs[{number}]"
            if run.kind not in kinds:
                raise _refused(here, "kind", run.kind, "not a kind of the campaign ("
                               + ", ".join(kinds) + ")")
            if run.spec in seen:
                raise _refused(here, "where", run.where, f"{_shown(run.spec)} is run twice "
                               f"(also {seen[run.spec]})")
            seen[run.spec] = here
            if cases is None:
                continue
            case = cases[run.case]
            if (case.kind, case.where) != (run.kind, run.where):
                try:  # the replay's own words for a place past the session's end
                    check_where(session, run.spec, options=first.options)
                except FaultInputError as error:
                    raise _refused(here, "where", run.where, header_text(str(error))) from None
                raise _refused(here, "where", run.where,
                               f"case {run.case} of the campaign over "
                               f"{header_text(session)} is {_shown(case.spec)}, "
                               f"not {_shown(run.spec)}")


def _session_cases(json_path: str, campaign: Campaign) -> Tuple[str, Optional[list]]:
    """(where the campaign's session is, its cases made again from it); the
    cases None when the session is not here."""
    candidates = [campaign.session]
    if not os.path.isabs(campaign.session):
        candidates.append(os.path.join(os.path.dirname(json_path), campaign.session))
    for candidate in candidates:
        try:
            if session_digest(candidate) != campaign.session_sha256:
                continue
        except (OSError, ValueError):
            continue
        everything = all_cases(candidate, campaign.kinds, campaign.budget, campaign.seed,
                               None, None, campaign.options)
        if len(everything) != campaign.cases:
            raise _refused(header_text(json_path), "cases", campaign.cases,
                           f"the campaign over {header_text(candidate)} has {len(everything)}")
        return candidate, everything
    return campaign.session, None
