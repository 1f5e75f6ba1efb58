"""Mutations of the real scene files (scenes/*.toml) are refused with one line naming the file and the key, or
accepted; never a traceback. Each example takes one scene as tomllib reads it, walks to one entry (a table value or
a list item at any depth) and breaks it: NaN or inf, a negative or zero number, 1e300, a string, a bool, an empty
list, a vector one component too long or too short, a table, 2000 nested lists or tables, a deleted key, a key with
a typo, an unknown key. Only parsing runs (parse_scene, or parse_rod_config for the rod scene): no particles."""

import copy
import math
import re
import sys
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from magsoro.errors import SceneError
from magsoro.rod.config import RodConfig, load_rod_config, parse_rod_config
from magsoro.scene import load_scene, parse_scene
from magsoro.scene.schema import Scene

SCENES_DIR = Path(__file__).resolve().parents[1] / "scenes"
SCENES = {p.name: tomllib.loads(p.read_text()) for p in sorted(SCENES_DIR.glob("*.toml"))}
ROD_SCENES = {name for name, data in SCENES.items() if "simulation" not in data}  # `magsoro rod` files
TOP_KEYS = set(Scene.model_fields) | set(RodConfig.model_fields)

UNKNOWN = "zz_unknown"  # a key no table has
DEPTH = 2000  # nesting of the deep values: beyond Python's default recursion limit

# numbers that must be > 0 (or >= 1), by the last key naming them; 'frequency' only in a field's time profile
# (a rotating field may turn either way), 'density' of the rod may be 0 (weightless)
POSITIVE = {"dx", "duration", "dt", "cfl", "depth", "density", "shear_modulus", "bulk_modulus", "C10", "radius",
            "length", "outer_radius", "width", "thickness", "scale", "size", "dimensions", "period", "diameter",
            "turns", "every", "fold_spread", "particles_per_cell", "order", "threads", "youngs_modulus", "end",
            "max_step", "n_nodes"}
NON_NEGATIVE = {"inner_radius", "damping", "wall_friction", "friction", "ramp", "start"}

# mutations that replace the entry's value; 'longer' / 'shorter' only for lists of numbers
VALUE_KINDS = ["nan", "inf", "-inf", "negative", "zero", "huge", "string", "numeric_string", "bool", "empty_list",
               "table", "deep_list", "deep_table", "delete"]


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _category(v) -> str:
    if _is_number(v):
        return "number"
    return {bool: "bool", str: "string", list: "list", dict: "table"}[type(v)]


def _entries(value, path=()):
    """The path (keys and list indices) of every table value and list item below ``value``, at any depth."""
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for k, v in items:
        yield path + (k,)
        yield from _entries(v, path + (k,))


ENTRIES = {name: list(_entries(data)) for name, data in SCENES.items()}


def _get(data, path):
    for p in path:
        data = data[p]
    return data


def _last_key(path) -> str:
    """The last table key of ``path``: for a list item, the key of its list."""
    return next(p for p in reversed(path) if isinstance(p, str))


def _kinds(name, path) -> list[str]:
    value = _get(SCENES[name], path)
    kinds = list(VALUE_KINDS)
    if isinstance(value, list) and value and all(_is_number(v) for v in value):
        kinds += ["longer", "shorter"]
    if isinstance(path[-1], str):
        kinds.append("rename")
    if isinstance(value, dict):
        kinds.append("unknown_key")
    return kinds


def _nested(depth, leaf):
    """``depth`` levels of lists (leaf []) or tables (leaf {}), built without recursion."""
    out = leaf
    for _ in range(depth):
        out = [out] if isinstance(leaf, list) else {UNKNOWN: out}
    return out


FIXED = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf, "huge": 1e300, "string": "abc",
         "numeric_string": "2e-4", "bool": True, "empty_list": []}


def _new_value(kind, old):
    """The value that mutation ``kind`` puts in place of ``old``."""
    if kind in FIXED:
        return FIXED[kind]
    if kind == "negative":  # same type as a number it replaces
        return (-abs(old) if old else type(old)(-1)) if _is_number(old) else -1.0
    if kind == "zero":
        return type(old)(0) if _is_number(old) else 0
    if kind == "longer":
        return old + old[-1:]
    if kind == "shorter":
        return old[:-1]
    if kind == "table":
        return {UNKNOWN: 1.0}
    return _nested(DEPTH, [] if kind == "deep_list" else {})


def _mutate(data, path, kind) -> None:
    parent, key = _get(data, path[:-1]), path[-1]
    if kind == "delete":
        del parent[key]
    elif kind == "rename":  # a typo: one character added
        parent[key + "x"] = parent.pop(key)
    elif kind == "unknown_key":
        parent[key][UNKNOWN] = 1.0
    else:
        parent[key] = _new_value(kind, parent[key])


