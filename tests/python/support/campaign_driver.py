"""The driver and session the campaign tests of the CLI share
(test_faults_ci.py, test_faults_shard.py): N line exchanges, Qn\\n answered
by Rn\\n, and a driver that aborts (a crash) on an answer it did not expect,
saying so first, and waits for ever (a hang) for one that does not come."""

from __future__ import annotations

import textwrap
from pathlib import Path

import wiretape

DRIVER = textwrap.dedent("""
    import os, sys, tty
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    for n in range(EXCHANGES):
        os.write(fd, f"Q{n}\\n".encode())
        line = b""
        while not line.endswith(b"\\n"):
            chunk = os.read(fd, 1)
            if not chunk:
                sys.exit(3)
            line += chunk
        if line != f"R{n}\\n".encode():
            print("driver: unexpected answer <&>", line, flush=True)
            os.abort()
""")


def write_campaign_files(folder: Path, exchanges: int) -> tuple[Path, Path]:
    """The session of `exchanges` exchanges, and the driver script (its one
    argument: the device path)."""
    session = folder / "lines.wtape"
    with wiretape.SessionWriter(str(session), port_type="serial") as writer:
        for n in range(exchanges):
            writer.write("tx", n * 10_000_000, f"Q{n}\n".encode())
            writer.write("rx", n * 10_000_000 + 1_000_000, f"R{n}\n".encode())
    driver = folder / "driver.py"
    driver.write_text(DRIVER.replace("EXCHANGES", str(exchanges)))
    return session, driver
