"""wiretape.Port from Python over loopback, pty and TCP: read semantics,
timeouts (None, 0, float), compound reads, in_waiting, the pollable fileno,
writes, state and serial controls."""

import datetime
import errno
import math
import select
import socket
import time

import pytest

import wiretape


# --- read: what is there, at least one byte, b"" on timeout -----------------


def test_read_returns_what_is_there_up_to_size(endpoint):
    endpoint.feed(b"hello world")
    endpoint.wait_in_waiting(11)
    assert endpoint.port.read(5) == b"hello"
    assert endpoint.port.read(100) == b" world"  # what is there, not 100


def test_read_default_size_is_one_byte(endpoint):
    endpoint.feed(b"ab")
    assert endpoint.port.read() == b"a"
    assert endpoint.port.read() == b"b"


def test_read_times_out_with_empty_bytes_after_the_timeout(endpoint):
    port = endpoint.port
    started = time.monotonic()
    assert port.read(10, timeout=0.2) == b""
    elapsed = time.monotonic() - started
    assert 0.15 <= elapsed < 3.0


def test_omitted_timeout_is_the_ports(endpoint):
    port = endpoint.port
    port.timeout = 0.2
    started = time.monotonic()
    assert port.read(10) == b""
    assert 0.15 <= time.monotonic() - started < 3.0


def test_timeout_zero_polls(endpoint):
    port = endpoint.port
    started = time.monotonic()
    assert port.read(10, timeout=0) == b""
    assert time.monotonic() - started < 0.5
    endpoint.feed(b"x")
    endpoint.wait_in_waiting(1)
    assert port.read(10, timeout=0) == b"x"


def test_timeout_none_blocks_until_data_arrives(endpoint):
    import threading

    port = endpoint.port
    port.timeout = 0  # the per-call None must win over the port's poll
    result = {}
    started = threading.Event()

    def reader():
        started.set()
        result["data"] = port.read(4, timeout=None)

    thread = threading.Thread(target=reader)
    thread.start()
    started.wait(5)
    endpoint.feed(b"late")
    thread.join(5)
    assert not thread.is_alive()
    assert result["data"] and b"late".startswith(result["data"])


def test_read_zero_bytes_returns_at_once(endpoint):
    assert endpoint.port.read(0, timeout=None) == b""


def test_negative_sizes_are_value_errors(loopback):
    with pytest.raises(ValueError, match="size"):
        loopback.read(-1)
    with pytest.raises(ValueError, match="count"):
        loopback.read_exactly(-5)
    with pytest.raises(ValueError, match="size"):
        loopback.read_until(b"\n", -1)


# --- compound reads ----------------------------------------------------------


def test_read_exactly_waits_for_all_bytes_across_pieces(endpoint):
    endpoint.feed(b"abc")
    endpoint.feed(b"defg")
    assert endpoint.port.read_exactly(6) == b"abcdef"
    assert endpoint.port.read(1) == b"g"


def test_read_exactly_returns_the_partial_data_on_timeout(endpoint):
    endpoint.feed(b"abc")
    endpoint.wait_in_waiting(3)
    started = time.monotonic()
    assert endpoint.port.read_exactly(10, timeout=0.2) == b"abc"
    assert time.monotonic() - started >= 0.15


def test_read_until_stops_after_the_delimiter_and_consumes_nothing_more(endpoint):
    endpoint.feed(b"line one\r\nline two\r\n")
    endpoint.wait_in_waiting(20)
    assert endpoint.port.read_until(b"\r\n") == b"line one\r\n"
    assert endpoint.port.in_waiting == 10
    assert endpoint.port.read_until(b"\r\n") == b"line two\r\n"


def test_read_until_default_is_newline_and_size_caps_it(endpoint):
    endpoint.feed(b"abcdef\nxyz\n")
    assert endpoint.port.read_until(size=3) == b"abc"
    assert endpoint.port.read_until() == b"def\n"
    assert endpoint.port.read_line() == b"xyz\n"


def test_read_until_finds_a_delimiter_split_across_arrivals(endpoint):
    port = endpoint.port
    endpoint.feed(b"OK\r")
    # The first part arrives, the read times out with it...
    assert port.read_until(b"\r\n", timeout=0.1) == b"OK\r"
    endpoint.feed(b"\nNEXT\r")
    endpoint.feed(b"\n")
    # ...and a delimiter split between two arrivals is still found.
    assert port.read_until(b"\r\n") == b"\nNEXT\r\n"


