"""Recording that fails part-way (issue 16): `wiretape record -o` and
`wiretape serve -o` under a file-size limit (RLIMIT_FSIZE, the deterministic
stand-in for a full disk) report the failure once, keep forwarding, end with
exit 3 naming the file, and leave a session that `wiretape verify` accepts.
An empty -o is a usage error."""

import re
import resource
import signal
import socket
import subprocess
import sys
import threading

import pytest

import wiretape
from wiretape import bridge, cli

from devices import wait_until

DEADLINE_S = 30.0
# Small enough that a few hundred KiB of traffic passes it, large enough for
# the header and the first records.
FILE_LIMIT = 64 * 1024
CHUNK = 4096


def _limit_file_size():
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_LIMIT, FILE_LIMIT))


class _Child:
    """The CLI in a child process under the file-size limit, its stderr
    collected line by line by a thread (so a test waits on events, not time)."""

    def __init__(self, argv):
        self.process = subprocess.Popen(
            [sys.executable, "-m", "wiretape.cli", *argv],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            preexec_fn=_limit_file_size)
        self.lines = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.process.stderr:
            self.lines.append(line)

    def stderr(self):
        return "".join(self.lines)

    def address(self):
        found = []

        def announced():
            for line in self.lines:
                match = re.search(r"clients use tcp (\S+):(\d+)", line)
                if match:
                    found.append((match.group(1), int(match.group(2))))
                    return True
            assert self.process.poll() is None, self.stderr()
            return False

        wait_until(announced, DEADLINE_S, what=lambda: "the address in " + self.stderr())
        return found[0]

    def interrupt(self):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            self.process.wait(DEADLINE_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._reader.join(DEADLINE_S)
        return self.process.returncode


def _echo(client, payload):
    client.sendall(payload)
    received = bytearray()
    while len(received) < len(payload):
        chunk = client.recv(len(payload) - len(received))
        assert chunk, "the proxy closed the client's connection"
        received += chunk
    assert bytes(received) == payload


@pytest.mark.parametrize("command", ["record", "serve"])
def test_a_file_that_cannot_grow_stops_the_recording_not_the_forwarding(command, tmp_path):
    output = tmp_path / "limited.wtape"
    device = ["--device", "type=loopback", "--listen", "127.0.0.1:0"]
    child = _Child([command, *device, "-o", str(output)])
    try:
        host, port = child.address()
        sent = bytearray()
        with socket.create_connection((host, port), timeout=DEADLINE_S) as client:
            def exchange_until_the_failure_is_reported():
                payload = bytes([len(sent) // CHUNK % 251]) * CHUNK
                _echo(client, payload)
                sent.extend(payload)
                assert child.process.poll() is None, child.stderr()
                return f"wiretape {command}: recording stopped" in child.stderr()

            wait_until(exchange_until_the_failure_is_reported, DEADLINE_S,
                       what=lambda: "the recording failure to be reported: " + child.stderr())
            # Forwarding goes on after the failure.
            for _ in range(8):
                _echo(client, b"still here " * 300)
        code = child.interrupt()
    finally:
        if child.process.poll() is None:
            child.process.kill()
    err = child.stderr()
    assert "terminate called" not in err and "Traceback" not in err, err
    assert err.count(f"wiretape {command}: recording stopped") == 1, err  # reported once
    assert code == cli.EXIT_RUNTIME, err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert len(errors) == 1, err
    assert str(output) in errors[0] and "file-size limit" in errors[0], errors[0]
    # The file ends at a whole record: verify accepts it, and what it holds
    # is what crossed, in order, up to the failure; no close after a failure.
    assert output.stat().st_size <= FILE_LIMIT
    assert cli.main(["verify", str(output)]) == cli.EXIT_OK
    reader = wiretape.SessionReader(str(output))
    records = list(reader)
    assert reader.damage is None
    assert records[0].kind == "open"
    assert "close" not in [r.kind for r in records]
    tx = b"".join(r.data for r in records if r.kind == "tx")
    assert len(tx) > 0 and bytes(sent).startswith(tx)


@pytest.mark.parametrize("command", ["record", "serve"])
def test_the_summary_counts_the_records_in_the_file_not_those_lost_with_the_failure(
        command, tmp_path):
    # Before, records_written counted every record handed to the writer: the
    # ones buffered when the write failed too (the summary said 19, verify
    # found 15).
    output = tmp_path / "limited.wtape"
    child = _Child([command, "--device", "type=loopback", "--listen", "127.0.0.1:0",
                    "-o", str(output)])
    try:
        host, port = child.address()
        with socket.create_connection((host, port), timeout=DEADLINE_S) as client:
            def exchange_until_the_failure_is_reported():
                _echo(client, b"x" * CHUNK)
                assert child.process.poll() is None, child.stderr()
                return f"wiretape {command}: recording stopped" in child.stderr()

            wait_until(exchange_until_the_failure_is_reported, DEADLINE_S,
                       what=lambda: "the recording failure to be reported: " + child.stderr())
        code = child.interrupt()
    finally:
        if child.process.poll() is None:
            child.process.kill()
    err = child.stderr()
    assert code == cli.EXIT_RUNTIME, err
    counts = re.findall(r"(\d+) records? written", err)
    assert len(counts) == 1, err
    reader = wiretape.SessionReader(str(output))
    in_file = len(list(reader))
    assert reader.damage is None
    assert int(counts[0]) == in_file, err
    # The end says the recording failed, naming the file.
    assert re.search(rf"{command}: failed", err), err
    assert "error:" in err and str(output) in err and "file-size limit" in err, err


# --- an empty -o ------------------------------------------------------------------


@pytest.mark.parametrize("argv", [
    ["record", "--device", "type=loopback", "--listen", "127.0.0.1:0", "-o", ""],
    ["record", "--device", "type=loopback", "--listen", "127.0.0.1:0", "--output=  "],
    ["serve", "--device", "type=loopback", "--listen", "127.0.0.1:0", "-o", ""],
    ["replay", "any.wtape", "--listen", "127.0.0.1:0", "-o", ""],
])
def test_an_empty_output_is_a_usage_error_naming_the_option(capsys, argv):
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == cli.EXIT_USAGE, err
    lines = [line for line in err.splitlines() if "error:" in line]
    assert len(lines) == 1, err
    assert "-o/--output" in lines[0] and "empty" in lines[0], lines[0]


def test_the_python_recorder_refuses_an_empty_output():
    with pytest.raises(ValueError, match="output"):
        bridge.record("type=loopback", "", listen="127.0.0.1:0")
