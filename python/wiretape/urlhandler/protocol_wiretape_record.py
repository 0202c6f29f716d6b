"""``wiretape+record://PATH?device=DEVICE&baud=N`` and
``wiretape+record://PATH?options=OPTS``: a pyserial port that records the
session with a device to PATH.

The device is a wiretape port recorded by the library's recorder
(``log=PATH``, capture=client), so the file holds exactly what a C++ driver's
``log=`` recording holds: ``rx`` when a read returns bytes (a ``read_until``
is one record), ``tx`` when a write is called, and the same events (open,
close, settings, buffer flushes, modem lines, breaks, device loss).

``device=`` takes a device path (``/dev/ttyUSB0``, which means
``type=serial,device=PATH``), ``rfc2217://HOST:PORT`` (a serial line
exported over RFC 2217) or a wiretape option string; ``options=`` takes an
option string (a bare path works there too). pyserial's other URLs
(``loop://``, ``socket://``...) are not devices wiretape opens: use the
matching option string (``type=loopback``, ``type=tcp,host=H,port=P``).
Serial lines, local or over RFC 2217, follow the driver's settings.
"""

from serial.serialutil import SerialException

from .. import _core
from ..options import join_options
from ._common import PortSerial, parse_url

SCHEME = "wiretape+record"


def _integer(url, key, text):
    try:
        return int(text)
    except ValueError:
        raise SerialException(f"{url!r}: {key}={text!r} is not an integer") from None


class _Request:
    """What a wiretape+record:// URL asks for."""

    def __init__(self, url):
        self.path, pairs = parse_url(url, SCHEME)
        device = None
        options = None
        self.baud = None
        # Keys passed to the recorder as they are (it checks their values).
        self.recorder = []
        for key, value in pairs:
            if key == "device":
                device = value
            elif key == "options":
                options = value
            elif key in ("baud", "baudrate"):
                self.baud = _integer(url, key, value)
            elif (key.startswith("meta_") and len(key) > 5) or key in ("flush_ms", "fsync"):
                self.recorder.append((key, value))
            else:
                raise SerialException(
                    f"{url!r}: unknown key {key!r}; valid keys: device, options, baud, "
                    "meta_KEY, flush_ms, fsync")
        if (device is None) == (options is None):
            raise SerialException(
                f"{url!r}: give exactly one of device= (a device path or a wiretape "
                "option string) or options= (a wiretape option string)")
        setting = device if device is not None else options
        try:
            self.options = _core.device_options(setting)
        except _core.OptionError as error:
            raise SerialException(f"{url!r}: {error}") from error
        # rfc2217://HOST:PORT is a wiretape device too; another URL read as
        # a device path is pyserial's own.
        if device is not None and "://" in device and \
                dict(_core.parse_options(self.options)).get("device") == device:
            raise SerialException(
                f"{url!r}: device={device!r} is a pyserial URL; wiretape records its own "
                "ports: give a device path, rfc2217://HOST:PORT or an option string "
                "(type=loopback, type=tcp,host=H,port=P)")

    def port_options(self, baud):
        """The option string of the recorded port."""
        extra = [("log", self.path)] + self.recorder
        if baud is not None:
            extra.append(("baud", baud))
        return join_options(self.options, _core.option_string(extra))


class _RecordingSerial(PortSerial):
    """A wiretape port with ``log=PATH``: the library records."""

    def __init__(self, request, *args, **kwargs):
        self._request = request
        super().__init__(*args, **kwargs)
        if request.baud is not None:
            self._baudrate = request.baud  # the port opens at that rate

    def _open_wiretape_port(self, url):
        import pathlib

        # As a cassette does: recordings/x.wtape in a fresh project records.
        pathlib.Path(self._request.path).parent.mkdir(parents=True, exist_ok=True)
        return _core.open_port(self._request.port_options(self._request.baud))


def serial_class_for_url(url):
    """pyserial's hook: the class that serves `url` (the URL is kept)."""
    request = _Request(url)

    class Serial(_RecordingSerial):
        def __init__(self, *args, **kwargs):
            super().__init__(request, *args, **kwargs)

    Serial.__qualname__ = "wiretape+record.Serial"
    return url, Serial
