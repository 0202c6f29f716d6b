"""Every fenced code block of README.md, docs/*.md and examples/hokuyo/README.md
either runs here or is listed, with its reason, in examples.toml.

Blocks run in a sandbox: a temporary working directory holding what the
examples name (SANDBOX_FILES), with the devices they name played by the
Hokuyo simulator on a pty and the reader's driver by hokuyo-scan
(SUBSTITUTIONS, DRIVER, MYDRIVER). A `record`/`replay --pty` service runs
until the block's next service or its end, then gets its Ctrl-C; blocks that
only make sense in turn run as STORIES. All of it is declared once, here.

A new block needs nothing when it runs; else one line in examples.toml."""

import configparser
import json
import os
import pathlib
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import threading

import pytest

from devices import wait_until
from doc_examples import REPO, Block, all_blocks, load_manifest, masked

BUILD_BIN = REPO / "build" / "bin"
VENV_BIN = pathlib.Path(sys.executable).parent
RECORDING = "examples/hokuyo/recordings/urg04lx_gd.wtape"

# Files the examples name, copied from the repository under the names the
# docs use (sandbox name: repository path).
SANDBOX_FILES = {
    "scan.wtape": RECORDING,
    "run.wtape": RECORDING,
    "tests/recordings/scan.wtape": RECORDING,
    "plc.pcapng": "tests/data/pcap/tcp.pcap",
    "all.pcapng": "tests/data/pcap/multi.pcap",
    "tests/test_sensor.jsonl": "tests/data/reserial/test_device_talk.jsonl",
}

# Stand-ins declared once: (text in the docs, text in the sandbox). A device
# path becomes the pty of a Hokuyo simulator ({scanner}); the reader's own
# driver becomes hokuyo-scan on the port it is given.
SUBSTITUTIONS = [
    ("/dev/ttyACM0", "{scanner}"),
    ("/dev/ttyUSB0", "{scanner}"),
    ("--test test_id", "--test test_text"),
    ("/dev/serial/by-id/usb-Hokuyo...", "{scanner}"),
    ("/tmp/", "{root}/"),
    # 5 cases of the same campaign instead of 20: seconds, not half a minute.
    ("budget=20,", "budget=5,"),
]

DRIVER = """#!/bin/sh
# The docs' ./driver [PORT] [--OPTIONS]: hokuyo-scan reads one scan from PORT,
# else from the device the docs name ({scanner}); options are ignored.
port={scanner}
case "${1:-}" in ""|-*) ;; *) port=$1 ;; esac
exec hokuyo-scan --port "type=serial,device=$port,timeout=1" --json >/dev/null
"""

FRAGMENT_PROGRAM = """#include <wiretape/wiretape.hpp>

#include <chrono>
#include <string>

using namespace std::chrono_literals;

int main() {
BODY
}
"""

# A command that serves until Ctrl-C: record or replay on a pty, no -- CMD.
SERVICE = re.compile(r"^wiretape (record|replay) (?!.* -- ).*--pty (?P<pty>\S+)", re.M)

# A block that is one option string (type=KIND,KEY=VALUE,...).
OPTION_STRING = re.compile(r"type=\w+(,[\w.]+=[^,\s]*)*")

# Blocks that only make sense in turn, as a reader follows the page: each
# story runs its blocks in order in one sandbox. A Python block whose first
# line is "# PATH" is the file the reader writes there; a block of bare
# paths names files the story must have made.
STORIES = {
    "testing.md: record the scanner's test once, then replay it": [
        ("docs/testing.md", "# tests/test_scanner.py"),
        ("docs/testing.md", "pytest tests/test_scanner.py --wiretape-record=once \\"),
        ("docs/testing.md", "tests/recordings/test_scanner/test_reads_version.wtape"),
        ("docs/testing.md", "pytest                                    # replays: no device needed"),
    ],
    "hokuyo.md: record your scanner for a bug report, then replay it": [
        ("docs/hokuyo.md", "wiretape record --device type=serial,device=/dev/ttyACM0,baud=115200 \\"),
        ("docs/hokuyo.md", 'hokuyo-scan --port "type=replay,file=my-urg.wtape" --json --scans 10'),
    ],
}

