"""The specs of ``wiretape edit``: what ``--cut`` keeps and what a
``--redact`` pattern scrubs (docs/cli.md "edit")."""

from __future__ import annotations

import dataclasses
import re
from typing import List, Optional

__all__ = ["Cut", "Redaction", "parse_cut", "parse_redaction"]


@dataclasses.dataclass(frozen=True)
class Cut:
    """The part of a session to keep: [start, end) in seconds, or in
    exchanges (numbered from 0, as in mismatch reports) when ``exchanges``."""

    start: Optional[float]
    end: Optional[float]
    exchanges: bool = False
    spec: str = ""  # as given, for messages

    def describe(self) -> str:
        def side(value: Optional[float]) -> str:
            return "" if value is None else f"{value:g}"
        unit = "exchanges" if self.exchanges else "s"
        return f"cut {side(self.start)}:{side(self.end)} {unit}"


@dataclasses.dataclass(frozen=True)
class Redaction:
    """A pattern over payload bytes and what its matches become."""

    pattern: "re.Pattern[bytes]"
    replacement: bytes = b"*"

    def scrub(self, length: int) -> bytes:
        if len(self.replacement) == 1:
            return self.replacement * length
        return (self.replacement * (length // len(self.replacement) + 1))[:length]


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--cut {where} {text!r} is not a number") from None
    if not value >= 0 or value == float("inf"):
        raise ValueError(f"--cut {where} {text!r} must be a finite number >= 0")
    return value


def parse_cut(spec: str) -> Cut:
    """``FROM:TO``: seconds (``1.5:4``, ``1.5s:4s``) or exchanges (``3e:7e``);
    either side may be empty (from the start, to the end)."""
    grammar = "expected FROM:TO in seconds (1.5:4) or exchanges (3e:7e), either side may be empty"
    if spec.count(":") != 1:
        raise ValueError(f"--cut {spec!r}: {grammar}")
    sides = [side.strip() for side in spec.split(":")]
    units = {side[-1] for side in sides if side and side[-1] in "se"}
    if len(units) > 1:
        raise ValueError(f"--cut {spec!r}: both sides must count the same (seconds or exchanges)")
    exchanges = units == {"e"}
    values: List[Optional[float]] = []
    for where, side in zip(("FROM", "TO"), sides):
        if side and side[-1] in "se":
            side = side[:-1]
        values.append(_number(side, where) if side else None)
    start, end = values
    if exchanges and any(v is not None and v != int(v) for v in values):
        raise ValueError(f"--cut {spec!r}: exchanges are whole numbers")
    if start is not None and end is not None and end <= start:
        raise ValueError(f"--cut {spec!r}: TO must be after FROM")
    if start is None and end is None:
        raise ValueError(f"--cut {spec!r}: {grammar}")
    return Cut(start, end, exchanges, spec)


#: The ``=`` between PATTERN and REPLACEMENT: not escaped, not a lookaround's.
_SEPARATOR = re.compile(r"(?<!\\)(?<!\(\?)(?<!\(\?<)(?<!\(\?P)=")


def parse_redaction(spec: str) -> Redaction:
    """``PATTERN[=REPLACEMENT]``: a regular expression (Python syntax) over
    the bytes; ``\\=`` is a literal ``=`` in the pattern, and so is the
    ``=`` of the regex syntax ``(?=``, ``(?<=`` and ``(?P=``."""
    split = _SEPARATOR.search(spec)
    pattern_text, replacement = (spec, "*") if split is None else (
        spec[:split.start()], spec[split.end():])
    if not pattern_text:
        raise ValueError(f"--redact {spec!r}: the pattern is empty")
    if not replacement:
        raise ValueError(f"--redact {spec!r}: the replacement is empty (leave out =... for *)")
    try:
        pattern = re.compile(pattern_text.encode("utf-8"))
    except re.error as error:
        raise ValueError(f"--redact {spec!r}: not a regular expression: {error}") from None
    if pattern.fullmatch(b"") is not None or pattern.search(b"") is not None:
        raise ValueError(f"--redact {spec!r}: the pattern matches the empty string")
    return Redaction(pattern, replacement.encode("utf-8"))
