"""wiretape convert --from reserial: a pytest-reserial cassette becomes a
session that the same pyserial client code replays against through
``wiretape://`` (a test suite moves over and keeps its recordings); bad
cassettes are one clean error naming the file and the place, exit 1."""

import base64
import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import serial

import wiretape
import wiretape.urlhandler
from wiretape import cli
from wiretape.tools import importers

DATA = Path(__file__).resolve().parents[2] / "data" / "reserial"
CASSETTE = DATA / "test_device_talk.jsonl"


def load_client():
    spec = importlib.util.spec_from_file_location("reserial_device_talk",
                                                  DATA / "test_device_talk.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


client = load_client()
TALKS = {"test_text": client.talk_text, "test_binary": client.talk_binary}


def run_cli(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def replay_with_client(session: Path, talk):
    """The cassette's client code, talking to the imported session; closing
    the port checks that every byte of the session was used."""
    wiretape.urlhandler.register()
    port = serial.serial_for_url(f"wiretape://{session}?timing=none&unused=error", timeout=10)
    try:
        return talk(port)
    finally:
        port.close()


def import_and_replay(capsys, tmp_path, cassette):
    for name, talk in TALKS.items():
        session = tmp_path / f"{name}.wtape"
        code, _, err = run_cli(capsys, "convert", cassette, session, "--from", "reserial",
                               "--test", name, "-q")
        assert code == 0, err
        assert replay_with_client(session, talk) == client.expected(talk)


def test_checked_in_cassette_replays_to_its_client(capsys, tmp_path):
    import_and_replay(capsys, tmp_path, CASSETTE)


def test_fresh_cassette_from_pytest_reserial_replays_to_its_client(capsys, tmp_path):
    """Records the client with pytest-reserial itself, then imports that."""
    if importlib.util.find_spec("pytest_reserial") is None:
        pytest.skip("pytest-reserial not installed: pip install pytest-reserial")
    shutil.copy(DATA / "test_device_talk.py", tmp_path)
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "--record", "test_device_talk.py"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    cassette = tmp_path / "test_device_talk.jsonl"
    assert importers.reserial_tests(cassette) == ["test_text", "test_binary"]
    import_and_replay(capsys, tmp_path, cassette)


def test_records_are_the_greeting_then_the_writes(tmp_path):
    header, records = importers.reserial_records(CASSETTE, "test_binary")
    assert list(records) == [("rx", 0, client.answer(b"BIN\x01\x02\n")),
                             ("tx", 0, b"BIN\x01\x02\n")]
    assert header.capture == "client"
    assert (header.source_format, header.source_files, header.source_details) == (
        "reserial", [CASSETTE.name], {"test": "test_binary"})
    assert (header.start_utc, header.host) == ("", "")  # not known, never invented


def test_a_mismatching_write_fails_the_replay(capsys, tmp_path):
    session = tmp_path / "s.wtape"
    assert run_cli(capsys, "convert", CASSETTE, session, "--from", "reserial",
                   "--test", "test_text", "-q")[0] == 0
    with pytest.raises(wiretape.ReplayMismatch):
        replay_with_client(session, lambda port: (port.write(b"IX\n"), port.read(1)))


def test_one_test_needs_no_name(capsys, tmp_path):
    cassette = tmp_path / "one.jsonl"
    cassette.write_text(json.dumps({"test_a": {"rx": base64.b64encode(b"\xffA").decode(),
                                               "tx": "UQ=="}}) + "\n")
    session = tmp_path / "s.wtape"
    code, _, err = run_cli(capsys, "convert", cassette, session, "--from", "reserial", "-q")
    assert code == 0, err
    records = [(r.kind, r.data) for r in wiretape.SessionReader(str(session))]
    assert records == [("rx", b"\xffA"), ("tx", b"Q")]


def write_lines(path, *items):
    path.write_text("".join((item if isinstance(item, str) else json.dumps(item)) + "\n"
                            for item in items))
    return path


GOOD = {"test_a": {"rx_encoding": "utf-8", "tx_encoding": "utf-8", "rx": "A", "tx": "B"}}

# (lines, --test, the line the message names or None, what it must say)
BAD = {
    "unknown_field": ([GOOD, {"test_b": {"rx": "", "tx": "", "speed": 3}}], "test_b", 2,
                      "test 'test_b': unknown field 'speed'"),
    "not_json": ([GOOD, '{"test_b": '], "test_a", 2, "not JSON"),
    "not_an_object": ([GOOD, "[1]"], "test_a", 2, "expected a JSON object"),
    "entry_not_an_object": ([{"test_a": "AB"}], None, 1, "expected a JSON object with rx and tx"),
    "rx_not_a_string": ([{"test_a": {"rx": 5, "tx": ""}}], None, 1,
                        "test 'test_a': rx: expected a string, got int"),
    "bad_base64": ([{"test_a": {"rx": "!!", "tx": ""}}], None, 1, "rx: not base64"),
    "bad_encoding": ([{"test_a": {"rx": "A", "tx": "", "rx_encoding": "latin-1"}}], None, 1,
                     "rx_encoding: expected \"utf-8\""),
    "several_tests_no_name": ([GOOD, {"test_b": {"rx": "", "tx": ""}}], None, None,
                              "choose one with --test NAME ('test_a', 'test_b')"),
    "no_such_test": ([GOOD], "test_z", None, "no test 'test_z' in this pytest-reserial "
                                             "cassette: it holds 'test_a'"),
    "empty": ([], None, None, "no test in this pytest-reserial cassette"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_cassette_is_one_clean_error(capsys, tmp_path, case):
    lines, test, line, message = BAD[case]
    cassette = write_lines(tmp_path / "bad.jsonl", *lines)
    output = tmp_path / "out.wtape"
    argv = ["convert", cassette, output, "--from", "reserial"] + (["--test", test] if test else [])
    code, _, err = run_cli(capsys, *argv)
    assert code == 1
    place = f"{cassette}:{line}: " if line else f"{cassette}: "
    assert place in err and message in err, err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    assert not output.exists()


def test_test_is_only_for_reserial(capsys, tmp_path):
    session = tmp_path / "s.wtape"
    write_lines(tmp_path / "a.jsonl", {"header": {}})
    code, _, err = run_cli(capsys, "convert", tmp_path / "a.jsonl", session, "--test", "x")
    assert code == 2
    assert "--from reserial" in err


def test_the_converted_session_names_its_cassette_and_invents_no_time_or_host(capsys, tmp_path):
    session = tmp_path / "s.wtape"
    assert run_cli(capsys, "convert", CASSETTE, session, "--from", "reserial",
                   "--test", "test_binary", "-q")[0] == 0
    header = wiretape.SessionReader(str(session)).header
    assert (header.source_format, header.source_files) == ("reserial", [CASSETTE.name])
    assert header.source_details == {"test": "test_binary"}
    assert (header.start_utc, header.host) == ("", "")
