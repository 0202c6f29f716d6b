"""The bound SessionHeader (one type for reading and writing, members
checked) and event_payload (event payloads made by the record-kind table)."""

import pytest

from wiretape import _core

MEMBERS = dict(port_options="type=tcp,host=10.0.0.5,port=502", port_type="tcp",
               start_utc="2026-01-02T03:04:05.000006Z", wiretape_version="9.9.9", host="bench",
               capture="wire", source_format="pcap", source_files=["plc.pcapng"],
               source_details={"stream": "tcp:0"}, device_address="10.0.0.5:502",
               edits=["cut 2e..5e"], metadata={"robot": "r2"})


def test_a_header_round_trips_through_writer_and_reader(tmp_path):
    header = _core.SessionHeader(**MEMBERS)
    path = tmp_path / "h.wtape"
    with _core.SessionWriter(path, header) as writer:
        assert writer.header.metadata_json == header.to_json()
        writer.write("rx", 1, b"x")
    with _core.SessionReader(path) as reader:
        read = reader.header
    assert read.metadata_json == header.to_json()
    for name, value in MEMBERS.items():
        assert getattr(read, name) == value, name
    # A header read is written again as it was.
    assert read.to_json() == header.to_json()
    assert _core.SessionHeader.from_dict(read.to_dict()) == read


def test_a_header_written_invents_nothing(tmp_path):
    path = tmp_path / "plain.wtape"
    with _core.SessionWriter(path, _core.SessionHeader(port_type="serial")):
        pass
    header = _core.SessionReader(path).header
    assert (header.start_utc, header.host, header.port_type) == ("", "", "serial")
    # Without a header, the writer records a session starting now, here.
    with _core.SessionWriter(tmp_path / "now.wtape", port_type="serial"):
        pass
    now = _core.SessionReader(tmp_path / "now.wtape").header
    assert now.start_utc and now.host and now.port_type == "serial"


def test_members_are_checked_by_name_and_type():
    with pytest.raises(ValueError, match="SessionHeader has no member 'hots'"):
        _core.SessionHeader(hots="x")
    with pytest.raises(ValueError, match="SessionHeader has no member 'hots'"):
        _core.SessionHeader.from_dict({"hots": "x"})
    with pytest.raises(TypeError, match="member 'host' must be a str, not int"):
        _core.SessionHeader(host=3)
    with pytest.raises(TypeError, match="member 'edits' must be a list of str"):
        _core.SessionHeader(edits=[1])
    with pytest.raises(TypeError, match="member 'metadata' must be a dict of str to str"):
        _core.SessionHeader(metadata={"k": 1})
    with pytest.raises(ValueError, match="capture must be 'client' or 'wire'"):
        _core.SessionHeader(capture="radio")
    with pytest.raises(ValueError, match="member 'host' is not valid UTF-8"):
        _core.SessionHeader(host="\ud800")
    with pytest.raises(ValueError, match="SessionHeader has no member 'hots'"):
        _core.SessionWriter("/nonexistent/never.wtape", hots="x")


def test_to_json_refuses_what_a_reader_would_refuse(tmp_path):
    header = _core.SessionHeader(start_utc="9999-01-01T00:00:00Z")
    with pytest.raises(_core.OptionError) as raised:
        header.to_json()
    assert raised.value.key == "start_utc"
    with pytest.raises(_core.OptionError):
        _core.SessionWriter(tmp_path / "x.wtape", header)
    assert not (tmp_path / "x.wtape").exists()


def test_header_members_can_be_changed_and_copied():
    header = _core.SessionHeader(**MEMBERS)
    header.port_options = "type=tcp,host=h,port=1"
    header.metadata = {}
    assert header.to_dict()["port_options"] == "type=tcp,host=h,port=1"
    import copy
    other = copy.copy(header)
    other.host = "elsewhere"
    assert header.host == "bench"


def test_event_payload_follows_the_record_kind_table():
    assert _core.event_payload("fault", {"where": "exchange:3", "kind": "corrupt"}) == \
        b'{"kind":"corrupt","where":"exchange:3"}'
    assert _core.event_payload("settings", {"baud": 9600, "applied": False}) == \
        b'{"baud":9600,"applied":false}'
    assert _core.event_payload("close", {}) == b"{}"
    for kind in _core.RECORD_KINDS:
        if kind["is_event"]:
            required = {f["name"]: {"string": "x", "integer": 1, "boolean": True}[f["type"]]
                        for f in kind["fields"] if f["required"]}
            payload = _core.event_payload(kind["name"], required)
            assert _core.record_content_problem(kind["name"], 0, payload) is None


@pytest.mark.parametrize("kind, fields, message", [
    ("fault", {"kind": "drop"}, 'fault event: required member "where" is missing'),
    ("settings", {"baud": "fast"}, 'settings event: member "baud" must be an integer, not a string'),
    ("settings", {"baud": True}, 'member "baud" must be an integer, not a boolean'),
    ("settings", {"baud": 1, "speed": 2}, 'settings event: unknown member "speed"'),
    ("settings", {"baud": 1.5}, 'settings event: member "baud" is a float'),
    ("settings", {"baud": 2 ** 70}, 'member "baud" is out of the 64-bit range'),
    ("rx", {}, "rx is a direction, not an event"),
    ("radio", {}, "unknown record kind 'radio'"),
])
def test_event_payload_names_the_kind_and_member_it_refuses(kind, fields, message):
    with pytest.raises(ValueError) as raised:
        _core.event_payload(kind, fields)
    assert message in str(raised.value)
