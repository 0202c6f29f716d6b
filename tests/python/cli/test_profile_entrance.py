"""--profile has one entrance (DESIGN §25): show, stats, diff, view, edit and
replay read it through _core.profile_from_spec (a name or a declared
profile alike), and whether a session's ``profile`` metadata is the default
is one rule (wiretape.session.chosen_profile): the session's profile unless
--profile names another or ``none``."""

import json

import pytest

import wiretape
from wiretape import _core, cli
from wiretape.cli import build_parser, replay_options_of
from wiretape.cli.parser import ParserError
from wiretape.session import ProfileChoice, chosen_profile


def session(path, metadata=None):
    with wiretape.SessionWriter(str(path), port_type="serial", metadata=metadata or {}) as writer:
        writer.write("tx", 1000, b"PING\nPI")
        writer.write("tx", 1500, b"NG2\n")
        writer.write("rx", 2000, b"PONG\n")
    return path


def header(metadata):
    made = _core.SessionHeader.starting_now()
    made.metadata = metadata
    return made


def test_the_rule():
    lines = header({"profile": "lines"})
    assert chosen_profile(None, lines) == ProfileChoice("lines")
    assert chosen_profile("scip", lines) == ProfileChoice("scip")
    assert chosen_profile("none", lines) == ProfileChoice(None)
    assert chosen_profile(None, header({})) == ProfileChoice(None)
    assert chosen_profile(None, lines, header({})) == ProfileChoice("lines")
    assert chosen_profile(None, lines, header({"profile": "lines"})) == ProfileChoice("lines")
    declared = header({"profile": "framing=delimiter:0a"})
    assert chosen_profile(None, declared).spec == "framing=delimiter:0a"
    unknown = chosen_profile(None, header({"profile": "my-own"}))
    assert unknown.spec is None and "profile='my-own' is not a profile" in unknown.note
    with pytest.raises(ValueError, match="different profiles .*give --profile"):
        chosen_profile(None, lines, header({"profile": "nmea"}))


def run(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_show_frames_by_the_sessions_profile_unless_told_none(tmp_path, capsys):
    path = session(tmp_path / "s.wtape", {"profile": "lines"})
    code, framed, _ = run(capsys, "show", path)
    assert code == 0 and "6 B  PING2\\n" in framed  # the line split over two records, whole
    code, raw, _ = run(capsys, "show", path, "--profile", "none")
    assert code == 0 and "PING2" not in raw and "NG2\\n" in raw


@pytest.mark.parametrize("command", ["show", "stats", "diff", "view", "edit", "replay"])
def test_every_command_takes_a_declared_profile(command):
    argv = {"diff": ["diff", "a.wtape", "b.wtape"], "edit": ["edit", "a.wtape", "b.wtape"],
            "replay": ["replay", "a.wtape", "--pty", "p"]}.get(command, [command, "a.wtape"])
    args = build_parser().parse_args(argv + ["--profile", "framing=delimiter:0a,ignore=0:1"])
    assert args.profile == "framing=delimiter:0a,ignore=0:1"


@pytest.mark.parametrize("command", ["show", "stats", "diff", "view", "edit", "replay"])
def test_every_command_refuses_a_bad_profile_naming_the_key(command):
    argv = {"diff": ["diff", "a.wtape", "b.wtape"], "edit": ["edit", "a.wtape", "b.wtape"],
            "replay": ["replay", "a.wtape", "--pty", "p"]}.get(command, [command, "a.wtape"])
    with pytest.raises(ParserError, match="option 'match' is not a profile's key"):
        build_parser().parse_args(argv + ["--profile", "framing=delimiter:0a,match=request"])
    with pytest.raises(ParserError, match="unknown profile 'nope'"):
        build_parser().parse_args(argv + ["--profile", "nope"])


def test_show_and_diff_frame_by_a_declared_profile(tmp_path, capsys):
    a = session(tmp_path / "a.wtape")
    code, out, _ = run(capsys, "show", a, "--profile", "framing=delimiter:0a")
    assert code == 0 and "6 B  PING2\\n" in out
    code, out, _ = run(capsys, "diff", a, a, "--profile", "framing=delimiter:0a")
    assert code == 0 and "sessions are identical" in out


def test_diff_of_sessions_naming_different_profiles_asks_for_one(tmp_path, capsys):
    a = session(tmp_path / "a.wtape", {"profile": "lines"})
    b = session(tmp_path / "b.wtape", {"profile": "nmea"})
    code, _, err = run(capsys, "diff", a, b)
    assert code == 2 and "give --profile" in err
    code, out, _ = run(capsys, "diff", a, b, "--profile", "none")
    assert code == 0 and "sessions are identical" in out


def test_view_of_a_session_naming_an_unknown_profile_is_shown_without_one(tmp_path, capsys):
    # The metadata is the session's, not the command's input: the page is
    # made without a profile, with a note (it was an OptionError before).
    path = session(tmp_path / "s.wtape", {"profile": "my-own"})
    code, _, err = run(capsys, "view", path, "-o", tmp_path / "s.html")
    assert code == 0, err
    assert "profile='my-own' is not a profile" in err


def test_replay_passes_a_declared_profile_as_its_keys():
    args = build_parser().parse_args(["replay", "a.wtape", "--pty", "p", "--match", "request",
                                      "--profile", "framing=delimiter:0a,echo=0:1"])
    assert ("framing", "delimiter:0a") in _core.parse_options(replay_options_of(args))
    assert ("echo", "0:1") in _core.parse_options(replay_options_of(args))
    args = build_parser().parse_args(["replay", "a.wtape", "--pty", "p", "--profile", "none"])
    assert "profile" not in dict(_core.parse_options(replay_options_of(args)))


def latency_names(capsys, *argv):
    code, out, err = run(capsys, "stats", "--json", *argv)
    assert code == 0, err
    return [row["name"] for row in json.loads(out)["latency"]]


def test_stats_names_requests_by_the_sessions_profile_unless_told_none(tmp_path, capsys):
    path = session(tmp_path / "s.wtape", {"profile": "lines"})
    assert latency_names(capsys, path) == ["all", "PING2"]
    assert latency_names(capsys, path, "--profile", "none") == ["all"]


def test_stats_names_requests_by_a_declared_profile(tmp_path, capsys):
    path = session(tmp_path / "s.wtape")
    assert latency_names(capsys, path) == ["all"]
    assert latency_names(capsys, path, "--profile", "framing=delimiter:0a") == ["all", "PING2\\n"]
