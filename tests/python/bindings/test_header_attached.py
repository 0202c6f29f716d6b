"""SessionHeader.attached (DESIGN §26): an attached recording's program, as
the header JSON's `attached` object, the same dict in Python both ways."""

import pytest

import wiretape

ATTACHED = {"pid": 4242, "command": "driver", "utc": "2026-12-03T05:00:00.000001Z",
            "descriptors": [3, 7], "device": "/dev/ttyUSB0",
            "warnings": ["the program moved bytes of the device with splice"]}


def test_attached_is_none_unless_the_recording_was_attached():
    assert wiretape.SessionHeader().attached is None
    assert "attached" not in wiretape.SessionHeader().to_dict()


def test_attached_round_trips_through_the_file_and_the_dict_layout(tmp_path):
    header = wiretape.SessionHeader(port_type="serial", attached=ATTACHED)
    assert header.attached == ATTACHED
    assert header.to_dict()["attached"] == ATTACHED
    assert wiretape.SessionHeader.from_dict(header.to_dict()).attached == ATTACHED
    path = tmp_path / "attached.wtape"
    with wiretape.SessionWriter(str(path), header) as writer:
        writer.write("rx", 1, b"x")
    assert wiretape.SessionReader(str(path)).header.attached == ATTACHED


def test_a_bad_attached_member_is_refused_naming_it():
    with pytest.raises(TypeError, match="attached"):
        wiretape.SessionHeader(attached={"pid": "not a number"})
    with pytest.raises(TypeError, match="attached"):
        wiretape.SessionHeader(attached=[1, 2])
