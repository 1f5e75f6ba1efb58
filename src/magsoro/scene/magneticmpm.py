"""Robot files of the magneticMPM research prototype (YAML) turned into magsoro scenes (docs/import.md).

The prototype describes a robot as a flat mapping (``name``, ``n_segments``, ``remenance`` [sic], ``segments``)
whose ``segments`` list holds one mapping per segment (``mesh``, ``magnetisation_vector``, ``density``,
``shear_modulus``, ``fixed``), with the meshes in a ``meshes/`` folder beside the YAML file, in mm. Each segment
becomes one ``[[robot.parts]]`` of a 3D scene: a mesh shape scaled to metres, a Neo-Hookean material, the remanence
``remenance x magnetisation_vector`` (T) and ``clamped = true`` where the segment is fixed. Simulation settings
(grid spacing, domain, floor, gravity) are derived from the meshes. Units assumed for the file's numbers: T for
``remenance``, kg/m^3 for ``density``, Pa for ``shear_modulus``; mesh lengths times ``scale`` give metres.

Nothing here runs the engine; :func:`fill_report` fills the written scene (as ``magsoro show`` does) to compare
the particle volume with the meshes'.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magsoro.config_errors import short_repr
from magsoro.errors import MagsoroError

TOP_KEYS = ("name", "n_segments", "remenance", "segments")
SEGMENT_KEYS = ("mesh", "magnetisation_vector", "density", "shear_modulus", "fixed")
SEGMENT_REQUIRED = ("mesh", "magnetisation_vector", "density", "shear_modulus")

# Plausible ranges, to catch a file written in other units (g/cm^3, kg/mm^3, MPa, mT); outside them the import
# still writes the scene and says so.
DENSITY_RANGE = (100.0, 25000.0)  # kg/m^3: foams to tungsten-loaded rubber
SHEAR_MODULUS_RANGE = (100.0, 1e10)  # Pa: soft gels to hard plastics
MAX_REMANENCE = 2.0  # T: above the best NdFeB


class RobotImportError(MagsoroError):
    """A robot file that cannot be imported; the message names the file and the key."""


@dataclass
class Segment:
    index: int
    mesh: Path  # resolved path of the mesh file
    vector: list[float]  # magnetisation_vector as given
    density: float  # kg/m^3
    shear_modulus: float  # Pa
    fixed: bool


@dataclass
class Robot:
    path: Path
    name: str
    remanence: float  # T (the file's "remenance")
    segments: list[Segment]


@dataclass
class Imported:
    """A converted robot: the scene as a dict (as TOML reads it) and as TOML text, plus what was derived."""

    scene: dict
    text: str
    robot: Robot
    dx: float  # m
    thinnest: float  # m: thickness of the thinnest segment
    floor: float | None  # m: height of the floor collider, None without one
    mesh_volumes: list[float]  # m^3 per segment
    warnings: list[str] = field(default_factory=list)


# ---------------------------------------------------------------- reading
def _yaml_loader():
    """PyYAML's safe loader, refusing duplicate keys (plain PyYAML keeps the last one silently)."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def mapping(loader, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = loader.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return yaml.SafeLoader.construct_mapping(loader, node, deep)

    Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)
    return Loader


#: values a robot file may hold once its aliases are expanded (a robot of a few hundred segments holds a few thousand)
MAX_YAML_VALUES = 100_000


def _expanded_size(node, limit: int) -> int:
    """How many values the composed YAML ``node`` holds with every alias expanded, counted without expanding
    them (an alias is the node it names, shared): a few hundred bytes of nested anchors (a 'billion laughs') expand
    to 10^9 values. Counting stops past ``limit``; an alias cycle counts as past it."""
    import yaml

    sizes: dict[int, int] = {}
    busy: set[int] = set()

    def size(n) -> int:
        key = id(n)
        if key in sizes:
            return sizes[key]
        if key in busy:  # a node that contains itself
            return limit + 1
        busy.add(key)
        total = 1
        if isinstance(n, yaml.SequenceNode):
            children = n.value
        elif isinstance(n, yaml.MappingNode):
            children = [c for pair in n.value for c in pair]
        else:
            children = []
        for c in children:
            total += size(c)
            if total > limit:
                break
        busy.discard(key)
        sizes[key] = total
        return total

    return size(node)


