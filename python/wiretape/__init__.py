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
``wiretape://`` (replay) and ``wiretape+record://`` (record): at once when
pyserial is imported already, else as pyserial is imported.

The members are loaded as they are first used (PEP 562), so that a program
using one part (the ``wiretape`` command's start-up above all) does not pay
for the others.
"""

import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
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


def __getattr__(name: str):
    if name in __all__:
        from . import _core

        value = getattr(_core, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))


class _RegisterWhenSerialIsImported:
    """A meta path finder that registers the URL handlers once pyserial's
    ``serial`` has been imported, so that ``import wiretape`` does not import
    pyserial (and the handlers' modules) for programs that never use it."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "serial":
            return None
        import importlib.machinery

        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is not None and hasattr(spec.loader, "exec_module"):
            spec.loader = _ThenRegister(spec.loader, self)
        return spec


class _ThenRegister:
    """pyserial's own loader, followed by the registration."""

    def __init__(self, loader, finder):
        self._loader = loader
        self._finder = finder

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        self._loader.exec_module(module)
        _stop_watching(self._finder)
        _register_url_handlers()

    def __getattr__(self, name):
        return getattr(self._loader, name)


def _stop_watching(finder) -> None:
    try:
        sys.meta_path.remove(finder)
    except ValueError:
        pass


def _register_url_handlers() -> None:
    from .urlhandler import register

    register()


if "serial" in sys.modules:
    _register_url_handlers()
else:
    sys.meta_path.insert(0, _RegisterWhenSerialIsImported())
