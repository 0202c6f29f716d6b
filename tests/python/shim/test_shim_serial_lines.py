"""The --as shim's serial lines (src/shim/serial_lines.c, DESIGN §20), unit
by unit: a Python program runs under the shim with a hard-coded path
redirected to a pty this test owns, and the test plays the bridge's end of
the side channel (src/shim/line_protocol.h), so each emulated ioctl's
message (and the client's byte count in it) is seen exactly. A descriptor
the shim did not redirect keeps the real ioctl's result and errno."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from wiretape import redirect

from shim_channel import TIOCM_CD, TIOCM_CTS, TIOCM_DSR, TIOCM_DTR, TIOCM_RI, TIOCM_RTS, \
    FakeBridge

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the preload shim is Linux only")

HARD_CODED = "/dev/ttyWIRETAPE_SHIM_TEST0"
DEADLINE_S = 60.0

# Each step prints one JSON line: what the call returned, or its errno.
PROGRAM = textwrap.dedent(r"""
    import array, fcntl, json, os, struct, sys, termios

    TIOCMGET, TIOCMBIS, TIOCMBIC, TIOCMSET = 0x5415, 0x5416, 0x5417, 0x5418
    TIOCMIWAIT, TIOCGICOUNT = 0x545C, 0x545D
    TCSBRK, TCSBRKP, TIOCSBRK, TIOCCBRK = 0x5409, 0x5425, 0x5427, 0x5428
    TCGETS2, TCSETS2 = 0x802C542A, 0x402C542B
    TIOCGSERIAL, TIOCSSERIAL, TIOCGRS485, TIOCSRS485 = 0x541E, 0x541F, 0x542E, 0x542F
    TIOCEXCL, TIOCNXCL = 0x540C, 0x540D
    BOTHER, CBAUD = 0o010000, 0o010017

    def step(name, call):
        try:
            result = call()
        except OSError as error:
            result = {"errno": error.errno}
        if isinstance(result, bytes):
            result = "ok"
        print(json.dumps([name, result]), flush=True)

    def get(fd, request):
        buffer = array.array("i", [0])
        fcntl.ioctl(fd, request, buffer, True)
        return buffer[0]

    def put(fd, request, value):
        return fcntl.ioctl(fd, request, struct.pack("i", value))

    def custom_baud(fd, baud):
        settings = bytearray(fcntl.ioctl(fd, TCGETS2, bytes(44)))
        cflag = struct.unpack_from("I", settings, 8)[0]
        cflag = (cflag & ~CBAUD & ~(CBAUD << 16)) | BOTHER | (BOTHER << 16)
        struct.pack_into("I", settings, 8, cflag)
        struct.pack_into("II", settings, 36, baud, baud)
        fcntl.ioctl(fd, TCSETS2, bytes(settings))
        return struct.unpack_from("II", fcntl.ioctl(fd, TCGETS2, bytes(44)), 36)[1]

    fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    other = int(sys.argv[2])
    os.write(fd, b"abc")
    step("mget", lambda: get(fd, TIOCMGET))
    step("mbic", lambda: put(fd, TIOCMBIC, 0x2) and 0)
    os.write(fd, b"de")
    step("mbis", lambda: put(fd, TIOCMBIS, 0x2) and 0)
    step("mset", lambda: put(fd, TIOCMSET, 0x4) and 0)
    step("miwait", lambda: fcntl.ioctl(fd, TIOCMIWAIT, 0x20))
    step("icount", lambda: list(struct.unpack("11i", fcntl.ioctl(fd, TIOCGICOUNT, bytes(80))[:44])))
    step("tcsbrk", lambda: fcntl.ioctl(fd, TCSBRK, 0))
    step("tcsbrkp", lambda: fcntl.ioctl(fd, TCSBRKP, 5))
    step("sbrk", lambda: fcntl.ioctl(fd, TIOCSBRK, 0))
    step("cbrk", lambda: fcntl.ioctl(fd, TIOCCBRK, 0))
    step("tcsendbreak", lambda: termios.tcsendbreak(fd, 0))
    step("tcdrain", lambda: termios.tcdrain(fd))
    step("custom_baud", lambda: custom_baud(fd, 250000))
    step("tcsetattr", lambda: termios.tcsetattr(fd, termios.TCSANOW, termios.tcgetattr(fd)))
    serial = bytearray(fcntl.ioctl(fd, TIOCGSERIAL, bytes(72)))
    struct.pack_into("i", serial, 24, 12)  # custom_divisor
    step("sserial", lambda: fcntl.ioctl(fd, TIOCSSERIAL, bytes(serial)))
    step("gserial", lambda: struct.unpack_from("i", fcntl.ioctl(fd, TIOCGSERIAL, bytes(72)), 24)[0])
    step("srs485", lambda: fcntl.ioctl(fd, TIOCSRS485, struct.pack("II", 1, 7) + bytes(24)))
    step("grs485", lambda: list(struct.unpack_from("II", fcntl.ioctl(fd, TIOCGRS485, bytes(32)))))
    step("excl", lambda: fcntl.ioctl(fd, TIOCEXCL, 0))
    step("nxcl", lambda: fcntl.ioctl(fd, TIOCNXCL, 0))
    copy = os.dup(fd)
    step("dup_mget", lambda: get(copy, TIOCMGET))
    os.close(copy)
    os.close(fd)
    # The numbers are free again: an unrelated descriptor reusing one is
    # not emulated, nor is one never redirected.
    reused = os.dup(other)
    step("reused_mget", lambda: get(reused, TIOCMGET) if reused in (fd, copy) else "not reused")
    step("other_mget", lambda: get(other, TIOCMGET))
    step("other_sbrk", lambda: fcntl.ioctl(other, TIOCSBRK, 0))
    step("other_gserial", lambda: len(fcntl.ioctl(other, TIOCGSERIAL, bytes(72))))
    # A child connects anew; its count starts from its own first byte.
    pid = os.fork()
    if pid == 0:
        child = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
        os.write(child, b"xyz")
        put(child, TIOCMBIC, 0x4)
        os._exit(0)
    os.waitpid(pid, 0)
