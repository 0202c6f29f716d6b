"""Serial lines through ``--as`` (DESIGN §20): a program that resets a board
by pulsing DTR, sets a custom baud with TCSETS2 and sends a break, and
pyserial's line properties, on a hard-coded path the shim redirects to the
bridge's pty. The shim tells the bridge through its side channel, and the
bridge applies the change exactly among the client's bytes.

There is no real serial port here: the device recorded is a ``type=replay``
library port playing a session with line events."""

import json
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

import wiretape
from wiretape import _core

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the preload shim is Linux only")

HARD_CODED = "/dev/ttyUSB0"
COMMAND_DEADLINE_S = 60.0
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.abspath(__file__)))))
SOURCE = os.path.join(REPO, "tests", "cpp", "shim", "reset_board.c")


def wiretape_cli(*arguments):
    return subprocess.run([sys.executable, "-m", "wiretape.cli", *arguments],
                          capture_output=True, text=True, timeout=COMMAND_DEADLINE_S)


@pytest.fixture(scope="module")
def reset_board(tmp_path_factory):
    """tests/cpp/shim/reset_board.c: CMake's build of it, or this test's."""
    built = os.path.join(REPO, "build", "bin", "reset_board")
    if os.path.isfile(built) and os.path.getmtime(built) >= os.path.getmtime(SOURCE):
        return built
    compiler = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if compiler is None:
        pytest.skip("NO C COMPILER (cc, gcc, clang) and no build/bin/reset_board: the "
                    "board reset through --as is not tested")
    program = tmp_path_factory.mktemp("reset_board") / "reset_board"
    subprocess.run([compiler, "-o", str(program), SOURCE], check=True,
                   timeout=COMMAND_DEADLINE_S)
    return str(program)


def board_session(path):
    """The board the program resets, as a recording: the lines the program
    sets, the break, and PONG for its PING."""
    ms = 1_000_000
    with wiretape.SessionWriter(str(path), capture="wire", port_type="serial",
                                port_options="type=serial,device=/dev/ttyUSB0") as writer:
        writer.write("open", 0, b"{}")
        writer.write("settings", 1 * ms, b'{"baud":250000}')
        writer.write("tx", 2 * ms, b"HELLO\n")
        writer.write("modem_lines", 3 * ms, b'{"dtr":false}')
        writer.write("modem_lines", 4 * ms, b'{"dtr":true}')
        writer.write("tx", 5 * ms, b"SYNC\n")
        writer.write("break", 6 * ms, b'{"duration_ms":250}')
        writer.write("tx", 7 * ms, b"PING\n")
        writer.write("rx", 8 * ms, b"PONG\n")
        writer.write("close", 9 * ms, b"{}")
    return str(path)


def timeline(path):
    """The session's records as (kind, what): the bytes, or the event's
    members without the proxy's own (applied, source); the client's line
    changes only, not the device's inputs (cts, dsr, ri, cd)."""
    out = []
    with _core.SessionReader(str(path)) as reader:
        for record in reader:
            if record.kind in ("rx", "tx"):
                out.append((record.kind, bytes(record.data)))
            elif record.kind in ("settings", "modem_lines", "break"):
                members = json.loads(record.data)
                for own in ("applied", "source"):
                    members.pop(own, None)
                if record.kind == "modem_lines" and not {"dtr", "rts"} & set(members):
                    continue
                out.append((record.kind, members))
    return out


def joined(events):
    """Adjacent byte records joined (the bridge may read a write in pieces)."""
    out = []
    for kind, what in events:
        if out and kind in ("rx", "tx") and out[-1][0] == kind:
            out[-1] = (kind, out[-1][1] + what)
        else:
            out.append((kind, what))
    return out


def record_the_reset(tmp_path, reset_board):
    device = board_session(tmp_path / "board.wtape")
    recording = tmp_path / "reset.wtape"
    done = wiretape_cli("record", "--device", f"type=replay,file={device}", "--as", HARD_CODED,
                        "-o", str(recording), "-q", "--", reset_board)
    assert done.returncode == 0, done.stderr
    return done, recording


def test_record_holds_the_pulse_the_break_and_the_baud_among_the_bytes(tmp_path, reset_board):
    done, recording = record_the_reset(tmp_path, reset_board)
    assert done.stdout == "cts=1 dtr=1\nread: PONG\n"
    events = joined(timeline(recording))
    settings = [what for kind, what in events if kind == "settings"]
    assert settings and settings[0]["baud"] == 250000
    lines_and_bytes = [(kind, what) for kind, what in events if kind != "settings"]
    assert lines_and_bytes == [
        ("tx", b"HELLO\n"),
        ("modem_lines", {"dtr": False}),
        ("modem_lines", {"dtr": True}),
        ("tx", b"SYNC\n"),
        ("break", {"duration_ms": 250}),
        ("tx", b"PING\n"),
        ("rx", b"PONG\n"),
    ]
    # The custom baud was set before the first byte.
    assert events.index(("tx", b"HELLO\n")) > [k for k, _ in events].index("settings")


