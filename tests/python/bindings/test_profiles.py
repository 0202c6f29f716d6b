"""Protocol profiles from Python: the registry, and the scip profile's
decoding of whole sessions for ``wiretape show --decode scip``.

The golden file ``tests/data/golden/urg04lx_gd.scip.txt`` holds the decoded
timeline of one small recording, as show prints it; regenerate it with
``python tests/python/bindings/test_profiles.py`` after a deliberate change to the
texts. The C++ tests (tests/cpp/replay/profile_test.cpp) check that every split of
the repository's recordings frames the same."""

import json
import pathlib
import sys
import textwrap
import time

import pytest

from wiretape import _core

from real_recordings import FLEXIPORT_DIR

ROOT = pathlib.Path(__file__).resolve().parents[3]
GOLDEN = ROOT / "tests" / "data" / "golden"
RECORDINGS = ROOT / "examples" / "hokuyo" / "recordings"
GOLDEN_RECORDING = RECORDINGS / "urg04lx_gd.wtape"
GOLDEN_TEXT = GOLDEN / "urg04lx_gd.scip.txt"

def scip_sessions():
    """Every SCIP recording the repository has: the Hokuyo example's and the
    real devices' flexiport logs (``name.log`` for name.logr + name.logw)."""
    sessions = sorted(RECORDINGS.glob("*.wtape"))
    sessions += sorted(path.with_suffix(".log") for path in FLEXIPORT_DIR.glob("*.logr"))
    return sessions


def test_the_real_devices_logs_are_among_the_sessions():
    logs = [path for path in scip_sessions() if path.suffix == ".log"]
    assert {path.name for path in logs} >= {"urg04lx_2011.log", "utm30lx_2011.log"}


def show_lines(items):
    """The timeline as ``wiretape show --decode scip`` prints it."""
    lines = []
    for t_ns, kind, data, description in items:
        if description is None:
            event = json.loads(data.decode("utf-8")) if data else {}
            description = json.dumps(event) if event else ""
        lines.append(f"{t_ns / 1e9:+.6f}s  {kind}  {description}")
    return lines


def test_scip_comes_first_in_the_registry():
    names = _core.profile_names()
    assert names[0] == "scip"
    assert all(_core.find_profile(name).name == name for name in names)


def test_an_unknown_profile_is_an_option_error_listing_the_known_ones():
    with pytest.raises(_core.OptionError) as raised:
        _core.find_profile("nmea-xyz")
    message = str(raised.value)
    assert "unknown profile 'nmea-xyz'" in message
    for name in _core.profile_names():
        assert name in message


def test_scip_frames_names_and_match_keys():
    scip = _core.find_profile("scip")
    assert scip.frames("tx", b"VV\nPP\r\nII\rGD0044072501\n") == [b"VV\n", b"PP\r\n", b"II\r", b"GD0044072501\n"]
    assert scip.frames("rx", b"VV\n00P\nA\n\nBM\n02R\n\nGD") == [b"VV\n00P\nA\n\n", b"BM\n02R\n\n", b"GD"]
    assert scip.frame_name("tx", b"GD0044072501\n") == "GD"
    assert scip.frame_name("tx", b"SCIP2.0\n") == "SCIP2.0"
    assert scip.match_key(b"VV\r\n") == b"VV"
    assert scip.describe("rx", b"BM\n02R\n\n") == (
        "BM                       reply to BM (laser on): status 02, 0 data lines, 8 bytes")
    with pytest.raises(ValueError, match="direction must be 'tx' or 'rx'"):
        scip.describe("up", b"VV\n")


def test_lines_frames_each_direction_at_line_feeds():
    lines = _core.find_profile("lines")
    assert lines.frames("rx", b"$GPGGA,1*47\r\n$GPRMC") == [b"$GPGGA,1*47\r\n", b"$GPRMC"]
    assert lines.frame_name("tx", b"AT+CSQ\n") == "AT+CSQ"
    records = [_core.Record(1, "tx", b"AT"), _core.Record(2, "tx", b"\nATI\n"), _core.Record(3, "rx", b"OK\n")]
    assert list(lines.decode_session(records)) == [
        (1, "tx", b"AT\n", "AT\\n"), (2, "tx", b"ATI\n", "ATI\\n"), (3, "rx", b"OK\n", "OK\\n")]


def test_a_recording_decodes_as_the_golden_file_says():
    items = list(_core.find_profile("scip").decode_session(GOLDEN_RECORDING))
    assert show_lines(items) == GOLDEN_TEXT.read_text().splitlines()


