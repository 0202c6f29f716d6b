"""A device with modem lines, played by a replay (a pty has none): CTS and
RI come up when the client says PING, before the device answers PONG."""

import wiretape
from wiretape import _core

MS = 1_000_000
BEFORE = {"cts": False, "dsr": True, "ri": False, "cd": False}
AFTER = {"cts": True, "dsr": True, "ri": True, "cd": True}


def line_device_session(path, answer_ms: int, close_ms: int) -> str:
    """Writes the device's session to `path`: the lines change 1 ms after
    the client's PING (at 5 ms), the answer comes at `answer_ms`."""
    with wiretape.SessionWriter(str(path), capture="wire", port_type="serial",
                                port_options="type=serial") as writer:
        writer.write("open", 0, b"{}")
        writer.write("modem_lines", 0, _core.event_payload("modem_lines", BEFORE))
        writer.write("tx", 5 * MS, b"PING\n")
        writer.write("modem_lines", 6 * MS, _core.event_payload("modem_lines", AFTER))
        writer.write("rx", answer_ms * MS, b"PONG\n")
        writer.write("close", close_ms * MS, b"{}")
    return str(path)
