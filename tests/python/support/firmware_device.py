"""A device whose answers drift (issue 41): a line device on TCP (run by
devices.TcpDevice) whose identity answer carries a firmware string, and
every answer a time stamp that a profile masks.

``ID?`` is answered ``ID ACME FW<firmware> T=NNNNN``, ``READ`` with
``VAL 17 T=NNNNN``, anything else ``ERR``; the time stamp ticks once an
answer from `clock`, so two runs started at other clocks differ only
there."""

# The answers are lines ending in "T=NNNNN\n": the time stamp's five digits
# are the 6th to 2nd bytes from the frame's end.
MASKED_TIME = "framing=delimiter:0a,ignore=-6:5"


class FirmwareDevice:
    """The `respond` of a devices.TcpDevice: answers whole lines, however
    they arrive in chunks."""

    def __init__(self, firmware: str, clock: int):
        self.firmware = firmware
        self.clock = clock
        self._pending = b""

    def __call__(self, data: bytes) -> bytes:
        self._pending += data
        answers = b""
        while b"\n" in self._pending:
            line, self._pending = self._pending.split(b"\n", 1)
            self.clock += 1
            if line == b"ID?":
                answers += f"ID ACME FW{self.firmware} T={self.clock:05d}\n".encode()
            elif line == b"READ":
                answers += f"VAL 17 T={self.clock:05d}\n".encode()
            else:
                answers += b"ERR\n"
        return answers
