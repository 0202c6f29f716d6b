"""compress=zstd where sessions are recorded: the `log=` key, the proxy
(`wiretape record --compress zstd`, `serve -o --compress zstd`) and the
Recorder of several channels all write format 2.0, which reads back as
recorded."""

import socket

import pytest

from wiretape import _core, bridge, cli

DEADLINE = 30


def version(path):
    header = _core.SessionReader(str(path)).header
    return header.version_major, header.version_minor


def test_the_log_key_records_compressed(tmp_path):
    path = tmp_path / "log.wtape"
    port = _core.open_port(f"type=loopback,log={path},compress=zstd")
    port.write(b"hello\n")
    assert port.read(6, timeout=5) == b"hello\n"
    port.close()
    assert version(path) == (2, 0)
    assert [(r.kind, r.data) for r in _core.SessionReader(path) if r.kind in ("tx", "rx")] == [
        ("tx", b"hello\n"), ("rx", b"hello\n")]


def test_the_key_needs_log_and_takes_none_or_zstd(tmp_path):
    with pytest.raises(_core.OptionError, match="compress"):
        _core.open_port("type=loopback,compress=zstd")
    with pytest.raises(_core.OptionError, match="compress"):
        _core.open_port(f"type=loopback,log={tmp_path / 'x.wtape'},compress=lz4")


def test_the_proxy_records_compressed(tmp_path):
    out = tmp_path / "proxy.wtape"
    handle = bridge.record("type=loopback", out, listen="127.0.0.1:0", quiet=True,
                           compress="zstd")
    try:
        host, port = handle.address.rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=DEADLINE) as client:
            client.sendall(b"PING\n")
            received = b""
            while len(received) < 5:
                chunk = client.recv(16)
                assert chunk, "the proxy closed the connection"
                received += chunk
        assert received == b"PING\n"
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    assert handle.result().ok, handle.result()
    assert version(out) == (2, 0)
    data = [(r.kind, r.data) for r in _core.SessionReader(out) if r.kind in ("tx", "rx")]
    assert b"".join(d for k, d in data if k == "tx") == b"PING\n"
    assert b"".join(d for k, d in data if k == "rx") == b"PING\n"


def test_a_recorder_of_several_channels_records_compressed(tmp_path):
    path = tmp_path / "channels.wtape"
    with _core.Recorder(path, compress="zstd") as recorder:
        gps = recorder.open_port("name=gps,type=loopback")
        imu = recorder.open_port("name=imu,type=loopback")
        gps.write(b"$GPGGA\r\n")
        imu.write(b"IMU1")
        assert gps.read(8, timeout=5) == b"$GPGGA\r\n"
        assert imu.read(4, timeout=5) == b"IMU1"
    assert version(path) == (2, 0)
    channels = {c.name: c.id for c in _core.SessionReader(path).header.channels}
    got = [r.data for r in _core.SessionReader(path, channels["imu"]) if r.kind == "rx"]
    assert got == [b"IMU1"]


@pytest.mark.parametrize("command", ["record", "serve", "convert", "edit"])
def test_the_commands_take_compress(capsys, command):
    assert cli.main([command, "--help"]) == 0
    assert "--compress {none,zstd}" in capsys.readouterr().out
