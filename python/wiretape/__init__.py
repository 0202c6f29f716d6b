"""wiretape: record and replay the wire-level session between a driver and its device."""

from ._core import __version__

__all__ = ["__version__"]
