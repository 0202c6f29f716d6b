"""A device on a pseudo-terminal, for the servers a lab exports serial
lines with (``serve --protocol rfc2217``, ser2net): the server opens the
terminal as a serial port; the test plays the device on the master side
and reads the line settings the server applied to the terminal."""

import contextlib
import os
import select
import termios
import time
import tty

DEADLINE = 10.0


class PtyDevice:
    def __init__(self):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.options = f"type=serial,device={self.path},baud=9600,exclusive=false"

    def read(self, count):
        data = bytearray()
        deadline = time.monotonic() + DEADLINE
        while len(data) < count and time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], 0.1)
            if ready:
                data += os.read(self.master, count - len(data))
        return bytes(data)

    def write(self, data):
        os.write(self.master, data)

    def speed(self):
        return termios.tcgetattr(self.slave)[5]

    def stop_bits(self):
        return 2 if termios.tcgetattr(self.slave)[2] & termios.CSTOPB else 1

    def close(self):
        os.close(self.master)
        os.close(self.slave)


@contextlib.contextmanager
def served_over_rfc2217():
    """A PtyDevice behind wiretape's own ``serve --protocol rfc2217``:
    yields the device and the server's ``HOST:PORT``. Skips the test when
    a serial port cannot be opened on a pseudo-terminal here."""
    from wiretape import bridge

    from devices import skip_unless_serial_opens_on_a_pty

    skip_unless_serial_opens_on_a_pty()
    device = PtyDevice()
    try:
        handle = bridge.serve(device.options, "127.0.0.1:0", protocol="rfc2217", quiet=True)
        try:
            yield device, handle.address
        finally:
            handle.stop()
            assert handle.wait(DEADLINE), "serve --protocol rfc2217 did not stop"
    finally:
        device.close()