def test_decoding_a_path_and_an_iterable_of_records_agree():
    scip = _core.find_profile("scip")
    for path in scip_sessions():
        from_path = list(scip.decode_session(path))
        from_records = list(scip.decode_session(_core.SessionReader(path)))
        assert from_path == from_records, path
        assert from_path, path


def test_a_damaged_session_decodes_up_to_the_damage():
    decoded = _core.find_profile("scip").decode_session(GOLDEN / "damaged.wtape")
    items = list(decoded)
    assert decoded.damage is not None
    assert decoded.damage.offset > 0
    assert len(items) > 0


def test_bad_sources_are_clear_errors():
    scip = _core.find_profile("scip")
    with pytest.raises(_core.PortError, match="no-such-session.wtape: cannot open"):
        scip.decode_session(ROOT / "no-such-session.wtape")
    with pytest.raises(TypeError, match="has no t_ns"):
        list(scip.decode_session([object()]))
    with pytest.raises(TypeError, match="data must be bytes, not str"):
        list(scip.decode_session([_Fake(1, "tx", "VV")]))
    with pytest.raises(TypeError, match="t_ns must be an integer 0..2"):
        list(scip.decode_session([_Fake(-1, "tx", b"VV")]))
    with pytest.raises(TypeError, match="t_ns must be an integer"):
        list(scip.decode_session([_Fake(2**70, "tx", b"VV")]))


class _Fake:
    def __init__(self, t_ns, kind, data):
        self.t_ns, self.kind, self.data = t_ns, kind, data


def test_events_keep_their_kind_and_payload():
    records = [_core.Record(5, "open", b"{}"), _core.Record(6, "tx", b"VV\n"),
               _core.Record(7, 0x7f, b"opaque")]
    items = list(_core.find_profile("scip").decode_session(records))
    assert items[0] == (5, "open", b"{}", None)
    assert items[1][:3] == (6, "tx", b"VV\n")
    assert items[2][2:] == (b"opaque", None)


if __name__ == "__main__":
    # Regenerates the golden file from the profile (review the diff).
    lines = show_lines(_core.find_profile("scip").decode_session(GOLDEN_RECORDING))
    GOLDEN_TEXT.write_text("\n".join(lines) + "\n")
    print(f"wrote {GOLDEN_TEXT} ({len(lines)} lines)", file=sys.stderr)


# --- replay with a profile, and the gap rule, with a line-based client -------

LINE_EXCHANGES = [(b"MEAS:VOLT?\n", b"+1.25\n"),
                  (b"MEAS:VOLT?\nMEAS:CURR?\n", b"+1.25\n+0.03\n"),  # sent as one burst
                  (b"*IDN?\n", b"ACME,PSU-1,42\n"),
                  (b"MEAS:VOLT?\n", b"+1.26\n"),
                  (b"OUTP ON\n", b"")]


def line_session(session_file):
    records = []
    t = 1_000
    for request, response in LINE_EXCHANGES:
        records.append(("tx", t, request))
        if response:
            records.append(("rx", t + 100, response))
        t += 10_000
    return session_file(records)


def send_split_and_paused(port, stream, rng, max_pause_s):
    """The client: its bytes cut at random places, random pauses between."""
    at = 0
    while at < len(stream):
        size = rng.randint(1, 6)
        port.write(stream[at:at + size])
        at += size
        # The client's own pace (a stimulus, not a synchronisation).
        time.sleep(rng.uniform(0, max_pause_s))


def test_a_line_client_splitting_and_pausing_at_random_replays_with_the_gap_rule(session_file):
    """No profile: `MEAS:VOLT?\\n` is also the start of the burst recorded
    earlier, so the matcher waits (gap) before taking it alone."""
    import random
    path = line_session(session_file)
    stream = b"".join(request for request, _ in LINE_EXCHANGES)
    expected = b"".join(response for _, response in LINE_EXCHANGES)
    for seed in range(3):
        rng = random.Random(seed)
        port = _core.open_port(f"type=replay,file={path},timing=none,match=request,"
                               "gap=1000,timeout=10")
        try:
            send_split_and_paused(port, stream, rng, 0.02)
            assert port.read_exactly(len(expected)) == expected, seed
        finally:
            port.close()


def test_a_line_client_through_the_url_handler_with_profile_lines(session_file):
    """profile=lines: each line is a request frame; frames decide, any pause."""
    import random
    import serial
    path = line_session(session_file)
    rng = random.Random(7)
    link = serial.serial_for_url(
        f"wiretape://{path}?timing=none&match=request&profile=lines&unused=ignore", timeout=10)
    try:
        for request, response in [(b"*IDN?\n", b"ACME,PSU-1,42\n"),
                                  (b"OUTP ON\n", b""),
                                  (b"MEAS:VOLT?\n", b"+1.25\n"),
                                  # The burst's first frame: the device answered
                                  # only after its second.
                                  (b"MEAS:VOLT?\n", b""),
                                  (b"MEAS:CURR?\n", b"+1.25\n+0.03\n")]:
            send_split_and_paused(link, request, rng, 0.01)
            if response:
                assert link.read(len(response)) == response, request
    finally:
        link.close()


