"""The session tools' typed results and a port with float timeouts, checked
by ``mypy --strict`` (tests/python/bindings/test_typing.py)."""

from __future__ import annotations

import sys

import wiretape
from wiretape.tools.stats import SessionStats, stats
from wiretape.tools.verify import VerifyResult, verify


def describe(path: str) -> str:
    figures: SessionStats = stats(path)
    check: VerifyResult = verify(path)
    duration: float = figures.duration_s
    records: int = figures.rx_records + figures.tx_records
    return f"{records} records in {duration:.3f} s, ok={check.ok}"


def echo() -> bytes:
    port = wiretape.open_port("type=loopback")
    port.timeout = 1.0
    port.write_all(b"hello")
    data: bytes = port.read(10, timeout=0.05)
    port.close()
    return data


if __name__ == "__main__":
    assert echo() == b"hello"
    print(describe(sys.argv[1]))
