"""No module of python/wiretape builds an option string by hand (DESIGN §25
"One builder, one reader"): every one is made by _core.option_string, whose
values are quoted and numbers written by one rule in C++. The patterns:
an f-string making a ``key={...}`` pair of an option string
(``f"type=replay,file={path}"``, ``f"channel={name}"``), a concatenation
onto ``"key="`` (``"type=replay,file=" + quote(path)``) and a
``",".join`` of ``f"{key}={value}"``. Text for people that only shows such pairs (a
message naming ``(type=replay,file=x)``, ``key=value, key=value`` for
reading) is not an option string and does not match."""

import ast
import pathlib
import re

PACKAGE_DIR = pathlib.Path(__file__).resolve().parents[3] / "python" / "wiretape"


# Option keys are lower case (LD_PRELOAD= in a command line is no option).
_PAIR_IN_TEMPLATE = re.compile(r"(?:^|,)[a-z_][a-z0-9_]*=\{\}(?:,|$)")
_KEY_BEFORE_VALUE = re.compile(r"(?:^|,)[a-z_][a-z0-9_]*=$")


def _template(node: ast.JoinedStr) -> str:
    return "".join(part.value if isinstance(part, ast.Constant) else "{}"
                   for part in node.values)


def _joined_by_comma(tree):
    """The f-strings inside a ``",".join(...)``."""
    inside = set()
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "join" and isinstance(node.func.value, ast.Constant)
                and node.func.value.value == ","):
            inside.update(id(inner) for inner in ast.walk(node) if isinstance(inner, ast.JoinedStr))
    return inside


def hand_built_option_strings(source: str):
    """(line, what) of every hand-built option string in `source`."""
    tree = ast.parse(source)
    joined = _joined_by_comma(tree)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            template = _template(node)
            if _PAIR_IN_TEMPLATE.search(template):
                found.append((node.lineno, f"f-string {template!r}"))
            elif template == "{}={}" and id(node) in joined:
                found.append((node.lineno, '",".join(f"{key}={value}" ...)'))
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
            for side in (node.left, node.right):
                if (isinstance(side, ast.Constant) and isinstance(side.value, str)
                        and _KEY_BEFORE_VALUE.search(side.value)):
                    found.append((node.lineno, f"{side.value!r} + ..."))
    return sorted(set(found))


def test_the_patterns_find_what_they_are_for():
    assert [what for _, what in hand_built_option_strings(
        'a = f"type=replay,file={path}"\n'
        'b = f"channel={name}"\n'
        'c = "type=replay,file=" + quote(path)\n'
        'd = options + ",log=" + quote(path)\n'
        'e = ",".join(f"{key}={value}" for key, value in pairs)\n')] == [
        "f-string 'type=replay,file={}'", "f-string 'channel={}'",
        "'type=replay,file=' + ...", "',log=' + ...", '",".join(f"{key}={value}" ...)']
    assert hand_built_option_strings(
        'a = f"replayed it (type=replay,file={name})"\n'
        'b = ", ".join(f"{key}={value}" for key, value in meta)\n'
        'c = f"--as {name}={path}: taken"\n'
        'd = f"t={t:>6} ms"\n'
        'f = ["--listen", f"{name}={place}"]\n'
        'env = "LD_PRELOAD=" + shim\n'
        'e = _core.option_string([("type", "replay"), ("file", path)])\n') == []


def test_no_module_builds_an_option_string_by_hand():
    found = {}
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        name = path.relative_to(PACKAGE_DIR).as_posix()
        hits = hand_built_option_strings(path.read_text(encoding="utf-8"))
        if hits:
            found[name] = hits
    assert not found, "option strings built by hand (use _core.option_string): " + "; ".join(
        f"{name}:{line} {what}" for name, hits in found.items() for line, what in hits)
