"""wiretape+record://recordings/x.wtape records in a project that has no
recordings/ folder yet, as a pytest cassette does (docs/testing.md §3)."""

import os

import serial

import wiretape


def test_record_url_creates_the_folders_of_its_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with serial.serial_for_url("wiretape+record://recordings/sub/gps.wtape?options=type=loopback",
                               timeout=5) as port:
        port.write(b"$GP\n")
        assert port.read_until(b"\n") == b"$GP\n"
    recorded = [r.data for r in wiretape.SessionReader("recordings/sub/gps.wtape")
                if r.kind == "tx"]
    assert recorded == [b"$GP\n"]
    assert os.path.isdir(tmp_path / "recordings" / "sub")