# The reader's own driver in testing.md (from mydriver import Scanner).
MYDRIVER = """class Scanner:
    \"\"\"A SCIP 2.0 scanner on a port that reads and writes bytes.\"\"\"

    def __init__(self, port):
        self.port = port

    def command(self, text):
        self.port.write(text.encode() + b"\\n")
        return self.port.read_until(b"\\n\\n").decode()

    def version(self):
        self.command("SCIP2.0")
        product = next(line for line in self.command("VV").splitlines()
                       if line.startswith("PROD:"))
        return product[product.index("URG"):]
"""

# Tools a fresh machine may lack, declared once: (what in a block's command
# needs one, the tool, why). A block needing a tool that is not on the
# sandbox's PATH is skipped, loudly, naming the tool; every other test that
# needs one skips the same way.
NEEDED_TOOLS = [
    (re.compile(r"\bwiretape convert\s+(?:\S+\.(?:pcapng|pcap|cap)(?:\s|$)|.*--from[ =]pcap\b)"),
     "tshark", "convert reads a capture with tshark (Debian: apt-get install tshark)"),
    (re.compile(r"(?:^|[|;&]\s*)tshark\b"), "tshark", "the block runs tshark"),
]


def require_tools(block, commands, sandbox):
    """Skips the block (SKIPPED LOUDLY, naming the tool) when one of
    `commands` needs a tool the sandbox's PATH lacks."""
    for command in commands:
        for pattern, tool, why in NEEDED_TOOLS:
            if pattern.search(command) and shutil.which(tool, path=sandbox.env["PATH"]) is None:
                pytest.skip(f"SKIPPED LOUDLY: {block.id} needs {tool}, which is not on PATH: "
                            f"{why}")


SHELL_LANGS = {"sh", "bash", "console", "shell"}
TIMEOUT_S = 60


def blocks_to_run():
    listed = load_manifest()
    in_stories = {key for steps in STORIES.values() for key in steps}
    return [block for block in all_blocks()
            if block.key not in listed and block.key not in in_stories]


def story_blocks(steps):
    blocks = {block.key: block for block in all_blocks()}
    missing = [key for key in steps if key not in blocks]
    assert not missing, f"STORIES names blocks that no longer exist: {missing}"
    return [blocks[key] for key in steps]


@pytest.mark.parametrize("name", list(STORIES))
def test_story(name, sandbox):
    for block in story_blocks(STORIES[name]):
        first = block.first_line
        if block.lang == "python" and re.fullmatch(r"# [\w./-]+\.py", first):
            path = sandbox.root / first[2:]
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(block.text)
        elif not block.lang:
            made = [line.strip() for line in block.text.splitlines() if line.strip()]
            absent = [path for path in made if not (sandbox.root / path).exists()]
            assert not absent, f"{block.id}: the story did not make {absent}"
        else:
            runner = runner_for(block)
            assert runner is not None, f"{block.id}: a story's block cannot run"
            runner(block, sandbox)


def test_every_block_is_run_or_listed():
    unrunnable = [f"{block.id} ({block.lang or 'no language'}): {block.first_line!r}"
                  for block in blocks_to_run() if runner_for(block) is None]
    assert not unrunnable, (
        "these blocks can neither run here nor are listed in "
        "tests/python/docs/examples.toml (add a line under the file's table: "
        "the block's first line = the reason):\n" + "\n".join(unrunnable))


def test_every_listed_block_exists():
    present = {block.key for block in all_blocks()}
    stale = [f"[{file}] {first_line!r}" for file, first_line in load_manifest()
             if (file, first_line) not in present]
    assert not stale, ("tests/python/docs/examples.toml lists blocks that no "
                       "longer exist (remove or update them):\n" + "\n".join(stale))


