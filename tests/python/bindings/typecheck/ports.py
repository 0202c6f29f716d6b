"""A port as a driver uses it, with ``datetime.timedelta`` timeouts, checked
by ``mypy --strict`` (tests/python/bindings/test_typing.py)."""

from __future__ import annotations

from datetime import timedelta

import wiretape


def echo() -> bytes:
    port = wiretape.open_port("type=loopback")
    port.timeout = timedelta(seconds=1)
    port.write_all(b"hello")
    data: bytes = port.read(10, timeout=timedelta(milliseconds=50))
    port.close()
    return data


if __name__ == "__main__":
    assert echo() == b"hello"
