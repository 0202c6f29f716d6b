"""`wiretape show` of a 10 MB session within 0.5 s (issue 26; bench/run.py
measures it): most of a run was imports show does not use. These tests hold
show to importing neither rich (show writes its own colours) nor the
importers (a session is recognised by its magic before them)."""

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


def _modules_of_a_run(*argv):
    done = subprocess.run([sys.executable, "-c", _PROGRAM, *argv], capture_output=True,
                          text=True, timeout=60)
    report = json.loads(done.stderr.strip().splitlines()[-1])
    return report["code"], set(report["modules"]), done.stdout


def test_show_imports_neither_rich_nor_the_importers(tmp_path):
    path = tmp_path / "s.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        writer.write("tx", 1000, b"PING\n")
        writer.write("rx", 2000, b"PONG\n")
    code, modules, out = _modules_of_a_run("show", "--color", "always", str(path))
    assert code == 0 and "PONG" in out, out
    assert not {m for m in modules if m == "rich" or m.startswith("rich.")}, sorted(modules)
    assert "wiretape.tools.convert" not in modules
    assert "wiretape.tools.pcap_import" not in modules


def test_show_still_names_the_convert_command_for_a_capture(tmp_path):
    capture = tmp_path / "plc.pcap"
    capture.write_bytes(bytes.fromhex("d4c3b2a1020004000000000000000000ffff000001000000"))
    done = subprocess.run([sys.executable, "-m", "wiretape.cli", "show", str(capture)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "wiretape convert --from pcap" in done.stderr, done.stderr
