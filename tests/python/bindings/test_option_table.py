"""The key table in C++ (`_core.option_keys()`, DESIGN §17 "Options") is the
one list of option keys: docs/options.md's tables and the CLI's flags that
mirror replay keys are held to it, and Python reads option strings through
the bound parser only."""

import argparse
import pathlib
import re

import pytest

import wiretape
from wiretape import _core
from wiretape.cli import build_parser
from wiretape.options import has_line_settings, option_values, replay_keys

DOCS = pathlib.Path(__file__).resolve().parents[3] / "docs" / "options.md"

# docs/options.md's sections and the port types their tables are about.
SECTION_TYPES = {
    "Common keys (every type)": tuple(_core.port_types()),
    "type=serial": ("serial",),
    "type=tcp": ("tcp",),
    "type=rfc2217": ("rfc2217",),
    "type=udp": ("udp",),
    "type=pty": ("pty",),
    "type=loopback": ("loopback",),
    "type=replay": ("replay",),
    "type=seriallog, tcplog, udplog": ("seriallog", "tcplog", "udplog"),
}
NO_DEFAULT = ("none", "—")


def documented_rows():
    """(section, key name, default cell, values cell) of every table row."""
    rows, section = [], None
    for line in DOCS.read_text(encoding="utf-8").splitlines():
        if line.startswith("## "):
            section = line[3:].strip()
            continue
        if section not in SECTION_TYPES or not line.startswith("| `"):
            continue
        cells = [cell.strip() for cell in line.strip().strip("|").split(" | ")]
        for name in re.findall(r"`([^`]+)`", cells[0]):
            rows.append((section, name, cells[1], cells[2] if len(cells) > 2 else ""))
    return rows


def table_name(key):
    return key.name + "KEY" if key.prefix else key.name


def test_the_docs_list_every_section_they_are_checked_by():
    headings = {line[3:].strip() for line in DOCS.read_text(encoding="utf-8").splitlines()
                if line.startswith("## ")}
    assert set(SECTION_TYPES) <= headings


def test_every_key_of_the_table_is_documented_with_its_types_default_and_choices():
    documented = {}
    for section, name, default, values in documented_rows():
        for port_type in SECTION_TYPES[section]:
            documented[(name, port_type)] = (section, default, values)
    for key in _core.option_keys():
        for port_type in key.port_types:
            where = (table_name(key), port_type)
            assert where in documented, f"{where} is in the key table but not in docs/options.md"
            section, default, values = documented[where]
            shown_default = default.strip("`")
            if key.required:
                assert shown_default == "required", (where, default)
            elif key.default is not None:
                assert shown_default == key.default, (where, default, key.default)
            else:
                assert shown_default in NO_DEFAULT, (where, default)
            for choice in key.choices:
                assert f"`{choice}`" in values, (where, choice, values)


def test_every_documented_key_is_in_the_table():
    for section, name, _, _ in documented_rows():
        for port_type in SECTION_TYPES[section]:
            assert any(table_name(key) == name and key.applies_to(port_type)
                       for key in _core.option_keys()), \
                f"docs/options.md documents {name!r} for type={port_type}; the key table has not"


def replay_parser():
    parser = build_parser()
    commands = next(action for action in parser._actions
                    if isinstance(action, argparse._SubParsersAction))
    return commands.choices["replay"]


def test_the_cli_mirrors_exactly_the_replay_keys_the_table_gives_a_flag():
    replay_rows = [key for key in _core.option_keys() if key.applies_to("replay")]
    flags = {key.flag: key for key in replay_rows if key.flag}
    actions = {option: action for action in replay_parser()._actions
               for option in action.option_strings}
    key_names = {key.name for key in replay_rows}
    mirroring = {option for option in actions
                 if option in flags or option.lstrip("-").replace("-", "_") in key_names}
    assert mirroring == set(flags)
    for flag, key in flags.items():
        action = actions[flag]
        if key.choices:
            assert tuple(action.choices) == tuple(key.choices), flag
        if key.default is not None:
            assert f"default {key.default}" in action.help, (flag, action.help)


def test_replay_keys_are_the_flags_named_as_their_keys():
    keys = replay_keys()
    assert "at_end" in keys and "timing" in keys and "gap" in keys
    assert "faults" not in keys, "--fault is a flag of its own"
    assert "file" not in keys and "strictness" not in keys
    given = vars(replay_parser().parse_args(["f.wtape"]))
    for key in keys:
        assert key in given, f"replay has no flag that stores {key!r}"


def test_parse_options_gives_the_pairs_as_open_port_reads_them():
    assert _core.parse_options('type=tcp host="a b,c"\tlisten') == [
        ("type", "tcp"), ("host", "a b,c"), ("listen", "1")]
    with pytest.raises(wiretape.OptionError, match="given twice"):
        _core.parse_options("port=1,port=2")
    with pytest.raises(wiretape.OptionError, match="never closed"):
        _core.parse_options('log="open')


def test_option_values_give_flexiport_names_under_the_key_they_stand_for():
    assert option_values("type=udp,dest_ip=10.0.0.7,dest_port=7000", "udp") == {
        "type": "udp", "dest_ip": "10.0.0.7", "dest_port": "7000",
        "host": "10.0.0.7", "port": "7000"}
    assert option_values("ip=10.0.0.1", "tcp")["host"] == "10.0.0.1"
    assert "host" not in option_values("ip=10.0.0.1")


def test_an_unknown_key_suggests_the_nearest_of_its_type():
    assert _core.suggest_key("bod", "serial") == "baud"
    assert _core.suggest_key("colour", "serial") is None
    with pytest.raises(wiretape.OptionError, match="did you mean 'timing'"):
        _core.check_replay_options("type=replay,file=x.wtape,timign=none")


def test_the_table_is_bound_with_types_ranges_and_flags():
    baud = next(key for key in _core.option_keys() if key.name == "baud")
    assert (baud.type, baud.default, baud.minimum, baud.maximum) == ("integer", "9600", 1,
                                                                      100_000_000)
    at_end = next(key for key in _core.option_keys() if key.name == "at_end")
    assert (at_end.flag, at_end.choices) == ("--at-end", ["silent", "closed"])


def test_the_types_with_line_settings_are_the_serial_lines_local_or_exported():
    assert [name for name in _core.port_types() if has_line_settings(name)] == \
        ["serial", "rfc2217"]
