"""A device with a text console, as the lab tools drive it: it answers an
empty line with its prompt and ``version`` with its firmware's version.
Its output follows the client's first line: pyserial's rfc2217 client (and
labgrid's) purges what came in before the port was open, as a real port's
open loses a banner printed before it."""

import wiretape

MS = 1_000_000
PROMPT = "ready> "
FIRMWARE = "2.4.1"


def console_session(path) -> str:
    """Writes the console's session to `path` (a session of a serial port,
    as `wiretape record` through a lab's exporter makes one)."""
    with wiretape.SessionWriter(str(path), capture="wire", port_type="serial",
                                port_options="type=serial") as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 5 * MS, b"\n")
        writer.write("rx", 6 * MS, b"\r\n" + PROMPT.encode())
        writer.write("tx", 9 * MS, b"version\n")
        writer.write("rx", 10 * MS, f"fw {FIRMWARE} build 77\r\n{PROMPT}".encode())
        writer.write("close", 20 * MS, b"{}")
    return str(path)
