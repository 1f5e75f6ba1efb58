"""No module reads another module's private attributes: every ``obj._name`` in src/magsoro (a single leading
underscore, not a dunder; also ``getattr``/``setattr``/``hasattr`` with such a name as a literal) is on ``self``,
``cls``, ``super()`` or a name the same module defines, or is an attribute that the same module's own code defines
(Python's convention: a leading underscore is private to its module). One object reaching into another module's
privates couples the two to each other's internals: the owner gives the quantity a public name instead (DESIGN.md,
"Where the engine goes next").

ALLOWED lists the accesses left, each with its reason (a third-party library's internals that have no public API;
"pending: <file>" for one in a file another change is editing, with the public name to switch to); the test fails
on any access not listed, and on an entry that no longer occurs (so the list only shrinks).
"""

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "magsoro"

#: (file relative to src/magsoro, the accessed expression as ast.unparse writes it) -> why it stays
ALLOWED = {
    # Warp's Module keeps its live kernels in a private set with no public API: cuda_compile builds a module of its
    # own per kernel group and takes the factory-built copies back out of the package's modules
    ("cuda_compile.py", "m._live_kernels"): "third party: Warp's Module internals",
    ("cuda_compile.py", "home._live_kernels"): "third party: Warp's Module internals",
}


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__") and name != "_"


def _module_names(tree: ast.Module) -> set[str]:
    """Names the module itself defines at its top level (classes, functions, assigned names), not imported ones."""
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                names |= {n.id for n in ast.walk(t) if isinstance(n, ast.Name)}
    return names


def _own_attributes(tree: ast.Module) -> set[str]:
    """Private attributes the module's own code defines: methods and class attributes of its classes, and the
    attributes its methods assign on ``self``/``cls``."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    names.add(item.name)
                elif isinstance(item, ast.Assign):
                    names |= {t.id for t in item.targets if isinstance(t, ast.Name)}
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    names.add(item.target.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            if isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
                names.add(node.attr)
    return {n for n in names if _is_private(n)}


def _own_receiver(obj: ast.expr, own_names: set[str]) -> bool:
    if isinstance(obj, ast.Name):
        return obj.id in ("self", "cls") or obj.id in own_names
    # super()._method(): the object's own (inherited) attribute
    return isinstance(obj, ast.Call) and isinstance(obj.func, ast.Name) and obj.func.id == "super"


def _accesses(tree: ast.Module):
    """(line, receiver, attribute name, expression) of every attribute access, including getattr/setattr/hasattr
    with a literal name."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            yield node.lineno, node.value, node.attr, ast.unparse(node)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id in ("getattr", "setattr", "hasattr") and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)):
            yield node.lineno, node.args[0], node.args[1].value, f"{node.func.id}({ast.unparse(node.args[0])}, {node.args[1].value!r})"


def private_accesses() -> list[tuple[str, int, str]]:
    """(file, line, expression) of every access to another module's private attribute under src/magsoro."""
    found = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        tree = ast.parse(path.read_text(), filename=str(path))
        own_names, own_attributes = _module_names(tree), _own_attributes(tree)
        for line, obj, attr, expr in _accesses(tree):
            if _is_private(attr) and attr not in own_attributes and not _own_receiver(obj, own_names):
                found.append((rel, line, expr))
    return sorted(found)


def test_no_module_reads_another_modules_privates():
    found = private_accesses()
    unlisted = [f"{f}:{line}: {expr}" for f, line, expr in found if (f, expr) not in ALLOWED]
    assert not unlisted, "private attributes of another module read:\n" + "\n".join(unlisted)
    stale = sorted(set(ALLOWED) - {(f, expr) for f, _, expr in found})
    assert not stale, f"ALLOWED entries that no longer occur (remove them): {stale}"
