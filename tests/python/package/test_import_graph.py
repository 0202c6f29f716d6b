"""No import circle in python/wiretape (DESIGN §25): every module's imports,
at its top and inside its functions alike, make a graph without a cycle, so
that no import inside a function hides one. An import inside a function is
there for start-up time only (show must not import rich or the importers,
tests/python/cli/test_show_startup.py); it still counts here."""

import ast
import pathlib

PACKAGE_DIR = pathlib.Path(__file__).resolve().parents[3] / "python" / "wiretape"


def _modules(package_dir):
    """Module name -> its source (None for the extension, a leaf: _core
    imports no Python module of the package)."""
    found = {}
    for path in sorted(package_dir.rglob("*")):
        parts = path.relative_to(package_dir.parent).with_suffix("").parts
        if path.suffix == ".py":
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            found[name] = path
        elif path.name.endswith((".so", ".pyi")):
            found.setdefault(".".join(parts).split(".cpython")[0], None)
    return found


def _absolute(module, is_package, level, name):
    if level == 0:
        return name or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def import_graph(package_dir=PACKAGE_DIR):
    """Module -> {module it imports: the line}; `from PKG import NAME` of a
    submodule NAME is an edge to the submodule, not to PKG's __init__."""
    modules = _modules(package_dir)

    def known(name):
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name

    graph = {}
    for module, path in modules.items():
        edges = graph.setdefault(module, {})
        if path is None:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _absolute(module, path.name == "__init__.py", node.level, node.module)
                targets = [base + "." + alias.name if base + "." + alias.name in modules
                           else base for alias in node.names]
            else:
                continue
            for target in map(known, targets):
                if target and target != module:
                    edges.setdefault(target, node.lineno)
    return graph


def find_cycle(graph):
    """One cycle as [a, b, ..., a], or None."""
    state = {}
    stack = []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for target in graph.get(node, {}):
            if state.get(target) == "open":
                return stack[stack.index(target):] + [target]
            if target not in state:
                found = visit(target)
                if found:
                    return found
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_the_package_imports_without_a_circle():
    graph = import_graph()
    assert "wiretape.cli.run" in graph and "wiretape._core" in graph  # the walk saw them
    cycle = find_cycle(graph)
    assert cycle is None, "import circle: " + " -> ".join(
        f"{a} (line {graph[a][b]})" for a, b in zip(cycle, cycle[1:])) + f" -> {cycle[-1]}"


def test_the_cli_modules_import_downward():
    graph = import_graph()
    assert "wiretape.cli.bridges" in graph["wiretape.cli.channels"]
    assert "wiretape.cli.channels" in graph["wiretape.cli.children"]
    for lower, higher in [("wiretape.cli.bridges", "wiretape.cli.channels"),
                          ("wiretape.cli.bridges", "wiretape.cli.children"),
                          ("wiretape.cli.bridges", "wiretape.cli.run"),
                          ("wiretape.cli.channels", "wiretape.cli.children"),
                          ("wiretape.cli.channels", "wiretape.cli.run"),
                          ("wiretape.cli.children", "wiretape.cli.run")]:
        assert higher not in graph[lower], f"{lower} imports {higher}"


def test_a_circle_hidden_in_a_function_is_found(tmp_path):
    package = tmp_path / "wiretape"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from . import b\n")
    (package / "b.py").write_text("def f():\n    from .a import x\n")
    (package / "c.py").write_text("from . import a\n")
    assert find_cycle(import_graph(package)) == ["wiretape.a", "wiretape.b", "wiretape.a"]
