"""Read and check scene files. Every error is one line naming the file, the key and what is allowed."""

from __future__ import annotations

import typing
from pathlib import Path

import pydantic
from pydantic import ValidationError

from magsoro.bundled import resolve_data_path
from magsoro.config_errors import check_nesting, short_repr
from magsoro.errors import SceneError
from magsoro.io.files import read_toml_file
from magsoro.scene.schema import SHAPES_2D, SHAPES_3D, Scene


def _loc_str(loc) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _inner_model(ann):
    """Strip Optional/list/Annotated and return the model class (or a list of union members)."""
    origin = typing.get_origin(ann)
    if origin is typing.Annotated:
        return _inner_model(typing.get_args(ann)[0])
    if origin in (list, tuple):
        return _inner_model(typing.get_args(ann)[0])
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        members = [a for a in typing.get_args(ann) if a is not type(None)]
        if len(members) == 1:
            return _inner_model(members[0])
        return [m for m in members if isinstance(m, type) and issubclass(m, pydantic.BaseModel)] or None
    if isinstance(ann, type) and issubclass(ann, pydantic.BaseModel):
        return ann
    return None


# tags of the callable discriminators in schema.py (vector or profile, library name or material table)
_UNION_TAGS = {"magnetization": {"vector": None, "profile": "profile"}, "material": {"name": None, "table": "material"},
               "robot": {"name": None, "table": "robot"}}


def _resolve(loc, root=None):
    """Follow loc through the model (Scene by default), dropping discriminator tags; return (clean loc, model class or None)."""
    from magsoro.scene.schema import AnyMagnetization, Material, Robot

    tagged = {"material": Material, "robot": Robot, "profile": _inner_model(AnyMagnetization), None: None}

    cls = Scene if root is None else root
    clean = []
    for part in loc:
        if isinstance(part, int):
            clean.append(part)
            continue
        if clean and clean[-1] in _UNION_TAGS and part in _UNION_TAGS[clean[-1]]:
            cls = tagged[_UNION_TAGS[clean[-1]][part]]
            continue
        if isinstance(cls, list):  # union: part is the tag
            match = [m for m in cls if getattr(m.model_fields.get("type"), "annotation", None) is not None and part in typing.get_args(m.model_fields["type"].annotation)]
            if match:
                cls = match[0]
                continue
            cls = None
        clean.append(part)
        if cls is not None and not isinstance(cls, list) and part in cls.model_fields:
            cls = _inner_model(cls.model_fields[part].annotation)
        else:
            cls = None
    return clean, cls


def _union_types(members) -> list[str]:
    """The 'type' values a union of models accepts (the members' Literal tags), in order."""
    if not isinstance(members, list):
        return []
    out = []
    for m in members:
        field = m.model_fields.get("type")
        if field is not None:
            out.extend(str(t) for t in typing.get_args(field.annotation) if str(t) not in out)
    return out


def format_validation_error(exc: ValidationError, source: str = "scene", root=None) -> str:
    """One line: '<source>: <key>: <problem>' for the first error, plus how many more there are."""
    errors = exc.errors()
    # a misspelt key shows as an unknown key plus a missing one: report the unknown key, it names the typo
    first = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    loc, _ = _resolve(first["loc"], root)
    key = _loc_str(loc) or "(top level)"
    kind = first["type"]
    if kind == "extra_forbidden":
        parent_loc, parent = _resolve(first["loc"][:-1], root)
        allowed = sorted(parent.model_fields) if isinstance(parent, type) else []
        import difflib

        close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        msg = (f"unknown key '{loc[-1]}'" + (f" (did you mean '{close[0]}'?)" if close else "")
               + (f"; allowed keys here: {', '.join(allowed)}" if allowed else ""))
    elif kind == "missing":
        msg = "required key is missing"
    elif kind == "union_tag_invalid":
        ctx = first.get("ctx", {})
        msg = f"unknown type {ctx.get('tag')!r}; allowed: {ctx.get('expected_tags')}"
    elif kind == "union_tag_not_found":
        _, members = _resolve(first["loc"], root)
        types = _union_types(members)
        msg = "needs a 'type' key" + (f"; allowed types: {', '.join(types)}" if types else "")
    else:
        msg = first["msg"]
        if kind == "value_error":  # our own validators' messages, without pydantic's prefix
            msg = msg.removeprefix("Value error, ")
        if "input" in first and not isinstance(first["input"], (dict, list)):
            msg += f" (got {short_repr(first['input'])})"
    more = f" (and {len(errors) - 1} more problem{'s' if len(errors) > 2 else ''})" if len(errors) > 1 else ""
    if not loc and kind == "value_error":  # a check across tables: its message names the keys
        return f"{source}: {msg}{more}"
    return f"{source}: {key}: {msg}{more}"


