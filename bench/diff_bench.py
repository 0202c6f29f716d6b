#!/usr/bin/env python3
"""`wiretape diff` of two long sessions (bench/run.py, group "diff"):
prints one JSON line. Usage: diff_bench.py WORKDIR

Two sessions of EXCHANGES sensor exchanges (a 13-byte request answered by
a 100-byte reply): B is A with a three-exchange handshake before it and one
reply changed every 10,000 exchanges. A third, C, answers every request
otherwise: nothing aligns, the worst case, which the alignment bounds (it
gives up past MAX_EDITS differences and pairs the rest by position).
- anchor_s: diff before issue 38: the first difference per direction,
  then exchange N against exchange N, every divergence counted (kept here
  as it was, over the same exchanges, _core.session_exchanges);
- aligned_s: diff() now, the exchanges aligned, of A and B;
- worst_s: diff() of A and C.
Times are CPU seconds of this process. The figure is aligned_s /
anchor_s: what the alignment costs over the comparison by position, on the
same machine in the same run.
"""

import json
import sys
import time
from pathlib import Path

from wiretape import _core
from wiretape.tools.diff import _compare, _Records, diff  # the anchor's first part, unchanged
from wiretape.tools.diff_exchanges import ExchangeParts

EXCHANGES = 100_000
REQUEST = b"GD0044072501\n"


def reply(n: int, changed: bool = False, other: bool = False) -> bytes:
    body = (b"X" if other else b"0") + (b"1" if changed else b"0") + b"%06d" % n
    return REQUEST + b"00P\n" + body * 10 + b"\n\n"


def write(path: Path, handshake: bool, changed_every: int = 0, other: bool = False) -> Path:
    if path.exists():
        return path
    with _core.SessionWriter(str(path), port_type="serial",
                             port_options="type=serial,device=/dev/ttyX") as writer:
        t = 0
        if handshake:
            for word in (b"VV\n", b"PP\n", b"II\n"):
                writer.write("tx", t, word)
                writer.write("rx", t + 500_000, word + b"00P\nready\n\n")
                t += 1_000_000
        for n in range(EXCHANGES):
            changed = bool(changed_every) and n % changed_every == changed_every // 2
            writer.write("tx", t, REQUEST)
            writer.write("rx", t + 500_000, reply(n, changed, other))
            t += 1_000_000
    return path


def anchor(path_a: str, path_b: str) -> int:
    """diff before issue 38: the first difference of each direction (as
    diff() still finds it), then exchange N of A against N of B."""
    records_a, records_b = _Records(path_a), _Records(path_b)
    for direction in ("rx", "tx"):
        _compare(records_a, records_b, direction)
    total = 0
    exchanges_a, exchanges_b = iter(ExchangeParts(path_a, None)), iter(ExchangeParts(path_b, None))
    while True:
        part_a, part_b = next(exchanges_a, None), next(exchanges_b, None)
        if part_a is None and part_b is None:
            return total
        for slot in (0, 1):
            pieces_a = part_a[slot] if part_a is not None else None
            pieces_b = part_b[slot] if part_b is not None else None
            if (pieces_a or pieces_b) and pieces_a != pieces_b:
                total += 1


def timed(work):
    """CPU seconds of `work` (this process, every thread): on a shared
    machine, wall time would measure the other processes too."""
    started = time.process_time()
    result = work()
    return time.process_time() - started, result


def main() -> int:
    work = Path(sys.argv[1])
    work.mkdir(parents=True, exist_ok=True)
    a = str(write(work / "diff-a.wtape", handshake=False))
    b = str(write(work / "diff-b.wtape", handshake=True, changed_every=10_000))
    c = str(write(work / "diff-c.wtape", handshake=False, other=True))
    anchor_s, positional = timed(lambda: anchor(a, b))
    aligned_s, aligned = timed(lambda: diff(a, b))
    worst_s, worst = timed(lambda: diff(a, c))
    print(json.dumps({
        "exchanges": EXCHANGES, "anchor_s": round(anchor_s, 3), "aligned_s": round(aligned_s, 3),
        "worst_s": round(worst_s, 3), "anchor_divergences": positional,
        "aligned_divergences": aligned.divergence_count,
        "aligned_summary": aligned.alignments[0].summary(),
        "worst_summary": worst.alignments[0].summary()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
