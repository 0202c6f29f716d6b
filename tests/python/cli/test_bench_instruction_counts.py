"""The instruction figures of `make bench` (bench/instruction_counts.py)
come from callgrind's output files; the parser is held to a captured one."""

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "bench"))

import instruction_counts  # noqa: E402

# valgrind-3.19.0, `valgrind --tool=callgrind --callgrind-out-file=FILE
# python -c "import wiretape.cli"`: its head, two cost lines, its end.
CAPTURED = """\
# callgrind format
version: 1
creator: callgrind-3.19.0
pid: 3074
cmd:  /work/wt/counts/.venv/bin/python -c import wiretape.cli
part: 1


desc: I1 cache:
desc: D1 cache:
desc: LL cache:

desc: Timerange: Basic block 0 - 87783582
desc: Trigger: Program termination

positions: line
events: Ir
summary: 386584525


ob=(1) /usr/lib/x86_64-linux-gnu/ld-linux-x86-64.so.2
fl=(1) ./elf/../sysdeps/x86_64/dl-machine.h
fn=(1) _dl_start
0 25
* 2
+4 1
+1 4

totals: 386584525
"""


def test_the_instructions_are_the_totals_line():
    assert instruction_counts.parse_callgrind_totals(CAPTURED) == 386584525


def test_totals_win_over_the_summary_and_the_summary_serves_alone():
    differing = CAPTURED.replace("totals: 386584525", "totals: 1000")
    assert instruction_counts.parse_callgrind_totals(differing) == 1000
    without_totals = CAPTURED.replace("totals: 386584525\n", "")
    assert instruction_counts.parse_callgrind_totals(without_totals) == 386584525


def test_other_text_is_refused_with_the_reason():
    with pytest.raises(ValueError, match="not a callgrind output"):
        instruction_counts.parse_callgrind_totals("==1== Memcheck, a memory error detector\n")
    with pytest.raises(ValueError, match="holds no count"):
        instruction_counts.parse_callgrind_totals(CAPTURED.replace("totals: 386584525", "totals: x"))
