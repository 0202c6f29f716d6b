"""`wiretape replay --pty` answers soon after it starts
(replay_pty_ready_ms in docs/benchmarks.md): most of its start-up is
imports and the parser, so what a replay does not use is not imported
(wiretape.faults, pyserial and the URL handlers, difflib) and only the
command run gets a parser."""

import json
import os
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


def test_a_replay_imports_neither_pyserial_nor_the_url_handlers_nor_difflib(tmp_path):
    code, modules, err = _modules_of_a_replay(tmp_path)
    assert "wiretape.cli.run" in modules, err
    assert not {m for m in modules if m == "serial" or m.startswith(("serial.", "wiretape.urlhandler"))}, \
        sorted(modules)
    assert "difflib" not in modules, sorted(modules)  # a usage error's hint needs it, nothing else


def test_a_replay_with_a_command_imports_no_dataclasses(tmp_path):
    # dataclasses imports inspect, ast and dis: 7 ms of the start-up of
    # every -- CMD (replay_as_overhead_ratio, docs/benchmarks.md).
    code, modules, err = _modules_of_a_replay(tmp_path)
    assert "wiretape.redirect" in modules, err  # CMD was run redirected
    assert not {"dataclasses", "inspect"} & modules, sorted(modules)


def test_a_replay_with_a_command_imports_neither_tempfile_nor_shutil(tmp_path):
    # shutil imports bz2 and lzma: 4 ms of every -- CMD's start-up. argparse
    # imports it for the help's width, tempfile at its top.
    code, modules, err = _modules_of_a_replay(tmp_path)
    assert "wiretape.redirect" in modules, err  # CMD was run redirected
    # (json: the report of _PROGRAM imports it)
    assert not {"tempfile", "shutil", "bz2", "lzma", "ctypes"} & modules, sorted(modules)


_PRIVATE_FILES = """
import json, os, stat, sys
from wiretape import redirect
folder = redirect.make_private_folder("wiretape-lines-")
path = redirect.make_private_file("wiretape-redirect-")
report = {"folder": folder, "file": path, "tempfile": "tempfile" in sys.modules,
          "folder_mode": stat.S_IMODE(os.stat(folder).st_mode),
          "file_mode": stat.S_IMODE(os.stat(path).st_mode), "file_size": os.path.getsize(path)}
os.unlink(path)
os.rmdir(folder)
import tempfile
report["gettempdir"] = tempfile.gettempdir()
print(json.dumps(report))
"""


def _private_files(tmp_path, **environment):
    env = {key: value for key, value in os.environ.items() if key not in ("TMPDIR", "TEMP", "TMP")}
    env.update(environment)
    done = subprocess.run([sys.executable, "-c", _PRIVATE_FILES], capture_output=True,
                          text=True, timeout=60, env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_a_commands_private_files_are_where_and_as_tempfile_makes_them(tmp_path):
    chosen = tmp_path / "chosen"
    chosen.mkdir()
    report = _private_files(tmp_path, TMPDIR=str(chosen))
    assert not report["tempfile"]  # made without importing it
    assert os.path.dirname(report["folder"]) == str(chosen) == report["gettempdir"]
    assert os.path.dirname(report["file"]) == str(chosen)
    assert os.path.basename(report["folder"]).startswith("wiretape-lines-")
    assert os.path.basename(report["file"]).startswith("wiretape-redirect-")
    assert (report["folder_mode"], report["file_mode"], report["file_size"]) == (0o700, 0o600, 0)


def test_a_temporary_folder_that_cannot_be_used_is_passed_over_as_tempfile_does(tmp_path):
    report = _private_files(tmp_path, TMPDIR=str(tmp_path / "missing"), TEMP=str(tmp_path))
    assert os.path.dirname(report["folder"]) == str(tmp_path) == report["gettempdir"]


def test_import_wiretape_registers_the_url_handlers_only_once_pyserial_is_imported():
    program = ("import sys, wiretape\n"
               "before = 'serial' in sys.modules or 'wiretape.urlhandler' in sys.modules\n"
               "import serial\n"
               "print(before, 'wiretape.urlhandler' in serial.protocol_handler_packages,\n"
               "      wiretape.SessionReader.__module__)")
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                          timeout=60)
    assert done.stdout.split() == ["False", "True", "wiretape._core"], done.stderr


def test_the_command_run_is_the_only_one_whose_parser_is_made(monkeypatch):
    import importlib

    from wiretape.cli.parser import build_parser

    cli_main = importlib.import_module("wiretape.cli.main")  # the module, not main()

    built = []

    def recording_build_parser(only=None):
        built.append(only)
        return build_parser(only)

    monkeypatch.setattr(cli_main, "build_parser", recording_build_parser)
    assert cli_main.main(["replay", "--help"]) == 0
    assert cli_main.main(["shwo"]) == 2  # a mistyped command: every command is declared
    assert cli_main.main(["--help", "replay"]) == 0  # wiretape's own --help lists them all
    assert built == ["replay", None, None]


def test_each_commands_help_is_the_same_when_only_its_parser_is_made(capsys):
    from wiretape.cli.parser import COMMAND_NAMES, build_parser

    every = build_parser()
    commands = next(action for action in every._actions if hasattr(action, "choices")
                    and isinstance(action.choices, dict)).choices
    assert tuple(commands) == COMMAND_NAMES
    for name in COMMAND_NAMES:
        alone = build_parser(only=name)
        sub = next(action for action in alone._actions if hasattr(action, "choices")
                   and isinstance(action.choices, dict)).choices[name]
        assert sub.format_help() == commands[name].format_help(), name


def test_the_console_script_runs_the_command_line_with_the_start_up_frozen():
    # pyproject.toml's `wiretape` script is wiretape._entry:main: the
    # command line's imports made with the collector off, then frozen out
    # of its way (replay_as_overhead_ratio); the command runs with
    # collection on.
    import pathlib
    import tomllib

    pyproject = pathlib.Path(__file__).resolve().parents[3] / "pyproject.toml"
    scripts = tomllib.loads(pyproject.read_text())["project"]["scripts"]
    assert scripts["wiretape"] == "wiretape._entry:main"
    program = ("import gc, importlib, json\n"
               "cli_main = importlib.import_module('wiretape.cli.main')  # the module\n"
               "seen = {}\n"
               "def main():\n"
               "    seen.update(enabled=gc.isenabled(), frozen=gc.get_freeze_count())\n"
               "    return 7\n"
               "cli_main.main = main\n"
               "from wiretape._entry import main as entry\n"
               "code = entry()\n"
               "print(json.dumps(dict(seen, code=code, enabled_after=gc.isenabled())))\n")
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                          timeout=60)
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["code"] == 7 and report["enabled"] and report["enabled_after"], report
    assert report["frozen"] > 1000, report  # the CLI's modules, not a handful
