"""Session files as a driver's tests use them, checked by ``mypy --strict``
(tests/python/bindings/test_typing.py): what the typing stubs promise."""

from __future__ import annotations

import tempfile
from pathlib import Path

from wiretape import SessionHeader, SessionReader, SessionWriter


def record_and_read(folder: Path) -> list[bytes]:
    path = folder / "typed.wtape"
    with SessionWriter(str(path), port_type="loopback") as writer:
        writer.write("tx", 1_000, b"PING\n")
        writer.write("rx", 2_000, b"PONG\n")
    with SessionReader(str(path)) as reader:
        header: SessionHeader = reader.header
        assert header.port_type == "loopback" and header.metadata == {}
        assert reader.damage is None
        return [record.data for record in reader if record.kind == "rx"]


def main() -> None:
    with tempfile.TemporaryDirectory() as folder:
        assert record_and_read(Path(folder)) == [b"PONG\n"]


if __name__ == "__main__":
    main()
