"""``wiretape+record://PATH?device=DEVICE&baud=N`` and
``wiretape+record://PATH?options=OPTS``: a pyserial port that records the
session with a device to PATH.

With ``device=``, DEVICE is opened with pyserial (a path or any pyserial URL)
and the recording is made here: ``rx`` when a read returns bytes, ``tx`` when
a write is called, and events for open, close, settings changes, buffer
flushes, modem lines and breaks (capture=client, as the library's ``log=``).
With ``options=``, the wiretape port OPTS is opened with ``log=PATH``: the
library records.
"""

import json
import threading
import time

import serial
from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from ._common import PortSerial, option_string, parse_url

SCHEME = "wiretape+record"

_RECORDER_KEYS = ("flush_ms", "fsync")
_SETTINGS = ("baudrate", "bytesize", "parity", "stopbits", "xonxoff", "rtscts", "dsrdtr")
_PARITY_NAMES = {"N": "none", "E": "even", "O": "odd", "M": "mark", "S": "space"}


def _boolean(url, key, text):
    lowered = text.strip().lower()
    if lowered in ("1", "true", "yes", "on", ""):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise SerialException(f"{url!r}: {key}={text!r} is not a boolean (true/false)")


def _integer(url, key, text):
    try:
        return int(text)
    except ValueError:
        raise SerialException(f"{url!r}: {key}={text!r} is not an integer") from None


class _Request:
    """What a wiretape+record:// URL asks for."""

    def __init__(self, url):
        self.path, pairs = parse_url(url, SCHEME)
        self.device = None
        self.options = None
        self.baud = None
        self.metadata = {}
        self.flush_ms = 100
        self.fsync = False
        for key, value in pairs:
            if key == "device":
                self.device = value
            elif key == "options":
                self.options = value
            elif key in ("baud", "baudrate"):
                self.baud = _integer(url, key, value)
            elif key.startswith("meta_") and len(key) > 5:
                self.metadata[key[5:]] = value
            elif key == "flush_ms":
                self.flush_ms = _integer(url, key, value)
            elif key == "fsync":
                self.fsync = _boolean(url, key, value)
            else:
                raise SerialException(
                    f"{url!r}: unknown key {key!r}; valid keys: device, options, baud, "
                    "meta_KEY, flush_ms, fsync")
        if (self.device is None) == (self.options is None):
            raise SerialException(
                f"{url!r}: give exactly one of device= (a pyserial device or URL) "
                "or options= (a wiretape option string)")
        if self.device == "":
            raise SerialException(f"{url!r}: device= is empty")


def _settings_event(port):
    return {
        "baud": port.baudrate,
        "databits": port.bytesize,
        "parity": _PARITY_NAMES.get(port.parity, str(port.parity)),
        "stopbits": port.stopbits,
        "flow": "rtscts" if port.rtscts else ("xonxoff" if port.xonxoff else "none"),
    }


class _LibraryRecordingSerial(PortSerial):
    """``options=``: a wiretape port recorded by the library (``log=PATH``)."""

    def __init__(self, request, *args, **kwargs):
        self._request = request
        super().__init__(*args, **kwargs)

    def _open_wiretape_port(self, url):
        import wiretape

        request = self._request
        extra = [("log", request.path), ("flush_ms", request.flush_ms),
                 ("fsync", "true" if request.fsync else "false")]
        extra += [("meta_" + key, value) for key, value in request.metadata.items()]
        options = request.options
        if "=" not in options and "," not in options:
            options = option_string([("type", "serial"), ("device", options)])
        if request.baud is not None:
            extra.append(("baud", request.baud))
        return wiretape.open_port(options + "," + option_string(extra))


