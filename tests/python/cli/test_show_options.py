"""wiretape show for people (issue 26): colour on a terminal (--color,
NO_COLOR), the Δt column, --kind, --from/--to, --grep, --full, and
--profile lines that keep the columns."""

import io
import re
from pathlib import Path

import pytest

from wiretape import cli
from wiretape.tools.show import color_wanted

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "golden" / "all_kinds.wtape"
HOKUYO = Path(__file__).resolve().parents[3] / "examples" / "hokuyo" / "recordings"
ANSI = re.compile(r"\x1b\[[0-9;]*m")


def run(capsys, *argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def record_lines(out):
    """The timeline's lines (they start with a signed time)."""
    return [line for line in out.splitlines() if re.match(r"^(\x1b\[[0-9;]*m)?[+-]\d", line)]


def kind_of(line):
    return re.match(r"^\S+\s+(?:\d+\.\d+s\s+)?(\S+)", line).group(1)


def test_color_always_paints_never_and_a_pipe_do_not(capsys):
    code, painted, _ = run(capsys, "show", str(GOLDEN), "--color", "always")
    assert code == 0
    assert ANSI.search(painted)
    _, plain, _ = run(capsys, "show", str(GOLDEN), "--color", "never")
    assert not ANSI.search(plain)
    assert ANSI.sub("", painted) == plain
    _, piped, _ = run(capsys, "show", str(GOLDEN))  # capsys is not a terminal
    assert piped == plain


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_color_auto_is_colour_on_a_terminal_unless_no_color(monkeypatch):
    monkeypatch.delenv("NO_COLOR", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    assert color_wanted("auto", _Terminal())
    assert not color_wanted("auto", io.StringIO())
    monkeypatch.setenv("NO_COLOR", "1")
    assert not color_wanted("auto", _Terminal())
    assert color_wanted("always", io.StringIO())
    monkeypatch.delenv("NO_COLOR")
    monkeypatch.setenv("TERM", "dumb")
    assert not color_wanted("auto", _Terminal())


def test_delta_column_is_the_time_since_the_line_before(capsys):
    _, out, _ = run(capsys, "show", str(GOLDEN))
    assert re.search(r"^time\s+Δt\s+kind\s+size\s+data$", out, re.M)
    lines = record_lines(out)
    assert lines[0].split()[:2] == ["+0.000000s", "open"]  # no Δt on the first line
    assert lines[1].split()[:3] == ["+0.000001s", "0.000001s", "tx"]
    assert lines[2].split()[:3] == ["+0.002500s", "0.002499s", "rx"]


def test_kind_keeps_the_kinds_named_and_delta_follows_what_is_shown(capsys):
    code, out, _ = run(capsys, "show", str(GOLDEN), "--kind", "settings,break")
    assert code == 0
    kinds = [kind_of(line) for line in record_lines(out)]
    assert record_lines(out)[2].split()[1] == "0.001900s"  # since the settings line shown
    assert out.rstrip().endswith("3 of 20 records shown")


def test_unknown_kind_is_a_usage_error_with_a_suggestion(capsys):
    code, _, err = run(capsys, "show", str(GOLDEN), "--kind", "rx,settngs")
    assert code == 2
    assert "unknown record kind 'settngs'" in err and "did you mean settings" in err


def test_from_and_to_are_seconds_of_session_time_both_ends_included(capsys):
    _, out, _ = run(capsys, "show", str(GOLDEN), "--from", "0.0025", "--to", "0.004")
    times = [line.split()[0] for line in record_lines(out)]
    assert times == ["+0.002500s", "+0.003000s", "+0.004000s"]
    code, _, err = run(capsys, "show", str(GOLDEN), "--from", "0.5", "--to", "0.1")
    assert code == 2 and "ends" in err
    code, _, err = run(capsys, "show", str(GOLDEN), "--from", "soon")
    assert code == 2 and "'soon' is not a number of seconds" in err


def test_grep_is_a_bytes_pattern_over_payloads(capsys):
    _, out, _ = run(capsys, "show", str(GOLDEN), "--grep", r"00P\n")
    lines = record_lines(out)
    assert len(lines) == 1 and "<- VV\\n00P\\n" in lines[0]
    _, out, _ = run(capsys, "show", str(GOLDEN), "--grep", r"\xfe\xff")
    assert [line.split()[0] for line in record_lines(out)] == ["+0.003000s"]
    code, _, err = run(capsys, "show", str(GOLDEN), "--grep", "(")
    assert code == 2 and "bad --grep pattern" in err


def test_full_shows_the_whole_payload(capsys):
    _, cut, _ = run(capsys, "show", str(GOLDEN), "--grep", r"\xff")
    assert "(+192 bytes)" in cut and "\\xff" not in cut
    _, full, _ = run(capsys, "show", str(GOLDEN), "--grep", r"\xff", "--full")
    assert "(+192 bytes)" not in full
    assert full.count("\\xfe\\xff") == 1


def test_filters_do_not_go_with_textconv(capsys):
    code, _, err = run(capsys, "show", str(GOLDEN), "--textconv", "--kind", "rx")
    assert code == 2 and "--kind does not go with --textconv" in err


def test_profile_lines_keep_the_columns(capsys):
    code, out, _ = run(capsys, "show", str(HOKUYO / "urg04lx_gd.wtape"), "--profile", "scip")
    assert code == 0
    lines = record_lines(out)
    assert {kind_of(line) for line in lines} == {"open", "tx", "rx", "close"}
    data_columns = set()
    for line in lines:
        kind = kind_of(line)
        column = line.index(f" {kind} ") + 1 + 17 + 1 + 8 + 2 if kind != "close" else None
        if column is not None:
            assert line[column - 2:column] == "  " and line[column] != " ", line
            data_columns.add(column)
    assert len(data_columns) == 1
