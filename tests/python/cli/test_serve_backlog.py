"""`wiretape serve` under a burst of clients: the listen backlog holds 200
connection attempts at once, and `--backlog N` sets it (docs/serve.md)."""

import os
import shutil
import select
import signal
import socket
import subprocess
import time

import pytest

from wiretape import cli

from devices import announced_address, interrupt, start_cli

CLIENTS = 200
DEADLINE = 30.0


def somaxconn():
    try:
        with open("/proc/sys/net/core/somaxconn") as f:
            return int(f.read())
    except OSError:
        return None


@pytest.mark.skipif((somaxconn() or 0) < CLIENTS,
                    reason="the kernel caps every listen backlog below 200 "
                           "(net.core.somaxconn)")
def test_200_clients_connecting_at_once_all_connect_and_are_accepted():
    child = start_cli("serve", "--device", "type=loopback", "--listen", "127.0.0.1:0")
    clients = []
    try:
        where = announced_address(child, "tcp")
        # A server that cannot accept now (as on a loaded machine): the
        # kernel's queue alone holds the connections.
        os.kill(child.pid, signal.SIGSTOP)
        try:
            for _ in range(CLIENTS):
                sock = socket.socket()
                sock.setblocking(False)
                clients.append(sock)
                sock.connect_ex(where)
            pending = set(clients)
            end = time.monotonic() + DEADLINE
            while pending and time.monotonic() < end:
                _, writable, _ = select.select([], list(pending), [],
                                               max(end - time.monotonic(), 0))
                for sock in writable:
                    assert sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR) == 0
                    pending.discard(sock)
            assert not pending, (f"{len(pending)} of {CLIENTS} connection attempts did not "
                                 f"complete within {DEADLINE} s")
        finally:
            os.kill(child.pid, signal.SIGCONT)
        # The server accepts every one: one controls the device, the others
        # are told why they are refused.
        refused = set()
        silent = set(clients)
        end = time.monotonic() + DEADLINE
        while len(refused) < CLIENTS - 1 and time.monotonic() < end:
            readable, _, _ = select.select(list(silent), [], [],
                                           max(end - time.monotonic(), 0))
            for sock in readable:
                if sock.recv(4096).startswith(b"wiretape: "):
                    refused.add(sock)
                silent.discard(sock)
        assert len(refused) == CLIENTS - 1
    finally:
        for sock in clients:
            sock.close()
        status, _, err = interrupt(child)
    assert status == 0, err


def run(capsys, *argv):
    status = cli.main(list(argv))
    return status, capsys.readouterr().err


@pytest.mark.parametrize("value", ["0", "-3", "x", str(2**31)])
def test_a_bad_backlog_is_a_usage_error_naming_the_flag(capsys, value):
    status, err = run(capsys, "serve", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "--backlog", value)
    assert status == 2
    assert "--backlog" in err


def test_backlog_without_a_tcp_listener_is_a_usage_error(capsys, tmp_path):
    status, err = run(capsys, "replay", str(tmp_path / "none.wtape"), "--udp", "127.0.0.1:0",
                      "--backlog", "300")
    assert status == 2
    assert "--backlog" in err and "--listen" in err


def listen_backlog(port):
    """The backlog of the TCP listener on `port`, as ss(8) shows it (a
    listening socket's Send-Q)."""
    out = subprocess.run(["ss", "-ltnH", f"sport = :{port}"], capture_output=True,
                         text=True, check=True).stdout
    fields = out.split()
    assert fields, f"no listener on port {port}: {out!r}"
    return int(fields[2])


@pytest.mark.skipif(shutil.which("ss") is None, reason="needs ss(8) to read a backlog")
@pytest.mark.parametrize("argv, expected", [
    ([], min(4096, somaxconn() or 4096)),
    (["--backlog", "300"], min(300, somaxconn() or 300)),
])
def test_the_listen_backlog_is_the_default_or_the_one_given(argv, expected):
    child = start_cli("serve", "--device", "type=loopback", "--listen", "127.0.0.1:0", *argv)
    try:
        _, port = announced_address(child, "tcp")
        assert listen_backlog(port) == expected
    finally:
        status, _, err = interrupt(child)
    assert status == 0, err
