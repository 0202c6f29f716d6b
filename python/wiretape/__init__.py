"""wiretape: record and replay the wire-level session between a driver and its device.

The C++ core (``wiretape._core``) does the work; this package re-exports it:

* :func:`open_port` and :class:`Port` -- serial, TCP, UDP, pty, loopback and
  replay ports from one option string;
* the exceptions :class:`OptionError`, :class:`PortError`, :class:`PortClosed`,
  :class:`ReplayMismatch`, :class:`SessionError`;
* session files: :class:`SessionReader`, :class:`SessionWriter`, :class:`SessionHeader`,
  :class:`Channel` (one port of a session of several), :class:`Record`, and the
  flexiport export :func:`export_flexiport`;
* :class:`Recorder` -- several ports recorded into one session file;
* :func:`attach` -- a running program's session recorded through ptrace
  (an :class:`Attachment`, ended with its :class:`AttachSummary`).

The commands that read session files are in :mod:`wiretape.tools`, the
exports in :mod:`wiretape.exports`, the pytest plugin in
:mod:`wiretape.testing`.

``import wiretape`` also registers the pyserial URL handlers
``wiretape://`` (replay) and ``wiretape+record://`` (record).
"""

from ._core import (
    Attachment,
    AttachSummary,
    Channel,
    OptionError,
    Port,
    PortClosed,
    PortError,
    Record,
    Recorder,
    ReplayMismatch,
    SessionError,
    SessionHeader,
    SessionReader,
    SessionWriter,
    __version__,
    attach,
    export_flexiport,
    open_port,
)
from .urlhandler import register as _register_url_handlers

__all__ = [
    "__version__",
    "open_port",
    "Port",
    "OptionError",
    "PortError",
    "PortClosed",
    "ReplayMismatch",
    "SessionError",
    "SessionHeader",
    "Channel",
    "SessionReader",
    "SessionWriter",
    "Record",
    "Recorder",
    "attach",
    "Attachment",
    "AttachSummary",
    "export_flexiport",
]

_register_url_handlers()
