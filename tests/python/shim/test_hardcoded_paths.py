"""Programs with a hard-coded device path: ``wiretape record ... -- CMD`` and
``wiretape replay FILE --as PATH -- CMD`` run CMD with that path redirected
to the bridge's pty by the preload shim (DESIGN §12, docs/replay.md
"Programs with a hard-coded device path").

The programs open ``/dev/ttyUSB0`` literally, a path this machine need not
have: the shim makes them open the pty instead."""

import os
import shutil
import signal
import subprocess
import sys
import textwrap

import pytest

from wiretape import _core, redirect

from devices import TcpDevice, wait_until

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the preload shim is Linux only")

HARD_CODED = "/dev/ttyUSB0"
# Generous: CMD, the bridge and Python start on a loaded CI machine.
COMMAND_DEADLINE_S = 60.0

C_CLIENT = r"""
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

/* Opens the hard-coded device, says hello, prints the reply line, and exits
 * with the status given as its argument (0 by default). */
int main(int argc, char **argv) {
  int fd = open("/dev/ttyUSB0", O_RDWR | O_NOCTTY);
  if (fd < 0) { perror("/dev/ttyUSB0"); return 4; }
  struct termios settings;
  if (tcgetattr(fd, &settings) == 0) {
    cfmakeraw(&settings);
    tcsetattr(fd, TCSANOW, &settings);
  }
  if (write(fd, "hello c\n", 8) != 8) { perror("write"); return 4; }
  char line[128];
  size_t length = 0;
  while (length < sizeof line - 1) {
    ssize_t got = read(fd, line + length, 1);
    if (got <= 0) break;
    length += (size_t)got;
    if (line[length - 1] == '\n') break;
  }
  line[length] = '\0';
  printf("read: %s", line);
  close(fd);
  return argc > 1 ? atoi(argv[1]) : 0;
}
"""

PYTHON_CLIENT = textwrap.dedent("""
    import sys
    import serial

    # pyserial, as a Python driver would use it, on the hard-coded path.
    with serial.Serial("/dev/ttyUSB0", 115200, timeout=30) as port:
        port.write(b"hello python\\n")
        print("read: " + port.readline().decode(), end="")
    sys.exit(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
""")


def wiretape(*arguments):
    """Runs the wiretape command line; returns the finished process."""
    return subprocess.run([sys.executable, "-m", "wiretape.cli", *arguments],
                          capture_output=True, text=True, timeout=COMMAND_DEADLINE_S)


@pytest.fixture(scope="module")
def c_client(tmp_path_factory):
    compiler = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if compiler is None:
        pytest.skip("NO C COMPILER (cc, gcc, clang): the C program with a hard-coded "
                    "device path is not tested")
    folder = tmp_path_factory.mktemp("c_client")
    source = folder / "client.c"
    source.write_text(C_CLIENT)
    program = folder / "client"
    subprocess.run([compiler, "-o", str(program), str(source)], check=True,
                   timeout=COMMAND_DEADLINE_S)
    return [str(program)]


@pytest.fixture(scope="module")
def python_client(tmp_path_factory):
    script = tmp_path_factory.mktemp("python_client") / "client.py"
    script.write_text(PYTHON_CLIENT)
    return [sys.executable, str(script)]


@pytest.fixture(params=["c", "python"])
def client(request):
    return request.getfixturevalue(f"{request.param}_client")


def record_with(client, tmp_path):
    """Records `client` against a device that answers in upper case."""
    session = tmp_path / "run.wtape"
    with TcpDevice() as device:
        done = wiretape("record", "--device", device.options, "--as", HARD_CODED,
                        "-o", str(session), "-q", "--", *client)
        received = bytes(device.received)
    return done, session, received