def _load_yaml(path, text: str):
    """The data of the YAML ``text`` with the duplicate-refusing safe loader; a document whose aliases would expand
    past MAX_YAML_VALUES values is refused from its composed form, before any value is built."""
    import yaml

    loader = _yaml_loader()(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if _expanded_size(node, MAX_YAML_VALUES) > MAX_YAML_VALUES:
            raise RobotImportError(f"{path}: its anchors and aliases expand to more than {MAX_YAML_VALUES:,} values "
                                   f"(aliases nested in aliases); write the values out")
        return loader.construct_document(node)
    finally:
        loader.dispose()


def _unknown(path, where: str, key, allowed) -> RobotImportError:
    near = difflib.get_close_matches(str(key), allowed, n=1)
    hint = f" (did you mean '{near[0]}'?)" if near else ""
    return RobotImportError(f"{path}: {where}{key}: unknown key{hint}; allowed: {', '.join(allowed)}")


def _number(path, key: str, value, positive: bool = True) -> float:
    # PyYAML follows YAML 1.1, where '1e5' (no dot) is a string: accept numbers written that way
    if isinstance(value, str):
        try:
            value = float(value.strip())
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RobotImportError(f"{path}: {key}: expected a finite number, got {short_repr(value)}")
    if positive and not value > 0:
        raise RobotImportError(f"{path}: {key}: must be > 0, got {short_repr(value)}")
    return float(value)


def _find_mesh(path: Path, key: str, name) -> Path:
    if not isinstance(name, str) or not name.strip():
        raise RobotImportError(f"{path}: {key}: expected a mesh file name, got {short_repr(name)}")
    from magsoro.geometry.mesh import MESH_SUFFIXES

    here = path.parent
    places = [here / "meshes" / name, here / name]  # the format's meshes/ folder first, then a path from the file
    for p in places:
        if p.is_file():
            if p.suffix.lower() not in MESH_SUFFIXES:
                raise RobotImportError(f"{path}: {key}: mesh file '{p}' has the unsupported format '{p.suffix}'; "
                                       f"use {', '.join(MESH_SUFFIXES)}")
            return p
    raise RobotImportError(f"{path}: {key}: mesh file '{name}' not found (looked for {places[0]} and {places[1]})")


def read_robot(path) -> Robot:
    """Read and check a prototype robot file. Raises :class:`RobotImportError` with one line naming the file and
    the key for an unknown or missing key, a wrong value or a missing mesh."""
    import yaml

    from magsoro.io.files import read_text_file

    path = Path(path)
    text = read_text_file(path, RobotImportError, "robot file")
    try:
        data = _load_yaml(path, text)  # a SafeLoader subclass: no arbitrary objects
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}, column {mark.column + 1}:" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise RobotImportError(f"{path}: not valid YAML:{where} {problem}") from None
    if not isinstance(data, dict):
        raise RobotImportError(f"{path}: expected a mapping of {', '.join(TOP_KEYS)} at the top, got "
                               f"{type(data).__name__ if data is not None else 'an empty file'}")
    for key in data:
        if key not in TOP_KEYS:
            raise _unknown(path, "", key, TOP_KEYS)
    for key in ("remenance", "segments"):
        if key not in data:
            raise RobotImportError(f"{path}: {key}: required key missing")
    name = data.get("name", path.stem)
    if not isinstance(name, (str, int, float)) or isinstance(name, bool):
        raise RobotImportError(f"{path}: name: expected a string, got {short_repr(name)}")
    remanence = _number(path, "remenance", data["remenance"], positive=False)
    if remanence < 0:
        raise RobotImportError(f"{path}: remenance: must be >= 0 T, got {short_repr(remanence)} (the sign goes into the vectors)")
    segments = data["segments"]
    if not isinstance(segments, list) or not segments:
        raise RobotImportError(f"{path}: segments: expected a non-empty list of segment mappings, got {short_repr(segments)}")
    if "n_segments" in data:
        n = data["n_segments"]
        if isinstance(n, bool) or not isinstance(n, int):
            raise RobotImportError(f"{path}: n_segments: expected an integer, got {short_repr(n)}")
        if n != len(segments):
            raise RobotImportError(f"{path}: n_segments: says {n} but segments lists {len(segments)}")
    out = []
    for i, seg in enumerate(segments):
        key = f"segments[{i}]"
        if not isinstance(seg, dict):
            raise RobotImportError(f"{path}: {key}: expected a mapping of {', '.join(SEGMENT_KEYS)}, got {short_repr(seg)}")
        for k in seg:
            if k not in SEGMENT_KEYS:
                raise _unknown(path, f"{key}.", k, SEGMENT_KEYS)
        for k in SEGMENT_REQUIRED:
            if k not in seg:
                raise RobotImportError(f"{path}: {key}.{k}: required key missing")
        vec = seg["magnetisation_vector"]
        if not isinstance(vec, list) or len(vec) != 3:
            raise RobotImportError(f"{path}: {key}.magnetisation_vector: expected a list of 3 numbers, got {short_repr(vec)}")
        vec = [_number(path, f"{key}.magnetisation_vector[{j}]", v, positive=False) for j, v in enumerate(vec)]
        fixed = seg.get("fixed", False)
        if fixed in (0, 1) and not isinstance(fixed, float):
            fixed = bool(fixed)
        else:
            raise RobotImportError(f"{path}: {key}.fixed: expected true or false, got {short_repr(fixed)}")
        out.append(Segment(
            index=i,
            mesh=_find_mesh(path, f"{key}.mesh", seg["mesh"]),
            vector=vec,
            density=_number(path, f"{key}.density", seg["density"]),
            shear_modulus=_number(path, f"{key}.shear_modulus", seg["shear_modulus"]),
            fixed=fixed,
        ))
    return Robot(path=path, name=str(name), remanence=remanence, segments=out)