def parse_scene(data: dict, source: str = "scene", base_dir: Path | None = None) -> Scene:
    """Validate a scene given as a dict (as read from TOML) and run the cross-key checks."""
    check_nesting(data, source, SceneError)
    try:
        scene = Scene.model_validate(data)
    except ValidationError as exc:
        raise SceneError(format_validation_error(exc, source)) from None
    scene.base_dir = base_dir  # where relative file names resolve
    for i, b in enumerate(scene.bodies):
        b.key, b.source, b.base_dir = f"bodies[{i}]", source, base_dir
    scene.material_library_paths = [_rel(base_dir, f) for f in scene.material_library]
    for i, f in enumerate(scene.material_library):
        if not scene.material_library_paths[i].is_file():
            raise SceneError(f"{source}: material_library[{i}]: file '{scene.material_library_paths[i]}' not found")
    _expand_robot(scene, source, base_dir)
    check_scene(scene, source, base_dir)
    return scene


def _rel(base_dir, name) -> Path:
    return Path(name) if base_dir is None else Path(base_dir) / name


def _expand_robot(scene: Scene, source: str, base_dir) -> None:
    """Append the robot's parts (inline and from its file) to scene.bodies, remembering where each came from."""
    from magsoro.scene.schema import Robot, RobotFile

    robot = scene.robot
    if robot is None:
        return
    if isinstance(robot, str):
        robot = Robot(file=robot)
    for j, part in enumerate(robot.parts):
        part.key, part.source, part.base_dir = f"robot.parts[{j}]", source, base_dir
        scene.bodies.append(part)
    if robot.file is None:
        if not robot.parts:
            raise SceneError(f"{source}: robot: give a robot file or [[robot.parts]]")
        return
    path = _rel(base_dir, robot.file)
    key = "robot" if isinstance(scene.robot, str) else "robot.file"
    if not path.is_file():
        raise SceneError(f"{source}: {key}: robot file '{path}' not found")
    data = read_toml_file(path, SceneError, "robot file")
    try:
        rf = RobotFile.model_validate(data)
    except ValidationError as exc:
        raise SceneError(format_validation_error(exc, str(path), RobotFile)) from None
    for i, f in enumerate(rf.material_library):
        lib = _rel(path.parent, f)
        if not lib.is_file():
            raise SceneError(f"{path}: material_library[{i}]: file '{lib}' not found")
        scene.material_library_paths.append(lib)
    for j, part in enumerate(rf.parts):
        part.key, part.source, part.base_dir = f"parts[{j}]", str(path), path.parent
        scene.bodies.append(part)


def apply_preview(data: dict, source: str = "scene") -> dict:
    """The scene dict with its [preview] settings put in place of the [simulation] / [output] ones (a copy;
    ``data`` is not changed). A scene without a [preview] table is an error: the caller asked for one."""
    import copy

    from magsoro.scene.schema import Preview

    if "preview" not in data:
        raise SceneError(f"{source}: preview: --preview needs a [preview] table in the scene "
                         f"(keys: {', '.join(Preview.model_fields)})")
    try:
        prev = Preview.model_validate(data["preview"])
    except ValidationError:
        parse_scene(data, source)  # reports the bad [preview] key the way every scene key is reported
        raise
    out = copy.deepcopy(data)
    sim = out.setdefault("simulation", {})
    for key, value in prev.model_dump(exclude_none=True).items():
        if key == "every":
            out.setdefault("output", {})["every"] = value
        else:
            sim[key] = value
    return out


