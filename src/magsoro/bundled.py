"""The repository folders the package ships with it (scenes/ and examples/: the robot library's scenes, meshes and
data, the tutorial's scenes), installed or in a checkout.

A wheel carries them as package data under ``magsoro/_bundled/`` (setup.py copies them there when it builds, with
:func:`bundled_files` choosing the files); a checkout (an editable install) reads them where they are. So the paths
the docs, the tests and users name, ``scenes/cantilever_2d.toml`` or ``examples/tutorial/strip.toml``, work in the
checkout as written and, from any other folder, resolve to the installed copy (:func:`resolve_data_path`).

This module imports nothing but the standard library: setup.py loads it by its file path at build time.
"""

from __future__ import annotations

from pathlib import Path

#: the repository's folders shipped inside the wheel, as magsoro/_bundled/<folder>
FOLDERS = ("scenes", "examples")
#: where the wheel puts them, relative to the package
BUNDLE_DIR = "_bundled"

_PACKAGE = Path(__file__).resolve().parent
_INSTALLED = _PACKAGE / BUNDLE_DIR
_CHECKOUT = _PACKAGE.parents[1]  # src/magsoro -> the repository root


def bundled_files(root) -> list[Path]:
    """The files of FOLDERS under ``root`` (a checkout or an unpacked sdist) that a wheel ships, relative to
    ``root``: every file but Python's byte-code caches."""
    root = Path(root)
    out = []
    for folder in FOLDERS:
        for path in sorted((root / folder).rglob("*")):
            rel = path.relative_to(root)
            if path.is_file() and "__pycache__" not in rel.parts and path.suffix not in (".pyc", ".pyo"):
                out.append(rel)
    return out


def data_root() -> Path | None:
    """The folder that holds scenes/ and examples/: the copy installed with the package (a wheel), else the
    checkout this module sits in; None when neither has them."""
    for root in (_INSTALLED, _CHECKOUT):
        if all((root / folder).is_dir() for folder in FOLDERS):
            return root
    return None


def data_folder(name: str) -> Path:
    """``scenes`` or ``examples``, installed or in the checkout. Raises FileNotFoundError naming both places."""
    if name not in FOLDERS:
        raise ValueError(f"{name!r} is not one of the shipped folders {FOLDERS}")
    root = data_root()
    if root is None:
        raise FileNotFoundError(f"{name}/ is neither installed with the package ({_INSTALLED / name}) nor in a "
                                f"checkout ({_CHECKOUT / name}): reinstall magsoro from its wheel or the repository")
    return root / name


def resolve_data_path(path) -> Path:
    """``path`` itself when it exists; a relative path that does not exist and starts with one of FOLDERS
    (``scenes/walker.toml``) names the copy shipped with the package when that has it, so the commands the docs
    give work from any folder. Anything else comes back unchanged (the error of whoever opens it names it)."""
    path = Path(path)
    if path.exists() or path.is_absolute() or not path.parts or path.parts[0] not in FOLDERS:
        return path
    root = data_root()
    if root is None or not (root / path).exists():
        return path
    return root / path
