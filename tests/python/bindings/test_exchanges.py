"""The one segmentation of a session into exchanges, bound from C++
(_core.session_exchanges, _core.session_client_sessions,
_core.ClientSessionTracker): what faults.cases(), `edit --cut Ne` and the
exports count with."""

import json
from pathlib import Path

import pytest

import wiretape
from wiretape import _core

REPO = Path(__file__).resolve().parents[3]
HOKUYO = REPO / "examples" / "hokuyo" / "recordings"


def write(path: Path, records, port_type="serial") -> str:
    with wiretape.SessionWriter(str(path), port_type=port_type) as writer:
        for kind, t_ns, data in records:
            writer.write(kind, t_ns, data)
    return str(path)


def event(**fields) -> bytes:
    return json.dumps(fields).encode()


def mbap(tid: int) -> bytes:
    pdu = b"\x03\x00\x00\x00\x01"
    return tid.to_bytes(2, "big") + b"\x00\x00" + (len(pdu) + 1).to_bytes(2, "big") + b"\x01" + pdu


def test_raw_exchanges_with_a_greeting(tmp_path):
    path = write(tmp_path / "s.wtape", [("rx", 1, b"hello"), ("tx", 2, b"A"), ("tx", 3, b"B"),
                                        ("rx", 4, b"ab"), ("tx", 5, b"C"), ("rx", 6, b"c")])
    exchanges = _core.session_exchanges(path)
    assert [e.index for e in exchanges] == [0, 1]
    first = exchanges[0]
    assert (first.first_record, first.end_record) == (0, 4)
    assert (first.request_bytes, first.response_bytes, first.response_records) == (2, 7, 2)
    assert (first.request_first_t_ns, first.request_last_t_ns) == (2, 3)
    assert (first.response_first_t_ns, first.response_last_t_ns) == (1, 4)
    assert first.client_session is None
    assert first.request_frames == [] and first.response_frames == []
    # Under match=request the greeting is an exchange of its own.
    assert [e.request_bytes for e in _core.session_exchanges(path, match="request")] == [0, 2, 1]
    # The replay's own keys count the same; match= given overrides the options'.
    assert len(_core.session_exchanges(path, options="timing=none,match=request")) == 3
    assert len(_core.session_exchanges(path, match="sequence", options="match=request")) == 2


def test_with_a_profile_request_frames_decide(tmp_path):
    one, two = mbap(1), mbap(2)
    path = write(tmp_path / "m.wtape", [("tx", 1, one[:5]), ("tx", 2, one[5:] + two),
                                        ("rx", 3, one[:3]), ("rx", 4, one[3:])])
    exchanges = _core.session_exchanges(path, profile="modbus-tcp")
    assert [e.request_frames for e in exchanges] == [[one], [two]]
    assert exchanges[1].response_frames == [one]
    assert len(_core.session_exchanges(path)) == 1
    # A declared profile through further replay keys.
    declared = _core.session_exchanges(path, options="framing=fixed:12")
    assert [e.request_frames for e in declared] == [[one], [two]]


def test_client_sessions_skip_monitors_and_end_at_the_clients_disconnect(tmp_path):
    path = write(tmp_path / "c.wtape", [
        ("client_connect", 1, event(peer="a", role="control")),
        ("tx", 2, b"A"),
        ("client_connect", 3, event(peer="m", role="monitor")),
        ("rx", 4, b"a"),
        ("client_disconnect", 5, event(peer="m", reason="closed")),
        ("tx", 6, b"B"),
        ("rx", 7, b"b"),
        ("client_disconnect", 8, event(peer="a", reason="closed")),
        ("client_connect", 9, event(peer="c", role="control")),
        ("tx", 10, b"C"),
        ("rx", 11, b"c")])
    sessions = _core.session_client_sessions(path)
    assert [(s.first_record, s.end_record, s.disconnect_t_ns) for s in sessions] == \
        [(0, 8, 8), (8, 11, None)]
    assert [(e.index, e.client_session) for e in _core.session_exchanges(path)] == \
        [(0, 0), (1, 0), (2, 1)]
    tracker = _core.ClientSessionTracker()
    changes = [tracker.feed(kind, data) for kind, data in [
        ("client_connect", event(peer="a", role="control")),
        ("client_connect", event(peer="m", role="monitor")),
        ("client_disconnect", event(peer="m")),
        ("client_disconnect", event(peer="a"))]]
    assert changes == ["began", "", "", "ended"]
    assert not tracker.open


