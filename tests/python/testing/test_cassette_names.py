"""Cassette names are one rule (wiretape/cassette_names.hpp): the pytest
plugin and the GoogleTest helper give a test the same name, and two tests
never share a cassette."""

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

from wiretape import _core
from wiretape.testing import cassette

pytest_plugins = ["pytester"]

REPO = Path(__file__).resolve().parents[3]

# (name parts, the cassette file name both sides must give)
NAMES = [
    (["test_plain"], "test_plain.wtape"),
    (["TestGroup", "test_in_class"], "TestGroup.test_in_class.wtape"),
    # Before, the C++ helper never cut a name (a 300-character file name
    # cannot be opened) while the plugin cut it and added a hash.
    (["Suite", "T" * 300], "Suite." + "T" * 81 + "-"
     + hashlib.sha1(("Suite." + "T" * 300).encode()).hexdigest()[:12] + ".wtape"),
    # Before, C++ gave a_b here and Python a__b.
    (["S", "a_/b"], "S.a__b-" + hashlib.sha1(b"S.a_/b").hexdigest()[:12] + ".wtape"),
]


def test_a_hash_of_the_whole_name_ends_a_name_that_had_to_change():
    for parts, expected in NAMES:
        assert _core.cassette_file_name(parts) == expected


def test_colliding_safe_names_get_distinct_cassettes():
    # Both read t_a_b once made safe; before, they shared one cassette.
    a, b = _core.safe_file_name("t[a b]"), _core.safe_file_name("t[a_b]")
    assert a.startswith("t_a_b-") and b.startswith("t_a_b-")
    assert a != b


def test_names_are_safe_and_bounded():
    for name in ["../../etc/passwd", "a/b", "", "\u00e9\u00e9", "x" * 500, "..", "a\x00b"]:
        safe = _core.safe_file_name(name)
        assert "/" not in safe and "\x00" not in safe and safe not in ("", ".", "..")
        assert len(safe) <= _core.MAX_CASSETTE_NAME_LENGTH


def test_the_plugin_names_a_test_by_its_nodeid_parts():
    class Item:
        nodeid = "tests/test_x.py::TestA::test_b[p 1]"
        name = "test_b[p 1]"
        path = REPO / "tests" / "test_x.py"

    assert cassette.cassette_file_name(Item) == _core.cassette_file_name(
        ["TestA", "test_b[p 1]"])
    assert cassette.default_cassette_dir(Item) == REPO / "tests" / "recordings" / "test_x"


CPP_PROGRAM = r"""
#include <iostream>
#include <string>
#include "wiretape/cassette_names.hpp"
int main() {
  std::string suite, test;
  while (std::getline(std::cin, suite) && std::getline(std::cin, test)) {
    std::cout << wiretape::testing::default_cassette_path("/src/x_test.cpp", suite, test)
              << "\n";
  }
}
"""


def test_the_cpp_helper_gives_the_same_names(tmp_path):
    """The GoogleTest helper's own code (compiled here) against the plugin's."""
    compiler = next((c for c in ("c++", "g++", "clang++")
                     if subprocess.run(["which", c], capture_output=True).returncode == 0), None)
    if compiler is None:
        pytest.skip("no C++ compiler")
    source = tmp_path / "names.cpp"
    source.write_text(CPP_PROGRAM)
    program = tmp_path / "names"
    subprocess.run([compiler, "-std=c++17", "-I", str(REPO / "include"), str(source), "-o",
                    str(program)], check=True, timeout=300)
    pairs = [parts for parts, _ in NAMES if len(parts) == 2]
    pairs.append(["Models/ScanTest", "Reads/3"])
    given = "".join(f"{suite}\n{test}\n" for suite, test in pairs)
    out = subprocess.run([str(program)], input=given, capture_output=True, text=True,
                         check=True, timeout=60).stdout.splitlines()
    expected = [f"/src/recordings/x_test/{_core.cassette_file_name(parts)}" for parts in pairs]
    assert out == expected


PARAMETRIZED = """
    import pytest

    IDS = ["a/b", "a b", "a::b", "a.b", "a_b", "x" * 300 + "1", "x" * 300 + "2"]

    @pytest.mark.parametrize("given", IDS, ids=IDS)
    def test_echo(wiretape_port, given):
        data = given.encode()[-8:] + b"\\n"
        wiretape_port.write_all(data)
        assert wiretape_port.read_exactly(len(data), timeout=5) == data

    class TestGroup:
        @pytest.mark.parametrize("given", ["p::q", "p.q"], ids=["p::q", "p.q"])
        def test_echo(self, wiretape_port, given):
            data = given.encode() + b"\\n"
            wiretape_port.write_all(data)
            assert wiretape_port.read_exactly(len(data), timeout=5) == data
"""


def test_parametrized_tests_whose_ids_differ_never_share_a_cassette(pytester):
    # Before, test_echo[a::b] was read as the class test_echo[a and the test
    # b], so its name was test_echo[a.b]: the second of the two replayed the
    # first's recording (and failed, or worse, passed on the wrong data).
    pytester.makepyfile(test_ids=PARAMETRIZED)
    result = pytester.runpytest("--wiretape-record=once", "--wiretape-device=type=loopback")
    result.assert_outcomes(passed=9)
    cassettes = sorted((pytester.path / "recordings" / "test_ids").glob("*.wtape"))
    assert len(cassettes) == 9, [c.name for c in cassettes]
    assert all(len(c.name) <= _core.MAX_CASSETTE_NAME_LENGTH + len(".wtape") for c in cassettes)
    # Each replays its own recording.
    result = pytester.runpytest()
    result.assert_outcomes(passed=9)


def test_a_parameter_id_holding_double_colons_is_not_a_class():
    class Item:
        nodeid = "tests/test_x.py::TestA::test_b[p::q]"
        name = "test_b[p::q]"
        path = REPO / "tests" / "test_x.py"

    assert cassette.cassette_file_name(Item) == _core.cassette_file_name(
        ["TestA", "test_b[p::q]"])
    names = set()
    for name in ("test_b[p::q]", "test_b[p.q]"):
        Item.nodeid, Item.name = "tests/test_x.py::" + name, name
        assert cassette.cassette_file_name(Item) == _core.cassette_file_name([name])
        names.add(cassette.cassette_file_name(Item))
    assert len(names) == 2
