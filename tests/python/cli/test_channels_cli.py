"""``record`` and ``replay`` of several channels (issue 25, DESIGN.md
section 19): the ``NAME=`` prefixes of the endpoint flags, their pairing
into channels and its usage errors (exit 2, naming the flag), and
``record --udp LISTEN --peer DRIVER`` for a device that streams datagrams."""

import select
import socket

import pytest

import wiretape
from wiretape import _core, cli
from wiretape.cli.endpoints import split_name

from devices import TcpDevice, announced_address, interrupt, start_cli, wait_until

DEADLINE_S = 10.0



def usage_error(capsys, *argv):
    """wiretape ARGV's stderr, asserting it is a usage error (exit 2)."""
    status = cli.main(list(argv))
    err = capsys.readouterr().err
    assert status == 2, err
    return err


# --- NAME= is a prefix only when NAME is a channel name --------------------


@pytest.mark.parametrize("text, expected", [
    ("gps=/dev/ttyUSB0", ("gps", "/dev/ttyUSB0")),
    ("rtk=type=tcp,host=caster,port=2101", ("rtk", "type=tcp,host=caster,port=2101")),
    ("lidar_cmd=127.0.0.1:2111", ("lidar_cmd", "127.0.0.1:2111")),
    # option keys are refused as names: the whole text is an option string
    ("type=tcp,host=10.0.0.5,port=10940", ("", "type=tcp,host=10.0.0.5,port=10940")),
    ("device=/dev/ttyUSB0", ("", "device=/dev/ttyUSB0")),
    # paths and addresses are not names
    ("/tmp/a=b", ("", "/tmp/a=b")),
    ("127.0.0.1:2101", ("", "127.0.0.1:2101")),
    ("/dev/ttyUSB0", ("", "/dev/ttyUSB0")),
])
def test_a_name_prefix_is_a_channel_name_and_nothing_else(text, expected):
    assert split_name(text) == expected


# --- usage errors of record ------------------------------------------------


def test_record_refuses_two_devices_of_one_name(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "gps=/dev/ttyUSB0", "--pty", "gps=/tmp/gps",
                      "--device", "gps=/dev/ttyUSB1")
    assert "--device is given twice for channel 'gps'" in err
    assert "--device gps=/dev/ttyUSB1" in err


def test_record_refuses_two_unnamed_client_sides_of_one_kind(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "/dev/ttyUSB0", "--pty", "/tmp/a", "--pty", "/tmp/b")
    assert "--pty is given twice" in err


def test_record_refuses_a_name_on_one_flag_and_not_on_its_partner(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "gps=/dev/ttyUSB0", "--pty", "/tmp/gps")
    assert "--pty /tmp/gps has no NAME=" in err
    assert "--device gps=/dev/ttyUSB0" in err


def test_record_refuses_a_client_side_whose_name_has_no_device(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "gps=/dev/ttyUSB0", "--pty", "gps=/tmp/gps",
                      "--listen", "rtk=127.0.0.1:2101")
    assert "channel 'rtk' has no device" in err
    assert "--listen rtk=127.0.0.1:2101" in err
    assert "--device rtk=OPTS" in err


def test_record_refuses_a_device_without_its_client_side(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "gps=/dev/ttyUSB0", "--pty", "gps=/tmp/gps",
                      "--device", "rtk=type=tcp,host=caster,port=2101")
    assert "channel 'rtk' has no client side" in err
    assert "--listen rtk=HOST:PORT" in err


def test_record_refuses_two_client_sides_of_one_channel(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "gps=/dev/ttyUSB0", "--pty", "gps=/tmp/gps",
                      "--listen", "gps=127.0.0.1:2101")
    assert "--listen gps=127.0.0.1:2101: not allowed with --pty gps=/tmp/gps" in err


def test_record_refuses_a_peer_without_its_udp(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "gps=/dev/ttyUSB0", "--pty", "gps=/tmp/gps",
                      "--peer", "gps=127.0.0.1:2947")
    assert "--peer gps=127.0.0.1:2947 is where --udp sends datagrams" in err


def test_a_bad_udp_address_after_a_name_is_refused_naming_the_flag(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "gps=/dev/ttyUSB0", "--udp", "gps=127.0.0.1:notaport")
    assert "--udp" in err and "the port must be a number" in err


def test_the_single_port_form_still_needs_a_device(capsys, tmp_path):
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"), "--pty", "/tmp/x")
    assert "required: --device" in err