# ---------------------------------------------------------------- converting
def _thickness(mesh) -> float:
    """Thickness of a solid (m): the smaller of its thinnest extent (oriented bounding box) and 4 V / A (the
    diameter of a long rod, twice the thickness of a thin sheet, which the box overestimates when curved)."""
    try:
        obb = float(np.min(mesh.bounding_box_oriented.primitive.extents))
    except Exception:  # noqa: BLE001 - a degenerate hull: fall back to the axis-aligned box
        obb = float(np.min(mesh.extents))
    return min(obb, 4.0 * float(mesh.volume) / float(mesh.area))


def _round(x: float, digits: int = 4) -> float:
    return float(f"{x:.{digits}g}")


def _part_name(i: int) -> str:
    return f"segment_{i}"


def convert(robot: Robot, out: Path, scale: float = 1e-3, cells_across: float = 3.0, particles_per_cell: int = 2,
            floor: str | float = "auto", gravity: float = 9.81, duration: float = 0.1,
            friction: float = 0.5) -> Imported:
    """Build the scene of ``robot`` for a scene file written at ``out`` (mesh paths are made relative to it).

    ``scale``: metres per mesh unit (1e-3 for meshes in mm). ``cells_across``: grid cells across the thinnest
    segment (dx = its thickness / cells_across). ``floor``: 'auto' (a floor at the lowest point of the meshes
    unless a segment is fixed), 'none', 'lowest', or a height in m. ``gravity``: m/s^2 along -z (0: none).
    ``friction``: Coulomb coefficient of the floor. ``duration``: simulated time, s.
    """
    from magsoro.geometry.mesh import MeshError, load_mesh

    if not scale > 0 or not math.isfinite(scale):
        raise RobotImportError(f"--scale: must be a finite number > 0 (m per mesh unit), got {scale}")
    if not cells_across > 0:
        raise RobotImportError(f"--cells-across: must be > 0, got {cells_across}")
    meshes = []
    for seg in robot.segments:
        try:
            meshes.append(load_mesh(seg.mesh, scale=scale))
        except MeshError as exc:
            raise RobotImportError(f"{robot.path}: segments[{seg.index}].mesh: {exc}") from None
    warnings = []
    for seg in robot.segments:
        key = f"{robot.path}: segments[{seg.index}]"
        if not DENSITY_RANGE[0] <= seg.density <= DENSITY_RANGE[1]:
            warnings.append(f"{key}.density = {seg.density:g} is read as kg/m^3, outside {DENSITY_RANGE[0]:g} to "
                            f"{DENSITY_RANGE[1]:g}: check the file's units")
        if not SHEAR_MODULUS_RANGE[0] <= seg.shear_modulus <= SHEAR_MODULUS_RANGE[1]:
            warnings.append(f"{key}.shear_modulus = {seg.shear_modulus:g} is read as Pa, outside "
                            f"{SHEAR_MODULUS_RANGE[0]:g} to {SHEAR_MODULUS_RANGE[1]:g}: check the file's units")
        br = robot.remanence * float(np.linalg.norm(seg.vector))
        if br > MAX_REMANENCE:
            warnings.append(f"{key}: |remenance x magnetisation_vector| = {br:g} T is above {MAX_REMANENCE:g} T: "
                            "check the units (T) and that the vector is a direction")
    lo = np.min([m.bounds[0] for m in meshes], axis=0)
    hi = np.max([m.bounds[1] for m in meshes], axis=0)
    thicknesses = [_thickness(m) for m in meshes]
    thinnest = min(thicknesses)
    dx = _round(thinnest / cells_across)
    extent = float(np.max(hi - lo))
    # room to bend and swing by the robot's own size on every side; the grid block follows the particles, so a
    # large domain costs nothing per step (docs/engine.md, "Grid block")
    margin = math.ceil(max(extent, 4 * dx) / dx) * dx
    has_fixed = any(s.fixed for s in robot.segments)
    if floor == "auto":
        floor_z = None if has_fixed else float(lo[2])
    elif floor == "none":
        floor_z = None
    elif floor == "lowest":
        floor_z = float(lo[2])
    else:
        floor_z = float(floor)
        if floor_z > lo[2] + 1e-12:
            raise RobotImportError(f"--floor: {floor_z:g} m is above the robot's lowest point ({lo[2]:g} m)")
    # domain_lo starts a whole number of cells below the meshes' lower bounds (the particle lattice starts at it);
    # the search below then shifts it by less than a cell to the lattice that fills the meshes most exactly
    below = margin if floor_z is None else (lo[2] - floor_z) + 4 * dx
    cells_below = [math.ceil(margin / dx)] * 2 + [math.ceil(below / dx - 1e-9)]
    domain_lo = [_exact(lo[a] - cells_below[a] * dx) for a in range(3)]
    domain_hi = [_exact(hi[a] + margin) for a in range(3)]
    if floor_z is not None and domain_lo[2] > floor_z - 2 * dx:  # keep the floor inside, off the wall cells
        domain_lo[2] = _exact(domain_lo[2] - 2 * dx)
    shift, fill_error = _best_lattice_shift(meshes, dx, particles_per_cell, np.asarray(domain_lo))
    if shift is not None:  # move the lattice (and the grid) by less than a cell: domain_lo goes one cell lower
        domain_lo = [_exact(domain_lo[a] + shift[a] - dx) for a in range(3)]

    out_dir = Path(out).resolve().parent
    parts, comments = [], []
    n = len(robot.segments)
    for seg, mesh, t in zip(robot.segments, meshes, thicknesses):
        part = {
            "name": _part_name(seg.index),
            "shape": {"type": "mesh", "file": _relpath(seg.mesh, out_dir), "scale": scale},
            "material": {"density": seg.density, "shear_modulus": seg.shear_modulus},
            "magnetization": [robot.remanence * v for v in seg.vector],
        }
        if seg.fixed:
            part["clamped"] = True
        if n > 1:
            part["priority"] = n - seg.index
        parts.append(part)
        comments.append(
            f"segment {seg.index} of {robot.path.name}: mesh {seg.mesh.name}, {mesh.volume * 1e9:.6g} mm^3, "
            f"thickness {t * 1e3:.4g} mm; Br = remenance {robot.remanence:g} T x magnetisation_vector {_fmt_vec(seg.vector)}"
            + ("; fixed: clamped" if seg.fixed else ""))
    simulation = {
        "dim": 3,
        "dx": dx,
        "particles_per_cell": int(particles_per_cell),
        "domain_lo": domain_lo,
        "domain_hi": domain_hi,
        "duration": float(duration),
    }
    if gravity:
        simulation["gravity"] = [0.0, 0.0, -float(gravity)]
    scene = {"name": robot.name, "simulation": simulation, "robot": {"parts": parts}}
    if floor_z is not None:
        scene["colliders"] = [{"type": "half_space", "point": [0.0, 0.0, floor_z], "normal": [0.0, 0.0, 1.0],
                               "mode": "friction", "friction": float(friction)}]
    import textwrap

    prose = [
        f"Imported from {robot.path.name} (magneticMPM robot format) by magsoro import-magneticmpm.",
        f"Units assumed: mesh lengths x {scale:g} m per file unit (--scale), remenance in T, density in kg/m^3,",
        "shear_modulus in Pa (Neo-Hookean, bulk modulus 20 G). Each part's magnetization is remenance x its",
        "magnetisation_vector, in the reference frame (T). Fixed segments are clamped whole.",
        f"dx: {cells_across:g} cells across the thinnest segment ({thinnest * 1e3:.4g} mm: the smaller of its thinnest",
        "extent and 4 V / A). Domain: the meshes' bounds plus the robot's size on every side"
        + (" (below: down to the floor)" if floor_z is not None else "") + ", its corner shifted by less than a cell",
        "to bring each part's particle volume closest to its mesh's"
        + (f" (worst {100 * fill_error:.2g} %)." if fill_error is not None else " (robot too large to search: not shifted)."),
        "Floor: " + (f"a half-space at z = {floor_z:g} m, Coulomb friction {friction:g} (our default)." if floor_z is not None
                     else "none" + (" (a segment is fixed; --floor lowest adds one)." if has_fixed else ".")),
        "Gravity: " + (f"{gravity:g} m/s^2 along -z (z is up)." if gravity else "none."),
        "Where meshes overlap, the part with the higher priority (the earlier segment) keeps the shared particles.",
        "The robot file gives no field source: add [[fields]] tables (docs/scenes.md), for example",
    ]
    header = textwrap.wrap(" ".join(prose), 110) + [
        "  [[fields]]", '  type = "uniform"', "  B = [0.0, 0.0, 0.02]", '  profile = { type = "ramp", duration = 0.05 }']
    text = _scene_text(scene, header, comments)
    volumes = [float(m.volume) for m in meshes]
    return Imported(scene=scene, text=text, robot=robot, dx=dx, thinnest=thinnest, floor=floor_z,
                    mesh_volumes=volumes, warnings=warnings)


