"""The simulator's device model, without a transport: what a SCIP 2.0 driver
will see from it."""
import hokuyo_testlib  # noqa: F401  (puts the simulator on sys.path)
import scip_sim
from scip_sim import Device, checksum, encode


def decode(text: bytes) -> int:
    value = 0
    for c in text:
        value = (value << 6) | (c - 0x30)
    return value


def lines_of(replies):
    return b"".join(data for _, data in replies).split(b"\n")


def assert_sums(lines):
    """Every line after echo (status and data) ends with its sum."""
    for line in lines[1:]:
        if not line:
            continue
        body, sum_byte = line[:-1], line[-1:]
        # Parameter lines leave their ';' out of the sum; data may end in ';'.
        assert sum_byte in (checksum(body), checksum(body.rstrip(b";"))), line


def test_urg_powers_on_in_scip11_and_switches():
    device = Device("urg04lx", now=0.0)
    assert lines_of(device.handle_line(b"VV", 0.0))[:2] == [b"VV", b"E"]
    assert lines_of(device.handle_line(b"SCIP2.0", 0.0))[:2] == [b"SCIP2.0", b"0"]
    lines = lines_of(device.handle_line(b"VV", 0.0))
    assert lines[:2] == [b"VV", b"00P"]
    assert b"SERI:H0706400;F" in lines  # as the real unit's line
    assert_sums(lines)


def test_parameters_are_those_of_the_real_units():
    urg = lines_of(Device("urg04lx", scip2=True, now=0.0).handle_line(b"PP", 0.0))
    assert b"AMIN:44;7" in urg and b"AMAX:725;o" in urg and b"SCAN:600;e" in urg
    utm = lines_of(Device("utm30lx", now=0.0).handle_line(b"PP", 0.0))
    assert b"AMAX:1080;Z" in utm and b"DMAX:60000;J" in utm and b"SCAN:2400;U" in utm


def test_laser_state_governs_scans():
    device = Device("urg04lx", scip2=True, now=0.0)
    assert lines_of(device.handle_line(b"GD0044072501", 0.0))[1] == b"10" + checksum(b"10")
    assert lines_of(device.handle_line(b"BM", 0.0))[1] == b"00P"
    assert lines_of(device.handle_line(b"BM", 0.0))[1] == b"02R"  # already on
    replies = device.handle_line(b"GD0044072501", 0.01)
    due, _ = replies[0]
    assert abs(due - 0.1) < 1e-9  # the next 100 ms scan boundary
    lines = lines_of(replies)
    assert lines[1] == b"00P"
    assert_sums(lines)
    data = b"".join(line[:-1] for line in lines[3:] if line)
    assert len(data) == 682 * 3
    assert decode(lines[2][:-1]) == 100  # device time at the boundary
    assert lines_of(device.handle_line(b"QT", 0.2))[1] == b"00P"
    assert lines_of(device.handle_line(b"GS0044072501", 0.2))[1] == b"10" + checksum(b"10")


def test_data_lines_are_64_characters():
    device = Device("utm30lx", laser_on=True, now=0.0)
    device.laser = True
    lines = lines_of(device.handle_line(b"GD0000108001", 0.0))
    data_lines = [line for line in lines[3:] if line]
    assert all(len(line) == 65 for line in data_lines[:-1])
    assert sum(len(line) - 1 for line in data_lines) == 1081 * 3


def test_stream_counts_down_on_scan_boundaries():
    device = Device("utm30lx", now=0.0)
    lines = lines_of(device.handle_line(b"ME0000108001103", 0.0))
    assert lines[:2] == [b"ME0000108001103", b"00P"]
    scans = device.due_scans(1.0)
    # Interval 1: every other 25 ms scan.
    assert [round(due, 3) for due, _ in scans] == [0.025, 0.075, 0.125]
    echoes = [data.split(b"\n")[0] for _, data in scans]
    assert echoes == [b"ME000010800110%d" % n for n in (2, 1, 0)]
    assert all(data.split(b"\n")[1] == b"99b" for _, data in scans)
    assert device.stream is None and not device.laser  # done: laser off again
    scan_lines = scans[0][1].split(b"\n")
    assert_sums(scan_lines)
    data = b"".join(line[:-1] for line in scan_lines[3:] if line)
    assert len(data) == 1081 * 6


def test_endless_stream_stops_with_qt():
    device = Device("urg04lx", scip2=True, now=0.0)
    device.handle_line(b"MD0044072501000", 0.0)
    scans = device.due_scans(0.35)
    assert len(scans) == 3
    assert all(data.startswith(b"MD0044072501000\n") for _, data in scans)
    device.handle_line(b"QT", 0.35)
    assert device.due_scans(10.0) == []


def test_time_adjust_mode():
    device = Device("urg04lx", scip2=True, start_time_ms=500, now=0.0)
    assert lines_of(device.handle_line(b"TM1", 0.0))[1] == b"01" + checksum(b"01")
    assert lines_of(device.handle_line(b"TM0", 0.0))[1] == b"00P"
    assert lines_of(device.handle_line(b"TM0", 0.0))[1] == b"02R"
    lines = lines_of(device.handle_line(b"TM1", 0.25))
    assert decode(lines[2][:-1]) == 750
    assert lines_of(device.handle_line(b"TM2", 0.0))[1] == b"00P"
    assert lines_of(device.handle_line(b"TM2", 0.0))[1] == b"03" + checksum(b"03")