def test_an_option_string_device_is_not_taken_for_a_name(capsys, tmp_path):
    """--device type=tcp,... is the single-port form: it asks for its client
    side as today, not for a channel called 'type'."""
    err = usage_error(capsys, "record", "-o", str(tmp_path / "r.wtape"),
                      "--device", "type=tcp,host=127.0.0.1,port=9")
    assert "give where the client connects: --pty PATH" in err
    assert "channel" not in err


# --- usage errors of replay ------------------------------------------------


def two_channel_session(path):
    """A session of two channels, gps (serial) and rtk (tcp): one exchange
    each."""
    header = _core.SessionHeader.starting_now()
    header.channels = [_core.Channel(id=0, name="gps", port_type="serial",
                                     port_options="type=serial,device=/dev/ttyUSB0"),
                       _core.Channel(id=1, name="rtk", port_type="tcp",
                                     port_options="type=tcp,host=caster,port=2101")]
    with _core.SessionWriter(str(path), header) as writer:
        writer.write("open", 0, b"", channel=0)
        writer.write("open", 0, b"", channel=1)
        writer.write("tx", 1_000_000, b"gps?\n", channel=0)
        writer.write("rx", 2_000_000, b"GPS!\n", channel=0)
        writer.write("tx", 3_000_000, b"rtk?\n", channel=1)
        writer.write("rx", 4_000_000, b"RTK!\n", channel=1)
    return path


def one_channel_session(path):
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        writer.write("tx", 1_000_000, b"q\n")
        writer.write("rx", 2_000_000, b"a\n")
    return path


def test_replay_refuses_a_channel_the_file_does_not_have(capsys, tmp_path):
    session = two_channel_session(tmp_path / "two.wtape")
    err = usage_error(capsys, "replay", str(session), "--pty", "gps=/tmp/gps",
                      "--listen", "rtc=127.0.0.1:0")
    assert "--listen rtc=127.0.0.1:0" in err
    assert "has no channel 'rtc'" in err
    assert "did you mean 'rtk'?" in err
    assert "gps, rtk" in err


def test_replay_of_several_channels_refuses_an_unnamed_endpoint(capsys, tmp_path):
    session = two_channel_session(tmp_path / "two.wtape")
    err = usage_error(capsys, "replay", str(session), "--pty", str(tmp_path / "gps"))
    assert "has 2 channels (gps, rtk)" in err
    assert "--pty" in err and "gps=" in err


def test_replay_refuses_a_named_endpoint_on_a_file_of_one_unnamed_channel(capsys, tmp_path):
    session = one_channel_session(tmp_path / "one.wtape")
    err = usage_error(capsys, "replay", str(session), "--pty", f"gps={tmp_path / 'gps'}")
    assert "has no channel 'gps'" in err
    assert "one unnamed channel" in err


def test_replay_refuses_two_endpoints_of_one_name(capsys, tmp_path):
    session = one_channel_session(tmp_path / "one.wtape")
    err = usage_error(capsys, "replay", str(session), "--pty", "gps=/tmp/a",
                      "--listen", "rtk=0", "--listen", "rtk=1")
    assert "--listen is given twice for channel 'rtk'" in err


def test_replay_refuses_mixing_named_and_unnamed(capsys, tmp_path):
    session = one_channel_session(tmp_path / "one.wtape")
    err = usage_error(capsys, "replay", str(session), "--pty", "gps=/tmp/a",
                      "--listen", "127.0.0.1:0")
    assert "--listen 127.0.0.1:0 has no NAME=" in err


# --- record --udp LISTEN --peer DRIVER: a device that streams --------------


