"""The ``wiretape_serial`` fixture, run on small test files with pytester: a
driver module that builds its own ``serial.Serial`` on a hard-coded path.
The "device" is a pseudo-terminal made here, answered by a thread; it is
gone when the cassette replays."""

import os
import pty
import select
import threading
import tty

import pytest

import wiretape

serial = pytest.importorskip("serial", reason="pyserial is not installed")

pytest_plugins = ["pytester"]


class FakeGadget:
    """A device on a pty, reached through the link `path`: answers
    ``PING\\n`` with ``PONG\\n`` and ``VER\\n`` with ``GADGET 1.0\\n``."""

    ANSWERS = {b"PING": b"PONG\n", b"VER": b"GADGET 1.0\n"}

    def __init__(self, path):
        self.path = path
        self.master, self._slave = pty.openpty()
        tty.setraw(self._slave)
        os.symlink(os.ttyname(self._slave), path)
        self.heard = b""
        self._wake_read, self._wake_write = os.pipe()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        pending = b""
        while True:
            readable, _, _ = select.select([self.master, self._wake_read], [], [])
            if self._wake_read in readable:
                return
            try:
                data = os.read(self.master, 256)
            except OSError:  # EIO: no one has the terminal open right now
                continue
            self.heard += data
            pending += data
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                os.write(self.master, self.ANSWERS.get(line, b"ERR\n"))

    def unplug(self):
        os.write(self._wake_write, b"x")
        self._thread.join(10)
        for fd in (self.master, self._slave, self._wake_read, self._wake_write):
            os.close(fd)
        os.unlink(self.path)


@pytest.fixture
def gadget(pytester):
    device = FakeGadget(str(pytester.path / "ttyGADGET"))
    yield device
    if os.path.lexists(device.path):
        device.unplug()


DRIVER = """
    from serial import Serial   # bound before any test runs: the class is patched

    PATH = {path!r}             # hard-coded, as drivers do

    class Gadget:
        def __init__(self):
            self.port = Serial(PATH, 115200, timeout=5)

        def ask(self, command):
            self.port.write(command + b"\\n")
            return self.port.read_until(b"\\n")

        def close(self):
            self.port.close()
"""

TESTS = """
    import serial
    from gadget import Gadget, PATH

    def test_gadget(wiretape_serial):
        gadget = Gadget()
        assert isinstance(gadget.port, serial.Serial)
        assert gadget.port.is_open
        assert gadget.ask(b"PING") == b"PONG\\n"
        gadget.port.baudrate = 9600              # recorded as a settings event
        gadget.port.timeout = 0                  # polls
        assert gadget.port.read(10) == b""
        gadget.port.timeout = 5
        gadget.port.dtr = True
        assert gadget.port.in_waiting == 0
        gadget.close()
        assert not gadget.port.is_open
        gadget.port.open()                       # a reopen continues the session
        assert gadget.ask(b"VER") == b"GADGET 1.0\\n"
        gadget.port.timeout = 0.2                # a silent device: the read times out
        assert gadget.port.read(1) == b""
        gadget.close()

    def test_serial_for_url(wiretape_serial):
        port = serial.serial_for_url(PATH, baudrate=115200, timeout=5)
        port.write(b"PI")
        port.write(b"NG\\n")                      # split differently from any recording
        assert port.readline() == b"PONG\\n"
        port.reset_input_buffer()
        port.close()

    class GadgetPort(serial.Serial):            # a driver's subclass
        def version(self):
            self.write(b"VER\\n")
            return self.readline()

    def test_subclass(wiretape_serial):
        with GadgetPort(PATH, 115200, timeout=5) as port:
            assert port.version() == b"GADGET 1.0\\n"
"""


def cassette_of(pytester, test):
    return pytester.path / "recordings" / "test_driver" / f"{test}.wtape"


def records(path):
    return [(r.kind, r.data) for r in wiretape.SessionReader(str(path))]


def make_driver_tests(pytester, path, tests=TESTS):
    pytester.makepyfile(gadget=DRIVER.format(path=path))
    pytester.makepyfile(test_driver=tests)
    pytester.syspathinsert()


