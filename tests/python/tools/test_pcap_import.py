"""``wiretape convert --from pcap``: a TCP conversation or UDP flow of a
packet capture becomes a session (tshark reads and reassembles it).

The captures of tests/data/pcap were made here from real exchanges on the
loopback interface (make_captures.py there); the live tests capture a real
pymodbus exchange and a UDP exchange with dumpcap, import them and replay
the import to the same client."""

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import textwrap

import pytest

import wiretape
from wiretape import cli
from wiretape.tools import pcap_capture, pcap_import
from wiretape.tools.convert import convert

from devices import announced_address, interrupt, start_cli, wait_until

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "data", "pcap")
DEADLINE_S = 30.0


@pytest.fixture(autouse=True)
def needs_tshark():
    if shutil.which("tshark") is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed (apt-get install tshark); "
                    "convert --from pcap is not tested")


def capture(name):
    return os.path.join(DATA, name)


def records_of(path):
    return [(record.kind, record.t_ns, record.data) for record in wiretape.SessionReader(str(path))]


def stream(records, kind):
    return b"".join(data for k, _, data in records if k == kind)


def run(capsys, *argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.err


def first_packet_time(path):
    result = subprocess.run(["tshark", "-r", path, "-c", "1", "-T", "fields",
                             "-e", "frame.time_epoch"], capture_output=True, text=True,
                            timeout=60)
    return pcap_capture.parse_epoch_ns(result.stdout)


# --- the captures checked in -------------------------------------------------

def test_a_tcp_conversation_becomes_a_session_with_directions_times_and_connection(tmp_path):
    out = tmp_path / "tcp.wtape"
    result = convert(capture("tcp.pcap"), out)
    assert result.from_format == "pcap"  # from the name

    records = records_of(out)
    assert [k for k, _, _ in records if k in ("tx", "rx")] == ["tx", "tx", "rx", "tx", "tx", "rx"]
    assert stream(records, "tx") == b"ABCD;hello;"
    assert stream(records, "rx") == b"R:ABCD;R:hello;"
    kinds = [k for k, _, _ in records]
    assert kinds[0] == "client_connect" and kinds[-1] == "client_disconnect"
    connect = wiretape.SessionReader(str(out))
    events = [r for r in connect if r.kind == "client_connect"]
    assert re.fullmatch(rb'\{"peer":"127\.0\.0\.1:\d+","role":"control"\}', events[0].data)
    times = [t for _, t, _ in records]
    assert times == sorted(times) and times[0] == 0 and times[-1] > 0

    header = wiretape.SessionReader(str(out)).header
    assert header.port_type == "tcp"
    assert header.port_options == "type=tcp,host=127.0.0.1,port=15021"
    assert header.capture == "wire"
    # Provenance (format 1.1): the capture, not the converting machine.
    assert header.source_format == "pcap"
    assert header.source_files == ["tcp.pcap"]
    assert header.device_address == "127.0.0.1:15021"
    assert header.host == ""
    start_ns = first_packet_time(capture("tcp.pcap"))
    seconds, ns = divmod(start_ns, 1_000_000_000)
    assert header.start_utc.endswith(f".{ns:09d}Z")
    import datetime
    assert header.start_utc.startswith(datetime.datetime.fromtimestamp(
        seconds, tz=datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S"))


def test_retransmitted_reordered_and_overlapping_segments_give_the_same_streams(tmp_path):
    """tcp-damaged.pcap is tcp.pcap with the first two data segments swapped,
    the second sent twice, and a segment overlapping two others."""
    convert(capture("tcp.pcap"), tmp_path / "a.wtape")
    clean = records_of(tmp_path / "a.wtape")
    convert(capture("tcp-damaged.pcap"), tmp_path / "b.wtape")
    damaged = records_of(tmp_path / "b.wtape")
    assert [(k, d) for k, _, d in damaged if k in ("tx", "rx")] == \
        [(k, d) for k, _, d in clean if k in ("tx", "rx")]
    times = [t for _, t, _ in damaged]
    assert times == sorted(times)


def test_a_udp_flow_keeps_each_datagram_and_the_device_is_the_lower_port(tmp_path):
    out = tmp_path / "udp.wtape"
    convert(capture("udp.pcap"), out)
    records = records_of(out)
    assert [(k, d) for k, _, d in records] == [
        ("tx", b"PING 1"), ("rx", b"PONG 1"), ("tx", b"PING 2\x00\xff"), ("rx", b"PONG 2\x00\xff")]
    header = wiretape.SessionReader(str(out)).header
    assert (header.port_type, header.port_options) == ("udp", "type=udp,host=127.0.0.1,port=15023")


def test_device_addr_turns_the_directions_around(tmp_path):
    out = tmp_path / "udp.wtape"
    client = pcap_import.conversations(capture("udp.pcap"))[0].endpoints[0]
    convert(capture("udp.pcap"), out, device_addr=f"{client[0]}:{client[1]}")
    assert [k for k, _, _ in records_of(out)] == ["rx", "tx", "rx", "tx"]


def test_several_conversations_are_listed_with_the_option_to_choose_one(capsys, tmp_path):
    out = tmp_path / "multi.wtape"
    code, err = run(capsys, "convert", capture("multi.pcap"), str(out))
    assert code == 1, err
    assert "multi.pcap" in err and "3 conversations" in err
    listed = re.findall(r"(tcp|udp):(\d+)\s+(\S+) <-> (\S+)\s+(TCP|UDP), (\d+) packets, "
                        r"(\d+) bytes", err)
    assert [(p, n, a.rsplit(":", 1)[1]) for p, n, _, a, _, _, _ in listed] == \
        [("tcp", "0", "15021"), ("tcp", "1", "15022"), ("udp", "0", "15023")]
    assert "--stream tcp:0" in err
    assert not out.exists()

    code, err = run(capsys, "convert", capture("multi.pcap"), str(out), "--stream", "tcp:1")
    assert code == 0, err
    assert stream(records_of(out), "tx") == b"second;"

    code, err = run(capsys, "convert", capture("multi.pcap"), str(out),
                    "--stream", "udp.port == 15023")
    assert code == 0, err
    assert stream(records_of(out), "tx") == b"PING 1PING 2\x00\xff"

    code, err = run(capsys, "convert", capture("multi.pcap"), str(out),
                    "--device-addr", "127.0.0.1:15021")
    assert code == 0, err
    assert stream(records_of(out), "rx") == b"R:ABCD;R:hello;"


@pytest.mark.parametrize("name, options, expected", [
    ("multi.pcap", ["--stream", "tcp:7"], "no conversation matching --stream tcp:7"),
    ("multi.pcap", ["--stream", "tcp.port == 1"], "no conversation matching --stream"),
    ("udp.pcap", ["--device-addr", "10.0.0.1:502"], "no conversation matching --device-addr"),
    ("multi.pcap", ["--stream", "tcp.port =="], "--stream is neither"),
    ("truncated.pcap", [], "truncated after packet 5 (packet 6 is cut short)"),
    ("make_captures.py", ["--from", "pcap"], "not a pcap or pcapng capture"),
])
def test_bad_input_is_one_clear_error_naming_the_file_exit_1(capsys, tmp_path, name, options,
                                                              expected):
    out = tmp_path / "out.wtape"
    code, err = run(capsys, "convert", capture(name), str(out), *options)
    assert code == 1, err
    assert name in err and expected in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_stream_and_device_addr_need_a_capture(capsys, tmp_path, session_file):
    path = session_file([("tx", 0, b"x")])
    code, err = run(capsys, "convert", str(path), str(tmp_path / "o.jsonl"), "--stream", "tcp:0")
    assert code == 2 and "--from pcap" in err, err


def test_a_capture_converts_straight_to_the_exports(tmp_path):
    result = convert(capture("udp.pcap"), tmp_path / "udp.jsonl")
    assert (result.records, result.to_format) == (4, "jsonl")
    result = convert(capture("tcp.pcap"), tmp_path / "tcp.pcapng")
    assert result.to_format == "pcapng" and result.records == 8


# --- live captures -------------------------------------------------------------

class Capture:
    """dumpcap on the loopback interface, writing `path`."""

    def __init__(self, path, capture_filter):
        if shutil.which("dumpcap") is None:
            pytest.skip("SKIPPED LOUDLY: dumpcap is not installed (apt-get install "
                        "wireshark-common); the live capture tests do not run")
        self.path = str(path)
        self.log = open(self.path + ".log", "w+")
        self.process = subprocess.Popen(["dumpcap", "-i", "lo", "-w", self.path, "-f",
                                         capture_filter], stdout=self.log, stderr=self.log)

        def started():
            self.log.seek(0)
            text = self.log.read()
            if self.process.poll() is not None:
                if "permission" in text.lower() or "not permitted" in text.lower():
                    pytest.skip("SKIPPED LOUDLY: no permission to capture on lo "
                                f"(run as root or in group wireshark): {text.strip()}")
                raise AssertionError(f"dumpcap ended: {text}")
            return "Capturing on" in text and os.path.exists(self.path)

        wait_until(started, DEADLINE_S, "dumpcap to start capturing")

    def wait_for(self, display_filter, count):
        """Until the file holds `count` packets matching the filter."""
        def seen():
            result = subprocess.run(["tshark", "-r", self.path, "-Y", display_filter],
                                    capture_output=True, text=True, timeout=60)
            return len(result.stdout.splitlines()) >= count

        wait_until(seen, DEADLINE_S, f"{count} packets of {display_filter!r} in the capture")

    def stop(self):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            self.process.wait(DEADLINE_S)
        self.log.close()


def free_port(kind=socket.SOCK_STREAM):
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


MODBUS_SERVER = textwrap.dedent("""
    import sys
    from pymodbus.datastore import (ModbusDeviceContext, ModbusSequentialDataBlock,
                                    ModbusServerContext)
    from pymodbus.server import StartTcpServer
    registers = ModbusSequentialDataBlock(1, [17, 42, 4711, 65535, 0, 1, 2, 3, 4, 5])
    context = ModbusServerContext(devices=ModbusDeviceContext(hr=registers), single=True)
    StartTcpServer(context, address=("127.0.0.1", int(sys.argv[1])))
""")


def modbus_reads(port):
    from pymodbus.client import ModbusTcpClient

    client = ModbusTcpClient("127.0.0.1", port=port, timeout=10, retries=0)
    assert client.connect(), f"no Modbus server on port {port}"
    try:
        values = []
        for address, count in ((0, 5), (3, 4)):
            reply = client.read_holding_registers(address, count=count, device_id=1)
            assert not reply.isError(), reply
            values.append(list(reply.registers))
        return values
    finally:
        client.close()


def accepting(port, server):
    def check():
        if server.poll() is not None:
            raise AssertionError("the pymodbus server ended: " + server.stderr.read().decode())
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return True
        except OSError:
            return False
    return check








def test_a_captured_pymodbus_exchange_replays_to_the_same_client(tmp_path):
    pytest.importorskip("pymodbus", reason="SKIPPED LOUDLY: pymodbus is not installed")
    port = free_port()
    server = subprocess.Popen([sys.executable, "-c", MODBUS_SERVER, str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_until(accepting(port, server), DEADLINE_S, "the pymodbus server to accept")
        live = Capture(tmp_path / "modbus.pcapng", f"tcp port {port}")
        try:
            values = modbus_reads(port)
            live.wait_for("tcp.flags.fin == 1", 2)
        finally:
            live.stop()
    finally:
        server.terminate()
        server.wait(DEADLINE_S)
    # registers 3 and 4 were read twice: the server answered consistently
    assert len(values[0]) == 5 and values[0][3:] == values[1][:2] and 4711 in values[0]

    session = tmp_path / "modbus.wtape"
    convert(tmp_path / "modbus.pcapng", session)
    records = records_of(session)
    assert [k for k, _, _ in records if k in ("tx", "rx")] == ["tx", "rx", "tx", "rx"]
    header = wiretape.SessionReader(str(session)).header
    assert header.port_options == f"type=tcp,host=127.0.0.1,port={port}"

    # exported again, Wireshark decodes the import as Modbus/TCP
    exported = tmp_path / "modbus-export.pcapng"
    convert(session, exported)
    decoded = subprocess.run(
        ["tshark", "-r", str(exported), "-o", f"mbtcp.tcp.port:{port}", "-Y",
         "modbus.regval_uint16", "-T", "fields", "-E", "aggregator=,", "-e", "mbtcp.trans_id",
         "-e", "modbus.func_code", "-e", "modbus.regval_uint16"],
        capture_output=True, text=True, timeout=60)
    rows = [line.split("\t") for line in decoded.stdout.splitlines()]
    assert [row[1] for row in rows] == ["3", "3"], decoded.stderr
    assert [[int(v) for v in row[2].split(",")] for row in rows] == values

    child = start_cli("replay", str(session), "--listen", "127.0.0.1:0", "--timing", "none")
    try:
        _, replay_port = announced_address(child, "tcp")
        assert modbus_reads(replay_port) == values
    finally:
        _, _, err = interrupt(child)
    assert child.returncode == 0, err


def test_a_captured_udp_exchange_replays_to_the_same_client(tmp_path):
    port = free_port(socket.SOCK_DGRAM)
    device = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    device.bind(("127.0.0.1", port))
    device.settimeout(DEADLINE_S)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.settimeout(DEADLINE_S)
    requests = [b"temperature?", b"\x00\x01binary\xff"]
    live = Capture(tmp_path / "udp.pcapng", f"udp port {port}")
    try:
        answers = []
        for request in requests:
            client.sendto(request, ("127.0.0.1", port))
            data, sender = device.recvfrom(1000)
            device.sendto(b"reply to " + data, sender)
            answers.append(client.recvfrom(1000)[0])
        live.wait_for("udp", 4)
    finally:
        live.stop()
        device.close()
        client.close()

    session = tmp_path / "udp.wtape"
    convert(tmp_path / "udp.pcapng", session, device_addr=f"127.0.0.1:{port}")
    assert [(k, d) for k, _, d in records_of(session)] == [
        ("tx", requests[0]), ("rx", answers[0]), ("tx", requests[1]), ("rx", answers[1])]

    child = start_cli("replay", str(session), "--udp", "127.0.0.1:0", "--timing", "none")
    try:
        host, replay_port = announced_address(child, "udp")
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:
            again.settimeout(DEADLINE_S)
            replies = []
            for request in requests:
                again.sendto(request, (host, replay_port))
                replies.append(again.recvfrom(1000)[0])
        assert replies == answers
    finally:
        _, _, err = interrupt(child)
    assert child.returncode == 0, err


def test_an_ipv6_conversation_imports_and_exports_with_its_addresses_and_ports(tmp_path):
    if not socket.has_ipv6:
        pytest.skip("SKIPPED LOUDLY: no IPv6 on this machine")
    server = socket.socket(socket.AF_INET6)
    try:
        server.bind(("::1", 0))
    except OSError as error:
        pytest.skip(f"SKIPPED LOUDLY: cannot bind ::1: {error}")
    server.listen(1)
    port = server.getsockname()[1]
    live = Capture(tmp_path / "v6.pcapng", f"tcp port {port}")
    try:
        client = socket.create_connection(("::1", port), timeout=DEADLINE_S)
        accepted, _ = server.accept()
        client.sendall(b"ping\n")
        assert accepted.recv(100) == b"ping\n"
        accepted.sendall(b"pong\n")
        assert client.recv(100) == b"pong\n"
        client_port = client.getsockname()[1]
        client.close()
        accepted.close()
        live.wait_for("tcp.flags.fin == 1", 2)
    finally:
        live.stop()
        server.close()

    session = tmp_path / "v6.wtape"
    convert(tmp_path / "v6.pcapng", session)
    header = wiretape.SessionReader(str(session)).header
    assert header.port_options == f"type=tcp,host=::1,port={port}"
    assert [(k, d) for k, _, d in records_of(session) if k in ("tx", "rx")] == \
        [("tx", b"ping\n"), ("rx", b"pong\n")]

    exported = tmp_path / "v6-export.pcapng"
    convert(session, exported)
    result = subprocess.run(["tshark", "-r", str(exported), "-Y", "tcp.len > 0", "-T", "fields",
                             "-e", "ipv6.src", "-e", "tcp.srcport", "-e", "ipv6.dst",
                             "-e", "tcp.dstport", "-e", "tcp.payload"],
                            capture_output=True, text=True, timeout=60)
    assert [line.split("\t") for line in result.stdout.splitlines()] == [
        ["::1", str(client_port), "::1", str(port), b"ping\n".hex()],
        ["::1", str(port), "::1", str(client_port), b"pong\n".hex()],
    ], result.stderr


def test_without_tshark_the_error_says_what_to_install(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))  # no tshark there
    code, err = run(capsys, "convert", capture("tcp.pcap"), str(tmp_path / "o.wtape"))
    assert code == 3 and "needs tshark" in err and "apt-get install tshark" in err, err
