"""The bound SessionHeader (one type for reading and writing, members
checked) and event_payload (event payloads made by the record-kind table)."""

import copy

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
    with pytest.raises(ValueError, match="header JSON has no member 'hots'"):
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


# --- to_dict and from_dict: the file's header JSON as a dict (DESIGN §25) ---

IDENTITY = {"kernel_name": "ttyUSB0", "subsystem": "usb", "vendor_id": "0403",
            "product_id": "6001", "serial_number": "A9X", "by_id": "/dev/serial/by-id/x"}


def _headers(tmp_path):
    """Headers of every shape the header JSON has, by name."""
    channels = [dict(id=0, name="cmd", port_options="type=tcp,host=h,port=1", port_type="tcp",
                     capture="wire", device_address="10.0.0.1:1"),
                dict(id=1, name="data", port_options="type=serial,device=/dev/ttyUSB0",
                     port_type="serial", device_identity=IDENTITY)]
    # Channels attached one by one to a recorder's header (header room), read back.
    attached = tmp_path / "attached.wtape"
    with _core.SessionWriter(attached, _core.SessionHeader(start_utc=MEMBERS["start_utc"],
                                                           host="bench", metadata={"k": "v"}),
                             header_room=512) as writer:
        for channel in channels:
            writer.add_channel(_core.Channel(**channel))
    return {
        "empty": _core.SessionHeader(),
        "members": _core.SessionHeader(**MEMBERS),
        "identity": _core.SessionHeader(port_type="serial", device_identity=IDENTITY,
                                        metadata={"robot": "r2", "site": "lab"}),
        "channels": _core.SessionHeader(port_type="tcp", port_options="type=tcp,host=h,port=1",
                                        capture="wire", device_address="10.0.0.1:1",
                                        channels=channels),
        "attached": _core.SessionReader(attached).header,
    }


@pytest.mark.parametrize("name", ["empty", "members", "identity", "channels", "attached"])
def test_to_dict_is_the_files_header_json_and_from_dict_takes_it_back(tmp_path, name):
    import json

    header = _headers(tmp_path)[name]
    assert header.to_dict() == json.loads(header.to_json())
    assert list(header.to_dict()) == list(json.loads(header.to_json()))  # its order too
    back = _core.SessionHeader.from_dict(header.to_dict())
    # The JSON holds no version: from_dict's is the one writers write.
    expected = copy.copy(header)
    expected.version_major, expected.version_minor = _core.SESSION_VERSION
    assert back == expected
    assert back.to_json() == header.to_json()


def test_to_dict_nests_the_source_and_names_no_version():
    layout = _core.SessionHeader(**MEMBERS).to_dict()
    assert layout["source"] == {"format": "pcap", "files": ["plc.pcapng"], "stream": "tcp:0"}
    assert not {"source_format", "source_files", "source_details", "version_major",
                "version_minor"} & set(layout)
    # A recorded session's header has no source, and one port no channels.
    plain = _core.SessionHeader(port_type="serial").to_dict()
    assert "source" not in plain and "channels" not in plain and "device_identity" not in plain


def test_from_dict_checks_the_layout_by_name_and_type():
    with pytest.raises(ValueError, match="header JSON has no member 'source_format'"):
        _core.SessionHeader.from_dict({"source_format": "pcap"})
    with pytest.raises(ValueError, match="header JSON has no member 'version_major'"):
        _core.SessionHeader.from_dict({"version_major": 1})
    with pytest.raises(TypeError, match="member 'source' must be a dict"):
        _core.SessionHeader.from_dict({"source": "pcap"})
    with pytest.raises(TypeError, match="member 'source.files' must be a list of str, not str"):
        _core.SessionHeader.from_dict({"source": {"format": "pcap", "files": "a.pcap"}})
    with pytest.raises(TypeError, match="member 'source.stream' must be a str, not int"):
        _core.SessionHeader.from_dict({"source": {"format": "pcap", "stream": 0}})
    with pytest.raises(TypeError, match="member 'host' must be a str, not int"):
        _core.SessionHeader.from_dict({"host": 3})
    # A source that names no format reads as the file reader reads it.
    assert _core.SessionHeader.from_dict({"source": {"files": []}}).source_format == "unknown"
