"""Help and hints (issue 26): usage lines with the CMD after --, the
--device note only where there is a --device, unknown options named with a
suggestion, files wiretape imports named with their convert command, and an
unwritable output named as the user typed it."""

import json
from pathlib import Path

import pytest

from wiretape import cli

ROOT = Path(__file__).resolve().parents[3]
SESSION = ROOT / "examples" / "hokuyo" / "recordings" / "urg04lx_gd.wtape"
RESERIAL = ROOT / "tests" / "data" / "reserial" / "test_device_talk.jsonl"
CAPTURE = ROOT / "tests" / "data" / "pcap" / "tcp.pcap"


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def error_line(err):
    lines = [line for line in err.splitlines() if "error:" in line]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize("command, tail", [
    ("faults", "SESSION -- CMD [ARG...] {port} [ARG...]"),
    ("record", "[-- CMD [ARG...]]"),
    ("replay", "FILE [-- CMD [ARG...]]"),
])
def test_usage_shows_the_command_after_the_separator(capsys, command, tail):
    code, out, _ = run(capsys, command, "--help")
    assert code == 0
    usage = out.split("\n\n", 1)[0]
    # The one-device form, before the form of several channels (record, replay).
    first_form = usage.split("\n       wiretape ", 1)[0]
    assert first_form.rstrip().endswith(tail), usage


@pytest.mark.parametrize("command, has_device", [
    ("record", True), ("serve", True), ("show", False), ("stats", False), ("replay", False),
    ("faults", False), ("diff", False),
])
def test_the_device_note_is_only_on_commands_with_device(capsys, command, has_device):
    _, out, _ = run(capsys, command, "--help")
    assert "exit codes:" in out
    assert ("--device takes a port option string" in out) == has_device


def test_an_unknown_top_level_flag_is_named_with_a_suggestion(capsys):
    code, _, err = run(capsys, "--pyt")
    assert code == 2
    line = error_line(err)
    assert "unknown option '--pyt'" in line
    assert "did you mean wiretape record --pty" in line
    code, _, err = run(capsys, "--verson")
    assert code == 2 and "did you mean --version?" in error_line(err)


def test_an_unknown_flag_of_a_command_is_named_by_the_command(capsys):
    code, _, err = run(capsys, "replay", SESSION, "--timnig=none")
    assert code == 2
    assert error_line(err) == ("wiretape replay: error: unknown option '--timnig=none' "
                               "(did you mean --timing?)")
    assert err.count("\n") == 1, "the line alone, no usage block before it"


def test_an_unknown_replay_key_says_did_you_mean_without_listing_every_key(capsys):
    code, _, err = run(capsys, "faults", SESSION, "--options", "timnig=none", "--", "true",
                       "{port}")
    assert code == 2
    line = error_line(err)
    assert "did you mean 'timing'?" in line
    assert "valid keys" not in line


def test_show_of_a_capture_names_the_convert_command(capsys):
    code, _, err = run(capsys, "show", CAPTURE)
    assert code == 1
    line = error_line(err)
    assert "a packet capture" in line
    assert f"wiretape convert --from pcap {CAPTURE} tcp.wtape" in line


@pytest.mark.parametrize("command", ["show", "stats", "verify"])
def test_an_unconverted_reserial_cassette_says_what_it_is(capsys, command):
    code, _, err = run(capsys, command, RESERIAL)
    assert code == 1
    line = error_line(err)
    assert "a pytest-reserial cassette" in line
    assert "wiretape convert --from reserial" in line and "t_ns" not in line


def test_converting_a_reserial_cassette_as_jsonl_says_what_it_is(capsys, tmp_path):
    code, _, err = run(capsys, "convert", RESERIAL, tmp_path / "out.wtape")
    assert code == 1
    line = error_line(err)
    assert "pytest-reserial cassette" in line and "--from reserial" in line
    assert "t_ns: missing" not in line


def test_an_unwritable_output_is_named_as_typed(capsys):
    # /proc takes no new files, whoever we are (root writes to read-only modes)
    missing = "/proc/x.pcapng"
    code, _, err = run(capsys, "convert", SESSION, missing)
    assert code == 3
    line = error_line(err)
    assert f"{missing}: No such file or directory" in line
    assert ".partial" not in line
