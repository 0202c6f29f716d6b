"""python/wiretape/_core.pyi names everything the extension binds, so that
editors and type checkers see the whole API."""

import ast
import pathlib

import wiretape
from wiretape import _core

STUBS = pathlib.Path(wiretape.__file__).with_name("_core.pyi")


def _stub_tree():
    return ast.parse(STUBS.read_text())


def _defined(body):
    names = set()
    for node in body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.ImportFrom):  # stubgen's `from wiretape import X as X`
            names.update(alias.asname or alias.name for alias in node.names)
    return names


def test_every_module_name_has_a_stub():
    public = {name for name in dir(_core) if not name.startswith("_")}
    assert public - _defined(_stub_tree().body) == set()


def test_every_public_member_of_every_class_has_a_stub():
    missing = {}
    for node in _stub_tree().body:
        if isinstance(node, ast.ClassDef) and hasattr(_core, node.name):
            real = {name for name in vars(getattr(_core, node.name)) if not name.startswith("_")}
            absent = real - _defined(node.body)
            if absent:
                missing[node.name] = sorted(absent)
    assert missing == {}


def test_the_package_re_exports_the_core():
    for name in ("open_port", "Port", "OptionError", "PortError", "PortClosed",
                 "ReplayMismatch", "SessionError", "SessionReader", "SessionWriter",
                 "Record", "export_flexiport"):
        assert getattr(wiretape, name) is getattr(_core, name), name
        assert name in wiretape.__all__
