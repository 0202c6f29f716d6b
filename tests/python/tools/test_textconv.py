"""``git diff`` of recordings through the documented textconv
(``wiretape show --textconv``, docs/cli.md): only real changes show."""

import shlex
import shutil
import subprocess
import sys

import pytest

import wiretape
from wiretape import _core, cli
from wiretape.tools.textconv import textconv

RECORDS = [
    (0, "open", b""),
    (1_000, "tx", b"VV\n"),
    (2_000_000, "rx", b"VV\n00P\nVEND:Hokuyo\n\n"),
    (3_000_000, "tx", b"GD0000076801\n"),
    (4_000_000, "rx", b"GD0000076801\n00P\nabcdefgh\n\n"),
    (5_000_000, "close", b""),
]


def record(path, records, start_utc, host):
    with wiretape.SessionWriter(str(path), port_options="type=tcp,host=10.0.0.5,port=10940",
                                port_type="tcp", capture="wire", start_utc=start_utc,
                                host=host) as writer:
        for t_ns, kind, data in records:
            writer.write(kind, t_ns, data)


def changed_lines(diff_text):
    return [line for line in diff_text.splitlines()
            if line[:1] in "+-" and not line.startswith(("+++", "---"))]


@pytest.fixture
def repository(tmp_path):
    if shutil.which("git") is None:
        pytest.skip("SKIPPED LOUDLY: git is not installed; the textconv is not tested")
    repo = tmp_path / "repo"
    repo.mkdir()

    def git(*argv):
        result = subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@example.org",
                                 *argv], cwd=repo, capture_output=True, text=True, timeout=60)
        assert result.returncode == 0, result.stderr
        return result.stdout

    git("init", "-q")
    (repo / ".gitattributes").write_text("*.wtape -text merge=binary diff=wtape\n")
    return repo, git


def configure(git, *options):
    command = " ".join(shlex.quote(part) for part in
                       (sys.executable, "-m", "wiretape.cli", "show", *options))
    git("config", "diff.wtape.textconv", command)


def two_recordings(repo, git):
    """The same run recorded twice: other start time and host, one byte of
    one reply different. Returns the diff of the second against the first."""
    record(repo / "scan.wtape", RECORDS, "2026-11-23T10:00:00.000001Z", "bench-a")
    git("add", ".")
    git("commit", "-q", "-m", "first")
    changed = list(RECORDS)
    changed[4] = (4_000_000, "rx", b"GD0000076801\n00P\nabcdXfgh\n\n")
    record(repo / "scan.wtape", changed, "2026-11-24T11:30:00.5Z", "bench-b")
    return git("diff")


def test_git_diff_shows_only_the_changed_byte_s_line(repository):
    repo, git = repository
    configure(git, "--textconv", "--no-start")
    diff = two_recordings(repo, git)
    lines = changed_lines(diff)
    assert len(lines) == 2, diff
    assert lines[0].startswith("-") and "abcdefgh" in lines[0], diff
    assert lines[1].startswith("+") and "abcdXfgh" in lines[1], diff
    assert "/tmp" not in diff and "bench-" not in diff


def test_without_no_start_the_start_and_host_show_but_never_the_temporary_name(repository):
    repo, git = repository
    configure(git, "--textconv")
    diff = two_recordings(repo, git)
    lines = changed_lines(diff)
    started = [line for line in lines if "started" in line]
    assert len(started) == 2 and "bench-a" in started[0] and "bench-b" in started[1], diff
    assert len(lines) == 4, diff
    assert "session " not in diff  # no file name: git's temporary copy would differ


def test_textconv_names_no_file_and_shows_damage_as_a_line(tmp_path, capsys):
    path = tmp_path / "scan.wtape"
    record(path, RECORDS, "2026-11-23T10:00:00Z", "bench-a")
    blob = path.read_bytes()
    path.write_bytes(blob[:-3])  # the last record cut short
    out = tmp_path / "out.txt"
    with open(out, "w") as stream:
        count, damage = textconv(path, start=False, out=stream)
    text = out.read_text()
    assert damage is not None and count == len(RECORDS) - 1
    assert str(path) not in text and "DAMAGED" in text and "started" not in text
    code = cli.main(["show", "--textconv", str(path)])
    printed = capsys.readouterr().out
    assert code == 0 and "DAMAGED" in printed and str(path) not in printed


