"""``wiretape_serial``: pyserial's own ``serial.Serial`` served by the test's
cassette (DESIGN §20, "In-process pyserial").

A driver that builds ``serial.Serial("/dev/ttyUSB0", 115200, timeout=1)``
itself cannot be handed a port. For one test, :class:`SerialPatch` patches
the methods of pyserial's native class (``serial.Serial``, which is
``serial.serialposix.Serial``), so every name a driver bound it to (``import
serial``, ``from serial import Serial``, ``serial.serialposix.Serial``, a
subclass, ``serial.serial_for_url`` of a path) opens the cassette instead of
the device: the replay port (type=replay), or, while recording, the real
device as a wiretape port recording to the cassette (``log=``). The data
path is the ``wiretape://`` URL handler's (urlhandler._common.PortSerial), so
pyserial's semantics are the same: timeouts None/0/float, ``read_until``,
``in_waiting``, buffer resets, modem lines and break through the Port API,
line settings applied to the device and recorded as settings events.

Patching the class, not the name, is what reaches a driver module that did
``from serial import Serial`` before the test began; the patch is undone
when the test ends, pass or fail (the class's own attributes are put back
exactly as they were).

One cassette holds one port. The first path the test opens is the one it
serves; opening another path is an error naming the marker's
``serial_port=`` (the path or paths the cassette serves; others then open
their real device), until sessions of several ports come (DESIGN §19).

The port the cassette serves lives as long as the test: a driver's
``close()`` and re-``open()`` continue the same session (the real device
stays open while recording), and a re-open drops what came in while closed,
as a real close does. Ports of other pyserial classes (``socket://``,
``rfc2217://``, ``loop://`` URLs) are not served.
"""

from __future__ import annotations

import os
from typing import Any, Callable, Dict, Iterable, List, Optional

from ..urlhandler._common import PortSerial

MARKER_KEY = "serial_port"

# PortSerial's pyserial interface: what a served instance runs instead of the
# native method (open, close and the rest of pyserial's are the patch's own).
_SERVED_METHODS = ("close", "_reconfigure_port", "read", "read_until", "readline", "write",
                   "flush", "reset_input_buffer", "reset_output_buffer", "fileno",
                   "_update_dtr_state", "_update_rts_state", "_update_break_state",
                   "send_break")
_SERVED_PROPERTIES = ("in_waiting", "cts", "dsr", "ri", "cd")
# PortSerial's helpers, which the native class does not have.
_HELPERS = ("_require_open", "_convert_errors", "_raise_converted", "_line", "_set_line")
_MISSING = object()  # an attribute the class did not have: deleted when the patch is undone


def _native_class():
    import serial

    return serial.serialposix.Serial if hasattr(serial, "serialposix") else serial.Serial


def served_paths(setting: Any) -> Optional[List[str]]:
    """The marker's ``serial_port=`` as a list of paths (None: every path)."""
    if setting is None:
        return None
    if isinstance(setting, (str, os.PathLike)):
        paths = [setting]
    elif isinstance(setting, (list, tuple, set, frozenset)):
        paths = list(setting)
    else:
        paths = []
    if not paths or not all(isinstance(p, (str, os.PathLike)) for p in paths):
        raise ValueError(f"{MARKER_KEY}= takes a device path or a list of them, "
                         f"not {setting!r}")
    return [os.fspath(p) for p in paths]


def _same_device(a: str) -> str:
    # A by-id link and the node it names are one device.
    return os.path.realpath(a)


