"""Special files (DESIGN §6): an input that is a pipe or FIFO is read as a
stream, and every command stays interruptible while it waits for a writer;
an output that is not a regular file is written through, never renamed over;
replay and the session writer need regular files (test_file_safety.py).

Commands run in child processes; nothing waits with a blind sleep: a FIFO's
other end is a thread, and a command blocked on a FIFO is recognised by the
FIFO among its open descriptors (/proc/PID/fd)."""

import contextlib
import os
import signal
import stat
import subprocess
import sys
import threading

import pytest

import wiretape
from devices import wait_until
from wiretape import _core

DEADLINE_S = 60

SESSION = [
    ("open", 0, b"{}"),
    ("tx", 1_000_000, b"PING\n"),
    ("rx", 2_000_000, b"PONG\n"),
    ("close", 3_000_000, b""),
]

SUFFIX = {"jsonl": ".jsonl", "pcapng": ".pcapng", "mcap": ".mcap", "flexiport": ".log"}


def _default_sigint():
    # A child of a shell's background job starts with SIGINT ignored, and
    # Python then keeps ignoring it: give it the default, as a terminal would.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def command(*argv):
    return [sys.executable, "-m", "wiretape.cli", *map(str, argv)]


def run_cli(*argv, stdin=subprocess.DEVNULL, input=None):
    """(exit code, stdout bytes, stderr text) of the command in a child."""
    result = subprocess.run(command(*argv), capture_output=True, timeout=DEADLINE_S,
                            stdin=None if input is not None else stdin, input=input,
                            preexec_fn=_default_sigint)
    return result.returncode, result.stdout, result.stderr.decode("utf-8", "replace")


@contextlib.contextmanager
def fifo_written(path, data):
    """A thread writes `data` into the FIFO `path`, a few bytes at a time,
    once a reader opens it; it is released and joined at the end."""

    def write():
        with open(path, "wb") as fifo:
            for start in range(0, len(data), 7):
                fifo.write(data[start:start + 7])
                fifo.flush()

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    try:
        yield
    finally:
        release(path)
        writer.join(DEADLINE_S)


class FifoReader(threading.Thread):
    """Reads the FIFO `path` to its end into `.data`."""

    def __init__(self, path):
        super().__init__(daemon=True)
        self.path, self.data = path, b""
        self.start()

    def run(self):
        with open(self.path, "rb") as fifo:
            self.data = fifo.read()


