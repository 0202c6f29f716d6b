"""A program that opens several hard-coded device paths, each a channel of
one session (issue 25, DESIGN §19): ``wiretape record --device NAME=OPTS
... --as NAME=PATH ... -- CMD`` records every channel into one file, and
``wiretape replay FILE -- CMD`` replays each channel on the path it was
recorded from (or its --as NAME=PATH), through the preload shim's table of
redirected devices (src/shim/)."""

import subprocess
import sys
import textwrap

import pytest

import wiretape
from wiretape import _core, cli

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the preload shim is Linux only")

PATH_A = "/dev/ttyWTA0"
PATH_B = "/dev/ttyWTB0"
# Generous: CMD, the bridges and Python start on a loaded CI machine.
COMMAND_DEADLINE_S = 60.0
MS = 1_000_000

# pyserial on two hard-coded paths: a request on each, its answer read, a
# DTR change on the first. With "swap", each path gets the other's request.
TWO_PORTS_CLIENT = textwrap.dedent("""
    import sys
    import serial

    swap = len(sys.argv) > 1 and sys.argv[1] == "swap"
    with serial.Serial("/dev/ttyWTA0", 115200, timeout=30) as a, \\
            serial.Serial("/dev/ttyWTB0", 115200, timeout=30) as b:
        a.write(b"B?\\n" if swap else b"A?\\n")
        print("a: " + a.readline().decode(), end="")
        b.write(b"A?\\n" if swap else b"B?\\n")
        print("b: " + b.readline().decode(), end="")
        a.dtr = False
""")


def wiretape_cli(*arguments):
    return subprocess.run([sys.executable, "-m", "wiretape.cli", *arguments],
                          capture_output=True, text=True, timeout=COMMAND_DEADLINE_S)


def device_session(path, device_path, question, answer):
    """A serial device on `device_path` that answers `question` with `answer`
    (replayed as the device of a recording)."""
    with wiretape.SessionWriter(str(path), capture="wire", port_type="serial",
                                port_options=f"type=serial,device={device_path}") as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 1 * MS, question)
        writer.write("rx", 2 * MS, answer)
        writer.write("close", 3 * MS, b"{}")
    return path


def two_port_session(path):
    """A session of channels a and b, recorded on PATH_A and PATH_B."""
    header = _core.SessionHeader.starting_now()
    header.channels = [_core.Channel(id=number, name=name, port_type="serial",
                                     port_options=f"type=serial,device={device}")
                       for number, (name, device) in enumerate((("a", PATH_A), ("b", PATH_B)))]
    with _core.SessionWriter(str(path), header) as writer:
        writer.write("open", 0, b"", channel=0)
        writer.write("open", 0, b"", channel=1)
        writer.write("tx", 1 * MS, b"A?\n", channel=0)
        writer.write("rx", 2 * MS, b"A!\n", channel=0)
        writer.write("tx", 3 * MS, b"B?\n", channel=1)
        writer.write("rx", 4 * MS, b"B!\n", channel=1)
    return path


@pytest.fixture
def client(tmp_path):
    script = tmp_path / "two_ports.py"
    script.write_text(TWO_PORTS_CLIENT)
    return [sys.executable, str(script)]


def test_record_of_a_program_with_two_hard_coded_paths_writes_both_channels(tmp_path, client):
    device_a = device_session(tmp_path / "a.wtape", PATH_A, b"A?\n", b"A!\n")
    device_b = device_session(tmp_path / "b.wtape", PATH_B, b"B?\n", b"B!\n")
    recording = tmp_path / "two.wtape"
    done = wiretape_cli("record", "-o", str(recording), "-q",
                        "--device", f"a=type=replay,file={device_a}",
                        "--device", f"b=type=replay,file={device_b}",
                        "--as", f"a={PATH_A}", "--as", f"b={PATH_B}", "--", *client)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "a: A!\nb: B!\n"
    reader = wiretape.SessionReader(str(recording))
    names = {channel.id: channel.name for channel in reader.header.channel_list()}
    assert sorted(names.values()) == ["a", "b"]
    seen = {}
    for record in reader:
        if record.kind in ("tx", "rx"):
            seen.setdefault((names[record.channel], record.kind), b"")
            seen[(names[record.channel], record.kind)] += record.data
        if record.kind == "modem_lines":
            seen.setdefault((names[record.channel], "modem_lines"), []).append(record.data)
    assert seen[("a", "tx")] == b"A?\n" and seen[("a", "rx")] == b"A!\n"
    assert seen[("b", "tx")] == b"B?\n" and seen[("b", "rx")] == b"B!\n"
    # The DTR change on the first path reached its own channel only.
    dtr_changes = {name: [data for data in seen.get((name, "modem_lines"), []) if b'"dtr"' in data]
                   for name in ("a", "b")}
    assert dtr_changes == {"a": [b'{"dtr":false,"applied":true}'], "b": []}

    replayed = wiretape_cli("replay", str(recording), "--as", f"a={PATH_A}",
                            "--as", f"b={PATH_B}", "-q", "--", *client)
    assert replayed.returncode == 0, replayed.stderr
    assert replayed.stdout == "a: A!\nb: B!\n"


def test_replay_redirects_each_channel_from_its_recorded_path(tmp_path, client):
    session = two_port_session(tmp_path / "two.wtape")
    done = wiretape_cli("replay", str(session), "-q", "--", *client)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "a: A!\nb: B!\n"
    assert "never opened" not in done.stderr


def test_a_program_that_swaps_the_requests_fails_naming_the_channel(tmp_path, client):
    session = two_port_session(tmp_path / "two.wtape")
    done = wiretape_cli("replay", str(session), "-q", "--", *client, "swap")
    assert done.returncode != 0, done.stdout
    assert "channel a: replay mismatch" in done.stderr


def test_a_program_that_never_opens_one_path_is_told_which(tmp_path):
    session = two_port_session(tmp_path / "two.wtape")
    done = wiretape_cli("replay", str(session), "-q", "--", sys.executable, "-c",
                        "import serial; p = serial.Serial('/dev/ttyWTA0', timeout=30); "
                        "p.write(b'A?\\n'); p.readline()")
    assert f"never opened {PATH_B}" in done.stderr
    assert f"never opened {PATH_A}" not in done.stderr
    assert done.returncode != 0


def usage_error(capsys, *argv):
    status = cli.main(list(argv))
    err = capsys.readouterr().err
    assert status == 2, err
    return err


def test_as_for_a_channel_without_a_device_is_a_usage_error(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "x.wtape"),
                      "--device", f"a=type=serial,device={PATH_A}", "--as", f"a={PATH_A}",
                      "--as", f"c={PATH_B}", "--", "true")
    assert "--as c=" in err and "'c'" in err


def test_as_given_twice_for_a_channel_is_a_usage_error(capsys, tmp_path):
    err = usage_error(capsys, "replay", str(two_port_session(tmp_path / "two.wtape")),
                      "--as", f"a={PATH_A}", "--as", f"a={PATH_B}", "--", "true")
    assert "--as is given twice for channel 'a'" in err


def test_two_channels_on_one_path_are_a_usage_error(capsys, tmp_path):
    err = usage_error(capsys, "replay", str(two_port_session(tmp_path / "two.wtape")),
                      "--as", f"b={PATH_A}", "--", "true")
    assert f"--as b={PATH_A}" in err and "same path" in err
