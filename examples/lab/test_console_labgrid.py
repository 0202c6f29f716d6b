"""A labgrid test of a device's console through its SerialDriver, run
against `wiretape replay --listen HOST:PORT --protocol rfc2217` in place
of the lab's exporter (labgrid_env.yaml; docs/testing.md, "With labgrid"):

    pytest -p labgrid --lg-env labgrid_env.yaml test_console_labgrid.py
"""


def test_console_reports_its_firmware(target):
    console = target.get_driver("SerialDriver")
    target.activate(console)
    console.sendline("")
    console.expect("ready> ")
    console.sendline("version")
    _, _, version, _ = console.expect(r"fw (\d+\.\d+\.\d+) build")
    assert version.group(1) == b"2.4.1"
