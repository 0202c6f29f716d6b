"""`wiretape demo`: records the simulated URG-04LX, replays without it, and
says whether both agree."""
import json
import subprocess
import time

import pytest

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


@pytest.mark.parametrize("method", ["cli", "bridge", "library"])
def test_each_way_of_recording_replays_the_same_scans(method, hokuyo_scan, repo, tmp_path):
    proxy = None if method == "library" else method
    recording = tmp_path / "scan.wtape"
    args = ["--json", "--mode", "md", "--scans", "2", "--cluster", "8"]
    with demo.Simulator(repo, "--model", "urg04lx", "--pty", str(tmp_path / "sim")) as sim:
        live, how = demo.record_scan(hokuyo_scan, sim, recording, args, tmp_path, proxy)
    assert live.returncode == 0, live.stderr
    assert {"cli": "wiretape record", "bridge": "wiretape.bridge", "library": "log="}[method] in how
    replayed = subprocess.run([str(hokuyo_scan), "--port",
                               f"type=replay,file={recording},timing=none", *args],
                              capture_output=True, text=True, timeout=60)
    assert replayed.returncode == 0, replayed.stderr
    assert demo.parse_scans(replayed) == demo.parse_scans(live)
    assert len(demo.parse_scans(live)) == 2
    assert all(len(s["ranges"]) == 86 for s in map(json.loads, live.stdout.splitlines()))
