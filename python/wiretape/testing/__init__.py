"""wiretape's pytest plugin (``wiretape.testing.plugin``, registered through
the ``pytest11`` entry point) and the cassette it gives each test
(``wiretape.testing.cassette``). See docs/testing.md."""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .cassette import WiretapeCassette, WiretapeWarning

__all__ = ["WiretapeCassette", "WiretapeWarning"]


def __getattr__(name: str) -> Any:
    # The cassette needs pytest; serial_patch, which wiretape.fuzzing uses in
    # drivers fuzzed without pytest, must import without it.
    if name in __all__:
        from . import cassette

        return getattr(cassette, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
