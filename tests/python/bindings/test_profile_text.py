"""Text a profile makes from device bytes reaches Python as str, whatever
the bytes (issue 23): an NMEA sentence whose checksum is two bytes >= 0x80
used to make show, diff and replay fail with ``nanobind::str(): conversion
error!`` (a RuntimeError, exit 3 or 2) instead of naming a broken frame or a
mismatch. The C++ side (tests/cpp/replay/profile_builtin_test.cpp,
ProfileText) checks every profile's text over random bytes is UTF-8."""

import random

import pytest

import wiretape
from wiretape import _core, cli

# The sentence of the report: '*' then two bytes that are not ASCII.
BAD_CHECKSUM = b"$GPGGA,123519,4807.038,N*\xff\xfe\r\n"


def nmea(body: bytes) -> bytes:
    checksum = 0
    for byte in body:
        checksum ^= byte
    return b"$" + body + b"*%02X\r\n" % checksum


def random_streams():
    generator = random.Random(23)
    specials = b"\n\r$!*,\a\xfe\xfd"
    streams = [BAD_CHECKSUM, b"\xff\xfe\n\x1b]0;x\x07\n", b"V\xff\n00P\n\n", b"\xe9\xe9\r\a"]
    for _ in range(200):
        streams.append(bytes(generator.choice(specials) if generator.random() < 0.5
                             else generator.randrange(256)
                             for _ in range(generator.randrange(1, 200))))
    return streams


@pytest.mark.parametrize("name", _core.profile_names())
def test_names_and_descriptions_of_any_bytes_are_str_without_control_characters(name):
    profile = _core.find_profile(name)
    for stream in random_streams():
        for direction in ("tx", "rx"):
            for frame in profile.frames(direction, stream) + [stream]:
                for text in (profile.frame_name(direction, frame),
                             profile.describe(direction, frame)):
                    assert isinstance(text, str)
                    assert not any(ord(c) < 0x20 or ord(c) == 0x7F for c in text), repr(text)


@pytest.mark.parametrize("name", _core.profile_names())
def test_decoding_a_session_of_any_bytes_never_raises(name):
    records = [wiretape.Record(t_ns=k, kind="tx" if k % 2 else "rx", data=stream)
               for k, stream in enumerate(random_streams())]
    items = list(_core.find_profile(name).decode_session(records))
    assert all(isinstance(description, str) for _, kind, _, description in items
               if kind in ("tx", "rx"))


def write_session(path, records):
    with wiretape.SessionWriter(str(path), port_options="type=loopback") as writer:
        for t_ns, kind, data in records:
            writer.write(kind, t_ns, data)


def test_show_and_diff_name_the_broken_sentence(tmp_path, capsys):
    good, bad = tmp_path / "good.wtape", tmp_path / "bad.wtape"
    # The same sentence but for one field (the checksum is left out of the key).
    write_session(good, [(1, "rx", nmea(b"GPGGA,123519,4807.038,S"))])
    write_session(bad, [(1, "rx", BAD_CHECKSUM)])
    assert cli.main(["verify", str(bad)]) == cli.EXIT_OK
    capsys.readouterr()
    assert cli.main(["show", "--profile", "nmea", str(bad)]) == cli.EXIT_OK
    shown = capsys.readouterr().out
    assert "BROKEN (bad checksum field '*\\xff\\xfe')" in shown, shown
    assert cli.main(["diff", "--profile", "nmea", str(good), str(bad)]) == cli.EXIT_CHECK_FAILED
    captured = capsys.readouterr()
    assert "conversion error" not in captured.out + captured.err
    assert "\\xff\\xfe" in captured.out, captured.out


@pytest.mark.parametrize("mode", ["match=request", "match=sequence,check=data"])
def test_a_client_writing_such_a_sentence_gets_a_replay_mismatch(tmp_path, mode):
    session = tmp_path / "s.wtape"
    write_session(session, [(1, "tx", nmea(b"PXXX,1")), (2, "rx", nmea(b"GPTXT,ok"))])
    port = wiretape.open_port(f"type=replay,file={session},timing=none,profile=nmea,"
                              f"unused=ignore,{mode}")
    try:
        with pytest.raises(wiretape.ReplayMismatch) as raised:
            port.write_all(b"$PXXX,1*\xff\xfe\r\n")
        assert "\\xff\\xfe" in str(raised.value), str(raised.value)
    finally:
        port.close()
