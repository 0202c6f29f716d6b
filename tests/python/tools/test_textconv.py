"""``git diff`` of recordings through the documented textconv
(``wiretape show --textconv``, docs/cli.md): only real changes show."""

import shlex
import shutil
import subprocess
import sys

import pytest

import wiretape
from wiretape import cli
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
