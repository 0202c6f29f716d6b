"""type=replay on a session of several ports from Python (DESIGN.md section
19): channel=, the causal order across channels, reports naming the
channel."""

from __future__ import annotations

import threading

import pytest

import wiretape
from wiretape import _core as core
from wiretape import open_port

MS = 1_000_000


def write_channels(path, channels, records):
    header = core.SessionHeader()
    header.channels = [
        core.Channel(id=i, name=name, port_type=port_type, port_options=f"type={port_type}")
        for i, (name, port_type) in enumerate(channels)
    ]
    header.port_type = channels[0][1]
    writer = core.SessionWriter(str(path), header)
    for channel, kind, t_ns, data in records:
        writer.write(kind, t_ns, data, channel=channel)
    writer.close()
    return str(path)


@pytest.fixture
def lidar(tmp_path):
    return write_channels(
        tmp_path / "lidar.wtape",
        [("cmd", "tcp"), ("data", "udp")],
        [
            (0, "tx", 100 * MS, b"START\n"),
            (0, "rx", 101 * MS, b"OK\n"),
            (1, "rx", 120 * MS, b"D1"),
            (1, "rx", 130 * MS, b"D2"),
        ],
    )


def read_exactly(port, size):
    got = b""
    while len(got) < size:
        chunk = port.read(size - len(got))
        if not chunk:
            break
        got += chunk
    return got


def test_each_channel_replays_its_own_bytes(lidar):
    cmd = open_port(f'type=replay,timing=none,timeout=10,file="{lidar}",channel=cmd')
    data = open_port(f'type=replay,timing=none,timeout=10,file="{lidar}",channel=data')
    assert read_exactly(data, 4) == b"D1D2"
    cmd.write(b"START\n")
    assert read_exactly(cmd, 3) == b"OK\n"


def test_causal_data_waits_for_the_start_command(lidar):
    cmd = open_port(f'type=replay,timing=causal,timeout=10,file="{lidar}",channel=cmd')
    data = open_port(f'type=replay,timing=causal,timeout=10,file="{lidar}",channel=data')
    started = threading.Event()
    result = {}

    def reader():
        result["data"] = read_exactly(data, 4)
        result["early"] = not started.is_set()

    thread = threading.Thread(target=reader)
    thread.start()
    # D1 alone would be due 120 ms after the open.
    assert not data.wait_readable(0.4)
    started.set()
    cmd.write(b"START\n")
    thread.join(10)
    assert result == {"data": b"D1D2", "early": False}


def test_a_bad_channel_names_the_key_and_the_channels(lidar):
    with pytest.raises(wiretape.OptionError) as missing:
        open_port(f'type=replay,file="{lidar}"')
    assert missing.value.key == "channel"
    assert "cmd, data" in str(missing.value)
    with pytest.raises(wiretape.OptionError) as unknown:
        open_port(f'type=replay,file="{lidar}",channel=dat')
    assert unknown.value.key == "channel"
    assert "did you mean 'data'?" in str(unknown.value)


def test_a_mismatch_names_the_channel(lidar):
    cmd = open_port(f'type=replay,timing=none,unused=ignore,timeout=10,file="{lidar}",channel=cmd')
    with pytest.raises(wiretape.ReplayMismatch, match="channel cmd: "):
        cmd.write(b"STOP\n")
