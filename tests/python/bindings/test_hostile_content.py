"""Session files whose CRCs are all valid but whose content is hostile:
terminal escape sequences in header fields, header strings that are not
UTF-8, event JSON nested 50,000 deep, times of 2**64-1. What ``verify``
accepts, every command reads; what would break a command, ``verify`` rejects
with the reason and the record's offset."""

import json
import struct

import pytest

import wiretape
from wiretape import _core, cli
from wiretape.session import header_text

ESC = "\x1b"
HOSTILE_TEXT = f"{ESC}]0;owned{chr(7)}{ESC}[2J\u202eevil\u0085"
GOOD_HEADER = {
    "port_options": "type=loopback",
    "port_type": "loopback",
    "start_utc": "2026-01-02T03:04:05.000006Z",
    "wiretape_version": "0.1.0",
    "host": "h",
    "capture": "client",
    "metadata": {},
}
KIND_CODES = {kind["name"]: kind["code"] for kind in _core.RECORD_KINDS}
# The bound docs/session-format.md gives for t_ns.
MAX_T_NS = (2**32 - 1) * 10**9 + 999_999_999


def raw_session(path, records=(), header=None, header_json=None):
    """A session file built byte by byte with every CRC right, so that only
    its content can be wrong. `records` are (kind, t_ns, payload bytes).
    Returns the offset of each record."""
    if header_json is None:
        header_json = json.dumps(header if header is not None else GOOD_HEADER).encode()
    fixed = _core.SESSION_MAGIC + struct.pack("<HHI", *_core.SESSION_VERSION, len(header_json))
    data = bytearray(fixed + header_json)
    data += struct.pack("<I", _core.crc32c(bytes(data)))
    offsets = []
    for kind, t_ns, payload in records:
        offsets.append(len(data))
        record = struct.pack("<IBBHQ", len(payload), KIND_CODES[kind], 0, 0, t_ns) + payload
        data += record + struct.pack("<I", _core.crc32c(record))
    path.write_bytes(bytes(data))
    return offsets


