"""The system call figures of `make bench` (bench/syscall_counts.py) come
from `strace -c -f` tables; the parser is held to a captured table, so that
a figure is never read from the wrong column or half a table."""

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "bench"))

import syscall_counts  # noqa: E402

# strace 6.1, `strace -c -f -o FILE socat -b65536 - /dev/null`, as written.
SOCAT_TABLE = """\
% time     seconds  usecs/call     calls    errors syscall
------ ----------- ----------- --------- --------- ----------------
 35.44    0.000431           6        62           mmap
 18.17    0.000221          13        16           read
 12.25    0.000149           9        15           openat
 10.20    0.000124           7        16           mprotect
  4.19    0.000051           3        17        17 recvfrom
  4.11    0.000050           3        15           newfstatat
  2.96    0.000036           2        14           close
  2.71    0.000033           3        10           rt_sigaction
  2.47    0.000030          15         2           munmap
  1.48    0.000018          18         1           socketpair
  0.99    0.000012           4         3         3 ioctl
  0.90    0.000011           5         2           pselect6
  0.74    0.000009           3         3           brk
  0.66    0.000008           4         2           pread64
  0.33    0.000004           4         1           fcntl
  0.33    0.000004           4         1           prlimit64
  0.33    0.000004           4         1           getrandom
  0.25    0.000003           3         1           write
  0.25    0.000003           3         1           getpid
  0.25    0.000003           3         1           uname
  0.25    0.000003           3         1           arch_prctl
  0.25    0.000003           3         1           set_tid_address
  0.25    0.000003           3         1           set_robust_list
  0.25    0.000003           3         1           rseq
  0.00    0.000000           0         1         1 access
  0.00    0.000000           0         1           execve
------ ----------- ----------- --------- --------- ----------------
100.00    0.001216           6       190        21 total
"""


def test_calls_are_read_from_the_calls_column_with_or_without_errors():
    calls = syscall_counts.parse_strace_summary(SOCAT_TABLE)
    assert calls["mmap"] == 62
    assert calls["recvfrom"] == 17  # a row with errors: calls is still the 4th column
    assert calls["access"] == 1
    assert calls["pselect6"] == 2
    assert "total" not in calls
    assert sum(calls.values()) == 190  # the table's own total
    assert len(calls) == 26


def test_a_table_per_personality_is_summed():
    second = "\nSystem call usage summary for 32 bit mode:\n" + SOCAT_TABLE
    calls = syscall_counts.parse_strace_summary(SOCAT_TABLE + second)
    assert calls["mmap"] == 124
    assert sum(calls.values()) == 380


def test_text_without_a_table_is_refused():
    with pytest.raises(ValueError, match="no strace -c table"):
        syscall_counts.parse_strace_summary("strace: exec: No such file or directory\n")


def test_a_broken_row_is_named_by_its_line():
    broken = SOCAT_TABLE.replace("        16           read", "        xx           read")
    with pytest.raises(ValueError, match=r"line 4: not a strace -c row"):
        syscall_counts.parse_strace_summary(broken)


def test_calls_per_unit_subtract_the_baseline_and_name_what_only_one_side_made():
    loaded = {"read": 2010, "write": 2005, "futex": 40}
    baseline = {"read": 10, "write": 5, "openat": 300}
    per_message = syscall_counts.per_unit(loaded, baseline, 1000)
    assert per_message == {"read": 2.0, "write": 2.0, "futex": 0.04, "openat": -0.3}
    socat = {"read": 2.0, "write": 1.0, "pselect6": 1.0}
    assert syscall_counts.beyond(per_message, socat, least=0.01) == {"write": 1.0, "futex": 0.04}
