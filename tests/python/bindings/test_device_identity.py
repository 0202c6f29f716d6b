"""The device identity in the session header (format 1.2, DESIGN §20
"Identity"): a dict member of SessionHeader, written and read back, checked
by name; read from a sysfs tree and presented as one; its serial number
cleared for redaction."""

import json
import os

import pytest

from wiretape import _core

ARDUINO = {
    "kernel_name": "ttyACM0", "subsystem": "usb", "vendor_id": "2341", "product_id": "0043",
    "serial_number": "85736323838351F0B1C1", "manufacturer": "Arduino (www.arduino.cc)",
    "product": "Arduino Uno", "interface": "CDC ACM", "location": "1-2:1.0",
    "by_id": "/dev/serial/by-id/usb-Arduino__www.arduino.cc__0043_85736323838351F0B1C1-if00",
}


def test_the_identity_round_trips_through_writer_and_reader(tmp_path):
    path = tmp_path / "id.wtape"
    with _core.SessionWriter(path, port_type="serial", device_identity=ARDUINO) as writer:
        writer.write("rx", 1, b"x")
    header = _core.SessionReader(path).header
    assert header.device_identity == ARDUINO
    assert header.to_dict()["device_identity"] == ARDUINO
    assert json.loads(header.metadata_json)["device_identity"] == ARDUINO
    assert _core.SessionHeader.from_dict(header.to_dict()) == header


def test_a_header_without_one_writes_none(tmp_path):
    header = _core.SessionHeader(port_type="serial")
    assert header.device_identity == {}
    assert "device_identity" not in json.loads(header.to_json())
    # Members not known are left out of the file.
    header.device_identity = {"kernel_name": "ttyS0", "subsystem": "pnp"}
    assert json.loads(header.to_json())["device_identity"] == {
        "kernel_name": "ttyS0", "subsystem": "pnp"}
    assert header.device_identity["vendor_id"] == ""


def test_members_are_checked_by_name_and_type():
    with pytest.raises(ValueError, match="device_identity has no member 'vid'.*vendor_id"):
        _core.SessionHeader(device_identity={"vid": "2341"})
    with pytest.raises(TypeError, match="member 'device_identity' must be a dict of str to str"):
        _core.SessionHeader(device_identity={"vendor_id": 0x2341})
    with pytest.raises(ValueError, match="member 'device_identity' is not valid UTF-8"):
        _core.SessionHeader(device_identity={"product": "\udcff"})


def test_clear_device_serial_clears_it_in_the_by_id_name_too():
    header = _core.SessionHeader(device_identity=ARDUINO)
    header.clear_device_serial()
    assert header.device_identity["serial_number"] == ""
    assert header.device_identity["by_id"] == (
        "/dev/serial/by-id/usb-Arduino__www.arduino.cc__0043_redacted-if00")
    # udev writes spaces and other bytes as _ in the name.
    spaced = dict(ARDUINO, serial_number="AB 12/3",
                  by_id="/dev/serial/by-id/usb-Maker_Board_AB_12_3-if00")
    header.device_identity = spaced
    header.clear_device_serial()
    assert header.device_identity["by_id"] == "/dev/serial/by-id/usb-Maker_Board_redacted-if00"
    # A name that does not show the serial as udev spells it is cleared whole.
    header.device_identity = dict(ARDUINO, by_id="/dev/serial/by-id/odd-name")
    header.clear_device_serial()
    assert header.device_identity["by_id"] == "/dev/serial/by-id/redacted"
    # No identity: nothing to do.
    empty = _core.SessionHeader()
    empty.clear_device_serial()
    assert empty.device_identity == {}


def test_a_presented_tree_reads_back_as_the_identity(tmp_path):
    tty, folder, by_id = _core.present_device_identity(ARDUINO, str(tmp_path / "sys"),
                                                       "/dev/ttyACM0")
    assert (tty, by_id) == ("ttyACM0", ARDUINO["by_id"])
    assert os.path.realpath(tmp_path / "sys" / "class" / "tty" / "ttyACM0") == folder
    (tmp_path / "dev").mkdir()
    (tmp_path / "dev" / "ttyACM0").write_text("")
    read = _core.read_device_identity(str(tmp_path / "dev" / "ttyACM0"),
                                      str(tmp_path / "sys"), str(tmp_path / "dev"))
    assert read == dict(ARDUINO, by_id="")  # the tree has no /dev links
    # A path not directly under /dev presents the recorded kernel name.
    tty, _, _ = _core.present_device_identity(ARDUINO, str(tmp_path / "sys2"), ARDUINO["by_id"])
    assert tty == "ttyACM0"
    # No name to present: nothing written, the by-id name still redirected.
    nameless = dict(ARDUINO, kernel_name="")
    assert _core.present_device_identity(nameless, str(tmp_path / "sys3"), "/tmp/x") == (
        "", "", ARDUINO["by_id"])
    assert not (tmp_path / "sys3").exists()


def test_a_pty_has_no_identity():
    master, slave = os.openpty()
    try:
        assert _core.read_device_identity(os.ttyname(slave)) == {}
    finally:
        os.close(master)
        os.close(slave)
    assert _core.read_device_identity("/nonexistent/ttyUSB9") == {}


def test_the_spec_names_the_members_the_library_writes():
    import pathlib
    doc = pathlib.Path(__file__).resolve().parents[3] / "docs" / "session-format.md"
    section = doc.read_text().split("#### Device identity (`device_identity`)\n", 1)[1]
    table = section.split("\n\n")[1]  # the paragraph after the introduction
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    names = [row.split("`")[1] for row in rows]
    assert names == list(_core.SessionHeader(device_identity={"kernel_name": "x"})
                         .device_identity)