def test_read_until_returns_the_partial_data_on_timeout(endpoint):
    endpoint.feed(b"no end")
    endpoint.wait_in_waiting(6)
    assert endpoint.port.read_until(b"\n", timeout=0.1) == b"no end"


def test_skip_and_skip_until(endpoint):
    port = endpoint.port
    endpoint.feed(b"0123456789#payload")
    endpoint.wait_in_waiting(18)
    assert port.skip(4) == 4
    assert port.skip_until(b"#") is True
    assert port.read_exactly(7) == b"payload"
    assert port.skip_until(b"#", timeout=0.1) is False
    assert port.skip(3, timeout=0.1) == 0


def test_a_compound_read_is_one_rx_record_however_it_was_sliced(tmp_path):
    log = tmp_path / "driver.wtape"
    with wiretape.open_port(f"type=loopback,timeout=5,log={log}") as port:
        port.write_all(b"alpha\nbeta\r\n")
        assert port.read_line() == b"alpha\n"
        assert port.read_until(b"\r\n") == b"beta\r\n"
        port.write_all(b"noise#")
        assert port.skip_until(b"#") is True
        port.write_all(b"gam")
        # Waits for the rest across several 50 ms slices, then times out.
        assert port.read_exactly(5, timeout=0.25) == b"gam"
        port.write_all(b"ma\n")
        assert port.read_until(b"\n", timeout=0.25) == b"ma\n"
        assert port.read_until(b"\n", timeout=0.05) == b""  # not recorded
    rx = [bytes(r.data) for r in wiretape.SessionReader(str(log)) if r.kind == "rx"]
    assert rx == [b"alpha\n", b"beta\r\n", b"noise#", b"gam", b"ma\n"]


def test_read_until_accepts_any_bytes_like_delimiter(loopback):
    loopback.write(b"a;b;")
    assert loopback.read_until(bytearray(b";")) == b"a;"
    assert loopback.read_until(memoryview(b";")) == b"b;"
    with pytest.raises(TypeError, match="str"):
        loopback.read_until(";")


# --- available, wait_readable, fileno ----------------------------------------


def test_in_waiting_and_available_count_what_a_read_returns_at_once(endpoint):
    port = endpoint.port
    assert port.in_waiting == 0
    assert port.available() == 0
    endpoint.feed(b"12345")
    endpoint.wait_in_waiting(5)
    assert port.available() == 5
    port.read(2)
    assert port.in_waiting == 3


def test_wait_readable_reports_data_and_times_out_without_it(endpoint):
    port = endpoint.port
    started = time.monotonic()
    assert port.wait_readable(0.1) is False
    assert time.monotonic() - started >= 0.08
    endpoint.feed(b"x")
    assert port.wait_readable(5) is True
    assert port.wait_readable(0) is True
    assert port.read(1) == b"x"  # waiting consumed nothing


def test_fileno_is_pollable_with_select(endpoint):
    port = endpoint.port
    fd = port.fileno()
    assert fd == port.native_handle() and fd >= 0
    assert select.select([fd], [], [], 0)[0] == []
    endpoint.feed(b"ping")
    assert select.select([fd], [], [], 5)[0] == [fd]
    assert select.select([port], [], [], 0)[0] == [port]  # the Port itself too
    assert endpoint.port.read_exactly(4) == b"ping"
    if endpoint.kind == "loopback":  # readable exactly when available() > 0
        assert select.select([fd], [], [], 0)[0] == []


def test_fileno_after_close_raises_and_native_handle_is_minus_one(loopback):
    loopback.close()
    assert loopback.native_handle() == -1
    with pytest.raises(wiretape.PortClosed):
        loopback.fileno()


# --- writing -------------------------------------------------------------------


def test_write_returns_the_count_and_reaches_the_device(endpoint):
    port = endpoint.port
    assert port.write(b"hello") == 5
    assert port.write_all(bytearray(b" big ") + memoryview(b"world")) == 10
    assert endpoint.collect(15) == b"hello big world"


