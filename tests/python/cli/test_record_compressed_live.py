"""A compressed session read while `wiretape record --compress zstd` is
still writing it: its last chunk is open, which is where the recorder is,
not damage. show and verify read every record before it, say the file is
still being written (a warning), and exit 0; once the recorder stopped,
the same file reads whole without the warning."""

import re
import socket
import struct
from pathlib import Path

from devices import DEADLINE_S, announced_address, interrupt, start_cli, wait_until

from wiretape import _core, cli

CHUNK_CODE = 0x21  # docs/session-format.md, "The chunk record"


def first_chunk_offset(path: Path):
    """The offset of the file's first chunk record, once it is in the file
    whole (the recorder flushed a part), else None."""
    data = path.read_bytes() if path.exists() else b""
    if len(data) < 16:
        return None
    at = 16 + struct.unpack_from("<I", data, 12)[0] + 4
    while at + 16 <= len(data):
        length, kind = struct.unpack_from("<IB", data, at)
        end = at + 16 + length + 4
        if end > len(data):
            return None
        if kind == CHUNK_CODE:
            return at
        at = end
    return None


def run(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_file_being_recorded_compressed_reads_up_to_its_open_chunk(tmp_path, capsys):
    output = tmp_path / "live.wtape"
    child = start_cli("record", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "--compress", "zstd", "-o", str(output))
    try:
        address = announced_address(child, "tcp")
        with socket.create_connection(address, timeout=DEADLINE_S) as client:
            client.sendall(b"$GPGGA,123519,4807.038,N\r\n")
            received = b""
            while len(received) < 26:
                received += client.recv(64)
            # The recorder flushes a part of its open chunk within flush_ms.
            wait_until(lambda: first_chunk_offset(output) is not None, DEADLINE_S * 4,
                       what="a first flushed chunk part in the file")
            chunk = first_chunk_offset(output)

            code, out, err = run(capsys, "show", output)
            assert code == 0, err
            assert "GPGGA" in out
            assert "still being written" in err and f"unfinished chunk at byte {chunk}" in err, err

            code, out, err = run(capsys, "stats", output)
            assert code == 0, out + err
            assert "still being written" in err, err

            code, out, err = run(capsys, "verify", output)
            assert code == 0, out + err
            assert re.search(r"ok, \d+ records", out), out
            assert f"still being written: it ends in an unfinished chunk at byte {chunk}" in out, out

            code, out, err = run(capsys, "verify", "--json", output)
            assert code == 0
            assert f'"unfinished_offset": {chunk}' in out, out
        status, _, err = interrupt(child)
        assert status == 0, err
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()

    code, out, err = run(capsys, "show", output)
    assert code == 0 and "still being written" not in err, err
    code, out, _ = run(capsys, "verify", output)
    assert code == 0 and "still being written" not in out, out


def test_the_same_bytes_left_by_a_killed_recorder_are_damage(tmp_path, capsys):
    """The bytes a running recorder's file holds, copied: nobody writes the
    copy, so its open chunk is what a killed recorder leaves (damage, the
    records before it kept)."""
    output = tmp_path / "live.wtape"
    child = start_cli("record", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "--compress", "zstd", "-o", str(output))
    try:
        address = announced_address(child, "tcp")
        with socket.create_connection(address, timeout=DEADLINE_S) as client:
            client.sendall(b"hello")
            received = b""
            while len(received) < 5:
                received += client.recv(64)
            wait_until(lambda: first_chunk_offset(output) is not None, DEADLINE_S * 4,
                       what="a first flushed chunk part in the file")
            copy = tmp_path / "copy.wtape"
            copy.write_bytes(output.read_bytes())
        interrupt(child)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()
    code, out, err = run(capsys, "verify", copy)
    assert code == 1, out
    assert "has no last part" in out and "still being written" not in out, out


def test_a_replay_of_a_file_being_written_serves_what_was_written(tmp_path, capfd):
    """The replay engine reads through the same reader: a file its writer
    holds (here a SessionWriter of this process, flushed inside its open
    chunk) is replayed up to there with a warning, not as damage."""
    path = tmp_path / "live.wtape"
    with _core.SessionWriter(path, compress="zstd") as writer:
        writer.write("rx", 1000, b"$GPGGA,1\r\n")
        writer.write("rx", 2000, b"$GPGGA,2\r\n")
        writer.flush()
        port = _core.open_port(f"type=replay,file={path},timing=none,unused=ignore,timeout=5")
        got = b""
        while len(got) < 20:
            chunk = port.read(64)
            if not chunk:
                break
            got += chunk
        port.close()
        assert got == b"$GPGGA,1\r\n$GPGGA,2\r\n"
        err = capfd.readouterr().err
        assert "warning" in err and "still being written" in err, err
        assert "damaged" not in err, err
