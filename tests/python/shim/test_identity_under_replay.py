"""The recorded device's identity presented under ``replay FILE --as PATH --
CMD`` (issue 24, DESIGN §20 "Identity"; docs/replay.md): a driver that
finds its device with pyserial's ``list_ports`` by VID:PID, or opens its
``/dev/serial/by-id`` name, finds the virtual device, though neither exists
on this machine."""

import subprocess
import sys
import textwrap

import pytest

from wiretape import _core

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the preload shim is Linux only")

COMMAND_DEADLINE_S = 60.0
BY_ID = "/dev/serial/by-id/usb-Arduino__www.arduino.cc__0043_85736323838351F0B1C1-if00"
ARDUINO = {
    "kernel_name": "ttyACM0", "subsystem": "usb", "vendor_id": "2341", "product_id": "0043",
    "serial_number": "85736323838351F0B1C1", "manufacturer": "Arduino (www.arduino.cc)",
    "product": "Arduino Uno", "interface": "CDC ACM", "location": "1-2:1.0", "by_id": BY_ID,
}

# A driver that looks for its board by USB ids, as Arduino tools do, then
# opens the port it found, or the by-id name it was given.
FINDER = textwrap.dedent("""
    import sys
    import serial
    from serial.tools import list_ports

    found = list(list_ports.grep("2341:0043"))
    if len(found) != 1:
        print("found", [(p.device, p.hwid) for p in list_ports.comports()])
        sys.exit(5)
    port = found[0]
    print("device", port.device)
    print("ids", hex(port.vid), hex(port.pid), port.serial_number)
    print("names", port.manufacturer, "|", port.product, "|", port.interface)
    print("hwid", port.hwid)
    target = sys.argv[1] if len(sys.argv) > 1 else port.device
    with serial.Serial(target, 115200, timeout=30) as line:
        line.write(b"PING\\n")
        print("read", line.readline().decode().strip())
""")


def wiretape(*arguments):
    return subprocess.run([sys.executable, "-m", "wiretape.cli", *map(str, arguments)],
                          capture_output=True, text=True, timeout=COMMAND_DEADLINE_S)


def recording(path, identity, device="/dev/ttyACM0"):
    with _core.SessionWriter(path, capture="wire", port_type="serial",
                             port_options=f"type=serial,device={device}",
                             device_identity=identity) as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 1_000_000, b"PING\n")
        writer.write("rx", 2_000_000, b"PONG\n")
    return path


@pytest.fixture
def finder(tmp_path):
    script = tmp_path / "finder.py"
    script.write_text(FINDER)
    return [sys.executable, str(script)]


def test_list_ports_finds_the_replay_by_vid_pid_and_the_by_id_name_opens_it(tmp_path, finder):
    session = recording(tmp_path / "uno.wtape", ARDUINO)
    done = wiretape("replay", session, "--as", "/dev/ttyACM0", "-q", "--", *finder, BY_ID)
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    assert "device /dev/ttyACM0" in lines
    assert "ids 0x2341 0x43 85736323838351F0B1C1" in lines
    assert "names Arduino (www.arduino.cc) | Arduino Uno | CDC ACM" in lines
    assert "hwid USB VID:PID=2341:0043 SER=85736323838351F0B1C1 LOCATION=1-2" in lines
    assert "read PONG" in lines


def test_a_driver_given_the_by_id_name_finds_the_kernel_name_too(tmp_path, finder):
    # --as the by-id name: list_ports lists the recorded kernel name, which
    # opens the virtual device as well.
    session = recording(tmp_path / "uno.wtape", ARDUINO, device=BY_ID)
    done = wiretape("replay", session, "--as", BY_ID, "-q", "--", *finder)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "device /dev/ttyACM0" in done.stdout.splitlines()
    assert "read PONG" in done.stdout.splitlines()


def test_the_path_given_to_as_names_the_presented_port(tmp_path, finder):
    session = recording(tmp_path / "uno.wtape", ARDUINO)
    done = wiretape("replay", session, "--as", "/dev/ttyUSB7", "-q", "--", *finder)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "device /dev/ttyUSB7" in done.stdout.splitlines()


def test_a_recording_without_an_identity_presents_none(tmp_path, finder):
    session = recording(tmp_path / "pty.wtape", {})
    done = wiretape("replay", session, "--as", "/dev/ttyACM0", "-q", "--", *finder,
                    "/dev/ttyACM0")
    # The finder finds nothing and says so (exit 5, CMD's own status).
    assert done.returncode == 5, done.stdout + done.stderr
    assert "2341" not in done.stdout


def test_record_on_a_pty_records_no_identity(tmp_path):
    import os
    master, slave = os.openpty()
    try:
        session = tmp_path / "pty.wtape"
        done = wiretape("record", "--device", os.ttyname(slave), "-o", session,
                        "--pty", tmp_path / "client", "--duration", "0.1", "-q")
        assert done.returncode == 0, done.stderr
        header = _core.SessionReader(session).header
        assert header.port_type == "serial"
        assert header.device_identity == {}
    finally:
        os.close(master)
        os.close(slave)


def test_the_presented_tree_is_removed_when_the_command_is_done(tmp_path, monkeypatch):
    import tempfile

    from wiretape.redirect import RedirectedCommand

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    command = RedirectedCommand(
        [sys.executable, "-c", "import os; print(os.path.realpath('/sys/class/tty/ttyACM0/device'))"],
        "/dev/ttyACM0", "/dev/null", identity=ARDUINO)
    try:
        assert command.exit_status() == 0
        assert any(p.name.startswith("wiretape-identity-") for p in tmp_path.iterdir())
        # The exit comes before the reader thread has drained the pipe.
        assert command.child.wait_for_output(lambda out: out.endswith(b"\n"), timeout=30)
        # The tty's device is the presented USB interface, inside the tree.
        assert command.child.stdout.decode().strip().startswith(str(tmp_path))
        assert command.child.stdout.decode().strip().endswith("/usb1/1-2/1-2:1.0")
    finally:
        command.close()
    assert not any(p.name.startswith("wiretape-identity-") for p in tmp_path.iterdir())
