"""What the wiretape URL handlers share: URL parsing and a pyserial
``Serial`` over a wiretape Port (option strings are built by
``_core.option_string``)."""

import urllib.parse

from serial.serialutil import (
    PortNotOpenError,
    SerialBase,
    SerialException,
    SerialTimeoutException,
)

# _core, not the package: ``import wiretape`` imports this module.
from .. import _core
from ..options import has_line_settings

#: The wiretape errors a pyserial caller sees as SerialException.
#: ReplayMismatch passes through: it is the report a test must show.
CONVERTED_ERRORS = (_core.OptionError, _core.SessionError, _core.PortError)


def _parity_name(letter: str) -> str:
    """pyserial's parity letter (PARITY_EVEN is "E") as the key table's
    parity choice it stands for."""
    for key in _core.option_keys():
        if key.name == "parity":
            for choice in key.choices:
                if choice[0].upper() == letter:
                    return choice
    return str(letter)


def parse_url(url, scheme):
    """(path, [(key, value)...]) of ``scheme://PATH?k=v&...``; SerialException
    naming the problem otherwise."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != scheme:
        raise SerialException(f"expected a URL of the form {scheme}://PATH?KEY=VALUE&...; got {url!r}")
    path = urllib.parse.unquote(parts.netloc + parts.path)
    if not path:
        raise SerialException(f"{url!r}: no session file path after {scheme}://")
    pairs = []
    seen = set()
    for key, value in urllib.parse.parse_qsl(parts.query, keep_blank_values=True):
        if not key:
            raise SerialException(f"{url!r}: empty key in the query")
        if key in seen:
            raise SerialException(f"{url!r}: key {key!r} given twice")
        seen.add(key)
        pairs.append((key, value))
    return path, pairs


class PortSerial(SerialBase):
    """A pyserial ``Serial`` over a wiretape Port, with pyserial's semantics:
    ``read(n)`` waits for n bytes until ``timeout`` (None blocks, 0 polls),
    ``write`` writes everything or raises ``SerialTimeoutException``.
    A replay mismatch propagates as ``wiretape.ReplayMismatch`` (an
    AssertionError with the full report); a device that went away or a port
    error becomes a ``SerialException`` naming it."""

    scheme = ""

    def __init__(self, *args, **kwargs):
        self._wiretape_port = None
        self._applied_write_timeout = ...  # none yet: the first write sets it
        super().__init__(*args, **kwargs)

    # -- what subclasses provide -------------------------------------------
    def _open_wiretape_port(self, url):
        raise NotImplementedError

    # -- pyserial's interface ----------------------------------------------
    def open(self):
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        self._wiretape_port = self._convert_errors(self._open_wiretape_port, self._port)
        self._applied_write_timeout = ...
        self.is_open = True
        try:
            self._reconfigure_port()
            # The OS raises DTR and RTS at open: only a level lowered before
            # open() (an Arduino not to reset) is news, as in pyserial's open.
            if not self._dsrdtr and not self._dtr_state:
                self._update_dtr_state()
            if not self._rtscts and not self._rts_state:
                self._update_rts_state()
        except BaseException:
            self.close()
            raise

    def close(self):
        port, self._wiretape_port = self._wiretape_port, None
        self.is_open = False
        if port is not None:
            # unused=error raises ReplayMismatch here: let it reach the test.
            self._convert_errors(port.close)

    def _reconfigure_port(self):
        port = self._wiretape_port
        if port is None:
            return
        # Line settings mean nothing to a replay; a serial line (local or
        # over RFC 2217) follows them. Only what changed is applied (a
        # recording shows a settings event where the driver changed
        # something, not at every open).
        if not has_line_settings(port.type) or not self._baudrate:
            return
        wanted = {
            "baud": int(self._baudrate),
            "databits": int(self._bytesize),
            "parity": _parity_name(self._parity),
            "flow": "rtscts" if self._rtscts else ("xonxoff" if self._xonxoff else "none"),
        }
        if self._stopbits in (1, 2):
            wanted["stopbits"] = int(self._stopbits)
        try:
            current = port.serial_settings()
            changed = {key: value for key, value in wanted.items() if current.get(key) != value}
            if set(changed) == {"baud"}:
                port.set_baud(changed["baud"])
            elif changed:
                port.configure(**changed)
        except Exception as error:
            raise SerialException(f"cannot apply the line settings {wanted}: {error}") from error

    def _require_open(self):
        if not self.is_open or self._wiretape_port is None:
            raise PortNotOpenError()
        return self._wiretape_port

    def _convert_errors(self, call, *args, **kwargs):
        __tracebackhide__ = True  # wiretape's frames, not the test's
        try:
            return call(*args, **kwargs)
        except CONVERTED_ERRORS as error:
            raise SerialException(f"{self._port}: {error}") from error

    @property
    def in_waiting(self):
        port = self._require_open()
        return self._convert_errors(port.available)

    # The data path (read, read_until, readline, write) is the cost of every
    # exchange a driver makes: each is one call into the port's C++ (a whole
    # line in one call, where pyserial's own read_until and readline read a
    # byte at a time), errors converted only once one was raised.
    def read(self, size=1):
        __tracebackhide__ = True  # wiretape's frames, not the test's
        port = self._wiretape_port  # None whenever the port is not open
        if port is None:
            raise PortNotOpenError()
        if size <= 0:
            return b""
        try:
            return port.read_exactly(size, self._timeout)
        except Exception as error:
            self._raise_converted(error)
            raise

    def read_until(self, expected=b"\n", size=None):
        __tracebackhide__ = True  # wiretape's frames, not the test's
        port = self._wiretape_port  # None whenever the port is not open
        if port is None:
            raise PortNotOpenError()
        try:
            return port.read_until(expected, size, self._timeout)
        except Exception as error:
            self._raise_converted(error)
            raise

    def readline(self, size=-1):
        __tracebackhide__ = True  # wiretape's frames, not the test's
        return self.read_until(b"\n", None if size is None or size < 0 else size)

    def write(self, data):
        __tracebackhide__ = True  # wiretape's frames, not the test's
        port = self._wiretape_port  # None whenever the port is not open
        if port is None:
            raise PortNotOpenError()
        if not data:
            return 0
        if self._write_timeout is not self._applied_write_timeout:
            port.timeout = self._write_timeout
            self._applied_write_timeout = self._write_timeout
        try:
            written = port.write_all(data)
        except Exception as error:
            self._raise_converted(error)
            raise
        if written < len(data):
            raise SerialTimeoutException("Write timeout")
        return written

    def _raise_converted(self, error):
        """Raises wiretape's port, option and session errors as the
        SerialException naming the port; returns on anything else."""
        __tracebackhide__ = True  # wiretape's frames, not the test's
        if isinstance(error, CONVERTED_ERRORS):
            raise SerialException(f"{self._port}: {error}") from error

    def flush(self):
        __tracebackhide__ = True  # wiretape's frames, not the test's
        port = self._require_open()
        self._convert_errors(port.drain)

    def reset_input_buffer(self):
        port = self._require_open()
        self._convert_errors(port.flush_input)

    def reset_output_buffer(self):
        port = self._require_open()
        self._convert_errors(port.flush_output)

    def fileno(self):
        port = self._require_open()
        return port.fileno()

    def _line(self, name, default):
        port = self._require_open()
        try:
            return bool(getattr(port, name))
        except Exception:  # no modem lines on this kind of port
            return default

    def _set_line(self, name, value):
        port = self._wiretape_port
        if port is None:
            return
        try:
            setattr(port, name, bool(value))
        except Exception:  # no modem lines on this kind of port
            pass

    def _update_dtr_state(self):
        self._set_line("dtr", self._dtr_state)

    def _update_rts_state(self):
        self._set_line("rts", self._rts_state)

    def _update_break_state(self):
        pass

    def send_break(self, duration=0.25):
        port = self._require_open()
        try:
            port.send_break(duration)
        except Exception:
            pass

    @property
    def cts(self):
        return self._line("cts", False)

    @property
    def dsr(self):
        return self._line("dsr", False)

    @property
    def ri(self):
        return self._line("ri", False)

    @property
    def cd(self):
        return self._line("cd", False)
