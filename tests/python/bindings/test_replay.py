"""type=replay from Python: chunking independence (hypothesis), request
mode, mismatches, the end of the session and the pollable handle."""

from __future__ import annotations

import os
import select
import tempfile
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from real_recordings import flexiport_log

from wiretape import _core as core
import wiretape
from wiretape import open_port


def write_session(path, records, port_type="serial"):
    with core.SessionWriter(str(path), port_type=port_type) as writer:
        for kind, t_ns, data in records:
            writer.write(kind, t_ns, data)
    return str(path)


def replay(path, keys="timing=none"):
    return open_port(f'type=replay,timeout=5,{keys},file="{path}"')


SESSION = [
    ("rx", 0, b"HELLO\n"),
    ("tx", 10_000_000, b"PING\n"),
    ("rx", 20_000_000, b"PONG\n"),
    ("tx", 30_000_000, b"TIME\n"),
    ("rx", 40_000_000, b"12:00\n"),
]

chunks = st.binary(min_size=1, max_size=40)
sessions = st.lists(st.tuples(st.sampled_from(["rx", "tx"]), chunks), min_size=1, max_size=30)
splits = st.lists(st.integers(min_value=1, max_value=50), min_size=1, max_size=20)


def stream(records, kind):
    return b"".join(data for k, data in records if k == kind)


@settings(max_examples=60, deadline=None)
@given(records=sessions, write_sizes=splits, read_sizes=splits, order=st.randoms(use_true_random=False))
def test_any_split_of_the_same_streams_replays_the_same(records, write_sizes, read_sizes, order):
    with tempfile.TemporaryDirectory() as tmp:
        path = write_session(
            os.path.join(tmp, "s.wtape"),
            [(kind, i * 1000, data) for i, (kind, data) in enumerate(records)],
        )
        port = replay(path, "timing=none,unused=error")
        to_write = stream(records, "tx")
        expected = stream(records, "rx")
        written, got, step = 0, b"", 0
        while written < len(to_write) or len(got) < len(expected):
            step += 1
            if written < len(to_write) and order.random() < 0.5:
                n = write_sizes[step % len(write_sizes)]
                written += port.write_all(to_write[written : written + n])
            else:
                timeout = 0 if written < len(to_write) else 5
                data = port.read(read_sizes[step % len(read_sizes)], timeout=timeout)
                if not data and written == len(to_write):
                    break
                got += data
        assert got == expected
        port.close()  # unused=error: everything was consumed


@settings(max_examples=40, deadline=None)
@given(order=st.permutations([b"VV\n", b"PP\n", b"II\n", b"MD\n"]), sizes=splits)
def test_request_mode_answers_commands_in_any_order_and_split(order, sizes):
    answers = {b"VV\n": b"version\n", b"PP\n": b"params\n", b"II\n": b"info\n", b"MD\n": b"scan\nscan\n"}
    records, t = [], 0
    for command in [b"VV\n", b"PP\n", b"II\n", b"MD\n"]:
        records.append(("tx", t, command))
        records.append(("rx", t + 1, answers[command][:5]))
        records.append(("rx", t + 2, answers[command][5:]))
        t += 10
    with tempfile.TemporaryDirectory() as tmp:
        port = replay(write_session(os.path.join(tmp, "s.wtape"), records), "timing=none,match=request")
        wire = b"".join(order)
        position, k = 0, 0
        while position < len(wire):
            n = sizes[k % len(sizes)]
            port.write_all(wire[position : position + n])
            position += n
            k += 1
        assert port.read_exactly(sum(len(answers[c]) for c in order)) == b"".join(answers[c] for c in order)


def test_mismatch_raises_replay_mismatch_with_its_fields(tmp_path):
    port = replay(write_session(tmp_path / "s.wtape", SESSION))
    assert port.read_line() == b"HELLO\n"
    port.write(b"PING\n")
    with pytest.raises(wiretape._core.ReplayMismatch) as caught:
        port.write(b"TIMX\n")
    error = caught.value
    assert error.tx_offset == 8
    assert error.session_time_ns == 30_000_000
    assert "58 0a  |X.|" in str(error)
    assert "offset 8" in str(error)


def test_greeting_at_open_and_answers_only_after_their_request(tmp_path):
    port = replay(write_session(tmp_path / "s.wtape", SESSION))
    assert port.read(100) == b"HELLO\n"
    assert port.read(100, timeout=0) == b""
    port.write(b"PI")
    assert port.available() == 0
    port.write(b"NG\n")
    assert port.read(100) == b"PONG\n"


def test_after_the_end_reads_time_out_and_blocking_reads_raise(tmp_path):
    port = replay(write_session(tmp_path / "s.wtape", [("rx", 0, b"x")]))
    assert port.read(10) == b"x"
    start = time.monotonic()
    assert port.read(10, timeout=0.05) == b""
    assert time.monotonic() - start >= 0.04
    with pytest.raises(core.PortClosed):
        port.read(10, timeout=None)
    closed = replay(write_session(tmp_path / "t.wtape", [("rx", 0, b"x")]), "timing=none,at_end=closed")
    assert closed.read(10) == b"x"
    with pytest.raises(core.PortClosed):
        closed.read(10, timeout=1)


def test_recorded_device_loss_raises_port_closed(tmp_path):
    port = replay(write_session(tmp_path / "s.wtape", [("rx", 0, b"bye"), ("device_lost", 1, b"")]))
    assert port.read_exactly(3) == b"bye"
    with pytest.raises(core.PortClosed):
        port.read(1)


def test_handle_becomes_readable_when_timed_data_falls_due(tmp_path):
    port = replay(write_session(tmp_path / "s.wtape", [("tx", 0, b"Q"), ("rx", 80_000_000, b"A")]),
                  "timing=causal")
    fd = port.native_handle()
    assert select.select([fd], [], [], 0)[0] == []
    port.write(b"Q")
    assert select.select([fd], [], [], 0)[0] == []
    assert select.select([fd], [], [], 5)[0] == [fd]
    assert port.available() == 1
    assert port.read(1) == b"A"
    assert select.select([fd], [], [], 0)[0] == []


def test_bad_replay_options_name_the_key(tmp_path):
    path = write_session(tmp_path / "s.wtape", SESSION)
    with pytest.raises(core.OptionError) as caught:
        replay(path, "timing=none,check=timing")
    assert caught.value.key == "check"
    with pytest.raises(core.OptionError) as caught:
        replay(path, "timing=sometimes")
    assert caught.value.key == "timing"


def test_flexiport_recording_replays_in_request_mode():
    log = flexiport_log("urg04lx_2011")
    port = open_port(f"type=replay,timing=none,match=request,unused=ignore,timeout=5,file={log}")
    port.write(b"PP\n")
    reply = port.read_until(b"\n\n")
    assert reply.startswith(b"PP\n00P\n")
    assert b"MODL:URG-04LX" in reply
