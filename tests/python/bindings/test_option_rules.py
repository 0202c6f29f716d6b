"""Option keys that would silently do nothing are errors naming the key and
what it needs; a NUL byte never cuts a value short; `wiretape replay`
refuses bad keys before it prints or opens anything."""

import pytest

import wiretape
from wiretape import _core, cli


@pytest.fixture
def session(tmp_path):
    path = tmp_path / "s.wtape"
    with wiretape.SessionWriter(str(path), port_options="type=loopback") as writer:
        writer.write("tx", 1, b"Q")
        writer.write("rx", 2, b"A")
    return path


def option_error(options):
    with pytest.raises(wiretape.OptionError) as caught:
        port = wiretape.open_port(options)
        port.close()
    return str(caught.value)


@pytest.mark.parametrize("key", ["flush_ms=50", "fsync", "log_errors=warn", "meta_robot=r2"])
def test_recording_keys_without_log_are_refused(key):
    message = option_error(f"type=loopback,{key}")
    name = key.split("=")[0]
    assert f"option '{name}' has no effect without log=FILE" in message, message


def test_recording_keys_with_log_are_accepted(tmp_path):
    log = tmp_path / "r.wtape"
    port = wiretape.open_port(f"type=loopback,log={log},flush_ms=50,fsync,log_errors=warn,"
                              "meta_robot=r2")
    port.close()
    assert wiretape.SessionReader(str(log)).header.metadata == {"robot": "r2"}


@pytest.mark.parametrize("keys, name, needs", [
    ("repeat=last", "repeat", "match=request"),
    ("unmatched=silent", "unmatched", "match=request"),
    ("match=sequence,repeat=cycle", "repeat", "match=request"),
    ("tolerance=50", "tolerance", "check=timing"),
    ("jitter=500", "jitter", "check=timing"),
    ("timing=none,speed=2", "speed", "timing=session or timing=causal"),
    ("ignoretimes,speed=2", "speed", "timing=session or timing=causal"),
])
def test_replay_keys_without_what_they_need_are_refused(session, keys, name, needs):
    message = option_error(f"type=replay,file={session},{keys}")
    assert f"option '{name}' has no effect without" in message and needs in message, message
    with pytest.raises(wiretape.OptionError):
        _core.check_replay_options(f"type=replay,file={session},{keys}")


@pytest.mark.parametrize("keys", ["match=request,repeat=last,unmatched=silent",
                                  "match=REQUEST,repeat=last",
                                  "check=timing,timing=session,tolerance=50",
                                  "strictness=2,jitter=500", "timing=session,speed=2", "speed=2"])
def test_replay_keys_with_what_they_need_are_accepted(session, keys):
    _core.check_replay_options(f"type=replay,file={session},{keys}")
    port = wiretape.open_port(f"type=replay,file={session},{keys},unused=ignore")
    port.close()


def test_seriallog_without_file_is_refused():
    message = option_error("type=seriallog,device=/dev/ttyS0")
    assert "'file'" in message and "type=seriallog" in message, message
    with pytest.raises(wiretape.OptionError) as caught:
        wiretape.open_port("type=tcplog,port=1")
    assert caught.value.key == "file"


def test_a_nul_byte_in_a_value_is_refused_naming_the_key(tmp_path):
    with pytest.raises(wiretape.OptionError) as caught:
        wiretape.open_port(f"type=loopback,log={tmp_path}/a\0b.wtape")
    assert caught.value.key == "log"
    assert "NUL" in str(caught.value)
    assert not list(tmp_path.iterdir())


def test_check_replay_options_opens_nothing(tmp_path):
    _core.check_replay_options(f"type=replay,file={tmp_path}/missing.wtape,timing=none")
    with pytest.raises(wiretape.OptionError, match="type=replay"):
        _core.check_replay_options("type=loopback")


@pytest.mark.parametrize("argv, key", [
    (["--options", "bogus=1"], "bogus"),
    (["--options", "repeat=last"], "repeat"),
    (["--unmatched", "silent"], "unmatched"),
    (["--tolerance", "20"], "tolerance"),
])
@pytest.mark.parametrize("side", [["--listen", "127.0.0.1:0"], ["--pty", "PTY"]])
def test_replay_usage_errors_come_before_any_output_or_side_effect(tmp_path, capfd, session,
                                                                  argv, key, side):
    side = [str(tmp_path / "tty") if arg == "PTY" else arg for arg in side]
    code = cli.main(["replay", str(session), *side, *argv])
    out, err = capfd.readouterr()
    assert code == cli.EXIT_USAGE, err
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("wiretape replay: error:"), err
    assert f"'{key}'" in lines[0]
    assert not (tmp_path / "tty").exists()