def release(path):
    """Opens and closes a FIFO's other ends, to free a thread still waiting
    on it after a failure."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)
    except OSError:
        return
    os.close(fd)


@pytest.fixture
def good(session_file):
    return session_file(SESSION, name="good.wtape")


def _as_arg(template, **values):
    return template.format(**values)


# --- inputs: pipes and FIFOs are read as streams --------------------------------------

READING = {
    "show": ["show", "{f}"],
    "show-jsonl": ["show", "{f}", "--format", "jsonl"],
    "stats": ["stats", "{f}"],
    "verify": ["verify", "{f}"],
    "convert-jsonl": ["convert", "{f}", "{tmp}/out.jsonl", "-q"],
    "convert-wiretape": ["convert", "{f}", "{tmp}/out.wtape", "-q"],
    "convert-pcapng": ["convert", "{f}", "{tmp}/out.pcapng", "-q"],
    "convert-flexiport": ["convert", "{f}", "{tmp}/out.log", "-q"],
    "diff-a": ["diff", "{f}", "{good}"],
    "diff-b": ["diff", "{good}", "{f}"],
}


def _outputs(tmp_path):
    names = ("out.jsonl", "out.logr", "out.logw", "out.wtape")
    return {name: (tmp_path / name).read_bytes() for name in names if (tmp_path / name).exists()}


@pytest.mark.parametrize("command_name", sorted(READING))
def test_a_fifo_input_is_read_as_a_stream(good, tmp_path, command_name):
    argv = READING[command_name]
    expected = run_cli(*[_as_arg(a, f=good, good=good, tmp=tmp_path) for a in argv])
    expected_files = _outputs(tmp_path)
    assert expected[0] == 0, expected
    fifo = tmp_path / "fifo"  # no suffix: read as .wtape, not sniffed
    os.mkfifo(fifo)
    with fifo_written(fifo, good.read_bytes()):
        got = run_cli(*[_as_arg(a, f=fifo, good=good, tmp=tmp_path) for a in argv])
    assert got[0] == 0, got
    assert got[1].replace(str(fifo).encode(), str(good).encode()) == expected[1]
    assert _outputs(tmp_path) == expected_files
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_pipe_on_stdin_is_read_as_a_stream(good):
    _, expected, _ = run_cli("show", good, "--format", "jsonl")
    code, out, err = run_cli("show", "/dev/stdin", "--format", "jsonl", input=good.read_bytes())
    assert code == 0, err
    assert out == expected
    with open(good, "rb") as redirected:  # `< file`: a regular file
        code, out, err = run_cli("stats", "/dev/stdin", "--json", stdin=redirected)
    assert code == 0, err


def test_a_jsonl_fifo_is_read_as_a_stream(good, tmp_path):
    source = tmp_path / "source.jsonl"
    assert run_cli("convert", good, source, "-q")[0] == 0
    fifo = tmp_path / "fifo.jsonl"
    os.mkfifo(fifo)
    with fifo_written(fifo, source.read_bytes()):
        code, _, err = run_cli("convert", fifo, tmp_path / "out.wtape", "-q")
    assert code == 0, err
    assert [(r.kind, r.t_ns, r.data) for r in wiretape.SessionReader(tmp_path / "out.wtape")] \
        == [(kind, t_ns, data) for kind, t_ns, data in SESSION]


def test_a_hostile_length_on_a_stream_is_damage_not_an_allocation(good):
    claim = (0xFFFF_FFF0).to_bytes(4, "little") + b"\x10" + bytes(11)
    data = good.read_bytes() + claim + b"x" * 100
    # A 4 GiB allocation would exceed this limit and fail the command.
    limit = "import resource; resource.setrlimit(resource.RLIMIT_AS, (1 << 31, 1 << 31))"
    result = subprocess.run(
        [sys.executable, "-c", limit + "\nfrom wiretape.cli import main; raise SystemExit("
         "main(['verify', '/dev/stdin']))"],
        input=data, capture_output=True, timeout=DEADLINE_S)
    err = result.stdout.decode() + result.stderr.decode()
    assert result.returncode == 1, err
    assert "claims a payload of 4294967280 bytes, but the file holds only 100 more bytes" in err


def test_a_stream_is_read_once(good, tmp_path):
    fifo = tmp_path / "fifo.wtape"
    os.mkfifo(fifo)
    with fifo_written(fifo, good.read_bytes()):
        with wiretape.SessionReader(fifo) as reader:
            assert len(list(reader)) == len(SESSION)
            with pytest.raises(wiretape.PortError, match="cannot be read again"):
                reader.rewind()


def test_devices_and_directories_stay_refused(capsys, tmp_path):
    for path, refusal in (("/dev/zero", "/dev/zero is a character device, not a regular file"),
                          (str(tmp_path), f"{tmp_path}: is a directory")):
        code, _, err = run_cli("show", path)
        assert code == 3, err
        assert refusal in err


# --- waiting for a writer is interruptible ------------------------------------------------

WAITING = {
    "show": ["show", "{f}"],
    "stats": ["stats", "{f}"],
    "verify": ["verify", "{f}"],
    "convert": ["convert", "{f}", "{tmp}/out.jsonl", "-q"],
    "convert-from-jsonl": ["convert", "{f}", "{tmp}/out.wtape", "--from", "jsonl", "-q"],
    "diff": ["diff", "{good}", "{f}"],
}


def _has_open(pid, path):
    try:
        names = os.listdir(f"/proc/{pid}/fd")
    except FileNotFoundError:
        return False
    for name in names:
        try:
            if os.readlink(f"/proc/{pid}/fd/{name}") == str(path):
                return True
        except OSError:
            pass
    return False


def _waits_for_partner(pid, opened_first):
    """Whether the process waits in open() for a FIFO's other end; where the
    kernel does not say (wchan hidden), whether it has opened `opened_first`."""
    try:
        with open(f"/proc/{pid}/wchan") as wchan:
            where = wchan.read()
    except OSError:
        where = ""
    if where in ("", "0"):
        return _has_open(pid, opened_first)
    return where == "wait_for_partner"


def interrupted_while_blocked(argv, blocked, signum=signal.SIGINT):
    """Starts the command, waits until `blocked(pid)` says it is waiting,
    sends `signum`; (exit code, stderr) once it has ended."""
    child = subprocess.Popen(command(*argv), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, preexec_fn=_default_sigint)
    try:
        wait_until(lambda: blocked(child.pid) or child.poll() is not None,
                   what=f"{argv[0]} to block")
        assert child.poll() is None, child.communicate()
        child.send_signal(signum)
        _, err = child.communicate(timeout=DEADLINE_S)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    return child.returncode, err


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("command_name", sorted(WAITING))
def test_waiting_for_a_writer_ends_with_a_signal(good, tmp_path, command_name, signum):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    argv = [_as_arg(a, f=fifo, good=good, tmp=tmp_path) for a in WAITING[command_name]]
    code, err = interrupted_while_blocked(argv, lambda pid: _has_open(pid, fifo), signum)
    assert code == 128 + signum, err  # batch work interrupted: 130/143, never 0
    assert b"Traceback" not in err
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


# --- outputs that are not regular files are written through -------------------------------


def _expected_output(good, tmp_path, fmt):
    out = tmp_path / "expected" / ("out" + SUFFIX[fmt])
    out.parent.mkdir(exist_ok=True)
    code, _, err = run_cli("convert", good, out, "--to", fmt, "-q")
    assert code == 0, err
    return (out.parent / "out.logr" if fmt == "flexiport" else out).read_bytes()


@pytest.mark.parametrize("fmt", ["jsonl", "pcapng", "mcap", "flexiport"])
def test_an_export_writes_through_a_fifo(good, tmp_path, fmt):
    expected = _expected_output(good, tmp_path, fmt)
    path = tmp_path / ("out" + SUFFIX[fmt])
    fifo = tmp_path / "out.logr" if fmt == "flexiport" else path
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    try:
        code, _, err = run_cli("convert", good, path, "--to", fmt, "-q")
    finally:
        release(fifo)
        reader.join(DEADLINE_S)
    assert code == 0, err
    assert reader.data == expected
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert not any(name.endswith(".partial") for name in os.listdir(tmp_path))


@pytest.mark.parametrize("fmt", ["jsonl", "pcapng", "mcap", "flexiport"])
def test_an_export_follows_a_symbolic_link_to_a_regular_file(good, tmp_path, fmt):
    expected = _expected_output(good, tmp_path, fmt)
    target = tmp_path / "elsewhere" / "target.bin"
    target.parent.mkdir()
    target.write_bytes(b"an earlier file " * 1000)
    path = tmp_path / ("out" + SUFFIX[fmt])
    link = tmp_path / "out.logr" if fmt == "flexiport" else path
    os.symlink(target, link)
    code, _, err = run_cli("convert", good, path, "--to", fmt, "-q")
    assert code == 0, err
    assert os.path.islink(link) and os.readlink(link) == str(target)
    assert target.read_bytes() == expected
    assert sorted(os.listdir(target.parent)) == ["target.bin"]


@pytest.mark.parametrize("fmt", ["jsonl", "pcapng", "mcap", "flexiport"])
def test_an_export_writes_through_dev_null(good, tmp_path, fmt):
    path = tmp_path / ("out" + SUFFIX[fmt])
    if fmt == "flexiport":
        for suffix in "rw":
            os.symlink("/dev/null", tmp_path / ("out.log" + suffix))
        code, _, err = run_cli("convert", good, path, "-q")
    else:
        code, _, err = run_cli("convert", good, "/dev/null", "--to", fmt, "-q")
    assert code == 0, err
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    left = ["good.wtape"] + (["out.logr", "out.logw"] if fmt == "flexiport" else [])
    assert sorted(os.listdir(tmp_path)) == left


@pytest.mark.parametrize("fmt", ["jsonl", "pcapng"])
def test_an_export_writes_through_a_terminal(good, tmp_path, fmt):
    expected = _expected_output(good, tmp_path, fmt)
    controller, terminal = os.openpty()
    try:
        import tty

        tty.setraw(terminal)  # the bytes as written, no newline translation
        name = os.ttyname(terminal)
        received = bytearray()
        done = threading.Event()

        def drain():
            while not done.is_set() or len(received) < len(expected):
                try:
                    chunk = os.read(controller, 65536)
                except OSError:
                    return
                received.extend(chunk)
                if len(received) >= len(expected):
                    return

        thread = threading.Thread(target=drain, daemon=True)
        thread.start()
        code, _, err = run_cli("convert", good, name, "--to", fmt, "-q")
        done.set()
        thread.join(DEADLINE_S)
    finally:
        os.close(terminal)
        os.close(controller)
    assert code == 0, err
    assert bytes(received) == expected


def test_an_export_to_a_fifo_waiting_for_its_reader_ends_with_a_signal(good, tmp_path):
    fifo = tmp_path / "out.pcapng"
    os.mkfifo(fifo)
    # Blocked in open(), waiting for the FIFO's reader.
    code, err = interrupted_while_blocked(["convert", good, fifo, "-q"],
                                          lambda pid: _waits_for_partner(pid, good))
    assert code == 130, err  # batch work interrupted
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_the_same_fifo_as_input_and_output_is_refused(tmp_path):
    fifo = tmp_path / "fifo.wtape"
    os.mkfifo(fifo)
    code, _, err = run_cli("convert", fifo, fifo, "--to", "jsonl")
    assert code == 3, err
    assert "same file" in err
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_export_flexiport_reads_a_fifo_and_writes_through_links(good, tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with fifo_written(fifo, good.read_bytes()):
        _core.export_flexiport(str(fifo), str(tmp_path / "out.log"))
    reads = [r for r in wiretape.SessionReader(tmp_path / "out.log") if r.kind in ("rx", "tx")]
    assert [(r.kind, r.data) for r in reads] == [("tx", b"PING\n"), ("rx", b"PONG\n")]


def test_a_flexiport_export_waiting_for_its_fifo_reader_ends_with_a_signal(good, tmp_path):
    fifo = tmp_path / "out.logr"
    os.mkfifo(fifo)
    # The C++ export opens its source, then waits for the FIFO's reader.
    code, err = interrupted_while_blocked(["convert", good, tmp_path / "out.log", "-q"],
                                          lambda pid: _has_open(pid, good))
    assert code == 130, err  # batch work interrupted
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