def test_write_of_nothing_is_zero(endpoint):
    assert endpoint.port.write(b"") == 0
    assert endpoint.port.write_all(b"") == 0


def test_write_refuses_str_with_a_clear_message(loopback):
    with pytest.raises(TypeError, match="bytes-like, not str"):
        loopback.write("text")
    with pytest.raises(TypeError, match="bytes-like"):
        loopback.write_all(12)


def test_flush_input_drops_unread_data(endpoint):
    endpoint.feed(b"stale")
    endpoint.wait_in_waiting(5)
    endpoint.port.flush_input()
    assert endpoint.port.read(5, timeout=0.1) == b""
    endpoint.port.flush_output()
    endpoint.port.drain()


# --- state ---------------------------------------------------------------------


def test_timeout_property_takes_seconds_none_and_zero():
    port = wiretape.open_port("type=loopback")
    try:
        assert port.timeout is None  # the default blocks
        port.timeout = 0.25
        assert math.isclose(port.timeout, 0.25)
        port.timeout = 2
        assert port.timeout == 2.0
        port.timeout = 0
        assert port.timeout == 0.0
        port.timeout = None
        assert port.timeout is None
    finally:
        port.close()


def test_timeouts_accept_a_timedelta(loopback):
    loopback.timeout = datetime.timedelta(milliseconds=250)
    assert math.isclose(loopback.timeout, 0.25)
    started = time.monotonic()
    assert loopback.read(1, timeout=datetime.timedelta(milliseconds=50)) == b""
    assert time.monotonic() - started >= 0.05
    loopback.write_all(b"ab\n")
    assert loopback.read_until(b"\n", timeout=datetime.timedelta(seconds=5)) == b"ab\n"
    for call in (lambda t: loopback.read_exactly(1, timeout=t),
                 lambda t: loopback.read_line(timeout=t),
                 lambda t: loopback.skip(1, timeout=t),
                 lambda t: loopback.skip_until(b"x", timeout=t),
                 lambda t: loopback.wait_readable(t)):
        call(datetime.timedelta(0))  # polls
    with pytest.raises(ValueError, match="timeout"):
        loopback.timeout = datetime.timedelta(seconds=-1)


def test_timeout_option_sets_the_property():
    with wiretape.open_port("type=loopback,timeout=1.5") as port:
        assert port.timeout == 1.5


@pytest.mark.parametrize("bad", [-1, -0.001, float("nan")])
def test_negative_or_nan_timeouts_are_value_errors(loopback, bad):
    with pytest.raises(ValueError, match="timeout"):
        loopback.timeout = bad
    with pytest.raises(ValueError, match="timeout"):
        loopback.read(1, timeout=bad)
    assert loopback.timeout == 1.0  # unchanged


def test_a_timeout_of_the_wrong_type_is_a_type_error(loopback):
    with pytest.raises(TypeError, match="timeout"):
        loopback.timeout = "1"


def test_description_type_access_and_repr(endpoint):
    port = endpoint.port
    assert port.type == endpoint.kind
    assert port.access == "readwrite"
    assert isinstance(port.description, str) and port.description
    assert endpoint.kind in repr(port)


def test_readonly_port_refuses_writes_with_port_error():
    with wiretape.open_port("type=loopback,access=readonly") as port:
        assert port.access == "readonly"
        with pytest.raises(wiretape.PortError) as raised:
            port.write(b"x")
        assert raised.value.errno == errno.EBADF
        assert "read-only" in str(raised.value)


def test_context_manager_closes_the_port():
    with wiretape.open_port("type=loopback") as port:
        assert port.is_open
    assert not port.is_open
    assert "closed" in repr(port)


def test_calls_on_a_closed_port_raise_port_closed(loopback):
    loopback.close()
    loopback.close()  # twice is fine
    with pytest.raises(wiretape.PortClosed):
        loopback.read(1)
    with pytest.raises(wiretape.PortClosed):
        loopback.write(b"x")


# --- serial controls --------------------------------------------------------------


def test_serial_controls_on_a_port_without_them_raise_enotsup(loopback):
    for call in (lambda: loopback.set_baud(9600), lambda: loopback.cts,
                 lambda: loopback.dtr, lambda: loopback.ri,
                 lambda: loopback.set_dtr(True), lambda: loopback.send_break(0.01),
                 lambda: loopback.serial_settings()):
        with pytest.raises(wiretape.PortError) as raised:
            call()
        assert raised.value.errno == errno.ENOTSUP
        assert "loopback" in str(raised.value)
    with pytest.raises(wiretape.PortError):
        loopback.baud = 115200