def test_a_driver_building_its_own_serial_records_then_replays_without_the_device(
        pytester, gadget):
    make_driver_tests(pytester, gadget.path)
    result = pytester.runpytest("--wiretape-record=once")
    result.assert_outcomes(passed=3)
    assert gadget.heard == b"PING\nVER\nPING\nVER\n"

    cassette = cassette_of(pytester, "test_gadget")
    kinds = [kind for kind, _ in records(cassette)]
    assert b"".join(data for kind, data in records(cassette) if kind == "tx") == b"PING\nVER\n"
    assert b"".join(data for kind, data in records(cassette) if kind == "rx") == \
        b"PONG\nGADGET 1.0\n"
    assert "settings" in kinds
    header = str(wiretape.SessionReader(str(cassette)).header)
    assert f"device={gadget.path}" in header and "baud=115200" in header
    assert cassette_of(pytester, "test_serial_for_url").exists()
    assert [p.name for p in pytester.path.rglob("*.recording-*")] == []

    gadget.unplug()
    result = pytester.runpytest()  # record=none: from the cassettes alone
    result.assert_outcomes(passed=3)
    result = pytester.runpytest("--wiretape-record=once")  # they exist
    result.assert_outcomes(passed=3)


def test_a_driver_that_writes_something_else_fails_with_the_mismatch_report(pytester, gadget):
    make_driver_tests(pytester, gadget.path)
    pytester.runpytest("--wiretape-record=once", "-k", "test_gadget").assert_outcomes(passed=1)
    gadget.unplug()

    make_driver_tests(pytester, gadget.path, TESTS.replace('ask(b"VER")', 'ask(b"VEX")'))
    result = pytester.runpytest("-k", "test_gadget")
    result.assert_outcomes(failed=1)
    cassette = cassette_of(pytester, "test_gadget")
    result.stdout.fnmatch_lines(["*ReplayMismatch*", "*wiretape*", f"*cassette: {cassette}*",
                                 "*--wiretape-record=rewrite*"])


def test_a_missing_cassette_is_an_error_naming_it_and_the_command_that_records_it(
        pytester, gadget):
    make_driver_tests(pytester, gadget.path)
    result = pytester.runpytest("-k", "test_gadget")
    result.assert_outcomes(errors=1)
    cassette = cassette_of(pytester, "test_gadget")
    result.stdout.fnmatch_lines([f"*{cassette}*does not exist*",
                                 "*pytest --wiretape-record=once test_driver.py::test_gadget*"])
    assert "--wiretape-device" not in result.stdout.str()  # the driver names the device
    assert gadget.heard == b""  # the device was not touched


def test_the_patch_is_undone_after_the_test_passed_or_failed(pytester, gadget):
    original = dict(vars(serial.Serial))
    make_driver_tests(pytester, gadget.path, """
        import os, pty, tty
        import serial
        from gadget import Gadget

        ORIGINAL = dict(vars(serial.Serial))

        def test_1_fails_while_patched(wiretape_serial):
            assert dict(vars(serial.Serial)) != ORIGINAL
            Gadget()
            assert False, "the driver failed"

        def test_2_passes_while_patched(wiretape_serial):
            assert Gadget().ask(b"PING") == b"PONG\\n"

        def test_3_pyserial_is_itself_again():
            assert dict(vars(serial.Serial)) == ORIGINAL
            master, slave = pty.openpty()
            tty.setraw(slave)
            port = serial.Serial(os.ttyname(slave), 115200, timeout=5)
            assert port.fd is not None              # the native open ran
            port.write(b"native")
            assert os.read(master, 6) == b"native"
            port.close()
            os.close(master)
            os.close(slave)
    """)
    result = pytester.runpytest("--wiretape-record=once", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=2, failed=1)
    result.stdout.fnmatch_lines(["*the driver failed*"])
    assert not cassette_of(pytester, "test_1_fails_while_patched").exists()
    assert cassette_of(pytester, "test_2_passes_while_patched").exists()
    assert dict(vars(serial.Serial)) == original


def test_a_second_path_is_an_error_naming_the_serial_port_option(pytester, gadget, tmp_path):
    other = FakeGadget(str(tmp_path / "ttyOTHER"))
    try:
        make_driver_tests(pytester, gadget.path, f"""
            import serial
            from gadget import Gadget

            def test_two_ports(wiretape_serial):
                Gadget()
                try:
                    serial.Serial({other.path!r}, 9600, timeout=1)
                except Exception:  # a driver that swallows errors still fails
                    pass
        """)
        result = pytester.runpytest("--wiretape-record=once")
        result.assert_outcomes(failed=1)
        result.stdout.fnmatch_lines([
            f"*wiretape_serial: the test opened {other.path} after {gadget.path}*"
            f"@pytest.mark.wiretape(serial_port='{gadget.path}')*"])
        assert other.heard == b""
    finally:
        other.unplug()


