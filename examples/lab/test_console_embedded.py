"""A pytest-embedded test of a device's console (its serial DUT), run
against a wiretape replay instead of the board: give pytest-embedded the
replay as its port, a ``wiretape://`` URL or the pty of `wiretape replay
--pty` (docs/testing.md, "With pytest-embedded"):

    pytest -p pytest_embedded --embedded-services serial \
        --port 'wiretape://recordings/console.wtape?timing=none' test_console_embedded.py
"""


def test_console_reports_its_firmware(dut):
    dut.write("")  # pytest-embedded ends each write with "\n"
    dut.expect_exact("ready> ", timeout=10)
    dut.write("version")
    version = dut.expect(r"fw (\d+\.\d+\.\d+) build", timeout=10)
    assert version.group(1) == b"2.4.1"