def test_record_and_replay_a_program_with_a_hard_coded_path(client, tmp_path):
    recorded, session, received = record_with(client, tmp_path)
    assert recorded.returncode == 0, recorded.stderr
    assert received.startswith(b"hello ")
    answer = received.upper()
    assert recorded.stdout == "read: " + answer.decode()
    with _core.SessionReader(str(session)) as reader:
        records = list(reader)
    assert b"".join(r.data for r in records if r.kind == "tx") == received
    assert b"".join(r.data for r in records if r.kind == "rx") == answer

    replayed = wiretape("replay", str(session), "--as", HARD_CODED, "-q", "--", *client)
    assert replayed.returncode == 0, replayed.stderr
    assert replayed.stdout == "read: " + answer.decode()
    assert "never opened" not in replayed.stderr


def test_a_failing_command_gives_its_own_exit_status(c_client, tmp_path):
    recorded, session, _ = record_with(c_client, tmp_path)
    assert recorded.returncode == 0, recorded.stderr
    replayed = wiretape("replay", str(session), "--as", HARD_CODED, "-q", "--",
                        *c_client, "5")
    assert replayed.returncode == 5, replayed.stderr
    assert replayed.stdout == "read: HELLO C\n"
    assert "exited with status 5" in replayed.stderr


def test_a_command_that_never_opens_the_path_is_named_and_fails_the_replay(c_client, tmp_path):
    _, session, _ = record_with(c_client, tmp_path)
    replayed = wiretape("replay", str(session), "--as", HARD_CODED, "--", "true")
    # `true` exits 0, so the status is the replay's: nothing was served.
    assert replayed.returncode == 1, replayed.stderr
    assert f"true never opened {HARD_CODED}" in replayed.stderr
    assert "no client connected" in replayed.stderr


def test_record_fails_when_the_command_never_opened_the_path(tmp_path):
    # As a replay does (exit 1); the recording is kept, as replay keeps -o.
    session = tmp_path / "run.wtape"
    with TcpDevice() as device:
        done = wiretape("record", "--device", device.options, "--as", HARD_CODED,
                        "-o", str(session), "--", "true")
    assert done.returncode == 1, done.stderr
    assert f"true never opened {HARD_CODED}" in done.stderr
    assert "nothing was recorded" in done.stderr
    with _core.SessionReader(str(session)) as reader:
        assert [record.kind for record in reader] == ["open", "close"]


def test_record_of_a_loopback_with_a_command_that_never_opened_the_path_fails(tmp_path):
    done = wiretape("record", "--device", "type=loopback", "--as", "/dev/ttyFAKE9",
                    "-o", str(tmp_path / "r.wtape"), "--", "true")
    assert done.returncode == 1, done.stderr
    assert "true never opened /dev/ttyFAKE9" in done.stderr


def test_a_failing_command_that_never_opened_the_path_gives_its_own_status(tmp_path):
    done = wiretape("record", "--device", "type=loopback", "--as", "/dev/ttyFAKE9",
                    "-o", str(tmp_path / "r.wtape"), "--", "sh", "-c", "exit 6")
    assert done.returncode == 6, done.stderr
    assert "nothing was recorded" in done.stderr


def test_no_command_after_the_separator_is_a_usage_error(c_client, tmp_path):
    _, session, _ = record_with(c_client, tmp_path)
    replayed = wiretape("replay", str(session), "--as", HARD_CODED, "--")
    assert replayed.returncode == 2
    assert "no command after --" in replayed.stderr
    with TcpDevice() as device:
        recorded = wiretape("record", "--device", device.options, "--as", HARD_CODED,
                            "-o", str(tmp_path / "other.wtape"), "--")
    assert recorded.returncode == 2
    assert "no command after --" in recorded.stderr


def test_a_command_that_does_not_exist_exits_127(c_client, tmp_path):
    _, session, _ = record_with(c_client, tmp_path)
    missing = str(tmp_path / "no-such-program")
    replayed = wiretape("replay", str(session), "--as", HARD_CODED, "--", missing)
    assert replayed.returncode == 127
    assert f"{missing}: command not found" in replayed.stderr


