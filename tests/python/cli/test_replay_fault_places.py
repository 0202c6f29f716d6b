"""``wiretape replay --fault`` placed in time, end to end (issue 37): a
`t:SECONDS` is checked and fired on the session's clock over every client
session a virtual device serves (docs/faults.md), not over the first client
session; and a replay that an injected silence ended before it served
anything says so, never that nothing the client sent matched."""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import sys
import threading

import pytest

import wiretape

from devices import wait_until

DEADLINE = 30.0  # seconds: generous, for a loaded machine
S = 1_000_000_000  # ns


def event(**fields) -> bytes:
    return json.dumps(fields).encode()


@pytest.fixture
def two_clients(tmp_path):
    """A proxy recording of two TCP clients, as `show` shows it: the first
    client's answer at +0.502 s, the second's at +1.6 s and +2.25 s, the
    recording running on to +11.4 s."""
    path = tmp_path / "two-clients.wtape"
    with wiretape.SessionWriter(str(path), capture="wire", port_type="tcp",
                                port_options="type=tcp,host=device,port=9") as writer:
        writer.write("open", 0, b"{}")
        writer.write("client_connect", S // 100, event(peer="127.0.0.1:40001", role="control"))
        writer.write("tx", S // 10, b"Q0\n")
        writer.write("rx", 502_000_000, b"R0\n")
        writer.write("client_disconnect", 600_000_000,
                     event(peer="127.0.0.1:40001", reason="disconnected"))
        writer.write("client_connect", S, event(peer="127.0.0.1:40002", role="control"))
        writer.write("tx", 1_200_000_000, b"Q1\n")
        writer.write("rx", 1_600_000_000, b"R1\n")
        writer.write("tx", 2 * S, b"Q2\n")
        writer.write("rx", 2_250_000_000, b"R2\n")
        writer.write("client_disconnect", 2_500_000_000,
                     event(peer="127.0.0.1:40002", reason="disconnected"))
        writer.write("close", 11_400_000_000, b"{}")
    return path


class Replay:
    """`wiretape replay FILE --listen 127.0.0.1:0 --timing none ARGS` as a
    child process, what it says on stderr collected as it comes."""

    def __init__(self, recording, *args):
        self.lines = []
        self._child = subprocess.Popen(
            [sys.executable, "-m", "wiretape.cli", "replay", str(recording),
             "--listen", "127.0.0.1:0", "--timing", "none", *args],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self._reader = threading.Thread(target=self._collect, daemon=True)
        self._reader.start()
        announced = self.wait_for(r"clients use tcp (\S+):(\d+)")
        self.address = (announced.group(1), int(announced.group(2)))

    def _collect(self):
        for line in self._child.stderr:
            self.lines.append(line)

    def said(self) -> str:
        return "".join(self.lines)

    def wait_for(self, pattern):
        """The first match of `pattern` in what the replay said, once it
        said it (it fails the test if the replay ends without)."""
        wait_until(lambda: re.search(pattern, self.said()) or self._child.poll() is not None,
                   DEADLINE, f"{pattern!r} from the replay")
        self._reader.join(0.1 if self._child.poll() is None else DEADLINE)
        found = re.search(pattern, self.said())
        assert found, f"exit {self._child.poll()}:\n{self.said()}"
        return found

    def ask(self, request: bytes, answer: bytes = b"") -> socket.socket:
        """A client session: connects, writes `request` and reads `answer`."""
        client = socket.create_connection(self.address, timeout=DEADLINE)
        client.sendall(request)
        got = b""
        while len(got) < len(answer):
            chunk = client.recv(len(answer) - len(got))
            if not chunk:
                break
            got += chunk
        assert got == answer, self.said()
        return client

    def stop(self):
        """Ctrl-C, as a user ends it: (exit code, everything it said)."""
        if self._child.poll() is None:
            self._child.send_signal(signal.SIGINT)
        try:
            code = self._child.wait(timeout=DEADLINE)
        except subprocess.TimeoutExpired:
            self._child.kill()
            code = self._child.wait()
        self._reader.join(DEADLINE)
        return code, self.said()


def test_a_time_in_a_later_client_session_is_accepted_and_fires_there(two_clients):
    # t:1.5 is past the first client session (its rx ends at 0.502 s) but
    # within the session: the fault fires at R1 (1.6 s), the second client's
    # first answer, exchange 1.
    replay = Replay(two_clients, "--fault", "silence@t:1.5")
    try:
        replay.ask(b"Q0\n", b"R0\n").close()
        replay.wait_for("client 127.0.0.1:[0-9]+ disconnected")
        with replay.ask(b"Q1\n"):
            fired = replay.wait_for(r"fault silence@t:1.5: .*")
    finally:
        code, said = replay.stop()
    assert "in exchange 1 " in fired.group(0), said
    assert code == 0, said  # the first client was served
    assert "past its end" not in said


def test_a_time_past_the_last_rx_of_every_client_session_is_refused(two_clients):
    result = subprocess.run([sys.executable, "-m", "wiretape.cli", "replay", str(two_clients),
                             "--listen", "127.0.0.1:0", "--fault", "silence@t:2.3"],
                            capture_output=True, text=True, timeout=DEADLINE)
    assert result.returncode == 2, result.stderr
    assert "silence@t:2.3: the session lasts 2.250 s; t:2.3 is past its end" in result.stderr


def test_a_silence_that_ended_the_replay_before_anything_was_served_says_so(two_clients):
    # t:0.4 fires at R0 (0.502 s): the first client gets nothing, and the
    # verdict names the fault, not the client.
    replay = Replay(two_clients, "--fault", "silence@t:0.4")
    try:
        with replay.ask(b"Q0\n"):
            fired = replay.wait_for(r"fault silence@t:0.4: .*")
        replay.wait_for("client 127.0.0.1:[0-9]+ disconnected")
    finally:
        code, said = replay.stop()
    assert "in exchange 0 " in fired.group(0), said
    assert code == 1, said
    assert ("no client was served any of the recording's rx: an injected fault ended the "
            "replay before any was served (fault silence@t:0.4: the device stopped answering)"
            in said), said
    assert "nothing the client sent matched" not in said
