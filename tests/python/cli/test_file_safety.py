"""The files the commands read and write (issue 16, items 4-7 and 12):

* input and output the same file is refused, hard and symbolic links
  included, naming both paths (exit 3);
* a device as a session is refused at once (exit 3, "X is a character
  device, not a regular file"); so is a FIFO where a regular file is needed
  (replay, a flexiport import, the session writer): never waited on. FIFOs
  as inputs of the reading commands and outputs written through are
  test_special_files.py's;
* a damaged input is used up to the damage, then exit 1, in every command;
  a file that cannot be opened (permission denied) is exit 3;
* the session writer writes regular files only: a FIFO, a symbolic link or
  a device node at its path is refused and left as it was.

Commands that might hang run in a subprocess with a generous deadline."""

import ctypes
import os
import stat
import subprocess
import sys

import pytest

import wiretape
from wiretape import _core, cli
from wiretape import session
from wiretape.tools.convert import convert

# A command that hangs fails the test here instead of hanging the suite.
DEADLINE_S = 60

SESSION = [
    ("open", 0, b"{}"),
    ("tx", 1_000_000, b"PING\n"),
    ("rx", 2_000_000, b"PONG\n"),
    ("close", 3_000_000, b""),
]

OUTPUT_FORMATS = ["wiretape", "jsonl", "pcapng", "mcap", "flexiport"]
SUFFIX = {"wiretape": ".wtape", "jsonl": ".jsonl", "pcapng": ".pcapng", "mcap": ".mcap",
          "flexiport": ".log"}


