"""wiretape's pytest plugin (``wiretape.testing.plugin``, registered through
the ``pytest11`` entry point) and the cassette it gives each test
(``wiretape.testing.cassette``). See docs/testing.md."""

from .cassette import WiretapeCassette, WiretapeWarning

__all__ = ["WiretapeCassette", "WiretapeWarning"]