def read_scene_toml(path) -> dict:
    """The raw dict of a TOML scene file; a missing file or bad TOML raises :class:`SceneError`. A relative
    ``scenes/...`` or ``examples/...`` path that does not exist here reads the copy installed with the package
    (:func:`magsoro.bundled.resolve_data_path`)."""
    return read_toml_file(resolve_data_path(path), SceneError, "scene file")


def apply_overrides(data: dict, overrides, flag: str = "--set") -> dict:
    """The scene dict with each ``KEY=VALUE`` text of ``overrides`` set (a copy): KEY a dotted scene path as in
    ``magsoro sweep`` (list entries by name or index: ``bodies.beam.material.shear_modulus``), VALUE a JSON value
    or a bare word. A malformed entry or a path that does not exist raises :class:`SceneError` naming ``flag``."""
    import copy

    from magsoro.sweep.params import SweepError, parse_item, set_path

    out = copy.deepcopy(data)
    for spec in overrides or ():
        key, sep, text = spec.partition("=")
        key = key.strip()
        if not sep or not key or any(not p for p in key.split(".")):
            raise SceneError(f"{flag} {spec}: expected KEY=VALUE with KEY a dotted scene path, e.g. simulation.dx=1e-4")
        try:
            set_path(out, key, parse_item(text, spec, flag), spec, flag)
        except SweepError as exc:
            raise SceneError(str(exc)) from None
    return out


def load_scene(path, preview: bool = False, overrides=None) -> Scene:
    """Read a TOML scene file and validate it; ``preview=True`` applies its [preview] table first, then each
    ``KEY=VALUE`` of ``overrides`` (:func:`apply_overrides`: ``magsoro run --set``).
    Raises :class:`SceneError` with a one-line message. A relative ``scenes/...`` or ``examples/...`` path that
    does not exist here loads the copy installed with the package (:func:`magsoro.bundled.resolve_data_path`)."""
    path = resolve_data_path(path)
    data = read_scene_toml(path)
    if preview:
        data = apply_preview(data, str(path))
    if overrides:
        data = apply_overrides(data, overrides)
    scene = parse_scene(data, str(path), path.parent)
    scene.source_path = path
    return scene


def _vec_len(value, n, key, source):
    if value is not None and len(value) != n:
        raise SceneError(f"{source}: {key}: needs {n} components in a {n}D scene, got {len(value)}")