class _PyserialRecordingSerial(SerialBase):
    """``device=``: a pyserial device, recorded here."""

    def __init__(self, request, *args, **kwargs):
        self._request = request
        self._device = None
        self._writer = None
        self._writer_lock = threading.Lock()
        self._opened_ns = 0
        super().__init__(*args, **kwargs)

    # -- recording ----------------------------------------------------------
    def _record(self, kind, data=b""):
        writer = self._writer
        if writer is None:
            return
        if isinstance(data, dict):
            data = json.dumps(data, sort_keys=True).encode("utf-8")
        t_ns = time.monotonic_ns() - self._opened_ns
        with self._writer_lock:
            writer.write(kind, t_ns, bytes(data))

    def _device_or_raise(self):
        if not self.is_open or self._device is None:
            raise PortNotOpenError()
        return self._device

    # -- pyserial's interface -------------------------------------------------
    def open(self):
        import wiretape

        if self.is_open:
            raise SerialException("Port is already open.")
        request = self._request
        if request.baud is not None:
            self._baudrate = request.baud
        settings = {name: getattr(self, name) for name in _SETTINGS}
        device = serial.serial_for_url(request.device, do_not_open=True, **settings)
        device.timeout = self._timeout
        device.write_timeout = self._write_timeout
        device.open()
        try:
            metadata = dict(request.metadata)
            metadata.setdefault("pyserial_device", request.device)
            self._writer = wiretape.SessionWriter(
                request.path, capture="client", port_options=self._port,
                port_type="serial", metadata=metadata, flush_ms=request.flush_ms,
                fsync=request.fsync)
        except BaseException:
            device.close()
            raise
        self._device = device
        self._opened_ns = time.monotonic_ns()
        self.is_open = True
        self._record("open", _settings_event(self))

    def close(self):
        device, self._device = self._device, None
        was_open = self.is_open
        self.is_open = False
        try:
            if device is not None:
                device.close()
        finally:
            if was_open:
                self._record("close")
            writer, self._writer = self._writer, None
            if writer is not None:
                writer.close()

    def _reconfigure_port(self):
        device = self._device
        if device is None:
            return
        device.timeout = self._timeout
        device.write_timeout = self._write_timeout
        device.inter_byte_timeout = self._inter_byte_timeout
        changed = False
        for name in _SETTINGS:
            value = getattr(self, name)
            if getattr(device, name) != value:
                setattr(device, name, value)
                changed = True
        if changed:
            self._record("settings", _settings_event(self))

    @property
    def in_waiting(self):
        return self._device_or_raise().in_waiting

    def read(self, size=1):
        data = self._device_or_raise().read(size)
        if data:
            self._record("rx", data)
        return data

    def read_until(self, expected=b"\n", size=None):
        # One record for the whole call, as the client sees it (pyserial's
        # own read_until would read, and so record, one byte at a time).
        data = self._device_or_raise().read_until(expected, size)
        if data:
            self._record("rx", data)
        return data

    def write(self, data):
        device = self._device_or_raise()
        data = bytes(data)
        entered_ns = time.monotonic_ns() - self._opened_ns
        written = device.write(data)
        count = len(data) if written is None else written
        if count:
            writer = self._writer
            if writer is not None:
                with self._writer_lock:
                    writer.write("tx", entered_ns, data[:count])
        return written

    def flush(self):
        self._device_or_raise().flush()
        self._record("drain")

    def reset_input_buffer(self):
        self._device_or_raise().reset_input_buffer()
        self._record("flush_input")

    def reset_output_buffer(self):
        self._device_or_raise().reset_output_buffer()
        self._record("flush_output")

    def fileno(self):
        return self._device_or_raise().fileno()

    def _update_dtr_state(self):
        if self._device is not None:
            self._device.dtr = self._dtr_state
            self._record("modem_lines", {"dtr": bool(self._dtr_state)})

    def _update_rts_state(self):
        if self._device is not None:
            self._device.rts = self._rts_state
            self._record("modem_lines", {"rts": bool(self._rts_state)})

    def _update_break_state(self):
        if self._device is not None:
            self._device.break_condition = self._break_state

    def send_break(self, duration=0.25):
        self._device_or_raise().send_break(duration)
        self._record("break", {"duration_ms": int(duration * 1000)})

    @property
    def cts(self):
        return self._device_or_raise().cts

    @property
    def dsr(self):
        return self._device_or_raise().dsr

    @property
    def ri(self):
        return self._device_or_raise().ri

    @property
    def cd(self):
        return self._device_or_raise().cd


def serial_class_for_url(url):
    """pyserial's hook: the class that serves `url` (the URL is kept)."""
    request = _Request(url)
    if request.options is not None:
        base = _LibraryRecordingSerial
    else:
        base = _PyserialRecordingSerial

    class RecordingSerial(base):
        def __init__(self, *args, **kwargs):
            super().__init__(request, *args, **kwargs)

    RecordingSerial.__name__ = "Serial"
    RecordingSerial.__qualname__ = "wiretape+record.Serial"
    return url, RecordingSerial
