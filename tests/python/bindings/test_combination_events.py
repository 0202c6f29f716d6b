"""The combination property test of DESIGN §17 and §25 "Combinations", for
the dimensions issue 37 found defects in: recordings with client flushes
and reopens before the first write, and the client's settings, DTR and
breaks interleaved with its writes (before a request, between the two tx
records of one, after one before its answer), under `check=data` and
`check=timing`, in both match modes, against an oracle that says what must
be served from the recording alone (the rules of docs/replay.md):

- a recorded flush gates the rx after it (match=sequence) only as long as
  the client could still make it: once the client writes past the place of
  the recorded flushes the rx they held is due at once, however few of them
  it made (`flush_wait` is set to a minute here, so waiting it out fails);
  a client that made every recorded flush reads the greeting before it
  writes; match=request serves the greeting at open whatever was flushed;
- the client makes each recorded settings, DTR and break event where the
  recording has it among its bytes, and that passes under check=timing
  (every event checked in order) and check=data (lines checked where the
  recording holds the device's);
- a client that reopens before its first write is served its last client
  session, and nothing said to the earlier ones.

Bounded for `make test`; WIRETAPE_COMBINATION_EXAMPLES raises the number of
examples, derandomized unless it is set (as test_combinations.py).
"""

from __future__ import annotations

import dataclasses
import json
import os
from typing import List, Tuple

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import wiretape
from wiretape import _core, bridge

from combination_clients import DEADLINE, PortClient, TcpClient
from devices import wait_until
from session_oracle import MS, ClientEvent, connect, disconnect, line_frame, lines_payload

EXAMPLES_FROM_ENV = os.environ.get("WIRETAPE_COMBINATION_EXAMPLES")
EXAMPLES = int(EXAMPLES_FROM_ENV or "60")
# Long enough that a gate waiting it out fails the client's read (DEADLINE).
FLUSH_WAIT_MS = 60_000

# The client's events that are checked (flushes are counted, not checked).
CHECKED_EVENT = st.one_of(
    st.sampled_from([9600, 115200]).map(lambda baud: ClientEvent("baud", baud)),
    st.integers(0, 1).map(lambda level: ClientEvent("dtr", level)),
    st.integers(1, 3).map(lambda ms: ClientEvent("break", ms)))
EVENTS = st.lists(CHECKED_EVENT, max_size=2).map(tuple)


@dataclasses.dataclass(frozen=True)
class Exchange:
    """A request recorded as one or two tx records, the client's events
    recorded before, between and after them, and the response's rx records."""

    request: Tuple[bytes, ...]
    response: Tuple[bytes, ...]
    before: Tuple[ClientEvent, ...] = ()
    between: Tuple[ClientEvent, ...] = ()  # only with a request of two records
    after: Tuple[ClientEvent, ...] = ()


@st.composite
def exchanges(draw, count, with_events):
    made = []
    for index in range(count):
        request = line_frame(b"Q%d " % index + draw(st.binary(max_size=8)))
        cut = draw(st.integers(0, len(request) - 1))
        parts = (request[:cut], request[cut:]) if cut else (request,)
        response = line_frame(b"R%d " % index + draw(st.binary(max_size=8)))
        split = draw(st.integers(0, len(response) - 1))
        events = EVENTS if with_events else st.just(())
        made.append(Exchange(parts, (response[:split], response[split:]) if split else (response,),
                             draw(events), draw(events) if cut else (), draw(events)))
    return made


def keys(match, timing, check):
    pairs = [("match", match), ("timing", timing), ("check", check), ("unused", "error"),
             ("flush_wait", FLUSH_WAIT_MS)]
    if check == "timing":
        pairs.append(("tolerance", 5000))  # the events are what is checked, not the clock
    return _core.option_string(pairs)


@st.composite
def modes(draw):
    match = draw(st.sampled_from(["sequence", "request"]))
    timing = draw(st.sampled_from(["none", "causal"]))
    check = draw(st.sampled_from(["data", "timing"])) if timing == "causal" else "data"
    return match, timing, check