def test_replay_passes_the_reset(tmp_path, reset_board):
    _, recording = record_the_reset(tmp_path, reset_board)
    replayed = wiretape_cli("replay", str(recording), "--as", HARD_CODED, "-q", "--",
                            reset_board)
    assert replayed.returncode == 0, replayed.stderr
    assert replayed.stdout == "cts=1 dtr=1\nread: PONG\n"


def test_a_replay_checking_events_names_the_missing_pulse_where_it_was(tmp_path,
                                                                      reset_board):
    """Under check=timing every recorded event is checked in its place: the
    custom baud before HELLO (the replay is given the client's terminal
    settings, issue 37), the pulse after HELLO, before SYNC."""
    _, recording = record_the_reset(tmp_path, reset_board)
    # A tolerance no loaded machine misses: the events are checked, not the clock.
    arguments = ("replay", str(recording), "--check", "timing", "--tolerance", "60000",
                 "--as", HARD_CODED, "-q", "--", reset_board)
    replayed = wiretape_cli(*arguments)
    assert replayed.returncode == 0, replayed.stderr
    omitted = wiretape_cli(*arguments, "--no-pulse")
    # 1, or the program's own failure (4) when it sees the replay end first.
    assert omitted.returncode in (1, 4), omitted.stdout + omitted.stderr
    assert "DTR low" in omitted.stderr, omitted.stderr
    assert "at tx byte offset 6" in omitted.stderr, omitted.stderr


def test_the_default_replay_names_a_missing_pulse(tmp_path, reset_board):
    _, recording = record_the_reset(tmp_path, reset_board)
    omitted = wiretape_cli("replay", str(recording), "--as", HARD_CODED, "-q", "--",
                           reset_board, "--no-pulse")
    assert omitted.returncode in (1, 4), omitted.stdout + omitted.stderr
    assert "the recording has DTR low before these bytes" in omitted.stderr, omitted.stderr
    assert "at tx byte offset 6" in omitted.stderr, omitted.stderr


FLASHER = textwrap.dedent("""
    import sys, time
    import serial

    # A flashing tool's reset (esptool's): 115200, EN low with IO0 high, then
    # released; its first command once the board is up.
    port = serial.Serial("/dev/ttyUSB0", 115200, timeout=30)
    if "--write-first" in sys.argv:
        port.write(b"SYNC\\n")
    if "--rts-first" in sys.argv:
        port.rts = False
    port.dtr = False
    port.rts = True
    time.sleep(0.1)
    port.dtr = True
    port.rts = False
    time.sleep(0.05)
    port.dtr = False
    if "--write-first" not in sys.argv:
        port.write(b"SYNC\\n")
    print("read: " + port.readline().decode(), end="")
""")


def test_check_timing_passes_the_command_that_made_the_recording(tmp_path):
    """Issue 37: `record --as PATH -- CMD` records the client's 115200 and
    its DTR/RTS reset; `replay --check timing --as PATH -- CMD` of the same
    command passes (its settings are matched in order with its lines and
    bytes), and the same calls in another order fail, naming both events."""
    ms = 1_000_000
    device = tmp_path / "board.wtape"
    with wiretape.SessionWriter(str(device), capture="wire", port_type="serial",
                                port_options="type=serial,device=/dev/ttyUSB0") as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 1 * ms, b"SYNC\n")
        writer.write("rx", 2 * ms, b"OK\n")
        writer.write("close", 3 * ms, b"{}")
    script = tmp_path / "flasher.py"
    script.write_text(FLASHER)
    recording = tmp_path / "flash.wtape"
    done = wiretape_cli("record", "--device", f"type=replay,file={device}", "--as", HARD_CODED,
                        "-o", str(recording), "-q", "--", sys.executable, str(script))
    assert done.returncode == 0, done.stderr
    events = [(kind, what) for kind, what in timeline(recording) if kind != "rx"]
    assert events[0][0] == "settings" and events[0][1]["baud"] == 115200, events
    assert events[1:] == [("modem_lines", {"dtr": False}), ("modem_lines", {"dtr": True}),
                          ("modem_lines", {"rts": False}), ("modem_lines", {"dtr": False}),
                          ("tx", b"SYNC\n")], events
    # A tolerance no loaded machine misses: the events are checked, not the clock.
    replay = ("replay", str(recording), "--check", "timing", "--tolerance", "60000",
              "--as", HARD_CODED, "-q", "--", sys.executable, str(script))
    replayed = wiretape_cli(*replay)
    assert replayed.returncode == 0, replayed.stderr
    assert replayed.stdout == "read: OK\n"
    assert wiretape_cli("replay", str(recording), "--as", HARD_CODED, "-q", "--",
                        sys.executable, str(script)).returncode == 0
    # 1, or the program's own failure when it sees the replay end first.
    reordered = wiretape_cli(*replay, "--rts-first")
    assert reordered.returncode != 0, reordered.stdout + reordered.stderr
    assert "the client made RTS low; the recording has DTR low" in reordered.stderr
    written_early = wiretape_cli(*replay, "--write-first")
    assert written_early.returncode != 0, written_early.stdout + written_early.stderr
    assert "the recording has DTR low before these bytes" in written_early.stderr


