"""A simulated thermometer on a pseudo-terminal, to record the example's
cassette without the hardware:

    python fake_thermometer.py /tmp/ttyTHERMO      # until Ctrl-C (or kill)

makes /tmp/ttyTHERMO a link to a pty that answers ``*IDN?`` and ``TEMP?``."""

import os
import pty
import signal
import sys
import tty

ANSWERS = {b"*IDN?": b"ACME THERMO 2.1\n", b"TEMP?": b"21.5\n"}


def main(link: str) -> None:
    # Ctrl-C and kill end it, also when started in the background of a
    # script (which would ignore SIGINT), and remove the link.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    master, slave = pty.openpty()
    tty.setraw(slave)
    os.symlink(os.ttyname(slave), link)
    print(f"thermometer on {link}", flush=True)
    pending = b""
    try:
        while True:
            pending += os.read(master, 256)  # the slave stays open here: no EIO
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                os.write(master, ANSWERS.get(line, b"ERR\n"))
    except KeyboardInterrupt:
        pass
    finally:
        os.unlink(link)


if __name__ == "__main__":
    main(sys.argv[1])