def test_as_without_a_command_and_a_device_without_a_path_are_usage_errors(tmp_path):
    with TcpDevice() as device:
        no_command = wiretape("record", "--device", device.options, "--as", HARD_CODED,
                              "--pty", str(tmp_path / "tty"), "-o", str(tmp_path / "a.wtape"))
        no_path = wiretape("record", "--device", device.options,
                           "-o", str(tmp_path / "b.wtape"), "--", "true")
    assert no_command.returncode == 2
    assert "give the command after --" in no_command.stderr
    assert no_path.returncode == 2
    assert "--as PATH" in no_path.stderr


def test_the_device_path_comes_from_the_option_string():
    assert redirect.device_path_of("type=serial,device=/dev/ttyUSB0,baud=9600") == HARD_CODED
    assert redirect.device_path_of('type=serial,device="/dev/My Port"') == "/dev/My Port"
    assert redirect.device_path_of("type=tcp,host=10.0.0.5,port=10940") is None
    assert redirect.device_path_of("type=serial\tdevice=/dev/ttyUSB0") == HARD_CODED


def test_a_device_setting_that_is_no_option_string_is_refused_by_the_parser():
    """The option string is read by the C++ parser, as open_port() reads it:
    what it refuses is refused here too, naming the problem."""
    with pytest.raises(_core.OptionError, match="inside the value of 'device'"):
        redirect.device_path_of('type=serial,device=/dev/a"b')
    with pytest.raises(_core.OptionError, match="given twice"):
        redirect.device_path_of("type=serial,device=/dev/a,device=/dev/b")


def test_the_shim_matches_what_the_path_resolves_to(tmp_path):
    """A by-id link is another name of the device: the shim compares what a
    path under /dev resolves to with what the device path resolves to
    (here /dev/./null is another name of /dev/null)."""
    cat = shutil.which("cat")
    stand_in = tmp_path / "stand-in"
    stand_in.write_text("redirected\n")
    hits = tmp_path / "hits"
    hits.write_text("")
    environment = dict(os.environ, LD_PRELOAD=redirect.shim_path(),
                       WIRETAPE_REDIRECT_FROM="/dev/null",
                       WIRETAPE_REDIRECT_TO=str(stand_in),
                       WIRETAPE_REDIRECT_HITS=str(hits))
    done = subprocess.run([cat, "/dev/./null", "/dev/null"], env=environment,
                          capture_output=True, text=True, timeout=COMMAND_DEADLINE_S)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "redirected\nredirected\n"
    assert hits.read_text().strip() != ""


def _mount_namespaces_work():
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "--mount", "true"], capture_output=True,
                           timeout=COMMAND_DEADLINE_S)
    return probe.returncode == 0


def test_a_static_program_is_reached_through_a_bind_mount(c_client, tmp_path):
    """The shim cannot reach a statically linked program; as root, over a
    path that exists, CMD runs in a private mount namespace with the pty
    bound over the path."""
    if not _mount_namespaces_work():
        pytest.skip("NOT ROOT OR NO MOUNT NAMESPACES: the bind mount for static "
                    "programs is not tested")
    compiler = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    device_path = tmp_path / "ttyStatic"
    device_path.write_text("")  # what the bind mount covers, only in CMD's namespace
    source = tmp_path / "static_client.c"
    source.write_text(C_CLIENT.replace('"/dev/ttyUSB0"', f'"{device_path}"'))
    program = tmp_path / "static_client"
    built = subprocess.run([compiler, "-static", "-o", str(program), str(source)],
                           capture_output=True, text=True, timeout=COMMAND_DEADLINE_S)
    if built.returncode != 0:
        pytest.skip(f"NO STATIC LIBC: the static program is not tested ({built.stderr.strip()})")

    _, session, _ = record_with(c_client, tmp_path)
    replayed = wiretape("replay", str(session), "--as", str(device_path), "-q", "--",
                        str(program))
    assert replayed.returncode == 0, replayed.stderr
    assert replayed.stdout == "read: HELLO C\n"
    assert "never opened" not in replayed.stderr
    # Nothing leaked to this namespace: the path is still the empty file.
    assert device_path.read_text() == ""