def test_bad_profile_names_in_replay_options_are_option_errors(session_file):
    path = line_session(session_file)
    with pytest.raises(_core.OptionError, match="unknown profile 'modbus-xyz'") as error:
        _core.open_port(f"type=replay,file={path},match=request,profile=modbus-xyz")
    assert error.value.key == "profile"


pytest_plugins = ["pytester"]

MARKED_TEST = textwrap.dedent("""
    import pytest

    @pytest.mark.wiretape(match="request", profile="lines")
    def test_lines(wiretape_port):
        for line in ORDER:
            wiretape_port.write_all(line)
            assert wiretape_port.read_exactly(len(line), timeout=5) == line
""")


def test_the_pytest_marker_passes_profile_to_the_replay(pytester):
    """Recorded in one order from wiretape's loopback (an echo), replayed
    with profile=lines from the marker in another."""
    pytester.makepyfile(test_marked="ORDER = [b'A1\\n', b'B2\\n']\n" + MARKED_TEST)
    pytester.runpytest("--wiretape-record=once",
                       "--wiretape-device=type=loopback").assert_outcomes(passed=1)
    pytester.makepyfile(test_marked="ORDER = [b'B2\\n', b'A1\\n']\n" + MARKED_TEST)
    pytester.runpytest().assert_outcomes(passed=1)
    pytester.makepyfile(test_marked="ORDER = [b'B2\\n', b'C3\\n']\n" + MARKED_TEST)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*the client's frame C3 matches no unused exchange*"])


def modbus_tcp(tid, pdu):
    return tid.to_bytes(2, "big") + b"\0\0" + (len(pdu) + 1).to_bytes(2, "big") + b"\x01" + pdu


def test_diff_with_a_profile_ignores_what_the_key_leaves_out(session_file, tmp_path):
    from wiretape.tools.diff import diff
    poll, reply = b"\x03\x00\x00\x00\x01", b"\x03\x02\x00\x2a"
    a = session_file([("tx", 1, modbus_tcp(1, poll)), ("rx", 2, modbus_tcp(1, reply))], name="a.wtape")
    b = session_file([("tx", 1, modbus_tcp(9, poll)), ("rx", 2, modbus_tcp(9, reply))], name="b.wtape")
    c = session_file([("tx", 1, modbus_tcp(9, b"\x03\x00\x07\x00\x01")),
                      ("rx", 2, modbus_tcp(9, reply))], name="c.wtape")
    assert not diff(a, b).identical
    assert diff(a, b, profile="modbus-tcp").identical
    different = diff(a, c, profile="modbus-tcp")
    assert not different.identical
    report = different.report()
    assert "tx: first difference at frame 0" in report
    assert "address 7" in report and "address 0" in report
    assert "rx: identical by key" in report