def free_udp_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_record_forwards_a_streaming_device_to_the_peer_and_records_it_as_rx(tmp_path):
    """A device that sends to a port the driver binds (gpsd's udp://):
    wiretape listens where the device sends, forwards each datagram to the
    driver and records it as rx, one record per datagram."""
    output = tmp_path / "stream.wtape"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as driver, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as device:
        driver.bind(("127.0.0.1", 0))
        listen = free_udp_port()
        child = start_cli("record", "--udp", f"127.0.0.1:{listen}",
                          "--peer", f"127.0.0.1:{driver.getsockname()[1]}", "-o", str(output))
        try:
            announced_address(child, "udp")
            # A first datagram until one reaches the driver: then the proxy
            # is forwarding.
            probe = b"$GPTXT,probe*00\r\n"

            def forwarded():
                device.sendto(probe, ("127.0.0.1", listen))
                return bool(select.select([driver], [], [], 0.05)[0])
            wait_until(forwarded, DEADLINE_S, "the probe at the driver")
            sent = [b"$GPGGA,1*00\r\n", b"$GPRMC,2*00\r\n", b"$GPGGA,3*00\r\n"]
            for datagram in sent:
                device.sendto(datagram, ("127.0.0.1", listen))
            got = []
            driver.settimeout(DEADLINE_S)
            while len(got) < len(sent):
                datagram = driver.recv(65535)
                if datagram != probe:
                    got.append(datagram)
        finally:
            status, _, err = interrupt(child)
        assert status == 0, err
    assert got == sent
    rx = [record.data for record in wiretape.SessionReader(str(output)) if record.kind == "rx"]
    assert rx[-3:] == sent and set(rx[:-3]) == {probe}


# --- several channels, end to end ------------------------------------------


def test_record_of_two_tcp_devices_writes_one_file_of_two_channels(tmp_path):
    output = tmp_path / "two.wtape"
    with TcpDevice() as first, TcpDevice(respond=lambda chunk: chunk[::-1]) as second:
        child = start_cli("record", "-o", str(output),
                          "--device", f"one={first.options}", "--listen", "one=127.0.0.1:0",
                          "--device", f"two={second.options}", "--listen", "two=127.0.0.1:0")
        try:
            addresses = [announced_address(child, "tcp"), announced_address(child, "tcp")]
            answers = []
            for address, question in zip(addresses, (b"hello\n", b"world\n")):
                with socket.create_connection(address, timeout=DEADLINE_S) as client:
                    client.sendall(question)
                    answer = b""
                    while len(answer) < len(question):
                        answer += client.recv(64)
                    answers.append(answer)
        finally:
            status, _, err = interrupt(child)
    assert status == 0, err
    assert answers == [b"HELLO\n", b"\ndlrow"]
    assert "one: stopped" in err and "two: stopped" in err
    reader = wiretape.SessionReader(str(output))
    names = {channel.id: channel.name for channel in reader.header.channel_list()}
    assert sorted(names.values()) == ["one", "two"]
    tx = {}
    for record in reader:
        if record.kind == "tx":
            tx.setdefault(names[record.channel], b"")
            tx[names[record.channel]] += record.data
    assert tx == {"one": b"hello\n", "two": b"world\n"}


# --- the outcome of several channels: the worst, naming its channel --------


class FinishedBridge:
    """A bridge that has ended with `outcome` (what the runner of several
    channels reads of a BridgeHandle)."""

    def __init__(self, outcome, message="", nothing_served=""):
        self.pty_path = None
        self.address = "127.0.0.1:1"
        self.device_description = "replay"
        self.stopped = False
        self._result = type("Result", (), {
            "outcome": outcome, "ok": outcome not in ("mismatch", "failed"),
            "message": message, "nothing_served": nothing_served,
            "stats": type("Stats", (), {"items": lambda self: [("records_written", 2)]})()})()

    def wait(self, timeout=None):
        return True

    def messages(self):
        return ["client 127.0.0.1:9 connected"]

    def stop(self):
        self.stopped = True

    def result(self):
        return self._result


def run_channels(*outcomes):
    from wiretape.cli.channels import _run_channels
    from wiretape.cli.console import Output
    from wiretape.cli.endpoints import Endpoint

    handles = [(Endpoint(name, {"listen": "127.0.0.1:0"}), bridge)
               for name, bridge in outcomes]
    return _run_channels(handles, Output(), "replay", lambda endpoint: "replaying f",
                         must_serve=True, quiet=False)


def test_channels_that_all_finished_well_exit_0(capsys):
    assert run_channels(("gps", FinishedBridge("finished")),
                        ("rtk", FinishedBridge("finished"))) == 0
    err = capsys.readouterr().err
    assert "wiretape replay: gps: finished: 2 records written" in err
    assert "wiretape replay: rtk: finished" in err
    # each channel's messages relayed under its name
    assert "wiretape replay: gps: client 127.0.0.1:9 connected" in err


def test_a_mismatch_on_one_channel_fails_naming_the_channel():
    from wiretape.cli.errors import CheckFailed

    with pytest.raises(CheckFailed, match=r"^channel rtk: replay mismatch: byte 3"):
        run_channels(("gps", FinishedBridge("finished")),
                     ("rtk", FinishedBridge("mismatch", "byte 3 differs")))