def test_no_times_hides_the_small_time_differences_of_a_run_recorded_again(repository):
    repo, git = repository
    configure(git, "--textconv", "--no-start", "--no-times")
    record(repo / "scan.wtape", RECORDS, "2026-11-23T10:00:00Z", "bench-a")
    git("add", ".")
    git("commit", "-q", "-m", "first")
    again = [(t_ns + 137_000 * index, kind, data) for index, (t_ns, kind, data) in enumerate(RECORDS)]
    again[2] = (again[2][0], "rx", b"VV\n00P\nVEND:Hokuy0\n\n")
    record(repo / "scan.wtape", again, "2026-11-23T10:05:00Z", "bench-a")
    lines = changed_lines(git("diff"))
    assert len(lines) == 2 and "Hokuyo" in lines[0] and "Hokuy0" in lines[1], lines

    configure(git, "--textconv", "--no-start")  # times kept: every record with a new time shows
    assert len(changed_lines(git("diff"))) == 2 * (len(RECORDS) - 1)


# A long reply (a scan: 3,369 bytes) whose byte 2,000 differs between two runs.
LONG_REPLY = bytes(((i * 7) % 64) + 48 for i in range(3_369))
FLIPPED_AT = 2_000


def long_records(reply):
    return [(0, "open", b""), (1_000, "tx", b"GD0000076801\n"), (2_000, "rx", reply),
            (3_000, "close", b"")]


def textconv_text(path, **options):
    from io import StringIO
    out = StringIO()
    textconv(path, out=out, **options)
    return out.getvalue()


def flipped(reply, at):
    return reply[:at] + bytes([reply[at] ^ 0x01]) + reply[at + 1:]


@pytest.mark.parametrize("times", [True, False])
def test_every_byte_of_a_long_payload_is_shown_and_a_flip_changes_its_line(tmp_path, times):
    # Before, textconv cut payloads at 64 bytes: the flip showed nothing.
    first, second = tmp_path / "first.wtape", tmp_path / "second.wtape"
    record(first, long_records(LONG_REPLY), "2026-11-23T10:00:00Z", "bench-a")
    record(second, long_records(flipped(LONG_REPLY, FLIPPED_AT)), "2026-11-23T10:00:00Z",
           "bench-a")
    before = textconv_text(first, start=False, times=times).splitlines()
    after = textconv_text(second, start=False, times=times).splitlines()
    assert len(before) == len(after)
    differing = [k for k, (a, b) in enumerate(zip(before, after)) if a != b]
    assert len(differing) == 1, differing
    # The line that differs is the one holding the flipped byte, and it
    # holds it: 64 bytes a line, the first on the record's own line.
    reply_line = next(k for k, line in enumerate(before) if "<- " in line and "3369 B" in line)
    assert differing[0] == reply_line + FLIPPED_AT // 64
    chunk = FLIPPED_AT // 64 * 64
    assert before[differing[0]].strip() == _core.escape_bytes(LONG_REPLY[chunk:chunk + 64], 64)
    assert after[differing[0]].strip() == _core.escape_bytes(
        flipped(LONG_REPLY, FLIPPED_AT)[chunk:chunk + 64], 64)
    # Every byte, in order: the reply's lines put together are the whole reply.
    shown = before[reply_line].split("<- ", 1)[1] + "".join(
        line.strip() for line in before[reply_line + 1:reply_line + (3_369 + 63) // 64])
    assert shown == _core.escape_bytes(LONG_REPLY, len(LONG_REPLY))
    # The lines that go on are indented under the payload's first byte.
    column = before[reply_line].index("<- ") + 3
    assert before[reply_line + 1].index(before[reply_line + 1].strip()) == column


def test_git_diff_shows_a_flipped_byte_of_a_long_reply(repository):
    repo, git = repository
    configure(git, "--textconv", "--no-start")
    record(repo / "scan.wtape", long_records(LONG_REPLY), "2026-11-23T10:00:00Z", "bench-a")
    git("add", ".")
    git("commit", "-q", "-m", "first")
    record(repo / "scan.wtape", long_records(flipped(LONG_REPLY, FLIPPED_AT)),
           "2026-11-24T10:00:00Z", "bench-b")
    lines = changed_lines(git("diff"))
    assert len(lines) == 2, lines
    assert lines[0].startswith("-") and lines[1].startswith("+")


def test_show_itself_still_cuts_long_payloads(tmp_path):
    from io import StringIO
    from wiretape.tools.show import show
    path = tmp_path / "s.wtape"
    record(path, long_records(LONG_REPLY), "2026-11-23T10:00:00Z", "bench-a")
    out = StringIO()
    show(path, out=out)
    assert "(+3305 bytes)" in out.getvalue()