def runner_for(block):
    if block.lang in SHELL_LANGS:
        return run_shell
    if block.lang == "python":
        return run_python
    if block.lang == "cpp":
        return run_cpp_program
    if block.lang in ("json", "jsonl"):
        return check_json
    if block.lang == "yaml":
        return check_yaml
    if block.lang == "ini":
        return check_ini
    if not block.lang and all(OPTION_STRING.fullmatch(line.strip())
                              for line in block.text.strip().splitlines()):
        return check_option_strings
    return None


@pytest.mark.parametrize("block", [pytest.param(b, id=b.id) for b in blocks_to_run()])
def test_example(block, sandbox):
    runner = runner_for(block)
    if runner is None:
        pytest.fail(f"{block.id}: cannot run; see test_every_block_is_run_or_listed")
    runner(block, sandbox)


def require_hokuyo_scan():
    if not (BUILD_BIN / "hokuyo-scan").exists():
        pytest.skip(f"hokuyo-scan is not built ({BUILD_BIN}): it plays the docs' driver")


class Sandbox:
    def __init__(self, root: pathlib.Path):
        self.root = root
        self.scanner = root / "ttySCANNER"
        self._simulator = None
        for name, source in SANDBOX_FILES.items():
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(REPO / source, root / name)
        (root / "mydriver.py").write_text(MYDRIVER)
        driver = root / "driver"
        driver.write_text(DRIVER.replace("{scanner}", str(self.scanner)))
        driver.chmod(0o755)
        self.env = dict(os.environ,
                        PATH=os.pathsep.join([str(VENV_BIN), str(BUILD_BIN),
                                              os.environ.get("PATH", "")]),
                        PYTHONDONTWRITEBYTECODE="1", PYTHONPATH=str(root))

    def substitute(self, text: str) -> str:
        # Only when named (`pytest` in the sandbox would collect them). The
        # examples are a copy, so that no block writes into the repository.
        if "examples/" in text and not (self.root / "examples").exists():
            shutil.copytree(REPO / "examples", self.root / "examples",
                            ignore=shutil.ignore_patterns("__pycache__"))
        if "build/" in text and not (self.root / "build").exists():
            (self.root / "build").symlink_to(REPO / "build")
        for documented, here in SUBSTITUTIONS:
            text = text.replace(documented, here)
        text = text.replace("{root}", str(self.root))
        if "{scanner}" in text:
            self.start_scanner()
            text = text.replace("{scanner}", str(self.scanner))
        return text

    def start_scanner(self):
        if self._simulator is not None:
            return
        require_hokuyo_scan()
        self._simulator = subprocess.Popen(
            [sys.executable, str(REPO / "examples" / "hokuyo" / "sim"),
             "--model", "urg04lx", "--pty", str(self.scanner)],
            cwd=self.root, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            start_new_session=True)
        wait_until(lambda: self.scanner.exists() or self._simulator.poll() is not None,
                   what="the simulator's pty")
        if not self.scanner.exists():
            pytest.fail("the Hokuyo simulator did not start: "
                        + self._simulator.stderr.read().decode(errors="replace"))

    def run(self, argv, stdin=None):
        return subprocess.run(argv, cwd=self.root, env=self.env, input=stdin,
                              capture_output=True, text=True, timeout=TIMEOUT_S)

    def start_service(self, block, command, pty):
        """Starts COMMAND and returns once it announces its pty to clients
        (its link existing is not enough: the bridge may not watch it yet)."""
        child = subprocess.Popen(["bash", "-c", command], cwd=self.root, env=self.env,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                 text=True, start_new_session=True)
        child.output, child.ready = [], threading.Event()

        def read_output():
            for line in child.stdout:
                child.output.append(line)
                if "clients use pty" in line:
                    child.ready.set()

        child.reader = threading.Thread(target=read_output, daemon=True)
        child.reader.start()
        wait_until(lambda: child.ready.is_set() or child.poll() is not None,
                   deadline_s=TIMEOUT_S, what=f"{block.id}: the pty of {command!r}")
        if not child.ready.is_set():
            child.reader.join(TIMEOUT_S)
            pytest.fail(f"{block.id}: {command!r} ended (exit {child.wait()}) without "
                        f"serving {pty}:\n{''.join(child.output)}")
        return child

    def stop_service(self, block, child):
        if child is None:
            return
        os.killpg(child.pid, signal.SIGINT)  # the Ctrl-C the docs ask for
        child.wait(timeout=TIMEOUT_S)
        child.reader.join(TIMEOUT_S)
        assert child.returncode == 0, \
            f"{block.id}: {child.args[-1]!r} ended with {child.returncode}:\n{''.join(child.output)}"

    def close(self):
        if self._simulator is not None:
            os.killpg(self._simulator.pid, signal.SIGTERM)
            self._simulator.wait(timeout=TIMEOUT_S)
            self._simulator.stderr.close()