def _check_shape(shape, dim, key, source, base_dir=None):
    allowed = SHAPES_2D if dim == 2 else SHAPES_3D
    if shape.type not in allowed:
        raise SceneError(f"{source}: {key}.type: '{shape.type}' is not a {dim}D shape; allowed: {', '.join(allowed)}")
    for attr in ("center", "size"):
        if hasattr(shape, attr):
            _vec_len(getattr(shape, attr), dim, f"{key}.{attr}", source)
    if shape.type in ("cylinder", "tube"):
        _vec_len(shape.axis, 3, f"{key}.axis", source)
    if shape.type == "tube" and shape.inner_radius >= shape.outer_radius:
        raise SceneError(f"{source}: {key}.inner_radius: must be < outer_radius ({shape.outer_radius} m), got {shape.inner_radius}")
    if shape.type in ("mesh", "extrusion"):
        _vec_len(shape.position, 3, f"{key}.position", source)
    if shape.type in ("mesh", "extrusion", "arc"):
        _vec_len(shape.rotation, 3, f"{key}.rotation", source)
    if shape.type == "mesh":
        path = _rel(base_dir, shape.file)
        if not path.is_file():
            raise SceneError(f"{source}: {key}.file: mesh file '{path}' not found")
    if shape.type == "extrusion":
        for i, v in enumerate(shape.vertices):
            _vec_len(v, 2, f"{key}.vertices[{i}]", source)
        if len(shape.vertices) < 3:
            raise SceneError(f"{source}: {key}.vertices: a polygon needs at least 3 vertices")
    if shape.type == "arc":
        if dim == 3 and shape.thickness is None:
            raise SceneError(f"{source}: {key}.thickness: required for an arc in a 3D scene (m)")
        if dim == 2 and shape.thickness is not None:
            raise SceneError(f"{source}: {key}.thickness: not used in a 2D scene (the depth is simulation.depth)")
        if shape.width > 2 * shape.radius:
            raise SceneError(f"{source}: {key}.width: must be <= 2 x radius ({2 * shape.radius} m), got {shape.width}")
        if not 0 < shape.end_angle - shape.start_angle <= 360:
            raise SceneError(f"{source}: {key}.end_angle: must exceed start_angle by at most 360 degrees")
    if shape.type == "polygon":
        for i, v in enumerate(shape.vertices):
            _vec_len(v, 2, f"{key}.vertices[{i}]", source)
        if len(shape.vertices) < 3:
            raise SceneError(f"{source}: {key}.vertices: a polygon needs at least 3 vertices")
    if hasattr(shape, "size") and any(s <= 0 for s in shape.size):
        raise SceneError(f"{source}: {key}.size: every edge length must be > 0, got {shape.size}")


