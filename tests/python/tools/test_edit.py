"""``wiretape edit``: cutting, redacting and dropping metadata, what the
header says afterwards, and bad input (docs/cli.md "edit")."""

import json
import os
import pathlib
import subprocess
import sys

import pytest

from wiretape import _core
from wiretape.tools.edit import MAX_SPAN, edit, parse_cut, parse_redaction

ROOT = pathlib.Path(__file__).resolve().parents[3]
GD = ROOT / "examples" / "hokuyo" / "recordings" / "urg04lx_gd.wtape"


def wiretape(*args):
    return subprocess.run([sys.executable, "-m", "wiretape.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=60)


def records(path):
    return [(r.t_ns, r.kind, r.data) for r in _core.SessionReader(path)]


def write_session(path, items, metadata=None, port_options="type=serial,device=/dev/ttyUSB0"):
    with _core.SessionWriter(path, capture="wire", port_type="serial", port_options=port_options,
                             metadata=metadata or {}, start_utc="2026-11-24T00:00:00Z",
                             host="alices-laptop") as writer:
        for t_ns, kind, data in items:
            writer.write(kind, t_ns, data)
    return path


def direction_bytes(path, kind):
    return b"".join(data for _, k, data in records(path) if k == kind)


def redaction_ranges(path):
    """[(record index among rx/tx, offset, length)] from the redaction events."""
    ranges, pending, index = [], [], -1
    for _, kind, data in records(path):
        if kind == "redaction":
            assert _core.record_content_problem("redaction", 0, data) is None
            event = json.loads(data)
            pending.append((event["offset"], event["length"]))
        elif kind in ("rx", "tx"):
            index += 1
            ranges += [(index, offset, length) for offset, length in pending]
            pending = []
    assert pending == [], "a redaction event must precede an rx or tx record"
    return ranges


def test_redaction_scrubs_matches_across_records_keeps_lengths_and_marks_them(tmp_path):
    src = write_session(tmp_path / "in.wtape", [
        (0, "open", b'{"description":"serial /dev/ttyUSB0"}'),
        (10, "tx", b"login al"),
        (20, "tx", b"ice pw=hun"),
        (30, "tx", b"ter2\n"),
        (40, "rx", b"welcome alice\n"),
    ])
    result = edit(src, tmp_path / "out.wtape",
                  redact=[parse_redaction(r"pw\=\w+"), parse_redaction("alice=#")])
    out = tmp_path / "out.wtape"
    assert direction_bytes(out, "tx") == b"login ##### **********\n"
    assert direction_bytes(out, "rx") == b"welcome #####\n"
    assert [len(d) for _, k, d in records(out) if k == "tx"] == [8, 10, 5]
    # "alice" spans the first two tx records, the password the last two.
    assert redaction_ranges(out) == [(0, 6, 2), (1, 0, 3), (1, 4, 6), (2, 0, 4), (3, 8, 5)]
    assert (result.matches, result.redacted_records) == (3, 4)
    header = _core.SessionReader(out).header
    assert header.host == ""
    assert header.edits == ["redacted 2 patterns (host and by-id serial numbers cleared)"]
    assert b"hunter2" not in out.read_bytes() and b"alice" not in out.read_bytes()


def test_a_match_reaching_further_back_than_the_span_is_not_joined(tmp_path):
    filler = b"x" * (MAX_SPAN + 10)
    src = write_session(tmp_path / "in.wtape", [
        (0, "open", b"{}"), (1, "tx", b"sec"), (2, "tx", filler), (3, "tx", b"ret"),
        (4, "tx", b"sec"), (5, "tx", b"ret"),
    ])
    edit(src, tmp_path / "out.wtape", redact=[parse_redaction("secret")])
    tx = [d for _, k, d in records(tmp_path / "out.wtape") if k == "tx"]
    assert tx[0] == b"sec" and tx[3:] == [b"***", b"***"]


def test_redaction_clears_host_by_id_serials_and_header_matches(tmp_path):
    by_id = "/dev/serial/by-id/usb-FTDI_FT232R_USB_UART_A12345XY-if00-port0"
    src = write_session(tmp_path / "in.wtape", [
        (0, "open", json.dumps({"description": f"serial {by_id} @ 115200 8N1"}).encode()),
        (1, "tx", b"V\n")], metadata={"owner": "alice", "robot": "r2"},
        port_options=f"type=serial,device={by_id},baud=115200")
    edit(src, tmp_path / "out.wtape", redact=[parse_redaction("alice")])
    header = _core.SessionReader(tmp_path / "out.wtape").header
    assert header.port_options == "type=serial,device=/dev/serial/by-id/redacted,baud=115200"
    assert header.metadata == {"owner": "*****", "robot": "r2"}
    assert header.host == ""
    opened = json.loads(records(tmp_path / "out.wtape")[0][2])
    assert opened == {"description": "serial /dev/serial/by-id/redacted @ 115200 8N1"}


def test_cut_by_exchanges_keeps_the_greeting_and_moves_the_part_back(tmp_path):
    out = tmp_path / "cut.wtape"
    result = edit(GD, out, cut=parse_cut("4e:6e"))
    original = records(GD)
    kept = records(out)
    first_tx = next(t for t, k, d in original if k == "tx")
    tx = [d for _, k, d in kept if k == "tx"]
    assert tx == [b"VV\n", b"PP\n"]  # exchanges 4 and 5, numbered from 0
    assert kept[0] == original[0]  # the open
    assert next(t for t, k, d in kept if k == "tx") == first_tx
    times = [t for t, _, _ in kept]
    assert times == sorted(times)
    assert kept[-1][1] == "close"
    assert result.edits == ("cut 4:6 exchanges",)
    assert _core.SessionReader(out).header.edits == ["cut 4:6 exchanges"]


def test_cut_by_exchanges_counts_as_replay_does_across_client_sessions(tmp_path):
    # A new client session begins a new exchange even with no rx between the
    # two clients' writes; a monitor's connect begins none.
    connect = lambda peer, role: json.dumps({"peer": peer, "role": role}).encode()
    src = write_session(tmp_path / "in.wtape", [
        (1, "client_connect", connect("a", "control")),
        (2, "tx", b"A"),
        (3, "client_connect", connect("m", "monitor")),
        (4, "client_disconnect", json.dumps({"peer": "a", "reason": "closed"}).encode()),
        (5, "client_connect", connect("b", "control")),
        (6, "tx", b"B"),
        (7, "rx", b"b")])
    assert [e.request_first_t_ns for e in _core.session_exchanges(str(src))] == [2, 6]
    out = tmp_path / "cut.wtape"
    edit(src, out, cut=parse_cut("1e:"))
    assert [d for _, k, d in records(out) if k == "tx"] == [b"B"]


def test_cut_keeps_the_client_in_force_whatever_monitors_did(tmp_path):
    connect = lambda peer, role: json.dumps({"peer": peer, "role": role}).encode()
    src = write_session(tmp_path / "in.wtape", [
        (1, "tx", b"X"),
        (2, "rx", b"x"),
        (3, "client_connect", connect("a", "control")),
        (4, "tx", b"A"),
        (5, "rx", b"a"),
        (6, "client_connect", connect("m", "monitor")),
        (7, "client_disconnect", json.dumps({"peer": "m", "reason": "closed"}).encode()),
        (8, "tx", b"B"),
        (9, "rx", b"b")])
    out = tmp_path / "cut.wtape"
    edit(src, out, cut=parse_cut("2e:"))
    kept = records(out)
    connects = [json.loads(d)["peer"] for _, k, d in kept if k == "client_connect"]
    assert connects == ["a"]  # the client's connect, not the monitor's
    assert [d for _, k, d in kept if k == "tx"] == [b"B"]


def test_cut_keeps_the_settings_and_client_in_force(tmp_path):
    src = write_session(tmp_path / "in.wtape", [
        (0, "open", b"{}"),
        (5, "rx", b"HELLO\n"),
        (10, "tx", b"a\n"), (11, "rx", b"A\n"),
        (20, "settings", b'{"baud":9600}'),
        (25, "client_connect", b'{"peer":"pty","role":"control"}'),
        (30, "settings", b'{"baud":115200}'),
        (40, "tx", b"b\n"), (41, "rx", b"B\n"),
        (50, "tx", b"c\n"), (51, "rx", b"C\n"),
        (60, "close", b"{}"),
    ])
    edit(src, tmp_path / "out.wtape", cut=parse_cut("0.00000004:0.00000005"))
    kept = records(tmp_path / "out.wtape")
    assert kept == [
        (0, "open", b"{}"),
        (5, "rx", b"HELLO\n"),
        (10, "client_connect", b'{"peer":"pty","role":"control"}'),
        (10, "settings", b'{"baud":115200}'),
        (10, "tx", b"b\n"), (11, "rx", b"B\n"),
        (20, "close", b"{}"),
    ]


def test_cut_holds_the_devices_lines_not_the_clients(tmp_path):
    """The device's inputs in force are served after the cut; the client's
    DTR/RTS changes before it are not put back, since replay checks them as
    changes the client makes."""
    inputs = b'{"cts":true,"dsr":true,"ri":false,"cd":false}'
    src = write_session(tmp_path / "in.wtape", [
        (0, "open", b"{}"),
        (1, "modem_lines", b'{"cts":true,"dsr":true,"ri":false,"cd":true}'),
        (5, "rx", b"HELLO\n"),
        (10, "tx", b"a\n"), (11, "rx", b"A\n"),
        (20, "modem_lines", b'{"dtr":false}'),
        (22, "modem_lines", inputs),
        (25, "modem_lines", b'{"dtr":true}'),
        (40, "tx", b"b\n"), (41, "rx", b"B\n"),
        (60, "close", b"{}"),
    ])
    edit(src, tmp_path / "out.wtape", cut=parse_cut("0.00000004:0.00000005"))
    kept = records(tmp_path / "out.wtape")
    assert kept == [
        (0, "open", b"{}"),
        (1, "modem_lines", b'{"cts":true,"dsr":true,"ri":false,"cd":true}'),
        (5, "rx", b"HELLO\n"),
        (10, "modem_lines", inputs),
        (10, "tx", b"b\n"), (11, "rx", b"B\n"),
        (20, "close", b"{}"),
    ]


def test_drop_meta_and_unknown_key(tmp_path):
    src = write_session(tmp_path / "in.wtape", [(0, "open", b"{}")],
                        metadata={"robot": "r2", "site": "lab"})
    edit(src, tmp_path / "out.wtape", drop_meta=["site"])
    header = _core.SessionReader(tmp_path / "out.wtape").header
    assert header.metadata == {"robot": "r2"}
    assert header.edits == ["dropped meta site"]
    done = wiretape("edit", src, tmp_path / "x.wtape", "--drop-meta", "nope")
    assert done.returncode == 2
    assert "has no metadata key 'nope' (its keys: robot, site)" in done.stderr


@pytest.mark.parametrize("args, message", [
    ([], "nothing to edit"),
    (["--cut", "5"], "expected FROM:TO"),
    (["--cut", "4:2"], "TO must be after FROM"),
    (["--cut", "1e:2"], None),  # a bare TO counts like FROM: allowed
    (["--cut", "1e:2s"], "both sides must count the same"),
    (["--cut", "x:2"], "FROM 'x' is not a number"),
    (["--cut", "99e:"], "--cut 99e:: the session has 9 exchanges (0 to 8), no exchange 99"),
    (["--redact", "("], "not a regular expression"),
    (["--redact", "a*"], "matches the empty string"),
    (["--redact", "a="], "the replacement is empty"),
])
def test_bad_edits_are_usage_errors_that_name_the_problem(tmp_path, args, message):
    done = wiretape("edit", GD, tmp_path / "out.wtape", *args)
    if message is None:
        assert done.returncode == 0, done.stderr
        return
    assert done.returncode == 2, done.stderr
    assert message in done.stderr


def test_edit_never_writes_over_its_input(tmp_path):
    src = tmp_path / "in.wtape"
    src.write_bytes(GD.read_bytes())
    os.link(src, tmp_path / "link.wtape")
    for target in (src, tmp_path / "link.wtape"):
        done = wiretape("edit", src, target, "--cut", "1e:")
        assert done.returncode == 3
        assert "same file" in done.stderr
    assert src.read_bytes() == GD.read_bytes()


def test_a_damaged_input_is_edited_up_to_the_damage(tmp_path):
    src = tmp_path / "in.wtape"
    data = bytearray(GD.read_bytes())
    data[-30] ^= 0xFF  # inside the last records
    src.write_bytes(bytes(data))
    reader = _core.SessionReader(src)
    intact = [(r.t_ns, r.kind, r.data) for r in reader]
    assert reader.damage is not None
    done = wiretape("edit", src, tmp_path / "out.wtape", "--drop-meta", "nope")
    assert done.returncode == 2  # the edit is refused before anything is read
    done = wiretape("edit", src, tmp_path / "out.wtape", "--redact", "Hokuyo")
    assert done.returncode == 1
    assert "corrupt" in done.stderr
    assert len(records(tmp_path / "out.wtape")) == len(intact) + 3  # three redaction events


def test_cli_summary(tmp_path):
    done = wiretape("edit", GD, tmp_path / "out.wtape", "--redact", "Hokuyo", "--cut", "2e:")
    assert done.returncode == 0, done.stderr
    assert "3 matches redacted in 3 records" in done.stderr
    assert "cut 2: exchanges" in done.stderr


# --- properties ---------------------------------------------------------------

from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(stream=st.binary(min_size=1, max_size=300).map(lambda b: b.replace(b"k", b"")),
       secrets=st.lists(st.integers(0, 300), max_size=5),
       cuts=st.lists(st.integers(1, 299), max_size=12))
def test_redacting_records_equals_redacting_the_whole_stream(tmp_path_factory, stream, secrets, cuts):
    for at in sorted(secrets, reverse=True):
        stream = stream[:at] + b"key=k3y" + stream[at:]
    bounds = sorted({0, len(stream), *[c for c in cuts if c < len(stream)]})
    chunks = [stream[a:b] for a, b in zip(bounds, bounds[1:])]
    folder = tmp_path_factory.mktemp("split")
    src = write_session(folder / "in.wtape", [(i, "tx", chunk) for i, chunk in enumerate(chunks)])
    edit(src, folder / "out.wtape", redact=[parse_redaction(r"key\=k\w*=#")])
    import re
    expected = re.sub(rb"key=k\w*", lambda m: b"#" * len(m.group(0)), stream)
    assert direction_bytes(folder / "out.wtape", "tx") == expected
    marked = sum(length for _, _, length in redaction_ranges(folder / "out.wtape"))
    assert marked == sum(len(m.group(0)) for m in re.finditer(rb"key=k\w*", stream))


# --- a scrubbed recording still replays --------------------------------------

import wiretape as wt  # noqa: E402


def login_session(path, password=b"hunter22"):
    return write_session(path, [
        (0, "open", b"{}"),
        (1_000, "tx", b"LOGIN alice "), (2_000, "tx", password + b"\n"),
        (3_000, "rx", b"OK\n"),
        (4_000, "tx", b"READ\n"), (5_000, "rx", b"42\n"),
        (6_000, "close", b"{}"),
    ])


@pytest.mark.parametrize("match", ["sequence", "request"])
def test_redacted_bytes_are_wildcards_when_the_client_writes_them(tmp_path, match):
    original = login_session(tmp_path / "in.wtape")
    scrubbed = tmp_path / "scrubbed.wtape"
    edit(original, scrubbed, redact=[parse_redaction(rb"hunter\d+".decode())])
    assert b"hunter22" not in scrubbed.read_bytes()

    def client(session, password, user=b"alice"):
        port = wt.open_port(f"type=replay,file={session},timing=none,match={match},"
                                  "unused=error,timeout=5")
        port.write(b"LOGIN " + user + b" " + password + b"\n")
        assert port.read_until(b"\n") == b"OK\n"
        port.write(b"READ\n")
        assert port.read_until(b"\n") == b"42\n"
        port.close()

    # The driver that made the recording, and another password of the same
    # length, both replay against the scrubbed recording...
    client(scrubbed, b"hunter22")
    client(scrubbed, b"s3cret!!")
    # ... while against the original a different password is a mismatch,
    # and the bytes around the scrubbed ones are still checked.
    with pytest.raises(wt.ReplayMismatch):
        client(original, b"s3cret!!")
    with pytest.raises(wt.ReplayMismatch):
        client(scrubbed, b"hunter22", user=b"alicE")


ARDUINO = {
    "kernel_name": "ttyACM0", "subsystem": "usb", "vendor_id": "2341", "product_id": "0043",
    "serial_number": "85736323838351F0B1C1", "manufacturer": "Arduino (www.arduino.cc)",
    "product": "Arduino Uno", "interface": "", "location": "1-2:1.0",
    "by_id": "/dev/serial/by-id/usb-Arduino__www.arduino.cc__0043_85736323838351F0B1C1-if00",
}


def test_redaction_always_clears_the_device_serial_number_and_its_by_id_part(tmp_path):
    # DESIGN §20: whatever the patterns, the identity's serial number goes,
    # in the by-id name too; the rest of the identity stays for replay.
    src = tmp_path / "in.wtape"
    with _core.SessionWriter(src, capture="wire", port_type="serial",
                             port_options="type=serial,device=/dev/ttyACM0",
                             device_identity=ARDUINO) as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 10, b"Arduino Uno says hi\n")
    edit(src, tmp_path / "out.wtape", redact=[parse_redaction("Uno")])
    identity = _core.SessionReader(tmp_path / "out.wtape").header.device_identity
    assert identity["serial_number"] == ""
    assert identity["by_id"] == (
        "/dev/serial/by-id/usb-Arduino__www.arduino.cc__0043_redacted-if00")
    # The patterns apply to the identity's text as to the rest of the header.
    assert identity["product"] == "Arduino ***"
    assert (identity["vendor_id"], identity["product_id"]) == ("2341", "0043")
    assert b"85736323838351F0B1C1" not in (tmp_path / "out.wtape").read_bytes()
    # Cutting alone keeps it.
    edit(src, tmp_path / "cut.wtape", cut=parse_cut("0:1"))
    assert _core.SessionReader(tmp_path / "cut.wtape").header.device_identity == ARDUINO
