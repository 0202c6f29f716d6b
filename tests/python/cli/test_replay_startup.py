"""`wiretape replay --pty` answers soon after it starts (issue 42,
replay_pty_ready_ms in docs/benchmarks.md): most of its start-up is
imports, and wiretape.faults, a fifth of them, is for --fault only."""

import json
import subprocess
import sys

import wiretape

_PROGRAM = """
import json, sys
from wiretape.cli import main
code = main(sys.argv[1:])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}), file=sys.stderr)
"""


def _recording(tmp_path):
    path = tmp_path / "ready.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial", capture="wire",
                                port_options="type=serial,device=/dev/ttyX") as writer:
        writer.write("open", 0, b"{}")
        writer.write("tx", 1_000_000, b"PING\n")
        writer.write("rx", 2_000_000, b"PONG\n")
    return path


def _modules_of_a_replay(tmp_path, *extra):
    done = subprocess.run([sys.executable, "-c", _PROGRAM, "replay", str(_recording(tmp_path)),
                           "--pty", str(tmp_path / "link"), "--timing", "none", "-q", *extra,
                           "--", sys.executable, "-c", "pass"],
                          capture_output=True, text=True, timeout=60)
    report = json.loads(done.stderr.strip().splitlines()[-1])
    return report["code"], set(report["modules"]), done.stderr


def test_a_replay_without_faults_does_not_import_the_fault_campaigns(tmp_path):
    code, modules, err = _modules_of_a_replay(tmp_path)
    assert "wiretape.cli.run" in modules, err  # the replay did run
    assert not {m for m in modules if m == "wiretape.faults" or m.startswith("wiretape.faults.")}, \
        sorted(modules)


def test_a_fault_past_the_end_is_still_refused_before_the_replay(tmp_path):
    code, modules, err = _modules_of_a_replay(tmp_path, "--fault", "drop@rx:99")
    assert code == 2, err
    assert "rx:99" in err, err