def check_scene(scene: Scene, source: str, base_dir: Path | None) -> None:
    """Checks that span several keys: dimensions, names, references, domain, files."""
    sim = scene.simulation
    dim = sim.dim
    _vec_len(sim.domain_lo, dim, "simulation.domain_lo", source)
    _vec_len(sim.domain_hi, dim, "simulation.domain_hi", source)
    if any(h <= l for l, h in zip(sim.domain_lo, sim.domain_hi)):
        raise SceneError(f"{source}: simulation.domain_hi: must exceed domain_lo along every axis")
    extent = [h - l for l, h in zip(sim.domain_lo, sim.domain_hi)]
    if min(extent) < 6 * sim.dx:
        raise SceneError(f"{source}: simulation.dx: {sim.dx} m is too coarse for a domain of {min(extent)} m (need at least 6 cells per axis)")
    _vec_len(sim.gravity, dim, "simulation.gravity", source)
    if not scene.bodies:
        raise SceneError(f"{source}: bodies: a scene needs at least one body ([[bodies]]) or robot part")
    names = [b.name for b in scene.bodies]
    for i, b in enumerate(scene.bodies):
        bsrc, bkey = b.source or source, b.key or f"bodies[{i}]"
        if b.name in names[:i]:
            raise SceneError(f"{bsrc}: {bkey}.name: duplicate body name '{b.name}'")
        _check_shape(b.shape, dim, f"{bkey}.shape", bsrc, b.base_dir)
        if b.pressure is not None:
            _check_shape(b.pressure.cavity, dim, f"{bkey}.pressure.cavity", bsrc, b.base_dir)
        _vec_len(b.velocity, dim, f"{bkey}.velocity", bsrc)
        stim = getattr(b.material, "stimulus", None)
        if stim is not None:
            _vec_len(stim.direction, dim, f"{bkey}.material.stimulus.direction", bsrc)
        mag = b.magnetization
        if b.magnetic and isinstance(mag, list) and all(c == 0 for c in mag):
            raise SceneError(f"{bsrc}: {bkey}.magnetization: body '{b.name}' is marked magnetic but its magnetisation is zero; give a non-zero vector (T) or a profile")
        if not isinstance(mag, list) and mag.type == "file" and not _rel(b.base_dir, mag.file).is_file():
            raise SceneError(f"{bsrc}: {bkey}.magnetization.file: file '{_rel(b.base_dir, mag.file)}' not found")
    for i, c in enumerate(scene.clamps):
        _check_shape(c.region, dim, f"clamps[{i}].region", source, base_dir)
        if c.body is not None and c.body not in names:
            raise SceneError(f"{source}: clamps[{i}].body: no body named '{c.body}'; bodies: {', '.join(names)}")
    for i, p in enumerate(scene.probes):
        if p.type == "collider_force":
            if p.bodies is not None:
                for name in p.bodies:
                    if name not in names:
                        raise SceneError(f"{source}: probes[{i}].bodies: no body named '{name}'; bodies: {', '.join(names)}")
                continue
            if p.collider >= len(scene.colliders):
                raise SceneError(f"{source}: probes[{i}].collider: {p.collider} is not a collider of the scene (it has "
                                 f"{len(scene.colliders)}: indices 0 to {len(scene.colliders) - 1} of [[colliders]])"
                                 if scene.colliders else f"{source}: probes[{i}].collider: the scene has no [[colliders]]")
            continue
        if p.type == "field" and p.position is not None:
            _vec_len(p.position, dim, f"probes[{i}].position", source)
            lo, hi = scene.simulation.domain_lo, scene.simulation.domain_hi
            if any(not (lo[a] <= p.position[a] <= hi[a]) for a in range(dim)):
                raise SceneError(f"{source}: probes[{i}].position: {list(p.position)} lies outside the domain "
                                 f"[{list(lo)}, {list(hi)}] m")
            continue
        if p.body not in names:
            raise SceneError(f"{source}: probes[{i}].body: no body named '{p.body}'; bodies: {', '.join(names)}")
        if p.type in ("tip", "point", "field"):
            _check_shape(p.region, dim, f"probes[{i}].region", source, base_dir)
    field_names = [f.name for f in scene.fields]
    for i, f in enumerate(scene.fields):
        if f.name is not None and f.name in field_names[:i]:
            raise SceneError(f"{source}: fields[{i}].name: duplicate field name '{f.name}'")
    probe_names = [p.name for p in scene.probes]
    for i, p in enumerate(scene.probes):
        if p.name in probe_names[:i]:
            raise SceneError(f"{source}: probes[{i}].name: duplicate probe name '{p.name}'")
    for i, c in enumerate(scene.colliders):
        for attr in ("point", "normal", "center", "size"):
            if hasattr(c, attr):
                _vec_len(getattr(c, attr), dim, f"colliders[{i}].{attr}", source)
        if c.type == "half_space" and all(v == 0 for v in c.normal):
            raise SceneError(f"{source}: colliders[{i}].normal: must be non-zero")
        if c.path is not None:
            for j, pos in enumerate(c.path.positions):
                _vec_len(pos, dim, f"colliders[{i}].path.positions[{j}]", source)
    for i, f in enumerate(scene.fields):
        if f.type == "keyframes":
            if f.file is not None:
                path = Path(f.file) if base_dir is None else Path(base_dir) / f.file
                if not path.is_file():
                    raise SceneError(f"{source}: fields[{i}].file: file '{path}' not found")
            else:
                if len(f.times) != len(f.values):
                    raise SceneError(f"{source}: fields[{i}].values: needs one vector per time ({len(f.times)} times, {len(f.values)} values)")
                for j, v in enumerate(f.values):
                    _vec_len(v, 3, f"fields[{i}].values[{j}]", source)
        if getattr(f, "path", None) is not None:
            for j, pos in enumerate(f.path.positions):
                _vec_len(pos, 3, f"fields[{i}].path.positions[{j}]", source)
    if scene.output.every is not None and scene.output.every > sim.duration:
        raise SceneError(f"{source}: output.every: {scene.output.every} s exceeds simulation.duration {sim.duration} s")
    if sim.plane == "axisymmetric":
        check_axisymmetric(scene, source)


def _along_axis(v, tol: float = 1e-12) -> bool:
    """Whether a 3-vector points along the y axis (the axis of an axisymmetric scene), or is zero."""
    x, y, z = (abs(float(c)) for c in v)
    return x <= tol * y and z <= tol * y