@pytest.fixture
def sandbox(tmp_path):
    box = Sandbox(tmp_path)
    yield box
    box.close()


def explain(block, result):
    return (f"{block.id} failed (exit {result.returncode}):\n{block.text}\n"
            f"--- stdout\n{result.stdout}\n--- stderr\n{result.stderr}")


def shell_script(text):
    """The commands of a shell block (prompts stripped) and the output it
    shows (the lines after a `$ ` command that are not commands)."""
    lines = text.splitlines()
    if not any(line.startswith("$ ") for line in lines):
        return text, None
    commands, shown, continued = [], [], False
    for line in lines:
        if line.startswith("$ ") or continued:
            command = line[2:] if line.startswith("$ ") else line
            commands.append(command)
            continued = command.rstrip().endswith("\\")
        else:
            shown.append(line)
    return "\n".join(commands) + "\n", "\n".join(shown)


def commands_of(script):
    """The commands of a shell script, continuation lines joined, comments
    and blank lines left out."""
    commands, pending = [], ""
    for line in script.splitlines():
        pending += line
        if pending.rstrip().endswith("\\"):
            pending = pending.rstrip()[:-1] + " "
            continue
        if pending.strip() and not pending.lstrip().startswith("#"):
            commands.append(pending.strip())
        pending = ""
    return commands


def run_shell(block, sandbox):
    if "git " in block.text:
        sandbox.run(["git", "init", "-q"])
    script, shown = shell_script(sandbox.substitute(block.text))
    require_tools(block, commands_of(script), sandbox)
    if "./driver" in script or "hokuyo-scan" in script:
        require_hokuyo_scan()
    if not any(SERVICE.search(command) for command in commands_of(script)):
        result = sandbox.run(["bash", "-euo", "pipefail", "-c", script])
        if shown:  # the output shown is the check: it may be an error's
            assert masked(shown) in masked(result.stdout + result.stderr), explain(block, result)
        else:
            assert result.returncode == 0, explain(block, result)
        return
    # A block with a service (record or replay on a pty, until Ctrl-C): each
    # command in turn; a service runs until the next one starts or the block
    # ends, then gets its Ctrl-C. The driver the docs leave to the reader is
    # hokuyo-scan on the service's pty, unless the block names a client.
    commands, service = commands_of(script), None
    try:
        for index, command in enumerate(commands):
            started = SERVICE.search(command)
            if not started:
                result = sandbox.run(["bash", "-euo", "pipefail", "-c", command])
                assert result.returncode == 0, explain(block, result)
                continue
            sandbox.stop_service(block, service)
            service = sandbox.start_service(block, command, pathlib.Path(started["pty"]))
            pty = started["pty"]
            if not any(pty in later for later in commands[index + 1:]
                       if not SERVICE.search(later)):
                require_hokuyo_scan()
                result = sandbox.run(["hokuyo-scan", "--port",
                                      f"type=serial,device={pty},timeout=10", "--json"])
                assert result.returncode == 0, explain(block, result)
    finally:
        sandbox.stop_service(block, service)