def test_the_worst_outcome_of_the_channels_is_the_commands():
    from wiretape.cli.errors import RuntimeFailure

    with pytest.raises(RuntimeFailure, match=r"^channel imu: device gone"):
        run_channels(("gps", FinishedBridge("mismatch", "replay mismatch: x")),
                     ("imu", FinishedBridge("failed", "device gone")),
                     ("rtk", FinishedBridge("finished", nothing_served="no client")))


def test_a_channel_that_served_nothing_fails_the_replay():
    from wiretape.cli.errors import CheckFailed

    with pytest.raises(CheckFailed, match=r"^channel rtk: no client connected"):
        run_channels(("gps", FinishedBridge("finished")),
                     ("rtk", FinishedBridge("finished",
                                            nothing_served="no client connected before the end")))


def test_the_unnamed_form_records_a_file_of_one_unnamed_channel(tmp_path):
    """The single-port form is today's: no `channels` in the header, every
    record on channel 0."""
    output = tmp_path / "one.wtape"
    with TcpDevice() as device:
        child = start_cli("record", "--device", device.options, "--listen", "127.0.0.1:0",
                          "-o", str(output))
        try:
            with socket.create_connection(announced_address(child, "tcp"),
                                          timeout=DEADLINE_S) as client:
                client.sendall(b"ping\n")
                answer = b""
                while len(answer) < 5:
                    answer += client.recv(64)
        finally:
            status, _, err = interrupt(child)
    assert status == 0, err
    assert answer == b"PING\n"
    assert "wiretape record: stopped" in err
    with wiretape.SessionReader(str(output)) as reader:
        assert reader.header.channels == []
        assert [c.name for c in reader.header.channel_list()] == [""]
        assert {record.channel for record in reader} == {0}
        assert '"channels"' not in reader.header.metadata_json


def test_replay_with_a_command_of_a_channel_without_a_device_path_is_refused(capsys,
                                                                            tmp_path):
    """-- CMD redirects each channel's recorded path: a TCP channel has none
    unless --as NAME=PATH gives it."""
    session = two_channel_session(tmp_path / "two.wtape")
    status = cli.main(["replay", str(session), "--", "true"])
    err = capsys.readouterr().err
    assert status == 2, err
    assert "channel 'rtk' names no device path" in err and "--as rtk=PATH" in err


# --- a channel left out of a replay: a note, not a failure (issue 37) -------


def three_channel_session(path):
    """Channels gps, rtk and imu (tcp): one exchange each."""
    names = ("gps", "rtk", "imu")
    header = _core.SessionHeader.starting_now()
    header.channels = [_core.Channel(id=number, name=name, port_type="tcp",
                                     port_options=f"type=tcp,host={name},port=9")
                       for number, name in enumerate(names)]
    with _core.SessionWriter(str(path), header) as writer:
        for number, name in enumerate(names):
            writer.write("open", 0, b"", channel=number)
            writer.write("tx", (2 * number + 1) * 1_000_000, f"{name}?\n".encode(), channel=number)
            writer.write("rx", (2 * number + 2) * 1_000_000, f"{name}!\n".encode(),
                         channel=number)
    return path


def test_a_channel_left_out_of_a_replay_is_named_in_the_summary_and_exits_0(tmp_path):
    session = three_channel_session(tmp_path / "three.wtape")
    child = start_cli("replay", str(session), "--timing", "none",
                      "--listen", "gps=127.0.0.1:0", "--listen", "rtk=127.0.0.1:0")
    try:
        for name in ("gps", "rtk"):
            with socket.create_connection(announced_address(child, "tcp"),
                                          timeout=DEADLINE_S) as client:
                client.sendall(f"{name}?\n".encode())
                answer = b""
                while len(answer) < 5:
                    chunk = client.recv(64)
                    assert chunk, f"{name}: the replay closed the connection"
                    answer += chunk
                assert answer == f"{name}!\n".encode()
    finally:
        status, _, err = interrupt(child)
    assert status == 0, err
    assert "wiretape replay: imu: not replayed (no endpoint names channel imu;" in err, err
    for served in ("gps", "rtk"):
        assert f"{served}: not replayed" not in err


def test_every_channel_replayed_leaves_no_note(capsys):
    run_channels(("gps", FinishedBridge("finished")), ("rtk", FinishedBridge("finished")))
    assert "not replayed" not in capsys.readouterr().err
