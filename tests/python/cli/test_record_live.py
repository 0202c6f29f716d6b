"""`wiretape record` on a terminal (issue 26): a live line of elapsed time
and byte counts on stderr while it records, nothing of it when stderr is
not a terminal; the proxy's own notes speak as `wiretape record: ...`
either way (the bridge runs quiet and the command relays its messages)."""

import os
import re
import select
import socket
import subprocess
import sys
import threading

from devices import DEADLINE_S, announced_address, interrupt, start_cli, wait_until

from wiretape.cli.bridges import _after, live_counts

ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


class _Stats:
    def __init__(self, **counts):
        self._counts = counts

    def items(self):
        return list(self._counts.items())


class _TerminalReader:
    """Everything written to a pty's master, read by a thread, decoded."""

    def __init__(self, master: int):
        self._master = master
        self._chunks = []
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self):
        while True:
            try:
                readable, _, _ = select.select([self._master], [], [], 30)
                if not readable:
                    return
                chunk = os.read(self._master, 4096)
            except OSError:  # EIO: the last writer closed the terminal
                return
            if not chunk:
                return
            with self._lock:
                self._chunks.append(chunk)

    def text(self) -> str:
        with self._lock:
            return b"".join(self._chunks).decode("utf-8", "replace")

    def join(self):
        self._thread.join(DEADLINE_S * 4)


def test_the_live_line_reads_as_time_and_sizes():
    assert live_counts(_Stats(bytes_to_device=5, bytes_from_device=12_300, records_written=3,
                              clients_accepted=1), 75.4) == \
        "1:15  5 B to the device, 12.3 kB from it, 3 records, 1 client"
    assert live_counts(_Stats(records_written=1), 3725) == \
        "1:02:05  0 B to the device, 0 B from it, 1 record"


def test_the_relay_prints_each_message_once_even_when_the_bridge_drops_old_ones():
    assert _after([], ["a", "b"]) == ["a", "b"]
    assert _after(["a", "b"], ["a", "b", "c"]) == ["c"]
    assert _after(["a", "b", "c"], ["a", "b", "c"]) == []
    # The bridge keeps its last messages only: "a" dropped, "d" and "e" new.
    assert _after(["a", "b", "c"], ["b", "c", "d", "e"]) == ["d", "e"]


def _record_on(stderr, output):
    return subprocess.Popen([sys.executable, "-m", "wiretape.cli", "record", "--device",
                             "type=loopback", "--listen", "127.0.0.1:0", "-o", str(output)],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=stderr,
                            env={**os.environ, "TERM": "xterm", "COLUMNS": "120"})


def test_on_a_terminal_record_shows_live_counts_then_a_summary(tmp_path):
    master, slave = os.openpty()
    child = _record_on(slave, tmp_path / "live.wtape")
    os.close(slave)
    terminal = _TerminalReader(master)
    try:
        def address():
            match = re.search(r"clients use tcp (\S+):(\d+)", ANSI.sub("", terminal.text()))
            return match and (match.group(1), int(match.group(2)))

        wait_until(address, DEADLINE_S * 4, what=lambda: "the address: " + terminal.text())
        with socket.create_connection(address(), timeout=DEADLINE_S) as client:
            client.sendall(b"hello")
            received = b""
            while len(received) < 5:
                received += client.recv(5 - len(received))
            # The live line counts what crossed (loopback echoes it back).
            wait_until(lambda: "5 B to the device, 5 B from it" in terminal.text(),
                       DEADLINE_S * 4, what=lambda: "the live counts: " + terminal.text())
        status, _, _ = interrupt(child)
    finally:
        if child.poll() is None:
            child.kill()
        terminal.join()
        os.close(master)
    text = ANSI.sub("", terminal.text())
    assert status == 0, text
    assert re.search(r"wiretape record: \d+:\d\d  5 B to the device", text), text
    # The bridge's own notes speak as the command does.
    assert "wiretape record: listening on" in text, text
    assert re.search(r"wiretape record: client \S+ connected", text), text
    assert "\nwiretape: " not in "\n" + text, text
    assert re.search(r"wiretape record: stopped: \d+ records? written, 5 bytes to the device, "
                     r"5 bytes from it, 1 client", text), text


def test_off_a_terminal_record_prints_no_live_line(tmp_path):
    child = start_cli("record", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "-o", str(tmp_path / "plain.wtape"))
    host, port = announced_address(child, "tcp")
    with socket.create_connection((host, port), timeout=DEADLINE_S) as client:
        client.sendall(b"hello")
        received = b""
        while len(received) < 5:
            received += client.recv(5 - len(received))
    status, _, err = interrupt(child)
    assert status == 0, err
    assert "\x1b" not in err and "\r" not in err, repr(err)
    assert "to the device, 5 B" not in err, err
    lines = err.splitlines()
    assert all(line.startswith("wiretape record: ") for line in lines), lines
    assert any(line.startswith("wiretape record: listening on") for line in lines), lines


def test_quiet_leaves_out_the_proxys_notes(tmp_path):
    child = start_cli("record", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "-q", "-o", str(tmp_path / "quiet.wtape"))
    announced_address(child, "tcp")
    status, _, err = interrupt(child)
    assert status == 0, err
    assert "listening on" not in err, err