def run(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def every_command(tmp_path, session):
    """argv of every command that reads a session file."""
    out = tmp_path / "out"
    return [
        ["show", session],
        ["show", session, "--format", "hex"],
        ["show", session, "--format", "jsonl"],
        ["show", session, "--profile", "lines"],
        ["stats", session],
        ["stats", session, "--json"],
        ["verify", session, "--json"],
        ["diff", session, session],
        ["convert", session, f"{out}.wtape"],
        ["convert", session, f"{out}.jsonl"],
        ["convert", session, f"{out}.pcapng"],
        ["convert", session, f"{out}.mcap"],
        ["convert", session, f"{out}.log", "--to", "flexiport"],
    ]


def nested(levels):
    return "[" * levels + "]" * levels


# --- 10: header text reaches a terminal escaped -----------------------------------


def test_header_text_escapes_what_a_terminal_would_obey_and_keeps_letters():
    assert header_text("José 日本 a=b,c") == "José 日本 a=b,c"
    assert header_text(f"{ESC}[31mred") == "\\x1b[31mred"
    assert header_text("a\nb\tc\\d") == "a\\nb\\tc\\\\d"
    assert header_text("\u202e\u0085\x7f") == "\\xe2\\x80\\xae\\xc2\\x85\\x7f"
    assert header_text(7) == "7"


def hostile_header_session(tmp_path):
    path = tmp_path / "hostile.wtape"
    with wiretape.SessionWriter(str(path), port_options=f"type=loopback,x={HOSTILE_TEXT}",
                                port_type=HOSTILE_TEXT, host=HOSTILE_TEXT,
                                wiretape_version=HOSTILE_TEXT,
                                metadata={HOSTILE_TEXT: HOSTILE_TEXT}) as writer:
        writer.write("tx", 1, b"A")
    return path


@pytest.mark.parametrize("argv", [["show"], ["show", "--format", "hex"], ["stats"],
                                  ["verify"], ["diff", "SELF"]])
def test_commands_print_header_fields_escaped(tmp_path, capsys, argv):
    session = hostile_header_session(tmp_path)
    argv = [session if arg == "SELF" else arg for arg in argv]
    code, out, err = run(capsys, argv[0], session, *argv[1:])
    assert code == 0, err
    for control in (ESC, chr(7), "\u202e", "\u0085"):
        assert control not in out + err, (control, out)
    if argv[0] in ("show", "stats"):
        assert "\\x1b]0;owned\\x07" in out


def test_stats_rows_escape_every_header_field(tmp_path):
    from wiretape.tools.stats import stats

    rows = dict(stats(hostile_header_session(tmp_path)).text_rows())
    for name in ("port_type", "port_options", "host", "wiretape_version", "metadata"):
        assert ESC not in rows[name] and "\\x1b" in rows[name], name


# --- 11: what verify accepts, every command reads ---------------------------------


def hostile_sessions(tmp_path):
    """name -> (path, offset of the record verify must name, or None when the
    header itself is refused)."""
    sessions = {}

    def add(name, records=(), **header):
        path = tmp_path / f"{name}.wtape"
        offsets = raw_session(path, records, **header)
        sessions[name] = (path, offsets[-1] if offsets else None)

    add("header_not_utf8", header_json=b'{"port_options":"type=serial,device=\xff","capture":"client"}')
    add("metadata_not_utf8", header_json=b'{"metadata":{"k":"\xc0\xaf"}}')
    add("header_lone_surrogate", header_json=b'{"host":"\\ud800"}')
    add("start_utc_year_9999", header={**GOOD_HEADER, "start_utc": "9999-12-31T23:59:59Z"})
    add("event_nested_50000", [("tx", 1, b"A"),
                               ("settings", 2, ('{"baud":9600,"x":' + nested(50_000) + "}").encode())])
    add("event_nested_65", [("close", 2, ('{"x":' + nested(64) + "}").encode())])
    add("event_not_utf8", [("device_lost", 2, b'{"error":"\xff"}')])
    add("event_not_an_object", [("close", 2, b"[1]")])
    add("t_ns_2_64_minus_1", [("tx", 1, b"A"), ("rx", 2**64 - 1, b"B")])
    add("t_ns_just_beyond", [("rx", MAX_T_NS + 1, b"B")])
    return sessions


def test_verify_rejects_hostile_content_with_the_reason_and_the_offset(tmp_path, capsys):
    for name, (path, offset) in hostile_sessions(tmp_path).items():
        code, out, err = run(capsys, "verify", path, "--json")
        assert code == 1, (name, out, err)
        result = json.loads(out)
        assert result["ok"] is False, name
        if offset is not None:
            assert result["offset"] == offset, (name, result)
            assert f"byte {offset}" in result["message"], (name, result)
        else:
            assert result["offset"] is not None and result["offset"] >= 16, (name, result)
        assert ESC not in result["message"]


def test_hostile_content_fails_every_command_cleanly(tmp_path, capsys):
    """No crash, no traceback, no runtime error: a damaged file (exit 1).
    diff and convert work up to the damage; their exit codes for damaged
    input are settled elsewhere, so here they need only not crash."""
    for name, (path, _) in hostile_sessions(tmp_path).items():
        for argv in every_command(tmp_path, path):
            code, out, err = run(capsys, *argv)
            expected = (0, 1) if argv[0] in ("diff", "convert") else (1,)
            assert code in expected, (name, argv, code, err)
            assert "Traceback" not in err and "RecursionError" not in err, (name, argv, err)


def test_content_at_the_limits_is_accepted_by_verify_and_every_command(tmp_path, capsys):
    path = tmp_path / "limits.wtape"
    raw_session(path, [
        ("open", 0, b'{"description":"caf\xc3\xa9 \xf0\x9f\x98\x80"}'),
        ("tx", 1, b"VV\n"),
        ("settings", 2, ('{"baud":9600,"deep":' + nested(63) + "}").encode()),
        ("rx", MAX_T_NS, b"late"),
    ], header={**GOOD_HEADER, "start_utc": "2261-12-31T23:59:59.999999Z",
               "host": "h\u00f4te \U0001f600", "metadata": {"clé": "värde"}})
    code, out, err = run(capsys, "verify", path)
    assert code == 0, out + err
    for argv in every_command(tmp_path, path):
        code, out, err = run(capsys, *argv)
        assert code == 0, (argv, out, err)


def test_replay_of_a_file_verify_accepts_opens(tmp_path):
    path = tmp_path / "limits.wtape"
    raw_session(path, [("tx", 1, b"Q"), ("rx", MAX_T_NS, b"A")])
    port = wiretape.open_port(f"type=replay,file={path},timing=none,unused=ignore")
    port.write(b"Q")
    assert port.read(1, timeout=1) == b"A"
    port.close()


def test_replay_of_a_hostile_file_stops_at_the_damage(tmp_path):
    path = tmp_path / "late.wtape"
    raw_session(path, [("tx", 1, b"Q"), ("rx", 2**64 - 1, b"A")])
    port = wiretape.open_port(f"type=replay,file={path},timing=none,unused=ignore")
    port.write(b"Q")
    assert port.read(1, timeout=0.2) == b""
    port.close()


def test_the_writer_refuses_what_the_reader_would(tmp_path):
    with pytest.raises(wiretape.OptionError, match="start_utc"):
        wiretape.SessionWriter(str(tmp_path / "a.wtape"), start_utc="9999-01-01T00:00:00Z")
