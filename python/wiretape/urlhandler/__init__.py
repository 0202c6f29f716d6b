"""pyserial URL handlers: ``wiretape://`` (replay) and ``wiretape+record://``.

``serial.serial_for_url(url)`` takes the URL's scheme, and imports
``<package>.protocol_<scheme>`` from each package listed in
``serial.protocol_handler_packages``. :func:`register` adds this package to
that list (``import wiretape`` and the pytest plugin call it). A module name
cannot be spelled with ``+`` in Python source, so the record handler lives in
``protocol_wiretape_record`` and is also entered in ``sys.modules`` as
``protocol_wiretape+record``, the name pyserial imports for
``wiretape+record://``.

URLs:

``wiretape://PATH?KEY=VALUE&...``
    replays the session file PATH (``wiretape:///abs/file.wtape`` or
    ``wiretape://relative/file.wtape``); the query holds the replay keys of
    ``type=replay`` (docs/options.md; ``wiretape.options.replay_keys()``), e.g.
    ``wiretape://run.wtape?timing=none&match=request``.

``wiretape+record://PATH?device=DEVICE&baud=115200``
    opens DEVICE (a path such as ``/dev/ttyUSB0``, which means
    ``type=serial,device=PATH``, or a wiretape option string,
    percent-encoded) and records the session to PATH with the library's
    recorder (``log=PATH``). ``baud`` (or ``baudrate``) sets the rate;
    settings given to ``serial_for_url`` (``bytesize``, ``parity``...) reach
    the device. ``meta_KEY=VALUE`` adds free metadata; ``flush_ms`` and
    ``fsync`` tune the recorder.

``wiretape+record://PATH?options=OPTS``
    opens the wiretape port OPTS (an option string such as
    ``type=tcp,host=10.0.0.5,port=10940``) and records it to PATH.
"""

import sys

PACKAGE = __name__


def _install_module_aliases():
    from . import protocol_wiretape_record

    sys.modules.setdefault(PACKAGE + ".protocol_wiretape+record", protocol_wiretape_record)


def register():
    """Makes ``serial.serial_for_url`` serve the wiretape URL schemes.
    Idempotent; does nothing when pyserial is not installed."""
    try:
        import serial
    except ImportError:
        return False
    _install_module_aliases()
    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)
    return True


try:  # pyserial imports this package before the handler module: alias first.
    _install_module_aliases()
except ImportError:  # pyserial missing: the handlers cannot be used anyway
    pass