def test_udp_datagrams_are_requests(tmp_path):
    path = write(tmp_path / "u.wtape", [("tx", 1, b"A"), ("tx", 2, b"B"), ("rx", 3, b"b")],
                 port_type="udp")
    assert [e.response_bytes for e in _core.session_exchanges(path)] == [0, 1]


def test_bad_keys_and_missing_files_are_errors(tmp_path):
    path = write(tmp_path / "s.wtape", [("tx", 1, b"A")])
    with pytest.raises(wiretape.OptionError, match="profile"):
        _core.session_exchanges(path, profile="no-such-profile")
    with pytest.raises((wiretape.PortError, wiretape.SessionError)):
        _core.session_exchanges(str(tmp_path / "missing.wtape"))


@pytest.mark.parametrize("name", sorted(p.name for p in HOKUYO.glob("*.wtape")))
def test_the_hokuyo_recordings_cut_alike_with_and_without_scip(name):
    path = str(HOKUYO / name)
    plain = _core.session_exchanges(path)
    framed = _core.session_exchanges(path, profile="scip")
    assert plain and len(plain) == len(framed)
    assert sum(e.response_bytes for e in plain) == sum(e.response_bytes for e in framed)
    assert all(len(e.request_frames) == 1 for e in framed)


def _recordings():
    paths = sorted(str(p) for p in HOKUYO.glob("*.wtape"))
    paths += sorted(str(p) for p in (REPO / "tests" / "data" / "golden").glob("*.wtape")
                    if p.name != "damaged.wtape")
    paths += sorted(str(p.with_suffix(".log")) for p in
                    (REPO / "tests" / "data" / "flexiport").glob("*.logr"))
    return [path for path in paths if _served_whole(path)]


def _served_whole(path):
    """Whether a replay serves the whole file: no recorded close or loss
    before its last record."""
    kinds = [record.kind for record in _core.SessionReader(path)]
    ends = [i for i, kind in enumerate(kinds) if kind in ("close", "device_lost")]
    return not ends or ends[0] == len(kinds) - 1


def _replayed_exchanges(path, keys, tmp_path):
    """The exchanges with rx as the C++ replay numbers them: a faithful
    client writes each recorded tx record; duplicate@every:1 fires once at
    the first rx of each exchange served, and the fault events the replay
    logs (docs/faults.md) name it."""
    log = tmp_path / "faulty.wtape"
    options = (f"type=replay,file={_core.quote_option_value(path)},timing=none,check=off,"
               f"unused=ignore,faults=duplicate@every:1,{keys},"
               f"log={_core.quote_option_value(str(log))}")
    port = _core.open_port(options)
    try:
        for record in _core.SessionReader(path):
            if record.kind == "tx" and record.data:
                port.write_all(record.data)
            while port.available():
                port.read(port.available(), timeout=0)
    except wiretape.PortClosed:
        pass  # a recorded close or loss: nothing after it is served
    finally:
        port.close()
    fired = set()
    for record in _core.SessionReader(str(log)):
        if record.kind == "fault":
            detail = json.loads(record.data)["detail"]
            fired.add(int(detail.split(" in exchange ")[1].split()[0]))
    return fired


@pytest.mark.parametrize("path", _recordings(), ids=lambda p: Path(p).name)
def test_the_replays_numbering_agrees_with_the_binding_on_every_recording(path, tmp_path):
    profiles = [None, "scip"] if "urg" in path or "utm" in path else [None]
    checked = False
    for profile in profiles:
        for match in ("sequence", "request"):
            keys = f"match={match}" + (",gap=0" if match == "request" else "")
            keys += f",profile={profile}" if profile else ""
            expected = {e.index for e in _core.session_exchanges(path, profile=profile, match=match)
                        if e.response_bytes}
            assert _replayed_exchanges(path, keys, tmp_path) == expected, keys
            checked = True
    assert checked


def test_an_exchange_carries_its_request_end_response_start_and_channel(tmp_path):
    # A greeting before the request is not its answer; with the lines
    # profile a request ends at the record completing its line.
    path = write(tmp_path / "s.wtape", [("rx", 1, b"hello\n"), ("tx", 2, b"A\n"),
                                        ("tx", 3, b"B"), ("rx", 5, b"a\n"), ("tx", 8, b"\n")])
    first, second = _core.session_exchanges(path, profile="lines")
    assert (first.request_end_t_ns, first.response_start_t_ns) == (2, 5)
    assert (first.request_first_t_ns, first.request_last_t_ns) == (2, 3)
    assert first.response_first_t_ns == 1
    assert (second.request_end_t_ns, second.response_start_t_ns) == (8, None)
    assert (first.channel_id, first.channel_name) == (0, "")
