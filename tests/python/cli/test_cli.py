"""The wiretape command line: --version, --help everywhere, exit codes
(0 ok, 1 check failed, 2 usage, 3 runtime), one-line errors, and the file
commands end to end."""

import json
import os
import re
import signal
import subprocess
import sys

import pytest

import wiretape
from wiretape import cli

from devices import announced_address, interrupt, start_cli

SUBCOMMANDS = ["record", "replay", "serve", "ports", "show", "stats", "verify",
               "convert", "diff", "demo"]

SESSION = [
    ("open", 0, b"{}"),
    ("tx", 1_000_000, b"PING\n"),
    ("rx", 2_000_000, b"PONG\n"),
    ("close", 3_000_000, b""),
]


def run(capsys, *argv):
    """main(argv) in this process: (exit code, stdout, stderr)."""
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line_error(err, *words):
    lines = [line for line in err.splitlines() if "error:" in line]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for word in words:
        assert word in lines[0], (word, lines[0])


# --- version and help ------------------------------------------------------------


def test_version(capsys):
    code, out, _ = run(capsys, "--version")
    assert code == 0
    assert out.strip() == f"wiretape {wiretape.__version__}"


def test_help_lists_every_subcommand_and_the_exit_codes(capsys):
    code, out, _ = run(capsys, "--help")
    assert code == 0
    for name in SUBCOMMANDS:
        assert re.search(rf"^\s+{name}\s", out, re.M), name
    assert "exit codes" in out


@pytest.mark.parametrize("name", SUBCOMMANDS)
def test_help_of_each_subcommand(capsys, name):
    code, out, _ = run(capsys, name, "--help")
    assert code == 0
    assert out.startswith(f"usage: wiretape {name}")


def test_record_help_mentions_device_for_the_demo(capsys):
    # demo.proxy_available() looks for --device in `record --help`.
    _, out, _ = run(capsys, "record", "--help")
    assert "--device" in out and "--pty" in out and "--listen" in out