MISMATCHING_CLIENT = textwrap.dedent("""
    import os
    import signal

    # Says what the recording does not expect, then waits for an answer
    # that a mismatch never sends: wiretape must end it. A driver that
    # hangs waits on when its line fails (a read that ends in EIO would
    # let it exit by itself, a race with wiretape noticing the replay's end).
    fd = os.open("/dev/ttyUSB0", os.O_RDWR | os.O_NOCTTY)
    os.write(fd, b"unexpected\\n")
    try:
        os.read(fd, 1)
    except OSError:
        pass
    signal.pause()
""")


def test_a_replay_that_ends_first_ends_the_command_and_gives_its_verdict(c_client, tmp_path):
    _, session, _ = record_with(c_client, tmp_path)
    script = tmp_path / "mismatching.py"
    script.write_text(MISMATCHING_CLIENT)
    replayed = wiretape("replay", str(session), "--as", HARD_CODED, "-q", "--",
                        sys.executable, str(script))
    assert replayed.returncode == 1, replayed.stderr
    assert "mismatch" in replayed.stderr
    assert "ending it" in replayed.stderr


# --- by-id links: another name of the device ----------------------------------------------------

BY_ID = "serial/by-id/usb-FTDI_FT232R_USB_UART_A50285BI-if00-port0"

BY_PATH_CLIENT = PYTHON_CLIENT.replace('"/dev/ttyUSB0"', "sys.argv[1]").replace(
    "int(sys.argv[1]) if len(sys.argv) > 1 else 0", "0")


@pytest.fixture
def device_and_link(tmp_path):
    """(a device node that exists, under /dev: a pty this test holds; a
    by-id style link to it under tmp_path)."""
    controller, device = os.openpty()
    link = tmp_path / BY_ID
    link.parent.mkdir(parents=True)
    link.symlink_to(os.ttyname(device))
    yield os.ttyname(device), str(link)
    os.close(device)
    os.close(controller)


def _cat_through_the_shim(redirect_from, opened, tmp_path):
    stand_in = tmp_path / "stand-in"
    stand_in.write_text("redirected\n")
    environment = dict(os.environ, LD_PRELOAD=redirect.shim_path(),
                       WIRETAPE_REDIRECT_FROM=redirect_from,
                       WIRETAPE_REDIRECT_TO=str(stand_in))
    return subprocess.run([shutil.which("cat"), opened], env=environment, capture_output=True,
                          text=True, timeout=COMMAND_DEADLINE_S)