def write_records(path, records, port_type):
    with wiretape.SessionWriter(str(path), capture="wire", port_type=port_type,
                                port_options=f"type={port_type}") as writer:
        writer.write("open", 0, b"{}")
        for number, (kind, data) in enumerate(records, start=1):
            writer.write(kind, number * MS, data)
    return str(path)


def exchange_records(made: List[Exchange]):
    records = []
    for exchange in made:
        records += [e.record() for e in exchange.before]
        records.append(("tx", exchange.request[0]))
        records += [e.record() for e in exchange.between]
        records += [("tx", part) for part in exchange.request[1:]]
        records += [e.record() for e in exchange.after]
        records += [("rx", part) for part in exchange.response]
    return records


def greeting_due_at_open(match, flushes_recorded, flushes_made):
    """The oracle's rule for a greeting recorded after the client's flushes:
    before any write, it is due once the client flushed as often
    (match=sequence), or at open (match=request)."""
    return match == "request" or flushes_made >= flushes_recorded


# --- events interleaved with writes, flushes before the first ---------------------------------


@st.composite
def port_cases(draw):
    flushes = draw(st.integers(0, 3))
    match_timing_check = draw(modes())
    # match=request serves the greeting at open, and a flush drops what is
    # due of it: that client makes none (match=sequence: fewer than recorded).
    made = st.integers(0, flushes) if match_timing_check[0] == "sequence" else st.just(0)
    return dict(modes=match_timing_check, flushes=flushes, flushes_made=draw(made),
                greeting=draw(st.sampled_from([b"", line_frame(b"hello")])),
                device_lines=draw(st.booleans()),
                exchanges=draw(exchanges(draw(st.integers(1, 3)), with_events=True)))


def run_port_case(tmp_path, modes, flushes, flushes_made, greeting, device_lines, exchanges):
    match, timing, check = modes
    records = [("modem_lines", lines_payload((True, True, False, True)))] if device_lines else []
    records += [("flush_input", b"{}")] * flushes
    if greeting:
        records.append(("rx", greeting))
    records += exchange_records(exchanges)
    path = write_records(tmp_path / "events.wtape", records, "serial")
    options = keys(match, timing, check)

    def describe():
        return f"keys: {options}\nflushes made: {flushes_made}\nrecords: {records}"

    port = wiretape.open_port(f'type=replay,file="{path}",timeout={DEADLINE},{options}')
    client = PortClient(port)
    for _ in range(flushes_made):
        port.flush_input()
    pending = greeting
    if greeting_due_at_open(match, flushes, flushes_made):
        assert client.read_exactly(len(greeting)) == greeting, describe()
        pending = b""
    for exchange in exchanges:
        for client_event in exchange.before:
            client.make(client_event)
        client.write(exchange.request[0])
        for client_event in exchange.between:
            client.make(client_event)
        for part in exchange.request[1:]:
            client.write(part)
        for client_event in exchange.after:
            client.make(client_event)
        # Past the recorded flushes: what they held is due with the answer.
        expected = pending + b"".join(exchange.response)
        got = client.read_exactly(len(expected))
        assert got == expected, f"served {got!r}, the recording says {expected!r}\n{describe()}"
        pending = b""
    port.close()  # unused=error: every byte and every recorded line change was used


