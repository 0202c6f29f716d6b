"""pyserial through wiretape://, on the data path each call takes (one call
into C++, a first attempt without waiting): lines, sizes and timeouts keep
pyserial's meaning, and the replay's pollable handle tells the truth even
when it is first asked for after data was released."""

import select

import serial

import wiretape
import wiretape.urlhandler

EXCHANGES = [("tx", 1_000, b"ID\n"), ("rx", 2_000, b"OK one\r\nOK two\r\n"),
             ("tx", 3_000, b"MORE\n"), ("rx", 4_000, b"TAIL")]


def open_url(path, timeout=10, **keys):
    wiretape.urlhandler.register()
    query = "&".join(f"{key}={value}" for key, value in {"timing": "none", **keys}.items())
    return serial.serial_for_url(f"wiretape://{path}?{query}", timeout=timeout)


def test_lines_sizes_and_the_end(session_file):
    port = open_url(session_file(EXCHANGES))
    port.write(b"ID\n")
    assert port.readline() == b"OK one\r\n"
    assert port.read_until(b"\r\n", 4) == b"OK t"
    assert port.read_until(b"\r\n") == b"wo\r\n"
    port.write(b"MORE\n")
    assert port.read_until(b"\n", 4) == b"TAIL"  # no delimiter: the size ends it
    port.close()


def test_a_read_with_nothing_there_waits_its_timeout(session_file):
    port = open_url(session_file(EXCHANGES), timeout=0)
    assert port.read(4) == b""  # nothing before the request: timeout 0 polls
    port.write(b"ID\n")
    assert port.read(6) == b"OK one"
    port.close()


def test_fileno_asked_for_after_the_answer_is_readable_at_once(session_file):
    port = open_url(session_file(EXCHANGES))
    port.write(b"ID\n")  # the answer is released now, before anyone polls
    readable, _, _ = select.select([port.fileno()], [], [], 10)
    assert readable
    assert port.read(len(b"OK one\r\nOK two\r\n")) == b"OK one\r\nOK two\r\n"
    readable, _, _ = select.select([port.fileno()], [], [], 0)
    assert not readable  # everything read: no longer readable
    port.close()


def test_a_closed_port_refuses_the_data_path(session_file):
    port = open_url(session_file(EXCHANGES))
    port.close()
    for call in (lambda: port.read(1), lambda: port.readline(), lambda: port.write(b"x")):
        try:
            call()
        except serial.PortNotOpenError:
            continue
        raise AssertionError("a closed port read or wrote")
