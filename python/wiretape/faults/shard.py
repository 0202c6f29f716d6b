"""Shards of a campaign: ``--shard K/N`` as given, or ``--shard auto`` from
the variables a CI engine sets for its shards (DESIGN §28)."""

from __future__ import annotations

import dataclasses
from typing import List, Mapping, Optional, Tuple


class FaultInputError(ValueError):
    """Bad input to a campaign (exit 2): names the problem."""


@dataclasses.dataclass(frozen=True)
class Shard:
    """Shard ``number`` of ``count`` (``--shard K/N``, K from 1): the cases
    whose index is K-1 modulo N. Every shard makes its own clean run.
    ``engine`` names the CI engine whose variables gave it (``--shard
    auto``); it is not part of which cases the shard owns."""

    number: int
    count: int
    engine: Optional[str] = dataclasses.field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.count < 1 or not 1 <= self.number <= self.count:
            raise FaultInputError(f"--shard {self.number}/{self.count}: K must be from 1 to N "
                                  "(e.g. 1/3, 2/3, 3/3)")

    @classmethod
    def parse(cls, text: str, environ: Optional[Mapping[str, str]] = None,
              shards: Optional[int] = None) -> "Shard":
        """``K/N`` as the command line gives it, or ``auto``: the engine's
        variables in ``environ`` (os.environ when None), with ``shards``
        (``--shards N``) the total where the engine gives none."""
        if text.strip() == "auto":
            import os
            return from_engine(os.environ if environ is None else environ, shards)
        if shards is not None:
            raise FaultInputError(f"--shards {shards} goes with --shard auto (a Kubernetes "
                                  f"Indexed Job's total), not with --shard {text}")
        number, slash, count = text.strip().partition("/")
        if not slash or not number.strip().isdigit() or not count.strip().isdigit():
            raise FaultInputError(f"--shard {text!r}: give K/N, e.g. 2/3 for the second of "
                                  "three shards, or auto")
        return cls(int(number), int(count))

    def owns(self, index: int) -> bool:
        return index % self.count == self.number - 1

    def __str__(self) -> str:
        return f"{self.number}/{self.count}"


#: The engines `--shard auto` knows: (name, index variable, total variable
#: (None: from --shards), whether the index counts from 0).
ENGINES = (("bazel", "TEST_SHARD_INDEX", "TEST_TOTAL_SHARDS", True),
           ("kubernetes", "JOB_COMPLETION_INDEX", None, True),
           ("gitlab", "CI_NODE_INDEX", "CI_NODE_TOTAL", False))

#: Bazel's file a sharded test touches to say it shards.
BAZEL_STATUS_FILE = "TEST_SHARD_STATUS_FILE"


def _whole_number(environ: Mapping[str, str], name: str) -> int:
    text = environ[name]
    if not text.strip().isdigit():
        raise FaultInputError(f"--shard auto: {name}={text!r} is not a whole number")
    return int(text)


def _engine_shard(environ: Mapping[str, str], name: str, index_name: str,
                  total_name: Optional[str], from_zero: bool,
                  shards: Optional[int]) -> Shard:
    index = _whole_number(environ, index_name)
    if total_name is None:
        if shards is None:
            raise FaultInputError(f"--shard auto: {index_name} is set ({name}) but its total "
                                  "is not: give it with --shards N (the Job's completions)")
        total, total_text = shards, f"--shards {shards}"
    else:
        if total_name not in environ:
            raise FaultInputError(f"--shard auto: {index_name} is set ({name}) but "
                                  f"{total_name} is not")
        total = _whole_number(environ, total_name)
        total_text = f"{total_name}={total}"
        if shards is not None and shards != total:
            raise FaultInputError(f"--shard auto: --shards {shards} but {total_text}")
    number = index + 1 if from_zero else index
    first, last = (0, total - 1) if from_zero else (1, total)
    if total < 1 or not 1 <= number <= total:
        raise FaultInputError(f"--shard auto: {index_name}={index} is out of range for "
                              f"{total_text} (from {first} to {last})")
    return Shard(number, total, engine=name)


def from_engine(environ: Mapping[str, str], shards: Optional[int] = None) -> Shard:
    """The shard the CI engine's variables give (DESIGN §28): K is the index
    + 1 for Bazel and Kubernetes, ``CI_NODE_INDEX`` for GitLab. Engines whose
    variables disagree, none set, or a value out of range: FaultInputError.
    Under Bazel, touches ``TEST_SHARD_STATUS_FILE`` (Bazel's sign that the
    test shards)."""
    found: List[Tuple[str, Shard]] = []
    for name, index_name, total_name, from_zero in ENGINES:
        if index_name in environ:
            found.append((name, _engine_shard(environ, name, index_name, total_name,
                                              from_zero, shards)))
        elif total_name is not None and total_name in environ:
            raise FaultInputError(f"--shard auto: {total_name} is set ({name}) but "
                                  f"{index_name} is not")
    if not found:
        names = ", ".join(f"{index} and {total}" if total else f"{index} with --shards N"
                          for _, index, total, _ in ENGINES)
        raise FaultInputError("--shard auto: no CI engine's shard variables are set (looked "
                              f"for {names})")
    name, shard = found[0]
    for other_name, other in found[1:]:
        if (other.number, other.count) != (shard.number, shard.count):
            raise FaultInputError(f"--shard auto: {name} says shard {shard} but {other_name} "
                                  f"says {other}")
    if name == "bazel" and environ.get(BAZEL_STATUS_FILE):
        with open(environ[BAZEL_STATUS_FILE], "a", encoding="utf-8"):
            pass
    return shard