@settings(max_examples=EXAMPLES, deadline=None, derandomize=EXAMPLES_FROM_ENV is None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(case=port_cases())
def test_events_among_writes_and_flushes_before_them_serve_what_the_recording_says(
        tmp_path_factory, case):
    match, timing, check = case["modes"]
    event(f"match={match} timing={timing} check={check}")
    event(f"flushes recorded {case['flushes']}, made {case['flushes_made']}")
    run_port_case(tmp_path_factory.mktemp("events"), **case)


# The shapes, in every bounded run whatever the property test drew.
def test_a_client_that_flushed_once_of_two_is_answered_at_its_write(tmp_path):
    for modes_ in [("sequence", "none", "data"), ("sequence", "causal", "timing")]:
        folder = tmp_path / "_".join(modes_)
        folder.mkdir()
        run_port_case(folder, modes_, 2, 1, b"", False,
                      [Exchange((b"PING:00001",), (b"STATUS",))])


def test_a_reset_pulse_and_the_baud_before_the_first_write_pass_check_timing(tmp_path):
    pulse = (ClientEvent("baud", 115200), ClientEvent("dtr", 0), ClientEvent("dtr", 1))
    run_port_case(tmp_path, ("sequence", "causal", "timing"), 1, 1, line_frame(b"boot"), True,
                  [Exchange((b"HEL", b"LO\n"), (b"OK\n",), before=pulse,
                            between=(ClientEvent("break", 2),), after=(ClientEvent("dtr", 0),))])


# --- reopens before the first write, on a virtual device -----------------------------------------


@st.composite
def reopen_cases(draw):
    return dict(modes=draw(modes()), reopens=draw(st.integers(1, 2)),
                flushes=[draw(st.integers(0, 2)) for _ in range(3)],
                greeting=draw(st.sampled_from([b"", line_frame(b"hello")])),
                exchanges=draw(exchanges(draw(st.integers(1, 2)), with_events=False)))


def run_reopen_case(tmp_path, modes, reopens, flushes, greeting, exchanges):
    """Client sessions that flush and leave without writing, then one that
    flushes and talks. A TCP client makes no flush: every recorded flush
    is one it made fewer than."""
    match, timing, check = modes
    records = []
    for number in range(reopens + 1):
        peer = f"127.0.0.1:{40001 + number}"
        records.append(("client_connect", connect(peer)))
        records += [("flush_input", b"{}")] * flushes[number]
        if number == reopens:
            if greeting:
                records.append(("rx", greeting))
            records += exchange_records(exchanges)
        records.append(("client_disconnect", disconnect(peer)))
        if number < reopens:
            records.append(("rx", b"said to nobody\n"))  # no client connected: never served
    path = write_records(tmp_path / "reopens.wtape", records, "tcp")
    options = keys(match, timing, check)

    def describe():
        return f"keys: {options}\nrecords: {json.dumps([(k, repr(d)) for k, d in records])}"

    handle = bridge.serve_replay(path, listen="127.0.0.1:0", replay_options=options, quiet=True)
    try:
        for number in range(1, reopens + 1):
            TcpClient(handle.address).close()
            wait_until(lambda: sum("disconnected" in m for m in handle.messages()) >= number,
                       DEADLINE, f"client {number}'s disconnect to be seen")
        client = TcpClient(handle.address)
        try:
            pending = greeting
            if greeting_due_at_open(match, flushes[reopens], 0):
                assert client.read_exactly(len(greeting)) == greeting, describe()
                pending = b""
            for exchange in exchanges:
                client.write(b"".join(exchange.request))
                expected = pending + b"".join(exchange.response)
                got = client.read_exactly(len(expected))
                assert got == expected, f"served {got!r}, the recording says {expected!r}\n{describe()}"
                pending = b""
            assert client.rest() == b"", describe()
        finally:
            client.close()
        wait_until(lambda: sum("disconnected" in m for m in handle.messages()) > reopens,
                   DEADLINE, "the last client's disconnect to be seen")
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    result = handle.result()
    assert result.ok, f"{result}\n{describe()}"


@settings(max_examples=max(10, EXAMPLES // 4), deadline=None, derandomize=EXAMPLES_FROM_ENV is None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(case=reopen_cases())
def test_reopens_and_flushes_before_the_first_write_serve_what_the_recording_says(
        tmp_path_factory, case):
    event(f"match={case['modes'][0]} check={case['modes'][2]} reopens={case['reopens']}")
    run_reopen_case(tmp_path_factory.mktemp("reopens"), **case)


def test_an_sdk_that_reopens_to_set_its_baud_is_answered_at_its_ping(tmp_path):
    run_reopen_case(tmp_path, ("sequence", "none", "data"), 1, [1, 2, 0], b"",
                    [Exchange((b"PING:00001",), (b"STATUS",))])