PYSERIAL_CLIENT = textwrap.dedent("""
    import serial

    with serial.Serial("/dev/ttyUSB0", 115200, timeout=30) as port:
        port.write(b"HELLO\\n")
        port.dtr = False
        port.dtr = True
        port.rts = False
        port.write(b"SYNC\\n")
        port.send_break(0.25)
        print("cts=%d dsr=%d cd=%d ri=%d" % (port.cts, port.dsr, port.cd, port.ri))
        port.write(b"PING\\n")
        print("read: " + port.readline().decode(), end="")
""")


def test_pyserial_lines_and_break_under_as(tmp_path):
    """pyserial's dtr, rts, cts, dsr, cd, ri and send_break on a hard-coded
    path: recorded in place, and the device's inputs read."""
    ms = 1_000_000
    device = tmp_path / "board.wtape"
    with wiretape.SessionWriter(str(device), capture="wire", port_type="serial",
                                port_options="type=serial,device=/dev/ttyUSB0") as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 1 * ms, b"HELLO\nSYNC\nPING\n")
        writer.write("rx", 2 * ms, b"PONG\n")
        writer.write("close", 3 * ms, b"{}")
    script = tmp_path / "client.py"
    script.write_text(PYSERIAL_CLIENT)
    recording = tmp_path / "pyserial.wtape"
    done = wiretape_cli("record", "--device", f"type=replay,file={device}", "--as", HARD_CODED,
                        "-o", str(recording), "-q", "--", sys.executable, str(script))
    assert done.returncode == 0, done.stderr
    # A recording without line events: CTS, DSR and CD asserted.
    assert done.stdout == "cts=1 dsr=1 cd=1 ri=0\nread: PONG\n"
    lines_and_bytes = [(kind, what) for kind, what in joined(timeline(recording))
                       if kind != "settings"]
    assert lines_and_bytes == [
        ("tx", b"HELLO\n"),
        ("modem_lines", {"dtr": False}),
        ("modem_lines", {"dtr": True}),
        ("modem_lines", {"rts": False}),
        ("tx", b"SYNC\n"),
        # send_break(0.25) is tcsendbreak(fd, 1): glibc asks for a tenth.
        ("break", {"duration_ms": 100}),
        ("tx", b"PING\n"),
        ("rx", b"PONG\n"),
    ]


WAITING_CLIENT = textwrap.dedent("""
    import array, fcntl, os, threading

    TIOCMGET, TIOCMIWAIT, TIOCGICOUNT, TIOCM_CTS = 0x5415, 0x545C, 0x545D, 0x20
    fd = os.open("/dev/ttyUSB0", os.O_RDWR | os.O_NOCTTY)
    woke = []
    waiter = threading.Thread(target=lambda: woke.append(fcntl.ioctl(fd, TIOCMIWAIT, TIOCM_CTS)))
    waiter.start()
    os.write(fd, b"GO\\n")
    waiter.join(60)
    lines = array.array("i", [0])
    fcntl.ioctl(fd, TIOCMGET, lines, True)
    counts = array.array("i", [0] * 20)
    fcntl.ioctl(fd, TIOCGICOUNT, counts, True)
    print("woke=%d cts=%d cts_changes=%d" % (len(woke), bool(lines[0] & TIOCM_CTS), counts[0]))
    os._exit(0)
""")


def test_tiocmiwait_wakes_when_the_replayed_device_raises_cts(tmp_path):
    """The device's CTS, recorded low and raised 2 s after the client's
    request, wakes a TIOCMIWAIT the client made before it."""
    ms = 1_000_000
    inputs = '{{"cts":{},"dsr":true,"ri":false,"cd":true}}'
    recording = tmp_path / "cts.wtape"
    with wiretape.SessionWriter(str(recording), capture="wire", port_type="serial",
                                port_options="type=serial,device=/dev/ttyUSB0") as writer:
        writer.write("open", 0, b"{}")
        writer.write("modem_lines", 1, inputs.format("false").encode())
        writer.write("tx", 1 * ms, b"GO\n")
        writer.write("modem_lines", 2001 * ms, inputs.format("true").encode())
        writer.write("close", 2002 * ms, b"{}")
    script = tmp_path / "client.py"
    script.write_text(WAITING_CLIENT)
    replayed = wiretape_cli("replay", str(recording), "--as", HARD_CODED, "-q", "--",
                            sys.executable, str(script))
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    assert "woke=1 cts=1 cts_changes=" in replayed.stdout, replayed.stdout + replayed.stderr
    assert "cts_changes=0" not in replayed.stdout