class SerialPatch:
    """The patch of one test. `open_port(path, baud)` opens the cassette's
    port (replay, or the device recording); `fail(message)` fails the test."""

    def __init__(self, open_port: Callable[[str, Optional[int]], Any],
                 fail: Callable[[str], None], paths: Optional[Iterable[str]] = None):
        self._open_port = open_port
        self._fail = fail
        self._paths = None if paths is None else {_same_device(p) for p in paths}
        self._served_path: Optional[str] = None
        self._port = None
        self._holder = None  # the serial.Serial that has the port open
        self._saved: Dict[str, Any] = {}
        self._class = None

    # -- which opens are served ---------------------------------------------
    def serves(self, path: Any) -> bool:
        if not isinstance(path, (str, os.PathLike)):
            return False
        return self._paths is None or _same_device(os.fspath(path)) in self._paths

    def attach(self, serial_object) -> Any:
        """The port for `serial_object`'s open(): the cassette's, opened on
        the first open and kept for the test."""
        path = os.fspath(serial_object._port)
        if self._served_path is not None and (
                self._paths is None and _same_device(path) != _same_device(self._served_path)):
            self._fail(
                f"wiretape_serial: the test opened {path} after {self._served_path}, and a "
                f"cassette holds one serial port. Name the port the cassette serves with "
                f"@pytest.mark.wiretape({MARKER_KEY}={self._served_path!r}) (a list names "
                f"several paths of that one device); other paths then open their real "
                f"device. Sessions of several ports are not supported yet.")
        if self._holder is not None and self._holder is not serial_object:
            self._fail(
                f"wiretape_serial: {path} is opened by a second serial.Serial while the "
                f"first is still open; the cassette serves one at a time (close the first)")
        if self._port is None:
            self._port = self._open_port(path, serial_object._baudrate)
            self._served_path = path
        else:
            # A real close drops what arrived while closed; the same call is
            # made while recording and while replaying, so both agree.
            self._port.flush_input()
        self._holder = serial_object
        return self._port

    def detach(self, serial_object) -> None:
        if self._holder is serial_object:
            self._holder = None

    # -- the patch ------------------------------------------------------------
    def install(self) -> None:
        cls = _native_class()
        self._class = cls
        patch = self

        def served(instance) -> bool:
            return instance.__dict__.get("_wiretape_patch") is patch

        def dispatch(name):
            native = getattr(cls, name)
            replacement = getattr(PortSerial, name)

            def method(self, *args, **kwargs):
                __tracebackhide__ = True  # wiretape's frames, not the test's
                if served(self):
                    return replacement(self, *args, **kwargs)
                return native(self, *args, **kwargs)

            method.__name__ = name
            method.__doc__ = getattr(native, "__doc__", None)
            return method

        def dispatch_property(name):
            native = getattr(cls, name)
            replacement = getattr(PortSerial, name)

            def getter(self):
                __tracebackhide__ = True  # wiretape's frames, not the test's
                if served(self):
                    return replacement.fget(self)
                return native.fget(self)

            return property(getter, doc=native.__doc__)

        native_open = cls.open
        native_close = cls.close

        def open(self):
            __tracebackhide__ = True  # wiretape's frames, not the test's
            if not patch.serves(self._port):
                self.__dict__.pop("_wiretape_patch", None)  # a served port moved to another path
                return native_open(self)
            self.__dict__["_wiretape_patch"] = patch
            try:
                PortSerial.open(self)  # the URL handler's open, over _open_wiretape_port
            except BaseException:
                self.__dict__.pop("_wiretape_patch", None)
                raise

        def open_wiretape_port(self, path):
            __tracebackhide__ = True  # wiretape's frames, not the test's
            return patch.attach(self)

        def close(self):
            if not served(self):
                return native_close(self)
            # The cassette's port stays open for the test (a reopen continues
            # the session); the plugin closes it when the test ends.
            self._wiretape_port = None
            self.is_open = False
            patch.detach(self)

        def out_waiting(self):
            return 0 if served(self) else native_out_waiting.fget(self)

        def nonblocking(self):
            if not served(self):
                return native_nonblocking(self)

        def cancel(native):
            def method(self):
                if not served(self):
                    return native(self)
            return method

        native_out_waiting = cls.out_waiting
        native_nonblocking = cls.nonblocking
        replacements: Dict[str, Any] = {"open": open, "close": close,
                                        "_open_wiretape_port": open_wiretape_port,
                                        "out_waiting": property(out_waiting),
                                        "nonblocking": nonblocking,
                                        "cancel_read": cancel(cls.cancel_read),
                                        "cancel_write": cancel(cls.cancel_write)}
        for name in _SERVED_METHODS:
            replacements.setdefault(name, dispatch(name))
        for name in _SERVED_PROPERTIES:
            replacements[name] = dispatch_property(name)
        for name in _HELPERS:
            assert not hasattr(cls, name), f"pyserial's Serial has its own {name}"
            replacements[name] = PortSerial.__dict__[name]
        for name, value in replacements.items():
            self._saved[name] = cls.__dict__.get(name, _MISSING)
            setattr(cls, name, value)

    def uninstall(self) -> None:
        """Puts the class's attributes back as they were."""
        cls, self._class = self._class, None
        if cls is None:
            return
        for name, value in self._saved.items():
            if value is _MISSING:
                delattr(cls, name)
            else:
                setattr(cls, name, value)
        self._saved.clear()
        if self._holder is not None:  # a driver's port left open: closed for good
            self._holder.__dict__.pop("_wiretape_patch", None)
            self._holder.is_open = False
            self._holder._wiretape_port = None
            self._holder = None


def fail_test(message: str) -> None:
    """A setup mistake fails the test, even inside a driver that catches
    SerialException (pytest's outcome is not an Exception)."""
    import pytest  # here: wiretape.fuzzing patches serial.Serial without pytest

    pytest.fail(message, pytrace=False)
