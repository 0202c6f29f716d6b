"""record and replay --help open with the one-device form and end with
examples, each of which the parser takes as it is written."""

import shlex

import pytest

from wiretape import cli
from wiretape.cli.parser import build_parser, split_command


def help_of(capsys, command):
    assert cli.main([command, "--help"]) == 0
    return capsys.readouterr().out


def examples_in(text):
    lines = text.split("\nexamples:\n", 1)[1].split("\n\n", 1)[0].replace("\\\n", "")
    return [shlex.split(line) for line in lines.splitlines()]


@pytest.mark.parametrize("command", ["record", "replay"])
def test_help_opens_with_one_device_and_ends_with_examples_that_parse(
        capsys, command, tmp_path, monkeypatch):
    out = help_of(capsys, command)
    usage = out.split("\n\n", 1)[0]
    assert usage.startswith(f"usage: wiretape {command} [-h]")
    assert usage.index("[-h]") < usage.index("NAME=OPTS" if command == "record" else ")...")
    examples = examples_in(out)
    assert len(examples) >= 3
    assert any("--" in example for example in examples)  # -- CMD
    assert any("gps=/tmp/gps" in " ".join(example) for example in examples)  # channels
    monkeypatch.chdir(tmp_path)
    for example in examples:
        assert example[:2] == ["wiretape", command]
        arguments, _ = split_command(example[1:])
        build_parser().parse_args(arguments)  # a usage error raises