def run_in_process(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def run_cli(*argv, cwd=None, preexec_fn=None):
    """The command in a child process: (exit code, stderr)."""
    result = subprocess.run([sys.executable, "-m", "wiretape.cli", *map(str, argv)],
                            capture_output=True, text=True, timeout=DEADLINE_S, cwd=cwd,
                            preexec_fn=preexec_fn, stdin=subprocess.DEVNULL)
    return result.returncode, result.stderr


def error_line(err):
    lines = [line for line in err.splitlines() if "error:" in line]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def good(session_file):
    return session_file(SESSION, name="good.wtape")


def snapshot(path):
    """What is at `path`: its type and, for a regular file, its bytes."""
    info = os.lstat(path)
    content = open(path, "rb").read() if stat.S_ISREG(info.st_mode) else None
    return stat.S_IFMT(info.st_mode), info.st_ino, content


# --- 4: the same file as input and output ------------------------------------------


@pytest.mark.parametrize("fmt", ["wiretape", "jsonl", "pcapng", "mcap"])
def test_convert_onto_its_own_input_is_refused(capsys, good, fmt):
    before = snapshot(good)
    code, _, err = run_in_process(capsys, "convert", good, good, "--to", fmt)
    assert code == 3
    line = error_line(err)
    assert line.count(str(good)) == 2 and "same file" in line
    assert snapshot(good) == before


@pytest.mark.parametrize("link", ["hard", "symbolic"])
def test_convert_sees_the_input_through_links(capsys, good, tmp_path, link):
    other = tmp_path / "other.wtape"
    if link == "hard":
        os.link(good, other)
        src, dst = good, other
    else:
        os.symlink(good, other)
        src, dst = other, good  # read through the link, write the file itself
    before = snapshot(good)
    code, _, err = run_in_process(capsys, "convert", src, dst, "--to", "jsonl")
    assert code == 3
    line = error_line(err)
    assert str(src) in line and str(dst) in line and "same file" in line
    assert snapshot(good) == before


def test_convert_of_a_flexiport_log_onto_itself_is_refused(capsys, good, tmp_path):
    prefix = str(tmp_path / "log.log")
    _core.export_flexiport(str(good), prefix)
    before = [snapshot(prefix + suffix) for suffix in "rw"]
    code, _, err = run_in_process(capsys, "convert", prefix, prefix, "--to", "flexiport")
    assert code == 3
    assert "same file" in error_line(err)
    assert [snapshot(prefix + suffix) for suffix in "rw"] == before


def test_convert_api_refuses_the_same_file(good):
    with pytest.raises(session.FileRefused, match="same file"):
        convert(good, good, to_format="jsonl")


@pytest.mark.parametrize("export", ["write_pcapng", "write_mcap"])
def test_the_export_functions_refuse_the_same_file(good, export):
    from wiretape import exports

    before = snapshot(good)
    with pytest.raises(session.FileRefused, match="same file"):
        getattr(exports, export)(good, good)
    assert snapshot(good) == before


def test_export_flexiport_onto_its_own_input_is_refused(good, tmp_path):
    prefix = str(tmp_path / "log.log")
    _core.export_flexiport(str(good), prefix)
    before = snapshot(prefix + "r")
    with pytest.raises(wiretape.PortError, match="same file"):
        _core.export_flexiport(prefix, prefix)
    assert snapshot(prefix + "r") == before


@pytest.mark.parametrize("link", [None, "hard"])
def test_replay_recording_onto_its_own_input_is_refused(good, tmp_path, link):
    output = good
    if link:
        output = tmp_path / "alias.wtape"
        os.link(good, output)
    before = snapshot(good)
    code, err = run_cli("replay", good, "--listen", "127.0.0.1:0", "-o", output)
    assert code == 3
    line = error_line(err)
    assert str(good) in line and str(output) in line and "same file" in line
    assert snapshot(good) == before


@pytest.mark.parametrize("alias", ["same", "symbolic"])
def test_open_port_replay_logging_to_its_own_file_is_refused(good, tmp_path, alias):
    log = good
    if alias == "symbolic":
        log = tmp_path / "link.wtape"
        os.symlink(good, log)
        source, log = log, good  # the replay reads through the link
    else:
        source = good
    before = snapshot(good)
    with pytest.raises(wiretape.PortError) as raised:
        wiretape.open_port(f"type=replay,file={source},log={log}")
    assert "same file" in str(raised.value)
    assert str(source) in str(raised.value) and str(log) in str(raised.value)
    assert snapshot(good) == before


def test_record_with_a_replay_device_onto_its_file_is_refused(good):
    before = snapshot(good)
    code, err = run_cli("record", "--device", f"type=replay,file={good}", "--listen",
                        "127.0.0.1:0", "-o", good, "--duration", "5", "-q")
    assert code == 3
    assert "same file" in error_line(err)
    assert snapshot(good) == before


# --- 5 and 12: FIFOs where regular files are needed, devices -------------------------------


@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "fifo.wtape"
    os.mkfifo(path)
    return path


def _fifo_commands():
    inputs = [
        ("replay", ["replay", "{fifo}", "--listen", "127.0.0.1:0"]),
        ("flexiport-import", ["show", "{tmp}/pair.log"]),
    ]
    outputs = [
        ("convert-to-wiretape", ["convert", "{good}", "{fifo}", "--to", "wiretape"]),
        ("replay-o", ["replay", "{good}", "--listen", "127.0.0.1:0", "-o", "{fifo}"]),
        ("record-o", ["record", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                      "-o", "{fifo}", "-q"]),
        ("serve-o", ["serve", "--device", "type=loopback", "--listen", "127.0.0.1:0",
                     "-o", "{fifo}", "-q"]),
    ]
    return inputs + outputs


@pytest.mark.parametrize("name,argv", _fifo_commands(), ids=[c[0] for c in _fifo_commands()])
def test_a_fifo_is_refused_at_once_not_waited_on(good, fifo, tmp_path, name, argv):
    if name == "flexiport-import":
        os.mkfifo(tmp_path / "pair.logr")
        (tmp_path / "pair.logw").write_bytes(b"")
    values = {"fifo": fifo, "good": good, "tmp": tmp_path}
    code, err = run_cli(*[arg.format(**values) for arg in argv])
    assert code == 3, err
    assert "is a FIFO, not a regular file" in error_line(err)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_character_device_is_not_called_an_empty_file(capsys):
    code, _, err = run_in_process(capsys, "verify", "/dev/zero")
    assert code == 3
    assert "/dev/zero is a character device, not a regular file" in error_line(err)
    with pytest.raises(wiretape.PortError, match="character device, not a regular file"):
        wiretape.SessionReader("/dev/zero")


def test_a_file_that_cannot_be_opened_is_an_os_error_not_damage(tmp_path):
    with pytest.raises(wiretape.PortError, match="missing.wtape: cannot open: No such file"):
        wiretape.SessionReader(tmp_path / "missing.wtape")


def test_a_really_empty_file_is_still_an_empty_file(capsys, tmp_path):
    empty = tmp_path / "empty.wtape"
    empty.write_bytes(b"")
    code, _, err = run_in_process(capsys, "show", empty)
    assert code == 1
    assert "empty file" in err


# --- 6: one rule for damaged input -------------------------------------------------------


def _damage(data, how):
    if how == "truncated":
        return data[:-3]
    if how == "flipped-crc":
        return data[:-1] + bytes([data[-1] ^ 0xFF])
    if how == "after-last-payload":
        return data + b"\x05\x00\x00\x00\x01"  # a record header cut short
    raise ValueError(how)


DAMAGE_COMMANDS = {
    "show": ["show", "{f}"],
    "stats": ["stats", "{f}"],
    "verify": ["verify", "{f}"],
    "diff-a": ["diff", "{f}", "{good}"],
    "diff-b": ["diff", "{good}", "{f}"],
    **{f"convert-{fmt}": ["convert", "{f}", "{tmp}/out" + SUFFIX[fmt]] for fmt in OUTPUT_FORMATS},
}


@pytest.mark.parametrize("how", ["truncated", "flipped-crc", "after-last-payload"])
@pytest.mark.parametrize("command", sorted(DAMAGE_COMMANDS))
def test_a_damaged_session_exits_1_in_every_command(capsys, good, tmp_path, command, how):
    damaged = tmp_path / "damaged.wtape"
    damaged.write_bytes(_damage(good.read_bytes(), how))
    argv = [arg.format(f=damaged, good=good, tmp=tmp_path) for arg in DAMAGE_COMMANDS[command]]
    code, out, err = run_in_process(capsys, *argv)
    assert code == 1, (out, err)
    assert "Traceback" not in err


# The child's exit status when it could not give up the capabilities.
_CANNOT_DROP = 99


def _without_file_permission_override():
    """As root, permission bits do not stop reading: the child drops the
    capabilities that skip them (CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH) from
    its bounding set before it runs the command, so that it is refused like
    any other user."""
    if os.geteuid() != 0:
        return None

    def drop():
        libc = ctypes.CDLL(None, use_errno=True)
        pr_capbset_drop = 24
        for capability in (1, 2):  # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH
            if libc.prctl(pr_capbset_drop, capability, 0, 0, 0) != 0:
                os._exit(_CANNOT_DROP)

    return drop


@pytest.mark.parametrize("command", sorted(DAMAGE_COMMANDS))
def test_an_unreadable_session_is_a_runtime_error_in_every_command(good, tmp_path, command):
    unreadable = tmp_path / "unreadable.wtape"
    unreadable.write_bytes(good.read_bytes())
    unreadable.chmod(0)
    argv = [arg.format(f=unreadable, good=good, tmp=tmp_path)
            for arg in DAMAGE_COMMANDS[command]]
    code, err = run_cli(*argv, preexec_fn=_without_file_permission_override())
    if code == _CANNOT_DROP:
        pytest.skip("cannot make a file unreadable for root here")
    assert code == 3, err
    assert "Permission denied" in error_line(err)


@pytest.mark.parametrize("fmt", ["pcapng", "mcap"])
def test_an_export_of_a_damaged_session_keeps_what_came_before(capsys, good, tmp_path, fmt):
    damaged = tmp_path / "damaged.wtape"
    damaged.write_bytes(_damage(good.read_bytes(), "after-last-payload"))
    out = tmp_path / ("out" + SUFFIX[fmt])
    code, _, _ = run_in_process(capsys, "convert", damaged, out)
    assert code == 1
    assert out.stat().st_size > 0
    assert not (tmp_path / (out.name + ".partial")).exists()


# --- 7: the session writer writes regular files ----------------------------------------------


def _device_node(path):
    """A character device like /dev/null, made where the test may lose it."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, AttributeError):
        pytest.skip("cannot make a device node here (not root)")
    return path


@pytest.fixture
def target(tmp_path):
    """A file a symbolic link points to: it must keep its bytes."""
    path = tmp_path / "target.bin"
    path.write_bytes(b"keep me")
    return path


def make_node(path, what, target):
    """What is not a regular file, at `path`: a FIFO, a symbolic link to
    `target`, or a character device."""
    if what == "fifo":
        os.mkfifo(path)
    elif what == "symlink":
        os.symlink(target, path)
    else:
        _device_node(path)


@pytest.mark.parametrize("what", ["fifo", "symlink", "device"])
def test_convert_to_a_session_writes_regular_files_only(good, tmp_path, target, what):
    # Exports write through instead: test_special_files.py.
    path = node = tmp_path / "out.wtape"
    make_node(node, what, target)
    before = snapshot(node)
    code, err = run_cli("convert", good, path, "--to", "wiretape")
    assert code == 3, err
    line = error_line(err)
    assert f"{node} is a " in line and "not a regular file" in line
    assert snapshot(node) == before
    assert target.read_bytes() == b"keep me"


@pytest.mark.parametrize("what", ["fifo", "symlink"])
def test_a_partial_file_of_the_wrong_kind_is_refused_too(good, tmp_path, target, what):
    path = tmp_path / "out.pcapng"
    make_node(tmp_path / "out.pcapng.partial", what, target)
    code, err = run_cli("convert", good, path)
    assert code == 3, err
    assert "not a regular file" in error_line(err)
    assert target.read_bytes() == b"keep me"
    assert not path.exists()


def test_an_existing_regular_output_is_replaced(capsys, good, tmp_path):
    for fmt in ["wiretape", "jsonl", "pcapng", "mcap"]:
        out = tmp_path / ("out" + SUFFIX[fmt])
        out.write_bytes(b"x" * 100_000)
        code, _, err = run_in_process(capsys, "convert", good, out)
        assert code == 0, err
        assert out.stat().st_size < 100_000


def test_dev_null_is_written_through_never_replaced(tmp_path):
    session.check_output("/dev/null")
    assert session.is_written_through("/dev/null")
    with session.open_output("/dev/null") as out:
        out.write(b"discarded")
    with pytest.raises(session.FileRefused, match="/dev/null is a character device"):
        session.check_regular_output("/dev/null")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    with pytest.raises(session.FileRefused, match=f"{tmp_path} is a directory"):
        session.open_output(tmp_path)


@pytest.mark.parametrize("what", ["fifo", "symlink", "device"])
def test_the_session_writer_writes_regular_files_only(tmp_path, target, what):
    path = tmp_path / "out.wtape"
    make_node(path, what, target)
    before = snapshot(path)
    code = ("import wiretape\n"
            f"try:\n    wiretape.SessionWriter({str(path)!r})\n"
            "except wiretape.PortError as error:\n    print(error)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=DEADLINE_S)
    assert "not a regular file" in result.stdout, result
    assert snapshot(path) == before
    assert target.read_bytes() == b"keep me"