def _on_axis(p) -> bool:
    return float(p[0]) == 0.0 and float(p[2]) == 0.0


def check_axisymmetric(scene: Scene, source: str) -> None:
    """simulation.dim = 'axisymmetric': what is not symmetric about the y axis, or not built for it yet, is refused
    in one line naming the key (docs/engine.md, "Axisymmetric bodies")."""
    sim = scene.simulation
    why = "in an axisymmetric scene"

    def refuse(key, text):
        raise SceneError(f"{source}: {key}: {text} {why}")

    if sim.domain_lo[0] != 0.0:
        refuse("simulation.domain_lo[0]", f"is {sim.domain_lo[0]:g} m; it must be 0, the axis r = 0,")
    if sim.plane_z != 0.0:
        refuse("simulation.plane_z", "must be 0: the (r, z) half-plane is the x-y plane of the field sources, z = 0,")
    if sim.gravity is not None and sim.gravity[0] != 0.0:
        refuse("simulation.gravity", "must be along the axis, [0, g_z],")
    if sim.magnetic_interaction != "none":
        refuse("simulation.magnetic_interaction", "'dipole' (the bodies' own field) is not built yet")
    for i, b in enumerate(scene.bodies):
        key = b.key or f"bodies[{i}]"
        mag = b.magnetization
        if isinstance(mag, list) and len(mag) == 3 and mag[2] != 0.0:
            refuse(f"{key}.magnetization", "has a hoop (third) component; give [B_r, B_z, 0] T")
        mat = b.material
        if getattr(mat, "prony", None) is not None:
            refuse(f"{key}.material.prony", "Prony viscoelasticity is not built yet")
    for i, f in enumerate(scene.fields):
        key = f"fields[{i}]"
        if f.type == "uniform":
            if not _along_axis(f.B):
                refuse(f"{key}.B", f"{list(f.B)} is not along the axis; give [0, B_z, 0] T")
        elif f.type == "keyframes":
            for j, v in enumerate(f.values or []):
                if not _along_axis(v):
                    refuse(f"{key}.values[{j}]", f"{list(v)} is not along the axis; give [0, B_z, 0] T")
        elif f.type in ("dipole", "cylinder_magnet", "loop", "helmholtz", "maxwell"):
            direction = f.moment if f.type == "dipole" else f.axis
            if not _along_axis(direction):
                refuse(f"{key}.{'moment' if f.type == 'dipole' else 'axis'}", f"{list(direction)} is not along the axis (y)")
            if not _on_axis(f.position):
                refuse(f"{key}.position", f"{list(f.position)} is off the axis; give [0, z, 0]")
            path = getattr(f, "path", None)
            for j, pos in enumerate(path.positions if path is not None else []):
                if not _on_axis(pos):
                    refuse(f"{key}.path.positions[{j}]", f"{list(pos)} is off the axis; give [0, z, 0]")
        else:
            refuse(f"{key}.type", f"'{f.type}' is not symmetric about the axis; allowed: uniform and keyframes along "
                                  f"the axis, and dipole, cylinder_magnet, loop, helmholtz, maxwell on it")
    for i, c in enumerate(scene.colliders):
        key = f"colliders[{i}]"
        across = c.type == "half_space" and float(c.normal[0]) == 0.0
        coaxial = c.type == "cylinder" and float(c.center[0]) == 0.0 and _along_axis(c.axis)
        centred = c.type == "sphere" and float(c.center[0]) == 0.0
        moving_off = c.path is not None and any(float(pos[0]) != 0.0 for pos in c.path.positions) and not across
        if not (across or coaxial or centred) or moving_off:
            refuse(f"{key}", "is not symmetric about the axis; allowed: planes across it (half_space with normal [0, 1] "
                             "or [0, -1]), and cylinders (axis [0, 1, 0]) and spheres centred on it (center [0, z])")
