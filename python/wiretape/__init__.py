"""wiretape: record and replay the wire-level session between a driver and its device.

The C++ core (``wiretape._core``) does the work; this package re-exports it:

* :func:`open_port` and :class:`Port` -- serial, TCP, UDP, pty, loopback and
  replay ports from one option string;
* the exceptions :class:`OptionError`, :class:`PortError`, :class:`PortClosed`,
  :class:`ReplayMismatch`, :class:`SessionError`;
* session files: :class:`SessionReader`, :class:`SessionWriter`,
  :class:`Record`, and the flexiport export, where this build has them.

``import wiretape`` also registers the pyserial URL handlers
``wiretape://`` (replay) and ``wiretape+record://`` (record).
"""

from . import _core
from ._core import (
    OptionError,
    Port,
    PortClosed,
    PortError,
    ReplayMismatch,
    SessionError,
    __version__,
    open_port,
)

__all__ = [
    "__version__",
    "open_port",
    "Port",
    "OptionError",
    "PortError",
    "PortClosed",
    "ReplayMismatch",
    "SessionError",
]

# Session files and bridges are bound by other parts of the extension; a
# build without them still offers the ports.
for _name in (
    "SessionReader",
    "SessionWriter",
    "SessionHeader",
    "Record",
    "RecordKind",
    "export_flexiport",
    "import_flexiport",
):
    if hasattr(_core, _name):
        globals()[_name] = getattr(_core, _name)
        __all__.append(_name)
del _name

from .urlhandler import register as _register_url_handlers  # noqa: E402

_register_url_handlers()