def test_serial_port_serves_the_named_path_and_leaves_the_others_real(
        pytester, gadget, tmp_path):
    other = FakeGadget(str(tmp_path / "ttyOTHER"))
    try:
        make_driver_tests(pytester, gadget.path, f"""
            import pytest
            import serial
            from gadget import Gadget, PATH

            @pytest.mark.wiretape(serial_port=PATH)
            def test_two_ports(wiretape_serial):
                assert Gadget().ask(b"PING") == b"PONG\\n"
                real = serial.Serial({other.path!r}, 9600, timeout=5)
                assert real.fd is not None            # pyserial's own open
                real.write(b"VER\\n")
                assert real.readline() == b"GADGET 1.0\\n"
                real.close()
        """)
        pytester.runpytest("--wiretape-record=once").assert_outcomes(passed=1)
        assert records(cassette_of(pytester, "test_two_ports"))[1:3] == [
            ("tx", b"PING\n"), ("rx", b"PONG\n")]
        gadget.unplug()
        assert other.heard == b"VER\n"
        pytester.runpytest().assert_outcomes(passed=1)  # the named one replays
        assert other.heard == b"VER\nVER\n"             # the other is the device
    finally:
        other.unplug()


def test_recording_from_a_device_that_is_not_there_is_pyserials_error_naming_it(
        pytester, tmp_path):
    make_driver_tests(pytester, str(tmp_path / "ttyNONE"), """
        import pytest
        import serial
        from gadget import Gadget, PATH

        def test_absent(wiretape_serial):
            with pytest.raises(serial.SerialException, match=PATH):
                Gadget()
    """)
    result = pytester.runpytest("--wiretape-record=once")
    # (Counted by kind, not in all: an editable install adds pytest's own
    # warning about its import hook to the inner run's count.)
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*test_absent passed while recording but opened no port "
                                 "from wiretape_serial: nothing was written to*"])
    assert not cassette_of(pytester, "test_absent").exists()


def test_a_second_serial_on_the_served_path_while_the_first_is_open_is_an_error(
        pytester, gadget):
    make_driver_tests(pytester, gadget.path, """
        import serial
        from gadget import Gadget, PATH

        def test_twice(wiretape_serial):
            first = Gadget()
            serial.Serial(PATH, 115200, timeout=1)
    """)
    result = pytester.runpytest("--wiretape-record=once")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([f"*wiretape_serial: {gadget.path} is opened by a second "
                                 "serial.Serial while the first is still open*"])


def test_a_bad_serial_port_setting_is_an_error_naming_it(pytester, gadget):
    make_driver_tests(pytester, gadget.path, """
        import pytest

        @pytest.mark.wiretape(serial_port=5)
        def test_bad(wiretape_serial):
            pass
    """)
    result = pytester.runpytest("--wiretape-record=once")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*test_bad: wiretape marker: serial_port= takes a device "
                                 "path or a list of them, not 5*"])


class FakePort:
    """Stands for the cassette's port: what SerialPatch asks of it."""

    type = "replay"

    def __init__(self):
        self.calls = []

    def __setattr__(self, name, value):
        if name in ("dtr", "rts"):
            self.calls.append((name, value))
        object.__setattr__(self, name, value)

    def flush_input(self):
        self.calls.append(("flush_input",))


def test_lines_lowered_before_open_are_applied_at_open_and_a_reopen_flushes_input():
    from wiretape.testing.serial_patch import SerialPatch

    port = FakePort()
    opened = []

    def open_port(path, baud):
        opened.append((path, baud))
        return port

    def fail(message):
        raise AssertionError(message)

    patch = SerialPatch(open_port, fail)
    patch.install()
    try:
        board = serial.Serial()
        board.port = "/dev/ttyUSB7"
        board.baudrate = 57600
        board.dtr = False   # an Arduino that must not reset when the port opens
        board.open()
        assert opened == [("/dev/ttyUSB7", 57600)]
        assert port.calls == [("dtr", False)]
        board.close()
        board.open()
        assert opened == [("/dev/ttyUSB7", 57600)]   # one port for the test
        assert port.calls == [("dtr", False), ("flush_input",), ("dtr", False)]
        board.close()
    finally:
        patch.uninstall()


def test_recorded_data_the_driver_never_read_fails_it_under_unused_error(pytester, gadget):
    make_driver_tests(pytester, gadget.path)
    pytester.runpytest("--wiretape-record=once", "-k", "test_gadget").assert_outcomes(passed=1)
    gadget.unplug()
    make_driver_tests(pytester, gadget.path, """
        import pytest
        from gadget import Gadget

        @pytest.mark.wiretape(cassette="recordings/test_driver/test_gadget.wtape",
                              unused="error")
        def test_only_ping(wiretape_serial):
            assert Gadget().ask(b"PING") == b"PONG\\n"
    """)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)  # a failure of the test's call, not of its teardown
    result.stdout.fnmatch_lines(["*ReplayMismatch*were never read*(unused=error)*"])
