"""`wiretape demo`: records the simulated URG-04LX, replays without it, and
says whether both agree."""
import time

from wiretape import demo


def test_demo_records_replays_and_agrees(hokuyo_scan, repo, monkeypatch, capsys):
    monkeypatch.setenv("WIRETAPE_BIN_DIR", str(hokuyo_scan.parent))
    started = time.monotonic()
    assert demo.run(repo) == 0
    elapsed = time.monotonic() - started
    out = capsys.readouterr().out
    assert "agree: 3 scans" in out
    assert "is caught" in out
    assert (repo / "build" / "demo" / "urg04lx-demo.wtape").stat().st_size > 0
    assert elapsed < 60


def test_demo_finds_the_repo_from_the_current_directory(repo, monkeypatch, tmp_path):
    monkeypatch.chdir(repo / "examples" / "hokuyo")
    assert demo.find_repo() == repo


def test_demo_without_the_program_says_so(repo, monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("WIRETAPE_BIN_DIR", str(tmp_path))
    assert demo.run(repo) == 3
    assert "hokuyo-scan is not built" in capsys.readouterr().err
