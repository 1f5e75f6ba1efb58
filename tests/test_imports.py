"""Import structure of the package: no import cycles between magsoro modules, the engine (magsoro.mpm) does not
import the package root, geometry does not import the engine, and MU0 is defined once (magsoro.constants).

The graph holds module-level imports only (class bodies and ``try``/``with``/``if`` blocks included, ``if
TYPE_CHECKING`` blocks excluded); imports inside functions are lazy and left out. An edge goes from a module to
the module an import names: ``from magsoro.x import y`` -> magsoro.x.y if that is a module, else magsoro.x.
"""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "src" / "magsoro"


def module_name(path: Path) -> str:
    parts = ("magsoro",) + path.relative_to(PKG).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_modules() -> dict[str, Path]:
    """Every module of the package (those of namespace-package folders included), by dotted name."""
    return {module_name(path): path for path in sorted(PKG.rglob("*.py")) if "__pycache__" not in path.parts}


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _module_level_imports(body):
    """Import statements run when the module is imported (not in functions, not under ``if TYPE_CHECKING``)."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        elif isinstance(node, ast.If):
            if not _is_type_checking(node.test):
                yield from _module_level_imports(node.body)
            yield from _module_level_imports(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody, *(h.body for h in node.handlers)):
                yield from _module_level_imports(block)
        elif isinstance(node, (ast.ClassDef, ast.With, ast.For, ast.While)):
            yield from _module_level_imports(node.body)
            yield from _module_level_imports(getattr(node, "orelse", []))


def import_graph(mods: dict[str, Path]) -> dict[str, set[str]]:
    """module -> set of magsoro modules it imports at module level."""
    graph = {}
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        edges = set()
        for node in _module_level_imports(ast.parse(path.read_text(encoding="utf-8"), str(path)).body):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:  # relative import
                    pkg = name.split(".") if is_pkg else name.split(".")[:-1]
                    pkg = pkg[: len(pkg) - (node.level - 1)]
                    base = ".".join(pkg + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            edges.update(t for t in targets if t == "magsoro" or t.startswith("magsoro."))
        edges.discard(name)
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as [a, b, ..., a], or None."""
    state, stack = {}, []

    def visit(u):
        state[u] = 1
        stack.append(u)
        for v in sorted(graph.get(u, ())):
            if state.get(v) == 1:
                return stack[stack.index(v):] + [v]
            if v not in state:
                found = visit(v)
                if found:
                    return found
        stack.pop()
        state[u] = 2
        return None

    for u in sorted(graph):
        if u not in state:
            found = visit(u)
            if found:
                return found
    return None


def test_no_import_cycles():
    cycle = find_cycle(import_graph(package_modules()))
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_find_cycle_reports_a_cycle(tmp_path):
    # the check itself can fail: a two-module cycle in a throwaway package is found and named
    pkg = tmp_path / "magsoro"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "a.py").write_text("from magsoro.sub.b import f\n")
    (pkg / "sub" / "b.py").write_text("def g():\n    from magsoro import x\nfrom magsoro.sub import a\n")
    (pkg / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from magsoro.sub import a\n")
    mods = {module_name(PKG / p.relative_to(pkg)): p for p in sorted(pkg.rglob("*.py"))}
    graph = import_graph(mods)
    assert graph["magsoro.sub.b"] == {"magsoro.sub.a"} and graph["magsoro.c"] == set()
    assert find_cycle(graph) == ["magsoro.sub.a", "magsoro.sub.b", "magsoro.sub.a"]


def test_engine_does_not_import_package_root():
    graph = import_graph(package_modules())
    bad = sorted(m for m, edges in graph.items() if m.startswith("magsoro.mpm.") and "magsoro" in edges)
    assert not bad, f"magsoro.mpm modules importing the package root: {bad}"


def test_geometry_does_not_import_engine():
    graph = import_graph(package_modules())
    bad = sorted((m, t) for m, edges in graph.items() if m == "magsoro.geometry" or m.startswith("magsoro.geometry.")
                 for t in edges if t == "magsoro.mpm" or t.startswith("magsoro.mpm."))
    assert not bad, f"geometry importing the engine: {bad}"


def test_mu0_defined_once():
    where = []
    for name, path in package_modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            targets = (node.targets if isinstance(node, ast.Assign)
                       else [node.target] if isinstance(node, (ast.AnnAssign, ast.AugAssign)) else [])
            if any(isinstance(t, ast.Name) and t.id == "MU0" for t in targets):
                where.append(f"{name}:{node.lineno}")
    assert len(where) == 1 and where[0].startswith("magsoro.constants:"), f"MU0 assigned at {where}"


def test_no_module_imports_package_root():
    # modules read MU0 from magsoro.constants and __version__ from magsoro._version
    graph = import_graph(package_modules())
    bad = sorted(m for m, edges in graph.items() if m != "magsoro" and "magsoro" in edges)
    assert not bad, f"modules importing the package root: {bad}"