def test_a_pty_reports_its_line_settings(tmp_path):
    with wiretape.open_port(f"type=pty,link={tmp_path / 'tty'}") as port:
        settings = port.serial_settings()
        assert set(settings) == {"baud", "databits", "stopbits", "parity", "flow"}
        assert settings["baud"] == port.baud
        assert settings["parity"] in ("none", "even", "odd", "mark", "space")


def test_configure_rejects_bad_values_on_a_pty(tmp_path):
    with wiretape.open_port(f"type=pty,link={tmp_path / 'tty'}") as port:
        with pytest.raises(ValueError, match="parity must be one of"):
            port.configure(parity="bogus")
        with pytest.raises(ValueError, match="databits"):
            port.configure(databits=9)
        with pytest.raises(ValueError, match="stopbits"):
            port.configure(stopbits=3)
        with pytest.raises(ValueError, match="flow"):
            port.configure(flow="magic")


def test_modem_lines_are_pyserial_style_properties(session_file):
    # A replay emulates a device with its lines up (CTS, DSR, CD) and no ring.
    path = session_file([("rx", 0, b"hi")])
    with wiretape.open_port(f"type=replay,timing=none,unused=ignore,file={path}") as port:
        assert (port.cts, port.dsr, port.ri, port.cd) == (True, True, False, True)
        assert (port.dtr, port.rts) == (True, True)  # raised at open, as pyserial
        port.dtr = False
        port.rts = False
        assert (port.dtr, port.rts) == (False, False)
        port.set_dtr(True)
        assert port.dtr is True and port.rts is False
        with pytest.raises(AttributeError):
            port.cts = False  # read-only: the device drives it


def test_modem_line_changes_are_recorded(session_file, tmp_path):
    path = session_file([("rx", 0, b"hi")])
    log = tmp_path / "driver.wtape"
    with wiretape.open_port(f"type=replay,timing=none,unused=ignore,file={path},log={log}") as port:
        port.dtr = False
        port.rts = True
        assert port.dtr is False
    events = [bytes(r.data) for r in wiretape.SessionReader(str(log)) if r.kind == "modem_lines"]
    # The device's lines at open first (a replay has lines: a modem's, up).
    assert events == [b'{"cts":true,"dsr":true,"ri":false,"cd":true}',
                      b'{"dtr":false}', b'{"rts":true}']


def test_send_break_duration_is_validated(loopback):
    with pytest.raises(ValueError, match="duration"):
        loopback.send_break(-1)


# --- open_port ---------------------------------------------------------------------


def test_open_port_connect_refused_is_a_port_error_with_errno():
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    number = probe.getsockname()[1]
    probe.close()  # nobody listens there now
    with pytest.raises(wiretape.PortError) as raised:
        wiretape.open_port(f"type=tcp,port={number},timeout=2")
    assert raised.value.errno == errno.ECONNREFUSED
    assert isinstance(raised.value, OSError)
    assert str(number) in str(raised.value)


def test_open_port_needs_a_string():
    with pytest.raises(TypeError):
        wiretape.open_port(None)


# --- option helpers ------------------------------------------------------------------


def test_option_values_are_quoted_once_in_cpp():
    quote = wiretape._core.quote_option_value
    assert quote("/dev/ttyUSB0") == "/dev/ttyUSB0"
    assert quote("/home/me/My Runs/a.wtape") == '"/home/me/My Runs/a.wtape"'
    assert quote('say "x"') == '"say \\"x\\""'
    assert quote("") == '""'
    assert quote("k=v,w") == '"k=v,w"'


def test_a_bare_device_path_means_a_serial_port():
    device_options = wiretape._core.device_options
    assert device_options("/dev/ttyACM0") == "type=serial,device=/dev/ttyACM0"
    assert device_options(" /dev/My Port ") == 'type=serial,device="/dev/My Port"'
    assert device_options("type=tcp,port=10940") == "type=tcp,port=10940"
    with pytest.raises(wiretape.OptionError, match="empty"):
        device_options("  ")