def _must_refuse(name, path, kind, old) -> bool:
    """Whether refusing the mutation is the only right answer (else either answer is fine)."""
    if kind in ("nan", "inf", "-inf", "table", "deep_list", "deep_table", "longer", "shorter", "rename", "unknown_key"):
        return True  # non-finite numbers, unknown keys, 2000-deep values, vectors of the wrong length
    cat, key = _category(old), _last_key(path)
    if kind in ("negative", "zero", "huge"):
        if cat == "number":
            rod_density = name in ROD_SCENES and key == "density"
            positive = (key in POSITIVE and not rod_density) or (key == "frequency" and "profile" in path)
            non_negative = key in NON_NEGATIVE or rod_density or (key == "magnitude" and "magnetization" in path)
            new = _new_value(kind, old)  # 1e300 is never refused for its sign
            return (positive and new <= 0) or (non_negative and new < 0)
        return cat != "string" or key != "friction"  # a number for a string, bool, list or table ('sticky' or 0.5)
    if kind in ("string", "numeric_string"):
        return cat in ("number", "bool", "list")  # no coercion of "2e-4"; a string for a table may name a file
    if kind == "bool":
        return cat != "bool"
    if kind == "empty_list":
        return cat in ("number", "bool", "string", "table") or (cat == "list" and bool(old) and _is_number(old[0]))
    return False  # delete: the key may be optional


def _names(msg, key) -> bool:
    """Whether ``key`` appears in ``msg`` as a whole name (so 'B' is not found in 'Body')."""
    return re.search(rf"(?<!\w){re.escape(key)}(?!\w)", msg) is not None


def check_mutation(name, path, kind) -> None:
    """Parse scene ``name`` with ``kind`` applied at ``path``; an assertion (or any non-SceneError) on failure."""
    source = str(SCENES_DIR / name)
    data = copy.deepcopy(SCENES[name])
    old = _get(data, path)
    _mutate(data, path, kind)
    ignored = []  # exceptions Python only prints ("Exception ignored in: ..."), e.g. from a repr() in pydantic-core
    hook, sys.unraisablehook = sys.unraisablehook, ignored.append
    try:
        if name in ROD_SCENES:
            parse_rod_config(data, source)
        else:
            parse_scene(data, source, SCENES_DIR)
    except SceneError as exc:
        msg = str(exc).strip()
    else:
        msg = None
    finally:
        sys.unraisablehook = hook
    assert not ignored, f"{ignored[0].exc_type.__name__} printed while parsing: {ignored[0].exc_value}"
    if msg is None:
        assert not _must_refuse(name, path, kind, old), f"accepted: {kind} at {path}"
        return
    # one line naming the file, then a key of the scene (a top-level key, or the misspelt one)
    assert "\n" not in msg, msg
    assert msg.startswith(source + ": "), msg
    first = re.match(r"\w*", msg[len(source) + 2:])[0]
    assert first in TOP_KEYS or (kind == "rename" and first == path[0] + "x"), msg
    if _must_refuse(name, path, kind, old):  # a refusal that has to be about the mutated key: it names it
        key = _last_key(path)
        names = {"rename": [key, key + "x"], "unknown_key": [UNKNOWN]}.get(kind, [key])
        assert any(_names(msg, k) for k in names), f"{names} not named: {msg}"


@st.composite
def mutations(draw):
    name = draw(st.sampled_from(sorted(SCENES)))
    path = draw(st.sampled_from(ENTRIES[name]))
    kind = draw(st.sampled_from(_kinds(name, path)))
    return name, path, kind


def test_every_scene_file_parses():
    """The unmutated scenes are valid (so every refusal below comes from the mutation)."""
    for name, data in SCENES.items():
        if name in ROD_SCENES:
            parse_rod_config(copy.deepcopy(data), name)
        else:
            parse_scene(copy.deepcopy(data), name, SCENES_DIR)


@settings(max_examples=2000, derandomize=True, deadline=None, database=None)
@given(mutations())
def test_mutated_scenes_are_refused_in_one_line_naming_the_key(mutation):
    name, path, kind = mutation
    check_mutation(name, path, kind)


def test_deeply_nested_values_in_a_scene_file_are_refused(tmp_path):
    """2000 nested arrays or inline tables in the TOML text: one line, not a RecursionError."""
    for name, value in [("lists", "[" * DEPTH + "]" * DEPTH), ("tables", "{ a = " * DEPTH + "1" + " }" * DEPTH)]:
        for scene, load in [("cantilever_2d.toml", load_scene), ("rod_cantilever.toml", load_rod_config)]:
            path = tmp_path / f"{name}_{scene}"
            path.write_text(f"deep = {value}\n" + (SCENES_DIR / scene).read_text())
            with pytest.raises(SceneError) as exc:
                load(path)
            msg = str(exc.value).strip()
            assert "\n" not in msg and msg.startswith(f"{path}: "), msg


def test_pressure_cavity_of_the_wrong_dimension_is_refused():
    """A 2D scene's pressure cavity with a 3-component size (found by the mutations above): one line naming
    bodies[0].pressure.cavity.size, as for a body's own shape."""
    data = copy.deepcopy(SCENES["axisymmetric_tube.toml"])
    data["bodies"][0]["pressure"]["cavity"]["size"] = [0.002, 0.006, 0.006]
    with pytest.raises(SceneError) as exc:
        parse_scene(data, str(SCENES_DIR / "axisymmetric_tube.toml"), SCENES_DIR)
    msg = str(exc.value)
    assert "\n" not in msg and "pressure.cavity.size" in msg, msg