#: Most lattice sites the search for the lattice shift may test (about 100 MB of positions)
MAX_SHIFT_SITES = 4e6


def _best_lattice_shift(meshes, dx: float, particles_per_cell: int, origin: np.ndarray, max_sites: float = MAX_SHIFT_SITES):
    """The shift of the particle lattice (m, per axis, below one particle spacing h) that brings every segment's
    particle volume closest to its mesh's volume (smallest worst relative error), and that error.

    The lattice a scene fills is origin + (i + 1/2) h. Filling each mesh once on a lattice m times finer
    (spacing h / m) gives, for each of the m^3 shifts (k + 1/2) h / m, k = 0..m-1 per axis, the particles of
    the shifted coarse lattice: the fine sites with the matching index residues mod m. Faces that are not on a
    lattice plane would otherwise cost up to one particle layer (1/6 of the volume of a segment 6 particles
    thick). m = 4, or 2 for large robots; (None, None) when even that exceeds ``max_sites``.
    """
    from magsoro.geometry.mesh import MeshShape
    from magsoro.geometry.primitives import lattice_points

    h = dx / particles_per_cell
    shapes = [MeshShape(mesh.vertices, mesh.faces) for mesh in meshes]
    coarse = sum(float(np.prod(np.floor((s.bounds()[1] - s.bounds()[0]) / h) + 2)) for s in shapes)
    m = next((k for k in (4, 2) if coarse * k**3 <= max_sites), None)
    if m is None:
        return None, None
    hf = h / m
    counts = []
    for s in shapes:
        lo, hi = s.bounds()
        pts = lattice_points(lo, hi, hf, 1, origin)
        j = np.rint((pts[s.contains(pts)] - origin) / hf - 0.5).astype(np.int64) % m
        counts.append(np.bincount((j[:, 0] * m + j[:, 1]) * m + j[:, 2], minlength=m**3))
    volumes = np.array([s.volume() for s in shapes])
    err = np.abs(np.array(counts) * h**3 / volumes[:, None] - 1.0)  # (segments, residues)
    best = int(np.argmin(err.max(axis=0) + 1e-9 * err.sum(axis=0)))
    residue = np.array([best // (m * m), (best // m) % m, best % m])
    # a coarse site origin + shift + (i + 1/2) h is the fine site j = k + (i + 1/2) m with shift = (k + 1/2) hf
    k = (residue - m // 2) % m
    return (k + 0.5) * hf, float(err[:, best].max())


def _exact(x: float) -> float:
    """x rounded to 12 significant digits: tidy in the file, and far below the lattice spacing."""
    return float(f"{x:.12g}")


def _fmt_vec(v) -> str:
    return "[" + ", ".join(f"{c:g}" for c in v) + "]"


def _relpath(path: Path, start: Path) -> str:
    import os

    try:
        return Path(os.path.relpath(Path(path).resolve(), start)).as_posix()
    except ValueError:  # another drive (Windows): no relative path exists
        return Path(path).resolve().as_posix()


# ---------------------------------------------------------------- writing
def _scene_text(scene: dict, header: list[str], part_comments: list[str]) -> str:
    from magsoro.io.tomlwrite import toml_value

    def value(v) -> str:
        return toml_value(v, signed_zero=False)  # a -0.0 left by the conversions is written 0.0

    lines = [f"# {h}" for h in header]
    lines.append(f"name = {value(scene['name'])}")
    lines += ["", "[simulation]"] + [f"{k} = {value(v)}" for k, v in scene["simulation"].items()]
    for part, comment in zip(scene["robot"]["parts"], part_comments):
        lines += ["", f"# {comment}", "[[robot.parts]]"] + [f"{k} = {value(v)}" for k, v in part.items()]
    for collider in scene.get("colliders", []):
        lines += ["", "[[colliders]]"] + [f"{k} = {value(v)}" for k, v in collider.items()]
    return "\n".join(lines) + "\n"


def fill_report(text: str, out: Path) -> list[dict]:
    """Fill the scene ``text`` (to be written at ``out``) as a run would and return, per part, its particles,
    the meshes' volume and the particles' volume (m^3). Raises SceneError if the scene does not validate."""
    import tomllib

    from magsoro.scene import parse_scene
    from magsoro.scene.build import fill_bodies

    out = Path(out)
    scene = parse_scene(tomllib.loads(text), str(out), out.resolve().parent)
    return fill_bodies(scene, str(out)).report
