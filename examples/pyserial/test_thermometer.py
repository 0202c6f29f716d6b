"""Replays recordings/test_thermometer/*.wtape: no thermometer needed.

Record again from the device with
    pytest --wiretape-record=rewrite test_thermometer.py
(or from the simulator: python fake_thermometer.py /tmp/ttyTHERMO, then add
--wiretape-device=/tmp/ttyTHERMO)."""

from thermometer import Thermometer


def test_identify_and_read(wiretape_serial):
    thermometer = Thermometer()
    assert thermometer.identify().startswith("ACME THERMO")
    assert 15.0 < thermometer.temperature() < 30.0
    thermometer.close()
