"""The doc-example runner on a machine without a tool the docs use: the
blocks that need it are skipped loudly, naming it, and do not fail (a fresh
machine without tshark passes `make test`)."""

import os
import pathlib
import subprocess
import sys

from doc_examples import REPO, all_blocks, load_manifest

RUNNER = REPO / "tests" / "python" / "docs" / "test_doc_examples.py"


def path_without(tool: str, folder: pathlib.Path) -> str:
    """A PATH of one folder holding a link to every program of today's PATH
    but `tool` (the first of each name, as a shell finds them)."""
    folder.mkdir()
    for directory in os.environ.get("PATH", "").split(os.pathsep):
        if not directory or not os.path.isdir(directory):
            continue
        for name in os.listdir(directory):
            program = os.path.join(directory, name)
            link = folder / name
            if name == tool or link.exists() or link.is_symlink():
                continue
            if os.path.isfile(program) and os.access(program, os.X_OK):
                link.symlink_to(program)
    return str(folder)


def capture_blocks():
    """The blocks run that convert a capture (tshark reads it)."""
    listed = load_manifest()
    return [block for block in all_blocks()
            if block.key not in listed and ("wiretape convert plc.pcapng" in block.text
                                            or "wiretape convert all.pcapng" in block.text)]


def test_blocks_needing_a_missing_tool_are_skipped_naming_it(tmp_path):
    blocks = capture_blocks()
    assert {block.file for block in blocks} >= {"README.md", "docs/cli.md"}
    env = dict(os.environ, PATH=path_without("tshark", tmp_path / "bin"))
    nodes = [f"{RUNNER}::test_example[{block.id}]" for block in blocks]
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
                             "-p", "no:xdist", *nodes],
                            cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    output = result.stdout + result.stderr
    assert result.returncode == 0, output
    assert f"{len(blocks)} skipped" in output, output
    for block in blocks:
        assert f"SKIPPED LOUDLY: {block.id} needs tshark, which is not on PATH" in output, output