def run_python(block, sandbox):
    code = sandbox.substitute(block.text)
    if "./driver" in code:
        require_hokuyo_scan()
    if re.search(r"^def test_", code, re.M):
        (sandbox.root / "test_doc_block.py").write_text(code)
        argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                "test_doc_block.py"]
    else:
        (sandbox.root / "doc_block.py").write_text(code)
        argv = [sys.executable, "doc_block.py"]
    result = sandbox.run(argv)
    assert result.returncode == 0, explain(block, result)


def run_cpp_program(block, sandbox):
    compiler = shutil.which(os.environ.get("CXX", "c++"))
    library = REPO / "build" / "libwiretape.a"
    if compiler is None or not library.exists():
        pytest.skip(f"C++ examples need a C++ compiler and {library} (make)")
    source = sandbox.substitute(block.text)
    if not re.search(r"^int main\(", source, re.M):
        # A fragment of statements: it runs as the body of main, with the
        # public header included (fragments that need more are listed).
        source = FRAGMENT_PROGRAM.replace("BODY", textwrap.indent(source, "  "))
    (sandbox.root / "example.cpp").write_text(source)
    compiled = sandbox.run([compiler, "-std=c++17", f"-I{REPO / 'include'}",
                            "example.cpp", str(library), "-lzstd", "-pthread", "-o", "example"])
    assert compiled.returncode == 0, explain(block, compiled)
    result = sandbox.run([str(sandbox.root / "example")])
    assert result.returncode == 0, explain(block, result)


# JSON blocks that show an event's payload, by file and the start of the
# block: checked against the record-kind table the readers use.
EVENT_PAYLOADS = {
    ("docs/recording.md", '{"baud":115200'): "settings",
}


def check_option_strings(block, sandbox):
    """Each line is an option string: a replay's checked as open_port would,
    any other's keys known to its port type (the key table)."""
    from wiretape import _core
    for line in block.text.strip().splitlines():
        options = dict(_core.parse_options(line))
        if options["type"] == "replay":
            _core.check_replay_options(line)
            continue
        known = {key.name for key in _core.option_keys() if options["type"] in key.port_types}
        unknown = sorted(set(options) - known - {"type"})
        assert not unknown, f"{block.id}: {line!r}: keys unknown to {options['type']}: {unknown}"


def check_json(block, sandbox):
    from wiretape import _core
    documents = json.loads(f"[{block.text}]") if block.lang == "json" else \
        [json.loads(line) for line in block.text.splitlines() if line.strip()]
    assert documents and all(isinstance(d, dict) for d in documents), \
        f"{block.id}: not JSON objects"
    for (file, start), kind in EVENT_PAYLOADS.items():
        if block.file == file and block.first_line.startswith(start):
            for document in documents:
                written = json.loads(_core.event_payload(kind, document))
                assert written == document, f"{block.id}: not a {kind} event as written"


def check_yaml(block, sandbox):
    yaml = pytest.importorskip("yaml", reason="PyYAML (pip install pyyaml) checks YAML blocks")
    document = yaml.safe_load(block.text)
    assert document is not None, f"{block.id}: empty YAML"
    # A CI job runs in this repository: the files its commands name exist.
    missing = [path for path in re.findall(r"(?<![\w/.-])((?:tests|examples|docs|python)/[\w./-]+)",
                                           block.text)
               if not (REPO / path).exists()]
    assert not missing, f"{block.id}: names files the repository does not have: {missing}"


def check_ini(block, sandbox):
    parser = configparser.ConfigParser()
    parser.read_string(block.text, source=block.id)
    assert parser.sections(), f"{block.id}: no section"


def test_a_console_block_is_held_to_the_output_it_shows(sandbox):
    run_shell(Block("x.md", 1, "console", "$ echo 'took 1.25 s' \\\n    /tmp/a\ntook 0.5 s /tmp/b\n"),
              sandbox)
    with pytest.raises(AssertionError, match="x.md:1 failed"):
        run_shell(Block("x.md", 1, "console", "$ echo hello\nbye\n"), sandbox)