def test_the_installed_entry_point_runs():
    result = subprocess.run([sys.executable, "-m", "wiretape.cli", "--version"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    assert result.stdout.strip() == f"wiretape {wiretape.__version__}"


# --- usage errors: exit 2 with a message -------------------------------------------


@pytest.mark.parametrize("argv, words", [
    ([], ["a command is required"]),
    (["teleport"], ["unknown command", "teleport"]),
    (["record", "--pty", "/tmp/x", "-o", "out.wtape"], ["--device"]),
    (["record", "--device", "/dev/null", "--pty", "a", "--listen", "1", "-o", "x"],
     ["not allowed"]),
    (["record", "--device", "type=loopback", "-o", "x.wtape"], ["--pty PATH or --listen"]),
    (["record", "--device", "type=loopback", "--pty", "p", "-o", "x", "--duration", "-3"],
     ["--duration"]),
    (["record", "--device", "type=loopback", "--pty", "p", "-o", "x", "--meta", "novalue"],
     ["--meta", "KEY=VALUE"]),
    (["replay", "f.wtape", "--pty", "p", "--timing", "sometimes"], ["--timing"]),
    (["replay", "f.wtape", "--pty", "p", "--speed", "0"], ["--speed"]),
    (["serve", "--device", "type=loopback"], ["--listen"]),
    (["show", "f.wtape", "--format", "xml"], ["--format"]),
    (["convert", "a.wtape"], ["OUT"]),
    (["convert", "a.wtape", "b.x", "--to", "png"], ["--to"]),
    (["diff", "a.wtape"], ["B"]),
    (["stats"], ["FILE"]),
])
def test_usage_errors_exit_2_with_one_line(capsys, argv, words):
    code, _, err = run(capsys, *argv)
    assert code == 2
    assert_one_line_error(err, *words)


def test_a_bad_device_option_string_is_a_usage_error(capsys, tmp_path):
    code, _, err = run(capsys, "record", "--device", "type=loopback,speed=warp",
                       "--listen", "127.0.0.1:0", "-o", str(tmp_path / "x.wtape"))
    assert code == 2
    assert_one_line_error(err, "speed")


def test_a_bad_listen_address_is_a_usage_error(capsys, tmp_path):
    code, _, err = run(capsys, "serve", "--device", "type=loopback", "--listen", "host:http")
    assert code == 2
    assert_one_line_error(err, "port must be a number")


# --- runtime errors: exit 3 --------------------------------------------------------


def test_a_bare_device_path_means_a_serial_device(capsys, tmp_path):
    missing = tmp_path / "ttyNOPE"
    code, _, err = run(capsys, "record", "--device", str(missing), "--listen", "127.0.0.1:0",
                       "-o", str(tmp_path / "x.wtape"))
    assert code == 3
    assert_one_line_error(err, str(missing))


def test_a_missing_session_file_is_a_runtime_error(capsys, tmp_path):
    for command in ("show", "stats", "verify"):
        code, _, err = run(capsys, command, str(tmp_path / "absent.wtape"))
        assert code == 3
        assert_one_line_error(err, "absent.wtape", "no such file")


def test_exit_code_mapping_is_one_table():
    assert cli.exit_code_for(KeyboardInterrupt()) == 0
    assert cli.exit_code_for(wiretape.ReplayMismatch("m", 0, 0, None)) == 1
    assert cli.exit_code_for(wiretape.SessionError("s", 0)) == 1
    assert cli.exit_code_for(wiretape.OptionError("o", "k")) == 2
    assert cli.exit_code_for(ValueError("v")) == 2
    assert cli.exit_code_for(wiretape.PortError(5, "p")) == 3
    assert cli.exit_code_for(wiretape.PortClosed(None, "c")) == 3
    assert cli.exit_code_for(FileNotFoundError(2, "f")) == 3
    assert cli.exit_code_for(NotImplementedError()) == 3


# --- ports -----------------------------------------------------------------------------


def test_ports_json_is_a_list_of_devices(capsys):
    code, out, _ = run(capsys, "ports", "--json")
    assert code == 0
    ports = json.loads(out)
    assert isinstance(ports, list)
    for port in ports:
        assert {"device", "by_id", "vid_pid", "description"} <= set(port)
        assert isinstance(port["by_id"], list)


def test_ports_table_runs(capsys):
    code, out, err = run(capsys, "ports")
    assert code == 0
    assert "device" in out or "no serial ports" in err


def test_by_id_links_map_devices_to_their_stable_names(tmp_path):
    directory = tmp_path / "by-id"
    directory.mkdir()
    target = tmp_path / "ttyUSB7"
    target.write_text("")
    (directory / "usb-FTDI_FT232R_A1B2-if00-port0").symlink_to(target)
    links = cli.ports._by_id_links(str(directory))
    assert links == {str(target): [str(directory / "usb-FTDI_FT232R_A1B2-if00-port0")]}
    assert cli.ports._by_id_links(str(tmp_path / "none")) == {}


# --- files: verify, stats, show, convert, diff -------------------------------------------


def test_verify_ok_and_damaged(capsys, session_file, tmp_path):
    good = session_file(SESSION)
    code, out, _ = run(capsys, "verify", str(good))
    assert code == 0
    assert "ok" in out
    code, out, _ = run(capsys, "verify", str(good), "--json")
    assert code == 0
    assert json.loads(out)["ok"] is True

    damaged = tmp_path / "damaged.wtape"
    data = good.read_bytes()
    damaged.write_bytes(data[:-3])  # the last record is cut short
    code, out, _ = run(capsys, "verify", str(damaged), "--json")
    assert code == 1
    report = json.loads(out)
    assert report["ok"] is False and report["offset"] > 0

    garbage = tmp_path / "garbage.wtape"
    garbage.write_bytes(b"not a session")
    code, out, _ = run(capsys, "verify", str(garbage))
    assert code == 1
    assert "DAMAGED" in out


def test_stats_json_counts_both_directions(capsys, session_file):
    path = session_file(SESSION)
    code, out, _ = run(capsys, "stats", str(path), "--json")
    assert code == 0
    stats = json.loads(out)
    assert stats["rx_bytes"] == 5 and stats["tx_bytes"] == 5
    assert stats["damaged"] is False
    code, out, _ = run(capsys, "stats", str(path))
    assert code == 0
    assert re.search(r"rx_bytes\s+5", out)


def test_show_jsonl_is_one_object_per_record(capsys, session_file):
    path = session_file(SESSION)
    code, out, _ = run(capsys, "show", str(path), "--format", "jsonl")
    assert code == 0
    records = [json.loads(line) for line in out.splitlines()]
    assert [r["kind"] for r in records] == ["open", "tx", "rx", "close"]
    assert records[1]["data_hex"] == b"PING\n".hex()


def test_show_decode_needs_the_text_format(capsys, session_file):
    path = session_file(SESSION)
    code, _, err = run(capsys, "show", str(path), "--format", "hex", "--decode", "scip")
    assert code == 2
    assert_one_line_error(err, "--decode")


def test_convert_and_diff(capsys, session_file, tmp_path):
    path = session_file(SESSION)
    copy = tmp_path / "copy.wtape"
    code, _, err = run(capsys, "convert", str(path), str(copy), "--to", "wiretape")
    assert code == 0
    assert "converted" in err
    code, out, _ = run(capsys, "diff", str(path), str(copy))
    assert code == 0
    assert "identical" in out

    other = session_file([("tx", 1_000_000, b"PING\n"), ("rx", 2_000_000, b"PANG\n")],
                         name="other.wtape")
    code, out, _ = run(capsys, "diff", str(path), str(other))
    assert code == 1
    assert "differ" in out


def test_convert_of_a_damaged_file_exits_1(capsys, session_file, tmp_path):
    good = session_file(SESSION)
    damaged = tmp_path / "damaged.wtape"
    damaged.write_bytes(good.read_bytes()[:-3])
    code, _, err = run(capsys, "convert", str(damaged), str(tmp_path / "out.jsonl"))
    assert code == 1
    assert "Traceback" not in err


# --- bridges ------------------------------------------------------------------------------








def test_record_through_tcp_then_ctrl_c_exits_0_with_a_complete_file(tmp_path):
    import socket

    output = tmp_path / "rec.wtape"
    child = start_cli("record", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                    "-o", str(output), "--meta", "who=test")
    try:
        host, number = announced_address(child, "tcp")
        with socket.create_connection((host, number), timeout=5) as client:
            client.sendall(b"echo me\n")
            received = b""
            client.settimeout(5)
            while len(received) < 8:
                chunk = client.recv(64)
                if not chunk:
                    break
                received += chunk
        assert received == b"echo me\n"
    finally:
        code, _, err = interrupt(child)
    assert code == 0, err
    reader = wiretape.SessionReader(str(output))
    records = list(reader)
    assert reader.damage is None
    assert b"".join(r.data for r in records if r.kind == "tx") == b"echo me\n"
    assert reader.header.metadata["who"] == "test"


def test_replay_serves_a_recording_over_tcp(tmp_path, session_file):
    import socket

    path = session_file(SESSION)
    child = start_cli("replay", str(path), "--listen", "127.0.0.1:0", "--timing", "none")
    try:
        host, number = announced_address(child, "tcp")
        with socket.create_connection((host, number), timeout=5) as client:
            client.sendall(b"PING\n")
            client.settimeout(5)
            received = b""
            while len(received) < 5:
                chunk = client.recv(64)
                if not chunk:
                    break
                received += chunk
        assert received == b"PONG\n"
    finally:
        code, _, err = interrupt(child)
    assert code == 0, err


def test_record_with_duration_ends_by_itself(tmp_path):
    output = tmp_path / "timed.wtape"
    result = subprocess.run([sys.executable, "-m", "wiretape.cli", "record", "--device",
                             "type=loopback", "--listen", "127.0.0.1:0", "-o", str(output),
                             "--duration", "0.3", "--quiet"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert os.path.getsize(output) > 0


def test_replay_mismatch_exits_1_with_the_report(tmp_path, session_file):
    import socket

    path = session_file(SESSION)
    child = start_cli("replay", str(path), "--listen", "127.0.0.1:0", "--timing", "none")
    try:
        host, number = announced_address(child, "tcp")
        with socket.create_connection((host, number), timeout=5) as client:
            client.sendall(b"PANG\n")
            client.settimeout(5)
            try:
                while client.recv(64):
                    pass
            except OSError:
                pass
        child.wait(15)  # a mismatch ends the replay by itself
    finally:
        code, _, err = interrupt(child)
    assert code == 1, err
    assert "replay mismatch" in err and "Traceback" not in err
    assert err.count("replay mismatch: replay mismatch") == 0


def test_ports_show_by_id_paths_and_usb_ids(capsys, monkeypatch, tmp_path):
    from serial.tools import list_ports, list_ports_common

    device = tmp_path / "ttyUSB0"
    device.write_text("")
    by_id = tmp_path / "by-id"
    by_id.mkdir()
    stable = by_id / "usb-Hokuyo_Data_Flex_Ltd._URG-04LX-if00"
    stable.symlink_to(device)

    info = list_ports_common.ListPortInfo(str(device), skip_link_detection=True)
    info.vid, info.pid = 0x15D1, 0x0000
    info.description = "URG-Series USB Driver"
    info.serial_number = "H1234"
    monkeypatch.setattr(list_ports, "comports", lambda *a, **k: [info])
    real_links = cli.ports._by_id_links
    monkeypatch.setattr(cli.ports, "_by_id_links",
                        lambda directory=str(by_id): real_links(directory))

    code, out, _ = run(capsys, "ports", "--json")
    assert code == 0
    [port] = json.loads(out)
    assert port["device"] == str(device)
    assert port["by_id"] == [str(stable)]
    assert port["vid_pid"] == "15d1:0000"
    assert port["description"] == "URG-Series USB Driver"
    assert port["serial_number"] == "H1234"

    code, out, _ = run(capsys, "ports")
    assert code == 0
    assert str(stable) in out and "15d1:0000" in out and "URG-Series" in out


def test_record_through_a_pty_and_sigterm_ends_it_cleanly(tmp_path):
    import select
    import time

    link = tmp_path / "ttyV0"
    output = tmp_path / "pty.wtape"
    child = start_cli("record", "--device", "type=loopback", "--pty", str(link),
                    "-o", str(output))
    try:
        announced = ""
        while "clients use" not in announced:
            line = child.stderr.readline()
            assert line, f"wiretape record ended early: {announced}"
            announced += line
        assert str(link) in announced, announced
        end = time.monotonic() + 10
        while not link.exists():
            assert child.poll() is None and time.monotonic() < end, announced
            select.select([], [], [], 0.01)
        client = os.open(str(link), os.O_RDWR | os.O_NOCTTY)
        try:
            import termios
            import tty

            tty.setraw(client, termios.TCSANOW)
            os.write(client, b"hi there")
            received = b""
            while len(received) < 8 and select.select([client], [], [], 5)[0]:
                received += os.read(client, 64)
            assert received == b"hi there"
        finally:
            os.close(client)
        child.send_signal(signal.SIGTERM)
        code, _, err = interrupt(child)
    finally:
        if child.poll() is None:
            interrupt(child)
    assert code == 0, err
    records = list(wiretape.SessionReader(str(output)))
    assert b"".join(r.data for r in records if r.kind == "tx") == b"hi there"


def test_serve_shares_a_device_over_tcp_and_records_it(tmp_path):
    import socket

    output = tmp_path / "served.wtape"
    child = start_cli("serve", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                    "-o", str(output))
    try:
        host, number = announced_address(child, "tcp")
        with socket.create_connection((host, number), timeout=5) as client:
            client.sendall(b"over tcp\n")
            client.settimeout(5)
            received = b""
            while len(received) < 9:
                chunk = client.recv(64)
                if not chunk:
                    break
                received += chunk
        assert received == b"over tcp\n"
    finally:
        code, _, err = interrupt(child)
    assert code == 0, err
    tx = b"".join(r.data for r in wiretape.SessionReader(str(output)) if r.kind == "tx")
    assert tx == b"over tcp\n"