""")


def run_program(tmp_path, channel=None):
    """Runs PROGRAM under the shim; returns {step: result}."""
    script = tmp_path / "program.py"
    script.write_text(PROGRAM)
    # The redirected pty and an unrelated one; both are drained by nobody,
    # and what the program writes fits in their buffers.
    controller, terminal = os.openpty()
    other_controller, other_terminal = os.openpty()
    env = dict(os.environ)
    env["LD_PRELOAD"] = redirect.shim_path()
    env[redirect.ENV_FROM] = HARD_CODED
    env[redirect.ENV_TO] = os.ttyname(terminal)
    env.pop(redirect.ENV_LINE_CHANNEL, None)
    if channel:
        env[redirect.ENV_LINE_CHANNEL] = channel
    try:
        done = subprocess.run([sys.executable, str(script), HARD_CODED, str(other_terminal)],
                              env=env, capture_output=True, text=True, timeout=DEADLINE_S,
                              pass_fds=(other_terminal,))
    finally:
        for fd in (controller, terminal, other_controller, other_terminal):
            os.close(fd)
    assert done.returncode == 0, done.stderr
    return dict(json.loads(line) for line in done.stdout.splitlines())


def unshimmed_results(tmp_path):
    """What the real ioctls give on a pty, without the shim."""
    controller, terminal = os.openpty()
    probe = textwrap.dedent("""
        import array, fcntl, json, sys
        fd = int(sys.argv[1])

        def outcome(call):
            try:
                result = call()
            except OSError as error:
                return {"errno": error.errno}
            return len(result) if isinstance(result, bytes) else result

        def mget():
            buffer = array.array("i", [0])
            fcntl.ioctl(fd, 0x5415, buffer, True)
            return buffer[0]

        print(json.dumps({"mget": outcome(mget),
                          "sbrk": outcome(lambda: fcntl.ioctl(fd, 0x5427, 0)),
                          "gserial": outcome(lambda: fcntl.ioctl(fd, 0x541E, bytes(72)))}))
    """)
    try:
        done = subprocess.run([sys.executable, "-c", probe, str(terminal)], capture_output=True,
                              text=True, timeout=DEADLINE_S, pass_fds=(terminal,), check=True)
    finally:
        os.close(controller)
        os.close(terminal)
    return json.loads(done.stdout)


@pytest.fixture
def channel(tmp_path):
    path = str(tmp_path / "lines")
    bridge = FakeBridge(path)
    yield path, bridge
    bridge.close()


def test_each_emulated_ioctl_tells_the_bridge_with_the_bytes_written_before_it(tmp_path,
                                                                             channel):
    path, bridge = channel
    results = run_program(tmp_path, path)
    assert results["mget"] == TIOCM_CTS | TIOCM_RI
    assert results["icount"][:4] == [3, 4, 5, 6]
    assert results["icount"][5] == 5  # tx: the bytes written so far
    assert results["custom_baud"] == 250000  # the pty keeps the custom rate
    assert results["gserial"] == 12
    assert results["grs485"] == [1, 7]
    assert results["dup_mget"] == TIOCM_CTS | TIOCM_RI
    for name in ("mbic", "mbis", "mset", "miwait", "tcsbrk", "tcsbrkp", "sbrk", "cbrk",
                 "tcsendbreak", "tcdrain", "tcsetattr", "sserial", "srs485", "excl", "nxcl"):
        assert not isinstance(results[name], dict), (name, results[name])
    ops = bridge.ops()
    assert ops[:3] == [("get", 3, 0, 0, 0),
                          ("set_outputs", 3, 0, TIOCM_DTR, 0),
                          ("set_outputs", 5, TIOCM_DTR, 0, 0)]
    # TIOCMSET raises what it names and lowers the other output.
    assert ops[3] == ("set_outputs", 5, TIOCM_RTS, TIOCM_DTR, 0)
    assert ops[4][0] == "wait" and ops[4][2] == TIOCM_CTS
    assert ops[5] == ("get", 5, 0, 0, 0)
    assert ops[6:12] == [("break", 5, 0, 0, 250), ("break", 5, 0, 0, 500),
                         ("break_on", 5, 0, 0, 0), ("break_off", 5, 0, 0, 0),
                         ("break", 5, 0, 0, 250), ("drain", 5, 0, 0, 0)]
    assert [op[0] for op in ops[12:15]] == ["settings", "settings", "get"]
    # The forked child: its own connection, its own count.
    assert ops[-1] == ("set_outputs", 3, 0, TIOCM_RTS, 0)
    assert [r["op"] for r in bridge.requests].count("hello") == 2


def test_a_descriptor_that_is_not_redirected_gets_the_real_ioctl(tmp_path, channel):
    path, _ = channel
    results = run_program(tmp_path, path)
    real = unshimmed_results(tmp_path)
    assert results["reused_mget"] in ("not reused", real["mget"])
    assert results["other_mget"] == real["mget"]
    assert results["other_sbrk"] == real["sbrk"]
    assert results["other_gserial"] == real["gserial"]


def test_without_a_channel_the_lines_are_the_programs_own(tmp_path):
    results = run_program(tmp_path, None)
    # CTS, DSR and CD asserted; DTR as the program left it (TIOCMSET: RTS).
    assert results["mget"] == TIOCM_DTR | TIOCM_RTS | TIOCM_CTS | TIOCM_DSR | TIOCM_CD
    assert results["dup_mget"] == TIOCM_RTS | TIOCM_CTS | TIOCM_DSR | TIOCM_CD
    assert results["miwait"] == {"errno": 5}
    assert results["custom_baud"] == 250000


def test_a_descriptor_inherited_open_on_the_pty_is_emulated(tmp_path, channel):
    """A program started with the device already open (a shell's `prog
    </dev/ttyUSB0`, a launcher that exec'd it) gets the lines on it too."""
    path, bridge = channel
    controller, terminal = os.openpty()
    env = dict(os.environ, LD_PRELOAD=redirect.shim_path())
    env[redirect.ENV_FROM] = HARD_CODED
    env[redirect.ENV_TO] = os.ttyname(terminal)
    env[redirect.ENV_LINE_CHANNEL] = path
    probe = ("import array, fcntl, sys\n"
             "b = array.array('i', [0])\n"
             "fcntl.ioctl(int(sys.argv[1]), 0x5415, b, True)\n"
             "print(b[0])\n")
    try:
        done = subprocess.run([sys.executable, "-c", probe, str(terminal)], env=env,
                              capture_output=True, text=True, timeout=DEADLINE_S,
                              pass_fds=(terminal,))
    finally:
        os.close(controller)
        os.close(terminal)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) == TIOCM_CTS | TIOCM_RI
    assert [r["op"] for r in bridge.requests] == ["hello", "get"]


# Two hard-coded paths of one program, each its own device (issue 25).
SECOND_HARD_CODED = "/dev/ttyWIRETAPE_SHIM_TEST1"
TWO_DEVICES_PROGRAM = textwrap.dedent(r"""
    import fcntl, json, os, struct, sys

    TIOCMBIS, TIOCMBIC = 0x5416, 0x5417
    first = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
    second = os.open(sys.argv[2], os.O_RDWR | os.O_NOCTTY)
    os.write(first, b"ab")
    os.write(second, b"cdef")
    fcntl.ioctl(first, TIOCMBIC, struct.pack("i", 0x2))
    fcntl.ioctl(os.dup(second), TIOCMBIS, struct.pack("i", 0x4))

    def same_device(path, fd):
        return os.stat(path).st_rdev == os.fstat(fd).st_rdev

    with open("/sys/class/tty/ttyWTIDA/marker") as marker_a, \
            open("/sys/class/tty/ttyWTIDB/marker") as marker_b:
        markers = [marker_a.read(), marker_b.read()]
    print(json.dumps({
        "ttys": [same_device("/dev/ttyWTIDA", first), same_device("/dev/ttyWTIDB", second)],
        "by_id": same_device("/dev/serial/by-id/usb-wiretape-second", second),
        "markers": markers,
        "listed": sorted(name for name in os.listdir("/dev") if name.startswith("ttyWTID")),
    }))
""")


def test_two_redirected_devices_each_reach_their_own_channel_and_identity(tmp_path):
    """Device 0 from the unsuffixed variables, device 1 from the _1 ones: a
    line change on one descriptor reaches its own device's bridge only,
    with that device's byte count, and each identity answers for its own
    pty."""
    bridges = [FakeBridge(str(tmp_path / name)) for name in ("lines-a", "lines-b")]
    script = tmp_path / "two.py"
    script.write_text(TWO_DEVICES_PROGRAM)
    ptys = [os.openpty(), os.openpty()]
    env = dict(os.environ, LD_PRELOAD=redirect.shim_path())
    for device, (path, (_, terminal), letter) in enumerate(
            zip((HARD_CODED, SECOND_HARD_CODED), ptys, "AB")):
        suffix = f"_{device}" if device else ""
        folder = tmp_path / f"sysfs-{letter}"
        folder.mkdir()
        (folder / "marker").write_text(letter)
        env[redirect.ENV_FROM + suffix] = path
        env[redirect.ENV_TO + suffix] = os.ttyname(terminal)
        env[redirect.ENV_LINE_CHANNEL + suffix] = str(tmp_path / f"lines-{letter.lower()}")
        env[redirect.ENV_IDENTITY_TTY + suffix] = f"ttyWTID{letter}"
        env[redirect.ENV_IDENTITY_SYSFS + suffix] = str(folder)
    env[redirect.ENV_IDENTITY_BY_ID + "_1"] = "/dev/serial/by-id/usb-wiretape-second"
    try:
        done = subprocess.run([sys.executable, str(script), HARD_CODED, SECOND_HARD_CODED],
                              env=env, capture_output=True, text=True, timeout=DEADLINE_S)
    finally:
        for controller, terminal in ptys:
            os.close(controller)
            os.close(terminal)
        for bridge in bridges:
            bridge.close()
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout)
    assert bridges[0].ops() == [("set_outputs", 2, 0, TIOCM_DTR, 0)]
    assert bridges[1].ops() == [("set_outputs", 4, TIOCM_RTS, 0, 0)]
    assert seen == {"ttys": [True, True], "by_id": True, "markers": ["A", "B"],
                    "listed": ["ttyWTIDA", "ttyWTIDB"]}
