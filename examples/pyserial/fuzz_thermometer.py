#!/usr/bin/env python3
"""Fuzzes the thermometer driver (thermometer.py) from its recording with
atheris: each input is a plan (docs/fuzzing.md) over the answers recorded in
recordings/test_thermometer/test_identify_and_read.wtape, and the driver's
own ``serial.Serial`` opens the mutated replay. A bad answer must end in one
of the driver's errors (TimeoutError, ValueError) or the replay's
(wiretape.fuzzing.DRIVER_ERRORS); anything else is a finding, which atheris
reports with the plan that caused it (write it as a session with
``FuzzedRecording.write`` to replay it with ``wiretape replay``).

Usage: fuzz_thermometer.py [libFuzzer flags: -runs=N -seed=N -max_total_time=S]
"""

import os
import sys

import atheris

from wiretape.fuzzing import DRIVER_ERRORS, FuzzedRecording

with atheris.instrument_imports():
    from thermometer import Thermometer

RECORDING = os.path.join(os.path.dirname(os.path.abspath(__file__)), "recordings",
                         "test_thermometer", "test_identify_and_read.wtape")
recording = FuzzedRecording(RECORDING)


def test_one_input(plan: bytes) -> None:
    with recording.serial(plan):
        try:
            thermometer = Thermometer()
            thermometer.identify()
            thermometer.temperature()
            thermometer.close()
        except (TimeoutError, ValueError) + DRIVER_ERRORS:
            pass  # a driver may refuse a bad answer: that is its right answer


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
