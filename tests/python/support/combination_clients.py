"""The clients of the combination property test
(tests/python/bindings/test_combinations.py): a `type=replay` port's or a
virtual device's TCP client, writing requests in pieces and making the
recording's client events, and `play`, which compares what each step is
served with what the oracle (session_oracle.py) says."""

from __future__ import annotations

import dataclasses
import select
import socket
import time
from typing import Callable, List, Optional, Sequence, Tuple

import pytest

import wiretape

from session_oracle import ClientEvent, Expectation, Lines

DEADLINE = 10.0  # seconds: generous, for what must happen at once
QUIET = 0.3  # seconds: how long "nothing more comes" is watched for


def pieces(data: bytes, chunk: int):
    """`data` in writes of `chunk` bytes (0: one write)."""
    size = chunk or len(data) or 1
    return [data[i:i + size] for i in range(0, len(data), size)]


class PortClient:
    """A client of a `type=replay` port, writing in pieces of `chunk` bytes."""

    def __init__(self, port, chunk=0):
        self.port = port
        self.chunk = chunk

    def write(self, data: bytes) -> None:
        for piece in pieces(data, self.chunk):
            self.port.write_all(piece)

    def make(self, client_event: ClientEvent) -> None:
        client_event.make(self.port)

    def lines(self) -> Lines:
        return (self.port.cts, self.port.dsr, self.port.ri, self.port.cd)

    def read_exactly(self, count: int) -> bytes:
        return self.port.read_exactly(count, timeout=DEADLINE)

    def read_closed(self) -> bool:
        """True when a read raises PortClosed (the device went away)."""
        try:
            self.port.read(1, timeout=DEADLINE)
        except wiretape.PortClosed:
            return True
        return False

    def when_back(self, action: Callable[[], None]) -> None:
        """Does `action` once the device is back from a reconnect fault (it
        refuses with PortClosed while gone)."""
        end = time.monotonic() + DEADLINE
        while True:
            try:
                action()
                return
            except wiretape.PortClosed:
                assert time.monotonic() < end, "the device never came back"
                self.port.wait_readable(0.01)  # a wait with a deadline, not a sleep

    def end(self) -> None:
        """The device went away for good: the client closes its port, as a
        driver does (a replay of another channel no longer waits on it)."""
        self.port.close()

    def rest(self) -> bytes:
        """What still comes: until the recording's end (at_end=closed) or
        QUIET seconds without a byte."""
        rest = b""
        while True:
            try:
                data = self.port.read(4096, timeout=QUIET)
            except wiretape.PortClosed:
                return rest
            if not data:
                return rest
            rest += data


class TcpClient:
    """A client of a virtual device on TCP (one client session). It has no
    line or settings of its own: the recording's client events are none of
    its."""

    def __init__(self, address, chunk=0):
        host, port = address.rsplit(":", 1)
        self.socket = socket.create_connection((host, int(port)), timeout=DEADLINE)
        self.chunk = chunk

    def write(self, data: bytes) -> None:
        for piece in pieces(data, self.chunk):
            self.socket.sendall(piece)

    def read_exactly(self, count: int) -> bytes:
        data = b""
        end = time.monotonic() + DEADLINE
        while len(data) < count and time.monotonic() < end:
            ready, _, _ = select.select([self.socket], [], [], end - time.monotonic())
            if not ready:
                break
            chunk = self.socket.recv(count - len(data))
            if not chunk:
                break
            data += chunk
        return data

    def rest(self) -> bytes:
        rest = b""
        while True:
            ready, _, _ = select.select([self.socket], [], [], QUIET)
            if not ready:
                return rest
            try:
                chunk = self.socket.recv(4096)
            except ConnectionError:
                return rest
            if not chunk:
                return rest
            rest += chunk

    def close(self):
        self.socket.close()


@dataclasses.dataclass
class Step:
    """One request a client writes and what the oracle says it gets: the
    client's recorded events made before it, and the device's lines seen
    once its answer is read (None: not checked)."""

    client: object
    request: bytes
    expectation: Expectation
    events: Tuple[ClientEvent, ...] = ()
    lines: Optional[Lines] = None
    name: str = ""


def play(client, requests, expectations, describe, greeting=b"", events=(), lines=()):
    """Reads the greeting, then plays one client's requests in order (see
    play_steps). `events[i]` and `lines[i]` go with request i."""
    got = client.read_exactly(len(greeting))
    assert got == greeting, f"greeting: served {got.hex()}\n{describe()}"
    steps = [Step(client, request, expectation,
                  events[number] if events else (), lines[number] if lines else None)
             for number, (request, expectation) in enumerate(zip(requests, expectations))]
    play_steps(steps, describe)


def play_steps(steps: Sequence[Step], describe):
    """Makes each step's events, writes its request, reads what the oracle
    says must come and compares; then checks that nothing more comes to any
    of the steps' clients. Returns normally or fails with `describe()` in
    the message."""
    back_pending: List[object] = []
    ended: List[object] = []
    for number, step in enumerate(steps):
        client, expectation = step.client, step.expectation
        if client in ended:
            continue
        where = f"request {number}{' on ' + step.name if step.name else ''} ({step.request!r})"
        asked_at = time.monotonic()

        made = []  # the events made: none twice when a try is refused

        def ask(whole=False):
            for client_event in step.events[len(made):]:
                client.make(client_event)
                made.append(client_event)
            if whole:
                client.port.write_all(step.request)
            else:
                client.write(step.request)

        if client in back_pending:
            client.when_back(lambda: ask(whole=True))
            back_pending.remove(client)
        elif expectation.closed:
            try:
                ask()
            except wiretape.PortClosed:
                pass  # the device may be gone at the write already
        else:
            ask()
        if expectation.closed or expectation.back_after_loss:
            assert client.read_closed(), f"{where}: the device did not go away\n{describe()}"
            if expectation.closed:
                with pytest.raises(wiretape.PortClosed):
                    client.write(b"after the device went away")
                getattr(client, "end", lambda: None)()
                ended.append(client)
                continue
            back_pending.append(client)
            continue
        got = client.read_exactly(expectation.count)
        took = time.monotonic() - asked_at
        # A lower bound only: a loaded machine is slower, never faster.
        assert took >= expectation.at_least_s * 0.9, (
            f"{where}: the whole response came after {took:.3f} s, the fault waits "
            f"{expectation.at_least_s:.3f} s\n{describe()}")
        if expectation.exact is not None:
            assert got == expectation.exact, (
                f"{where}: served {got.hex()} where the oracle says {expectation.exact.hex()}\n"
                f"{describe()}")
        else:
            assert len(got) == expectation.length, f"{where}: {got.hex()}\n{describe()}"
            problem = expectation.check(got)
            assert not problem, f"{where}: served {got.hex()}: {problem}\n{describe()}"
        if step.lines is not None and got and not expectation.silent:
            # The line change was recorded before the response: due no later.
            assert client.lines() == step.lines, (
                f"{where}: the device's lines (cts, dsr, ri, cd) are {client.lines()}, the "
                f"recording says {step.lines}\n{describe()}")
    clients = []
    for step in steps:
        if step.client not in clients and step.client not in ended:
            clients.append(step.client)
    for client in clients:
        rest = client.rest()
        assert rest == b"", f"served more than the oracle says: {rest.hex()}\n{describe()}"
