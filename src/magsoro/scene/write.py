"""Write a scene (loaded, edited or built in Python) back to a TOML file that loads to an equal scene."""

from __future__ import annotations

import math
import os
from pathlib import Path

from pydantic import BaseModel

from magsoro.errors import SceneError
from magsoro.io.tomlwrite import dumps
from magsoro.scene.schema import Body, FileMagnetization, Initial, KeyframedField, Material, MeshShape, Robot, Scene

# the keys that hold file names, relative to the scene file (or to a body's file): rewritten when the scene is
# written to another folder; tests/test_write_scene.py checks that every key described as relative is listed
PATH_KEYS = {(Scene, "robot"), (Scene, "material_library"), (Robot, "file"), (MeshShape, "file"), (FileMagnetization, "file"),
             (KeyframedField, "file"), (Material, "file"), (Initial, "from_")}


def _same(a, b) -> bool:
    """a equals the default b, to the bit for floats (-0.0 is not 0.0) and to the type (True is not 1)."""
    if isinstance(a, BaseModel) or isinstance(b, BaseModel):
        return type(a) is type(b) and all(_same(getattr(a, k), getattr(b, k)) for k in type(a).model_fields)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and (repr(a) == repr(b) if isinstance(a, float) else a == b)


class _Writer:
    """Turns a Scene into plain dicts and lists, with each file name rebased from the folder it resolves against
    to ``target`` (None: file names as they are) and each value TOML cannot hold refused by its key."""

    def __init__(self, target):
        self.target = None if target is None else Path(target).resolve()

    def table(self, model: BaseModel, key: str, base) -> dict:
        if isinstance(model, Body) and model.base_dir is not None:
            base = model.base_dir
        out = {}
        for name, field in type(model).model_fields.items():
            value = getattr(model, name)
            if isinstance(model, Scene) and name == "bodies":
                value = [b for b in value if not _robot_part(b)]  # written once, by the robot key
            if not field.is_required() and _same(value, field.get_default(call_default_factory=True)):
                continue  # defaults are left out: the file says what the scene chose
            sub = f"{key}.{name}" if key else name
            if (type(model), name) in PATH_KEYS and not isinstance(value, BaseModel):
                value = self.path(value, sub, base)
            out[field.alias or name] = self.value(value, sub, base)  # the file's key ([initial] from: alias)
        if "type" in out:  # a tagged table reads best with its type first (a base class's keys come before it)
            out = {"type": out.pop("type"), **out}
        return out

    def value(self, v, key: str, base):
        if isinstance(v, BaseModel):
            return self.table(v, key, base)
        if v is None:
            raise SceneError(f"{key}: None cannot be written to TOML, which has no null; give a value (or, where "
                             "None is the default, leave the key at it)")
        if isinstance(v, (bool, int, str)):
            return v
        if isinstance(v, float):
            if not math.isfinite(v):
                raise SceneError(f"{key}: {v} cannot be written to a scene file (only finite numbers load)")
            return v
        if isinstance(v, dict):
            return {str(k): self.value(x, f"{key}.{k}", base) for k, x in v.items()}
        if isinstance(v, (list, tuple)) or (hasattr(v, "tolist") and getattr(v, "ndim", 0) > 0):  # numpy arrays
            return [self.value(x, f"{key}[{i}]", base) for i, x in enumerate(list(v))]
        if hasattr(v, "item") and getattr(v, "ndim", None) == 0:  # numpy scalars
            return self.value(v.item(), key, base)
        if isinstance(v, os.PathLike):
            return self.path(os.fspath(v), key, base)
        raise SceneError(f"{key}: a value of type {type(v).__name__} cannot be written to TOML (numbers, strings, booleans, "
                         "lists and tables can)")

    def path(self, value, key: str, base):
        """A file name (or a list of them) relative to ``self.target``, where it was relative to ``base``."""
        if isinstance(value, (list, tuple)):
            return [self.path(v, f"{key}[{i}]", base) for i, v in enumerate(value)]
        if not isinstance(value, (str, os.PathLike)) or self.target is None:
            return value
        value = os.fspath(value)
        if Path(value).is_absolute():
            return Path(value).as_posix()
        full = (Path(base) if base is not None else Path.cwd()) / value
        try:
            return Path(os.path.relpath(full.resolve(), self.target)).as_posix()
        except ValueError:  # another drive (Windows): no relative path exists
            return full.resolve().as_posix()


def scene_dict(scene: Scene, relative_to=None) -> dict:
    """The scene as the dict a TOML file of it holds (keys at their defaults left out), for :func:`parse_scene`.
    ``relative_to``: the folder the file goes to (file names are rewritten relative to it); None keeps them as
    they are (relative to ``scene.base_dir``). Raises :class:`SceneError` naming the first key TOML cannot hold."""
    functions = sorted(scene.magnetization_functions)
    if functions:
        raise SceneError(f"bodies {', '.join(functions)}: a magnetisation given by set_magnetization (a Python "
                         "function) cannot be written to TOML; give it as a [bodies.magnetization] table (e.g. "
                         "type = \"expression\" or \"file\") instead")
    writer = _Writer(relative_to)
    return writer.table(scene, "", scene.base_dir)


def _robot_part(body: Body) -> bool:
    """A body the loader appended to the scene's bodies from its robot (inline parts or the robot file)."""
    return body.key is not None and (body.key.startswith("robot.parts[") or body.key.startswith("parts["))


def scene_toml(scene: Scene, relative_to=None) -> str:
    """TOML text of ``scene``: :func:`scene_dict` written by :func:`magsoro.io.tomlwrite.dumps`."""
    return dumps(scene_dict(scene, relative_to))


def write_scene(scene: Scene, path, check: bool = True) -> Path:
    """Save ``scene`` as a TOML scene file at ``path`` that :func:`magsoro.scene.load_scene` reads back to an equal
    scene; returns the path.

    Only keys that differ from their defaults are written (the loaded scene is the same either way), floats as
    ``repr`` (they read back bit-identical). File names (meshes, magnetisation and keyframe files, material
    entries and libraries, the robot file) are written relative to the new file's folder, so they still name
    the same files wherever the scene goes; absolute names stay absolute. A robot's parts are written once, under
    its robot key (a robot file stays a reference to that file). A scene loaded with ``preview=True`` is written
    with the preview settings in its [simulation] table, as it was loaded.

    Refused with a one-line :class:`SceneError`, writing nothing: a value TOML cannot hold (None where the default
    is not None, a non-finite number, an object that is not a number, string, list or table), a magnetisation set
    by :meth:`Scene.set_magnetization`, and, with ``check=True``, a scene that would not load from ``path`` (the
    message names the key, as loading the file would; ``check=False`` writes it all the same, e.g. before its
    mesh files are copied next to it).
    """
    import tomllib

    from magsoro.io.files import atomic_write_text
    from magsoro.scene.load import parse_scene

    path = Path(path)
    text = scene_toml(scene, path.parent)
    made = [p for p in [path.parent, *path.parent.parents] if not p.exists()]
    path.parent.mkdir(parents=True, exist_ok=True)  # before the check: '../x' does not resolve from a missing folder
    if check:
        try:
            parse_scene(tomllib.loads(text), str(path), path.parent)
        except SceneError:
            for folder in made:  # innermost first; a refused scene leaves nothing behind
                folder.rmdir()
            raise
    atomic_write_text(path, text)
    return path
