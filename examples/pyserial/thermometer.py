"""A driver for a (made-up) serial thermometer, written as drivers are: it
opens its device itself, on a path it knows. Its test needs no change to it:
the ``wiretape_serial`` fixture serves that ``serial.Serial`` from a
cassette."""

import serial

DEVICE = "/dev/ttyUSB0"


class Thermometer:
    def __init__(self, path: str = DEVICE):
        self._serial = serial.Serial(path, 115200, timeout=1)

    def _ask(self, command: bytes) -> str:
        self._serial.write(command + b"\n")
        answer = self._serial.read_until(b"\n")
        if not answer.endswith(b"\n"):
            raise TimeoutError(f"no answer to {command!r}")
        return answer.decode("ascii").strip()

    def identify(self) -> str:
        return self._ask(b"*IDN?")

    def temperature(self) -> float:
        return float(self._ask(b"TEMP?"))

    def close(self) -> None:
        self._serial.close()