def test_cli_replay_and_diff_take_profile(session_file, tmp_path):
    import subprocess
    poll, reply = b"\x03\x00\x00\x00\x01", b"\x03\x02\x00\x2a"
    a = session_file([("tx", 1, modbus_tcp(1, poll)), ("rx", 2, modbus_tcp(1, reply))], name="a.wtape")
    b = session_file([("tx", 1, modbus_tcp(9, poll)), ("rx", 2, modbus_tcp(9, reply))], name="b.wtape")
    wiretape_cli = [sys.executable, "-m", "wiretape.cli"]
    done = subprocess.run(wiretape_cli + ["diff", "--profile", "modbus-tcp", str(a), str(b)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "identical by key" in done.stdout
    done = subprocess.run(wiretape_cli + ["diff", "--profile", "nope", str(a), str(b)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "nope" in done.stderr
    from wiretape.cli import build_parser, replay_options_of
    args = build_parser().parse_args(["replay", str(a), "--match", "request", "--profile",
                                      "modbus-tcp", "--gap", "20", "--listen", "127.0.0.1:0"])
    assert "profile=modbus-tcp" in replay_options_of(args)
    assert "gap=20" in replay_options_of(args)


def test_python_callables_as_match_key_and_response_fix(session_file):
    from wiretape.profiles import callable_profile
    path = session_file([("tx", 1, b"get 1 temp\n"), ("rx", 2, b"temp 20\n"),
                         ("tx", 3, b"get 2 volt\n"), ("rx", 4, b"volt 5\n")])
    calls = []

    def key(request):  # the request number varies from run to run
        calls.append(request)
        return request.split(b" ", 2)[2]

    def fix(recorded, actual, response):
        return actual.split(b" ")[1] + b": " + response

    name = callable_profile("lines", match_key=key, fix_response=fix)
    port = _core.open_port(f"type=replay,file={path},timing=none,match=request,"
                           f"profile={name},timeout=10")
    try:
        port.write(b"get 7 volt\n")
        assert port.read_exactly(len(b"7: volt 5\n")) == b"7: volt 5\n"
        port.write(b"get 8 temp\n")
        assert port.read_exactly(len(b"8: temp 20\n")) == b"8: temp 20\n"
    finally:
        port.close()
    assert b"get 7 volt\n" in calls
    with pytest.raises(_core.OptionError, match="unknown profile"):
        callable_profile("nope", match_key=key)
    with pytest.raises(TypeError):
        callable_profile("lines", match_key="not callable")


CALLABLE_MARKED_TEST = textwrap.dedent("""
    import pytest

    def last_word(request):
        return request.split()[-1]

    @pytest.mark.wiretape(match="request", profile="lines", match_key=last_word)
    def test_lines(wiretape_port):
        for line, answer in ORDER:
            wiretape_port.write_all(line)
            assert wiretape_port.read_exactly(len(answer), timeout=5) == answer
""")


def test_the_pytest_marker_takes_python_callables(pytester):
    pytester.makepyfile(test_marked="ORDER = [(b'1 A\\n', b'1 A\\n'), (b'2 B\\n', b'2 B\\n')]\n"
                        + CALLABLE_MARKED_TEST)
    pytester.runpytest("--wiretape-record=once",
                       "--wiretape-device=type=loopback").assert_outcomes(passed=1)
    # Other numbers, another order: the key is the last word.
    pytester.makepyfile(test_marked="ORDER = [(b'9 B\\n', b'2 B\\n'), (b'8 A\\n', b'1 A\\n')]\n"
                        + CALLABLE_MARKED_TEST)
    pytester.runpytest().assert_outcomes(passed=1)


@pytest.mark.parametrize("name", ["nmea", "slcan", "modbus-rtu", "modbus-tcp", "mavlink"])
def test_every_profile_frames_random_bytes_completely(name):
    """Hostile input: every byte lands in exactly one frame, in order, in any
    split; nothing hangs or crashes."""
    import random
    profile = _core.find_profile(name)
    rng = random.Random(name)
    for _ in range(50):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 2000)))
        frames = profile.frames("tx", data)
        assert b"".join(frames) == data
        assert all(frames)
        for frame in frames:
            profile.match_key(frame)
            profile.frame_name("tx", frame)
            profile.describe("rx", frame)


def crc16_modbus(data):
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc.to_bytes(2, "little")


def nmea_sentence(body):
    checksum = 0
    for byte in body:
        checksum ^= byte
    return b"$" + body + b"*%02X\r\n" % checksum


ONE_REQUEST = {
    "nmea": nmea_sentence(b"PXXX,1"),
    "slcan": b"O\r",
    "modbus-rtu": b"\x01\x03\x00\x00\x00\x01" + crc16_modbus(b"\x01\x03\x00\x00\x00\x01"),
    "modbus-tcp": modbus_tcp(1, b"\x03\x00\x00\x00\x01"),
    # A v1 packet of a message whose CRC_EXTRA the profile does not check.
    "mavlink": b"\xfe\x00\x00\x01\x01\xc8\x00\x00",
}


@pytest.mark.parametrize("name", ["nmea", "slcan", "modbus-rtu", "modbus-tcp", "mavlink"])
def test_random_client_bytes_against_a_profile_are_mismatches_or_ignored(name, session_file):
    import random
    path = session_file([("tx", 1, ONE_REQUEST[name]), ("rx", 2, b"ok\r\n")])
    rng = random.Random(name)
    data = bytes(rng.randrange(256) for _ in range(3000))
    silent = _core.open_port(f"type=replay,file={path},timing=none,match=request,"
                             f"profile={name},unmatched=silent,unused=ignore,timeout=0.05")
    try:
        silent.write(data)
        assert silent.read(100) in (b"", b"ok\r\n")
    finally:
        silent.close()
    strict = _core.open_port(f"type=replay,file={path},timing=none,match=request,"
                             f"profile={name},unused=ignore,timeout=0.05")
    try:
        for at in range(0, len(data), 97):
            try:
                strict.write(data[at:at + 97])
            except _core.ReplayMismatch as mismatch:
                assert "replay mismatch" in str(mismatch)
    finally:
        strict.close()