def test_clock_wraps_at_24_bits():
    device = Device("urg04lx", scip2=True, start_time_ms=0xFFFFFF - 50, now=0.0)
    assert device.timestamp_ms(0.0) == 0xFFFFFF - 50
    assert device.timestamp_ms(0.1) == 49


def test_baud_change_comes_after_the_reply():
    device = Device("urg04lx", scip2=True, now=0.0)
    assert lines_of(device.handle_line(b"SS115200", 0.0))[1] == b"00P"
    assert device.baud == 115200 and device.baud_changed == 115200
    assert lines_of(device.handle_line(b"SS115200", 0.0))[1] == b"03" + checksum(b"03")
    assert lines_of(device.handle_line(b"SS000300", 0.0))[1] == b"01" + checksum(b"01")


def test_fault_injection():
    device = Device("urg04lx", scip2=True, now=0.0)
    device.handle_line(b"DB55", 0.0)
    assert lines_of(device.handle_line(b"BM", 0.0))[1] == b"01" + checksum(b"01")
    assert lines_of(device.handle_line(b"GD0044072501", 0.0))[1] == b"55" + checksum(b"55")
    assert b"Hardware trouble" in b"".join(lines_of(device.handle_line(b"II", 0.0)))
    device.handle_line(b"DB00", 0.0)
    assert lines_of(device.handle_line(b"BM", 0.0))[1] == b"00P"


def test_sum_and_garbage_injection_hit_once():
    device = Device("urg04lx", scip2=True, bad_sum=["GD"], garbage=["PP"], now=0.0)
    device.laser = True
    lines = lines_of(device.handle_line(b"GD0044012001", 0.0))
    assert [checksum(line[:-1]) == line[-1:] for line in lines[2:6]] == [True, True, False, True]
    assert_sums(lines_of(device.handle_line(b"GD0044012001", 0.0)))
    assert device.handle_line(b"PP", 0.0)[0][1].startswith(b"\x00\xff")
    assert device.handle_line(b"PP", 0.0)[0][1].startswith(b"PP\n")


def test_unknown_command_is_0e():
    device = Device("urg04lx", scip2=True, now=0.0)
    assert lines_of(device.handle_line(b"XX", 0.0))[1] == b"0E" + checksum(b"0E")
    assert lines_of(device.handle_line(b"ME0044072501101", 0.0))[1] == b"0E" + checksum(b"0E")


def test_line_splitter_takes_lf_or_cr_and_drops_noise():
    splitter = scip_sim.LineSplitter(limit=16)
    assert splitter.feed(b"VV\nPP\r\nI") == [b"VV", b"PP"]
    assert splitter.feed(b"I\n") == [b"II"]
    assert splitter.feed(b"x" * 40) == []
    assert splitter.feed(b"QT\n") == [b"QT"]


def test_encode_matches_the_real_timestamp():
    assert encode(6968830, 4) == b"JUGn"


def test_pty_line_speed_changes_after_the_ss_reply(simulator):
    import os
    import select
    import termios
    import time
    import tty

    sim = simulator("--model", "urg04lx", "--scip2")
    fd = os.open(sim.where, os.O_RDWR | os.O_NOCTTY)
    try:
        tty.setraw(fd)
        assert termios.tcgetattr(fd)[4] != termios.B115200
        os.write(fd, b"SS115200\n")
        reply = b""
        end = time.monotonic() + 10
        while not reply.endswith(b"\n\n") and time.monotonic() < end:
            if select.select([fd], [], [], 1)[0]:
                reply += os.read(fd, 100)
        assert reply == b"SS115200\n00P\n\n"
        # The simulator applies the speed right after writing the reply.
        while termios.tcgetattr(fd)[4] != termios.B115200 and time.monotonic() < end:
            select.select([], [], [], 0.01)
        assert termios.tcgetattr(fd)[4] == termios.B115200
    finally:
        os.close(fd)


def test_command_line_errors_are_clear():
    import subprocess
    import sys

    from hokuyo_testlib import EXAMPLE

    def sim(*args):
        return subprocess.run([sys.executable, str(EXAMPLE / "sim"), *args],
                              capture_output=True, text=True, timeout=30)

    result = sim("--model", "urg04lx")
    assert result.returncode == 2 and "--pty" in result.stderr
    result = sim("--model", "nosuch", "--pty", "/tmp/x")
    assert result.returncode == 2 and "nosuch" in result.stderr
    result = sim("--listen", "localhost:http")
    assert result.returncode == 2 and "HOST:PORT" in result.stderr
    result = sim("--pty", "/nonexistent-dir/link")
    assert result.returncode == 3 and "nonexistent-dir" in result.stderr


def test_tcp_client_that_leaves_gets_a_fresh_device_next(simulator):
    import socket

    sim = simulator("--model", "utm30lx", "--listen", "127.0.0.1:0")
    host, port = sim.where.rsplit(":", 1)

    def exchange(command):
        with socket.create_connection((host, int(port)), timeout=10) as conn:
            conn.sendall(command)
            reply = b""
            while not reply.endswith(b"\n\n"):
                chunk = conn.recv(4096)
                assert chunk, "the simulator closed the connection"
                reply += chunk
            return reply

    assert exchange(b"BM\n") == b"BM\n00P\n\n"
    assert exchange(b"BM\n") == b"BM\n00P\n\n"  # laser off again: a new power-on