def test_the_shim_redirects_a_by_id_link_to_the_device(device_and_link, tmp_path):
    """CMD opens the link (outside /dev here), the path given is the device."""
    device, link = device_and_link
    done = _cat_through_the_shim(device, link, tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "redirected\n"


def test_the_shim_redirects_the_device_a_given_by_id_link_names(device_and_link, tmp_path):
    """The reverse: the path given is the link, CMD opens the device."""
    device, link = device_and_link
    done = _cat_through_the_shim(link, device, tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "redirected\n"


@pytest.mark.parametrize("given, opened", [("device", "link"), ("link", "device")])
def test_replay_as_one_name_of_the_device_reaches_a_program_opening_the_other(
        python_client, device_and_link, tmp_path, given, opened):
    names = dict(zip(("device", "link"), device_and_link))
    _, session, received = record_with(python_client, tmp_path)
    script = tmp_path / "by_path_client.py"
    script.write_text(BY_PATH_CLIENT)
    replayed = wiretape("replay", str(session), "--as", names[given], "-q", "--",
                        sys.executable, str(script), names[opened])
    assert replayed.returncode == 0, replayed.stderr
    assert replayed.stdout == "read: " + received.upper().decode()
    assert "never opened" not in replayed.stderr


# --- Ctrl-C while CMD runs ----------------------------------------------------------------------

HANGING_CLIENT = textwrap.dedent("""
    import os
    import signal
    import sys

    import serial

    # Talks to the device once, says so (its pid in a file), then waits for
    # a signal, as a driver that runs until it is stopped.
    with serial.Serial("/dev/ttyUSB0", 115200, timeout=30) as port:
        port.write(b"hello\\n")
        print("read: " + port.readline().decode(), end="", flush=True)
        with open(sys.argv[1] + ".tmp", "w") as pid_file:
            pid_file.write(str(os.getpid()))
        os.rename(sys.argv[1] + ".tmp", sys.argv[1])
        while True:
            signal.pause()
""")


def _alive(pid):
    """False once `pid` is gone (or a zombie nobody reaped yet)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _interrupted(arguments, tmp_path, whom):
    """Runs wiretape with the hanging client as CMD, Ctrl-C once the client
    has talked to the device: to wiretape alone, or to its whole process
    group as a terminal does. (exit status, stdout, stderr, CMD's pid)."""
    script = tmp_path / "hanging.py"
    script.write_text(HANGING_CLIENT)
    pid_file = tmp_path / "cmd.pid"
    child = subprocess.Popen([sys.executable, "-m", "wiretape.cli", *arguments, "--",
                              sys.executable, str(script), str(pid_file)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
    try:
        wait_until(lambda: pid_file.exists() or child.poll() is not None, COMMAND_DEADLINE_S,
                   "CMD to talk to the device")
        assert pid_file.exists(), child.communicate(timeout=COMMAND_DEADLINE_S)
        cmd_pid = int(pid_file.read_text())
        if whom == "group":
            os.killpg(child.pid, signal.SIGINT)
        else:
            child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=COMMAND_DEADLINE_S)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
            child.communicate()
    wait_until(lambda: not _alive(cmd_pid), COMMAND_DEADLINE_S, "CMD to be gone")
    # wiretape ended cleanly (CMD, Python too, may show its own KeyboardInterrupt).
    assert "wiretape/" not in err, err
    return child.returncode, out, err, cmd_pid


def _assert_complete(session, tx, rx):
    verified = wiretape("verify", str(session))
    assert verified.returncode == 0, verified.stdout + verified.stderr
    with _core.SessionReader(str(session)) as reader:
        records = list(reader)
        assert reader.damage is None, reader.damage
    assert records[-1].kind == "close"
    assert b"".join(r.data for r in records if r.kind == "tx") == tx
    assert b"".join(r.data for r in records if r.kind == "rx") == rx


@pytest.mark.parametrize("whom", ["wiretape", "group"])
def test_ctrl_c_ends_record_and_its_command_and_the_recording_verifies(tmp_path, whom):
    session = tmp_path / "run.wtape"
    with TcpDevice() as device:
        code, out, err, _ = _interrupted(["record", "--device", device.options, "--as",
                                          HARD_CODED, "-o", str(session)], tmp_path, whom)
    assert out == "read: HELLO\n", err
    # Batch work ended by Ctrl-C exits 130 (DESIGN §23), never 0; what was
    # recorded until then is kept, complete.
    assert code == 130, err
    _assert_complete(session, b"hello\n", b"HELLO\n")


@pytest.mark.parametrize("whom", ["wiretape", "group"])
def test_ctrl_c_ends_replay_and_its_command(tmp_path, whom):
    session = tmp_path / "run.wtape"
    with TcpDevice() as device:
        _interrupted(["record", "--device", device.options, "--as", HARD_CODED,
                      "-o", str(session)], tmp_path, "wiretape")
    (tmp_path / "cmd.pid").unlink()
    copy = tmp_path / "replayed.wtape"
    code, out, err, _ = _interrupted(["replay", str(session), "--as", HARD_CODED,
                                      "-o", str(copy)], tmp_path, whom)
    assert out == "read: HELLO\n", err
    assert code == 130, err
    assert "mismatch" not in err.lower(), err
    _assert_complete(copy, b"hello\n", b"HELLO\n")
