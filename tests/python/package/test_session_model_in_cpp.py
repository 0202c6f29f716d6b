"""No module of python/wiretape re-derives the session model (DESIGN §17,
§25 "Session shape in C++"): exchanges are counted, latencies paired, fault
places checked, fault plans parsed and the byte layout walked in C++ only,
bound once. These checks look for the shapes such a copy takes, and that
the commands which need these facts ask the bindings for them."""

import ast
import pathlib
import re

PACKAGE_DIR = pathlib.Path(__file__).resolve().parents[3] / "python" / "wiretape"

# Modules that write other formats byte by byte: pcapng blocks and the IP
# and UDP/TCP headers Wireshark reads. Neither reads a .wtape's layout.
STRUCT_WRITERS = {"exports/pcapng.py", "exports/network.py"}

# The record layout's sizes: a module that uses them walks records itself.
LAYOUT_NAMES = {"RECORD_OVERHEAD", "RECORD_HEADER_SIZE", "FILE_HEADER_SIZE"}

# A fault plan's places in a regular expression: a second parser.
FAULT_SYNTAX = re.compile(r"@channel|exchange:|rx:|\bt:")


def modules():
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        yield path.relative_to(PACKAGE_DIR).as_posix(), ast.parse(path.read_text(encoding="utf-8"))


def imported_modules(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            yield node.module


def regex_patterns(tree):
    """The literal patterns given to re.compile/search/match/findall/... ."""
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and isinstance(node.func.value, ast.Name) and node.func.value.id == "re"
                and node.args and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)):
            yield node.lineno, node.args[0].value


def names_used(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            yield node.attr
        elif isinstance(node, ast.Name):
            yield node.id


def test_the_checks_see_what_they_look_for():
    tree = ast.parse("import struct\nimport re\nre.compile(r'@channel:([^@;]+)')\n"
                     "size = _core.RECORD_OVERHEAD + n\n")
    assert "struct" in set(imported_modules(tree))
    assert [FAULT_SYNTAX.search(text) is not None for _, text in regex_patterns(tree)] == [True]
    assert LAYOUT_NAMES & set(names_used(tree)) == {"RECORD_OVERHEAD"}


def test_only_the_writers_of_other_formats_use_struct():
    users = {name for name, tree in modules() if "struct" in set(imported_modules(tree))}
    assert users <= STRUCT_WRITERS, f"struct outside the pcapng/IP writers: {users - STRUCT_WRITERS}"


def test_no_module_walks_the_record_layout():
    found = {name: sorted(LAYOUT_NAMES & set(names_used(tree))) for name, tree in modules()}
    assert not {name: used for name, used in found.items() if used}


def test_no_module_parses_fault_places_with_a_regex():
    found = [(name, line, text) for name, tree in modules()
             for line, text in regex_patterns(tree) if FAULT_SYNTAX.search(text)]
    assert not found, f"fault syntax parsed in Python (use _core.parse_faults): {found}"


def test_the_commands_ask_the_bindings():
    uses = {name: set(names_used(tree)) for name, tree in modules()}
    # Fault places and the shape a campaign spreads its cases over.
    assert {"session_shape", "check_against", "parse_faults"} <= uses["faults/cases.py"]
    # stats' latencies: the segmentation's pairing.
    assert "LatencyMeter" in uses["tools/stats.py"]
    # verify: the reader's own check of every record.
    assert "check_session_records" in uses["tools/verify.py"]
    # --cut Ne: the exchanges of the one segmentation.
    assert any("session_exchanges" in used for name, used in uses.items()
               if name.startswith("tools/edit"))
