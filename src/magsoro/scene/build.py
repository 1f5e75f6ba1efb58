"""Turn a validated :class:`~magsoro.scene.schema.Scene` into engine objects (Model, Control, settings, probes)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magsoro.errors import SceneError
from magsoro.fields import (
    CuboidMagnet,
    CurrentLoop,
    CylinderMagnet,
    Dipole,
    HelmholtzPair,
    Keyframes,
    KeyframedVector,
    MaxwellPair,
    Ramp,
    Rotating,
    Sine,
    Uniform,
)
from magsoro.geometry import magnetization as magprofiles
from magsoro.geometry.mesh import MeshError, MeshShape
from magsoro.geometry.primitives import (
    AnnularSector,
    Box,
    Cylinder,
    Polygon,
    Rectangle,
    Slab,
    Sphere,
    Transformed,
    Tube,
    euler_rotation,
    fill_lattice,
)
from magsoro.materials.library import MaterialLibraryError, get_material, load_library
from magsoro.mpm.laws.elastic import DEFAULT_LAW, FIT_MODEL_LAWS, LAWS, PARAMETER_KEYS, law_of_file_model
from magsoro.mpm.colliders import WALL_CELLS, Collider
from magsoro.mpm.laws.eigenstrain import KeyframeStimulus, SineStimulus, Stimulus
from magsoro.mpm.laws.prony import prony_problem
from magsoro.mpm.kernels.stencil import MAGNETIZATION_FOLLOWS
from magsoro.mpm.model import Control, ContactSettings, Model, SolverSettings
from magsoro.scene.schema import Scene


def make_shape(spec, base_dir: Path | None = None, dim: int = 3):
    """Geometry object for a shape table of the scene; mesh files resolve against ``base_dir``."""
    t = spec.type
    if t == "box":
        return Box(spec.center, spec.size)
    if t == "cylinder":
        return Cylinder(spec.center, spec.radius, spec.length, spec.axis)
    if t == "sphere":
        return Sphere(spec.center, spec.radius)
    if t == "rectangle":
        return Rectangle(spec.center, spec.size, np.deg2rad(spec.angle))
    if t == "polygon":
        return Polygon(spec.vertices)
    if t == "tube":
        return Tube(spec.center, spec.outer_radius, spec.inner_radius, spec.length, spec.axis)
    if t == "extrusion":
        return Transformed(Slab(Polygon(spec.vertices), spec.thickness), spec.position, euler_rotation(spec.rotation))
    if t == "arc":
        sector = AnnularSector(spec.radius, spec.width, np.deg2rad(spec.start_angle), np.deg2rad(spec.end_angle))
        if dim == 2:
            return Transformed(sector, spec.center)
        return Transformed(Slab(sector, spec.thickness), spec.center, euler_rotation(spec.rotation))
    if t == "mesh":
        path = Path(spec.file) if base_dir is None else Path(base_dir) / spec.file
        return MeshShape.from_file(path, spec.scale, spec.position, euler_rotation(spec.rotation))
    raise SceneError(f"unknown shape type {t!r}")


def _pad3(v, fill=0.0):
    out = np.full(3, fill, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64).ravel()
    out[: len(v)] = v
    return out


def make_field(spec, base_dir: Path | None, key: str = "fields"):
    t = spec.type
    if t == "uniform":
        if spec.profile is None:
            return Uniform(spec.B)
        p = spec.profile
        if p.type == "ramp":
            return Uniform(Ramp(spec.B, p.duration, p.start))
        return Uniform(Sine(spec.B, p.frequency, np.deg2rad(p.phase), p.offset))
    if t == "rotating":
        return Uniform(Rotating(spec.magnitude, spec.frequency, spec.u, spec.v, np.deg2rad(spec.phase), spec.ramp))
    if t == "keyframes":
        if spec.file is not None:
            path = Path(spec.file) if base_dir is None else Path(base_dir) / spec.file
            try:
                return Uniform(KeyframedVector.from_csv(path))
            except (ValueError, FileNotFoundError) as exc:
                raise SceneError(f"{key}.file: {exc}") from None
        return Uniform(KeyframedVector(spec.times, spec.values))
    path = Keyframes(spec.path.times, spec.path.positions) if getattr(spec, "path", None) is not None else None
    if t == "dipole":
        return Dipole(spec.moment, spec.position, path)
    if t == "cylinder_magnet":
        return CylinderMagnet(spec.diameter, spec.length, spec.remanence, spec.position, spec.axis, spec.model, spec.order, path=path)
    if t == "cuboid_magnet":
        return CuboidMagnet(spec.dimensions, spec.remanence, spec.position, spec.orientation, path=path)
    if t in ("loop", "helmholtz", "maxwell"):
        if t == "loop":
            return CurrentLoop(spec.radius, spec.current, spec.position, spec.axis, turns=spec.turns)
        cls = HelmholtzPair if t == "helmholtz" else MaxwellPair
        return cls(spec.radius, spec.current, spec.position, spec.axis, turns=spec.turns)
    raise SceneError(f"unknown field type {t!r}")


def make_collider(spec, dim: int, plane_z: float):
    kw = dict(mode=spec.mode, friction=spec.friction)
    if spec.path is not None:
        pos = np.array([_pad3(p, plane_z if dim == 2 else 0.0) for p in spec.path.positions])
        if dim == 2:
            pos[:, 2] = plane_z
        kw["path"] = Keyframes(spec.path.times, pos)
    z = plane_z if dim == 2 else 0.0

    def p3(v):
        out = _pad3(v)
        if dim == 2:
            out[2] = z
        return out

    if spec.type == "half_space":
        return Collider.half_space(p3(spec.point), _pad3(spec.normal), **kw)
    if spec.type == "box":
        size = _pad3(spec.size, 1.0)  # 2D: unbounded along z
        return Collider.box(p3(spec.center), 0.5 * size if dim == 3 else np.array([0.5 * size[0], 0.5 * size[1], 1e3]), **kw)
    if spec.type == "sphere":
        return Collider.sphere(p3(spec.center), spec.radius, **kw)
    if spec.type == "cylinder":
        return Collider.cylinder(p3(spec.center), spec.radius, 0.5 * spec.length, spec.axis, **kw)
    raise SceneError(f"unknown collider type {spec.type!r}")


def resolve_material(spec, base_dir, key: str, library: dict | None = None) -> dict:
    """Material of a body as engine numbers: model id, initial shear modulus, bulk modulus, params, density,
    and the library remanence (T, 0 when not from the library).

    ``spec`` is a Material table or a library entry name. Reads ``spec.library`` (an entry of ``library``, default
    the built-in one) or ``spec.file`` (a `magsoro fit-material` entry) when given; inline keys override it.
    """
    values = {}
    remanence = None
    lib_key = key
    if isinstance(spec, str):
        from magsoro.scene.schema import Material

        spec = Material(library=spec)
    else:
        lib_key = f"{key}.library"
    if spec.library is not None:
        try:
            entry = get_material(spec.library, library)
        except MaterialLibraryError as exc:
            raise SceneError(f"{lib_key}: {exc}") from None
        values.update(model=DEFAULT_LAW, density=entry.density, shear_modulus=entry.shear_modulus)
        remanence = entry.remanence
        if spec.model not in (None, DEFAULT_LAW):
            values.pop("shear_modulus")  # the library's modulus is Neo-Hookean; another model needs its own constants
    if spec.file is not None:
        from magsoro.io.files import read_toml_file


        path = Path(spec.file) if base_dir is None else Path(base_dir) / spec.file
        if not path.is_file():
            raise SceneError(f"{key}.file: material file '{path}' not found")
        try:
            entry = read_toml_file(path, SceneError, f"material file ({key}.file)")
        except SceneError as exc:  # the file names itself; the key names the body
            raise SceneError(f"{key}.file: {exc}") from None
        model = law_of_file_model(entry.get("model"))  # fit-material's model names map onto the laws
        if model is None:
            raise SceneError(f"{key}.file: '{path}' holds model {entry.get('model')!r}; the engine supports "
                             f"{', '.join(LAWS)} and fit-material's {', '.join(FIT_MODEL_LAWS)}")
        values["model"] = model
        if "density" in entry:
            values["density"] = entry["density"]
        if "prony" in entry:
            problem = prony_problem(entry["prony"])
            if problem is not None:
                raise SceneError(f"{key}.file: '{path}' prony {problem}")
            values["prony"] = entry["prony"]
        try:
            values.update(LAWS[model].from_material_file(entry))
        except KeyError as exc:
            raise SceneError(f"{key}.file: '{path}' lacks parameter {exc} of model {entry.get('model')!r}") from None
    for name in ("model", "density", *PARAMETER_KEYS, "bulk_modulus", "prony"):
        v = getattr(spec, name)
        if v is not None:
            values[name] = v
    model = values.get("model", DEFAULT_LAW)
    law = LAWS[model]
    if values.get("density") is None:
        raise SceneError(f"{key}.density: required (kg/m^3), inline or in the material file")
    problem = law.problem(values)
    if problem is not None:
        raise SceneError(f"{key}: {problem}")
    try:
        params = law.pack(values)
        G = law.initial_shear_modulus(values)
    except (KeyError, TypeError) as exc:
        raise SceneError(f"{key}: model '{model}' lacks parameter {exc}") from None
    if not G > 0:
        raise SceneError(f"{key}: the initial shear modulus must be > 0 Pa, got {G}")
    K = float(values.get("bulk_modulus") or 20.0 * G)
    follows = MAGNETIZATION_FOLLOWS[getattr(spec, "magnetization_follows", "F")]
    prony = values.get("prony")
    if prony is not None and getattr(spec, "stimulus", None) is not None:
        raise SceneError(f"{key}: a material cannot have both prony and stimulus (not supported yet)")
    return {"model": law.code, "follows": follows, "shear_modulus": G, "bulk_modulus": K, "params": params,
            "density": float(values["density"]), "remanence": remanence,
            "prony": None if prony is None else [[float(g), float(t)] for g, t in prony]}


def make_stimulus(spec, key: str) -> Stimulus:
    """The engine's :class:`~magsoro.mpm.laws.eigenstrain.Stimulus` of a material's ``stimulus`` table."""
    p = spec.profile
    try:
        if p.type == "ramp":
            profile = KeyframeStimulus.ramp(p.duration, p.start, p.initial, p.final)
        elif p.type == "keyframes":
            profile = KeyframeStimulus(p.times, p.values)
        elif p.type == "sine":
            profile = SineStimulus(p.frequency, p.amplitude, p.offset, np.deg2rad(p.phase))
        else:
            profile = KeyframeStimulus.constant(p.value)
        return Stimulus(profile, spec.stretch, spec.modulus_factor, spec.direction)
    except ValueError as exc:
        raise SceneError(f"{key}: {exc}") from None


def make_magnetization(spec, remanence: float | None, base_dir, key: str):
    """Profile function X (N, 3) m -> Br (N, 3) T for a body's ``magnetization`` (vector or profile table).

    ``remanence`` (T) is the library material's, used when a profile gives no magnitude.
    """
    if isinstance(spec, list):
        return magprofiles.uniform(spec)

    def magnitude():
        if spec.magnitude is not None:
            return spec.magnitude
        if remanence is None:
            raise SceneError(f"{key}.magnitude: required (T) unless the material is a library entry (whose remanence is the default)")
        return remanence

    try:
        if spec.type == "uniform":
            d = np.asarray(spec.direction, dtype=np.float64)
            return magprofiles.uniform(magnitude() * d / np.linalg.norm(d))
        if spec.type == "rotating":
            return magprofiles.rotating(magnitude(), spec.axis, spec.origin, spec.period, spec.u, spec.v, np.deg2rad(spec.phase))
        if spec.type == "table":
            vec = np.asarray(spec.vectors, dtype=np.float64)
            if spec.magnitude is not None:
                n = np.linalg.norm(vec, axis=1, keepdims=True)
                vec = spec.magnitude * np.divide(vec, n, out=np.zeros_like(vec), where=n > 0)
            return magprofiles.table(spec.axis, spec.origin, spec.positions, vec, spec.interpolation)
        if spec.type == "file":
            key = f"{key}.file"
            return magprofiles.from_array_file(Path(spec.file) if base_dir is None else Path(base_dir) / spec.file)
        if spec.type == "expression":
            return magprofiles.expression([spec.x, spec.y, spec.z])
    except (ValueError, FileNotFoundError) as exc:
        raise SceneError(f"{key}: {exc}") from None
    raise SceneError(f"{key}: unknown magnetisation type {spec.type!r}")


@dataclass
class Particles:
    """The particles of a scene before any engine object exists (used by build and by `magsoro show`).

    positions (N, dim) m; volumes (N,) m^3 (2D: area x depth); density, shear_modulus, bulk_modulus (N,);
    remanence (N, 3) T; body (N,) int; clamped (N,) bool; material_model (N,) int; material_params
    (N, LAW_PARAM_COUNT) Pa (Ogden exponents dimensionless); velocity (N, dim) m/s; stimulus (N,) int, the row of
    ``stimuli`` (:class:`magsoro.mpm.laws.eigenstrain.Stimulus`, one per body whose material has one) or -1; prony
    (N,) int, the row of ``pronies`` (Prony tables [[g, tau], ...], one per body whose material has one) or -1.
    """

    positions: np.ndarray
    volumes: np.ndarray
    density: np.ndarray
    shear_modulus: np.ndarray
    bulk_modulus: np.ndarray
    remanence: np.ndarray
    body: np.ndarray
    clamped: np.ndarray
    material_model: np.ndarray
    material_params: np.ndarray
    velocity: np.ndarray
    body_names: list[str]
    report: list[dict]
    stimulus: np.ndarray | None = None
    stimuli: list = field(default_factory=list)
    magnetization_follows: np.ndarray | None = None
    prony: np.ndarray | None = None
    pronies: list = field(default_factory=list)
    pressure_area: np.ndarray | None = None
    pressure_row: np.ndarray | None = None
    pressures: list = field(default_factory=list)
    displacement: np.ndarray | None = None  # (N, dim) m: the bodies' initial displacement u(X) (None: none)
    deformation: np.ndarray | None = None  # (N, dim, dim): F = I + grad u that goes with it


def initial_displacement(expressions, X: np.ndarray, step: float):
    """The displacement u (N, dim) m of expressions ``expressions`` (one per axis, in x, y, z of the reference
    positions ``X`` (N, dim) m; 2D: z = 0), evaluated safely (:func:`magsoro.geometry.magnetization.compile_expression`),
    and F = I + grad u (N, dim, dim) from central differences of half-width ``step`` (m), exact for a field linear in
    X up to rounding. Raises ExpressionError / ValueError for a bad or non-finite expression."""
    X = np.asarray(X, dtype=np.float64)
    n, dim = X.shape
    if len(expressions) != dim:
        raise ValueError(f"needs {dim} components (one per axis of a {dim}D scene), got {len(expressions)}")
    funcs = [magprofiles.compile_expression(e) for e in expressions]

    def u_at(Y):
        xyz = [Y[:, a] for a in range(dim)] + [np.zeros(n)] * (3 - dim)
        return np.stack([np.broadcast_to(np.asarray(f(*xyz), dtype=np.float64), (n,)) for f in funcs], axis=1)

    u = u_at(X)
    F = np.broadcast_to(np.eye(dim), (n, dim, dim)).copy()
    for b in range(dim):
        e = np.zeros(dim)
        e[b] = step
        F[:, :, b] += (u_at(X + e) - u_at(X - e)) / (2.0 * step)
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(F))):
        bad = int(np.flatnonzero(~(np.all(np.isfinite(u), axis=1) & np.all(np.isfinite(F), axis=(1, 2))))[0])
        raise ValueError(f"not finite (or not differentiable) at x = {X[bad].tolist()} m")
    det = np.linalg.det(F)
    if np.any(det <= 0):
        bad = int(np.flatnonzero(det <= 0)[0])
        raise ValueError(f"inverts the material (det(I + grad u) = {det[bad]:.3g}) at x = {X[bad].tolist()} m")
    return u, F


def pressure_faces(pts: np.ndarray, occupied: np.ndarray, cavity, lo: np.ndarray, h: float, depth: float,
                   axisymmetric: bool = False) -> np.ndarray:
    """Reference area vectors (N, dim) of the particle faces of ``pts`` that look into ``cavity``: for each axis a
    and side s, a particle whose lattice neighbour X + s h e_a lies in the cavity and is not a particle site
    (``occupied``: (M, dim) every particle of the scene; ``lo`` the domain's lower corner, which the lattice is
    aligned to) gets s e_a h^(dim-1) (in 2D times ``depth``), the outward normal of that face times its area. On
    the lattice the faces close up, so the sum over a closed cavity is zero and a pressure on them gives each part
    the force p times its projected area, as on the smooth wall. ``axisymmetric``: a face is a ring, its length h
    times 2 pi times its radius (the particle's r, plus or minus h / 2 for the faces across r)."""
    n, dim = pts.shape
    area = np.zeros((n, dim))
    idx, occ = _lattice_index(pts, lo, h), _lattice_index(occupied, lo, h)
    code = _site_coder([idx, occ])  # valid for the neighbours one site away too
    occ_codes = code(occ)
    face = h ** (dim - 1) * (depth if dim == 2 else 1.0)
    for a in range(dim):
        for side in (-1, 1):
            Y = pts.copy()
            Y[:, a] += side * h
            j = idx.copy()
            j[:, a] += side
            exposed = cavity.contains(Y) & ~np.isin(code(j), occ_codes)
            if axisymmetric:
                r_face = pts[exposed, 0] + (0.5 * side * h if a == 0 else 0.0)
                area[exposed, a] += side * h * 2.0 * np.pi * r_face
            else:
                area[exposed, a] += side * face
    return area


def _lattice_index(pts, lo, h):
    """Integer lattice coordinates of lattice points (exact: every fill uses the same grid-aligned lattice)."""
    return np.rint((pts - lo) / h - 0.5).astype(np.int64)


def _site_coder(sites: list[np.ndarray]):
    """A function giving integer lattice sites (M, dim) unique int64 codes (for np.isin), valid for every site in
    ``sites`` and their neighbours one site away."""
    span = np.max(np.concatenate([np.abs(i).max(axis=0, keepdims=True) for i in sites if len(i)]), axis=0) * 2 + 5
    off = span // 2 + 1

    def code(i):
        c = np.zeros(len(i), dtype=np.int64)
        for a in range(i.shape[1]):
            c = c * span[a] + (i[:, a] + off[a])
        return c

    return code


#: Largest lattice (candidate particle sites in a body's bounding box) a body may be filled on: 10^8 sites are
#: 2.4 GB of float64 positions before the shape test, about what this project's 24 GB machines can hold with
#: the rest of a run.
MAX_LATTICE_SITES = 1e8


#: an axisymmetric scene's grid reaches this many cells to r < 0 (the user's domain starts at the axis, r = 0): the
#: mirror nodes of the axis (one cell in) clear of the domain walls (two cells inside the grid's edge)
AXIS_PAD_CELLS = 4


def model_domain(sim) -> tuple[np.ndarray, np.ndarray]:
    """The engine's domain (lo, hi) of the scene's [simulation]: the scene's own, except that an axisymmetric
    scene's grid reaches AXIS_PAD_CELLS cells past the axis (the nodes that mirror those next to it). The particle
    lattice is the same either way (the pad is a whole number of cells)."""
    lo, hi = np.asarray(sim.domain_lo, dtype=np.float64).copy(), np.asarray(sim.domain_hi, dtype=np.float64).copy()
    if sim.plane == "axisymmetric":
        lo[0] = -AXIS_PAD_CELLS * sim.dx
    return lo, hi


def ring_volumes(pts: np.ndarray, area: float) -> np.ndarray:
    """Volumes (m^3) of the rings an axisymmetric scene's particles stand for: 2 pi r times their area (m^2)."""
    return 2.0 * np.pi * pts[:, 0] * area


def fill_bodies(scene: Scene, source: str = "scene", magnetization=None) -> Particles:
    """Fill every body with particles on the grid-aligned lattice and give them material and remanence.

    ``magnetization``: optional Python callable X (N, 3) m -> Br (N, 3) T applied to every body, or a dict
    {body name: callable}; it replaces the scene's magnetisation of those bodies. Overlapping bodies keep the
    shared particles for the one with the higher ``priority``; without distinct priorities they are refused.
    """
    sim = scene.simulation
    dim, dx, ppc = sim.dim, sim.dx, sim.particles_per_cell
    lo, hi = model_domain(sim)
    axisymmetric = sim.plane == "axisymmetric"
    depth = sim.depth if dim == 2 else 1.0
    h = dx / ppc
    libs = scene.material_library_paths
    try:
        library = load_library(libs) if libs else None
    except MaterialLibraryError as exc:
        raise SceneError(f"{source}: material_library: {exc}") from None
    names = [b.name for b in scene.bodies]
    if magnetization is None and scene.magnetization_functions:
        magnetization = scene.magnetization_functions  # set by Scene.set_magnetization
    if isinstance(magnetization, dict):
        unknown = [k for k in magnetization if k not in names]
        if unknown:
            raise SceneError(f"magnetization: no body named '{unknown[0]}'; bodies: {', '.join(names)}")
    per_body = []
    report = []
    for i, b in enumerate(scene.bodies):
        bsrc = b.source or source
        bkey = b.key or f"bodies[{i}]"
        base_dir = b.base_dir
        if base_dir is None:
            base_dir = scene.base_dir
        try:
            shape = make_shape(b.shape, base_dir, dim)
            # the domain and the size are checked before the lattice is filled: a mesh in mm read as m would
            # otherwise allocate terabytes before any check
            blo, bhi = shape.bounds()
            blo, bhi = np.asarray(blo, dtype=np.float64)[:dim], np.asarray(bhi, dtype=np.float64)[:dim]
            margin = WALL_CELLS * dx  # walls act on the outer two cells
            if axisymmetric and blo[0] < 0.0:
                raise SceneError(f"{bsrc}: {bkey}.shape: body '{b.name}' reaches r = {blo[0]:g} m; in an axisymmetric scene "
                                 f"x is the radius, r >= 0 (draw the body's (r, z) section right of the axis)")
            if np.any(blo < lo + margin) or np.any(bhi > hi - margin):
                raise SceneError(
                    f"{bsrc}: {bkey}.shape: body '{b.name}' spans {blo.tolist()} to {bhi.tolist()} m, outside the domain "
                    f"[{lo.tolist()}, {hi.tolist()}] shrunk by two cells ({margin} m); move it or enlarge simulation.domain_lo/domain_hi"
                    " (a mesh in mm needs shape.scale = 1e-3)"
                )
            sites = float(np.prod(np.floor((bhi - blo) / h) + 1.0))
            if sites > MAX_LATTICE_SITES:
                raise SceneError(
                    f"{bsrc}: {bkey}.shape: body '{b.name}' ({(bhi - blo).tolist()} m across) would need {sites:.3g} "
                    f"lattice sites at the particle spacing {h:g} m (simulation.dx / particles_per_cell); at most "
                    f"{MAX_LATTICE_SITES:.0e} are allowed: check the shape's size and units, or coarsen simulation.dx"
                )
            pts, v_each = fill_lattice(shape, dx, ppc, lo, dim)
        except MeshError as exc:
            raise SceneError(f"{bsrc}: {bkey}.shape.file: {exc}") from None
        except ValueError as exc:
            raise SceneError(f"{bsrc}: {bkey}.shape: {exc}") from None
        if len(pts) == 0:
            raise SceneError(f"{bsrc}: {bkey}.shape: body '{b.name}' holds no particle at dx = {dx} m; refine simulation.dx or enlarge the shape")
        mat = resolve_material(b.material, base_dir, f"{bsrc}: {bkey}.material", library)
        fn = magnetization.get(b.name) if isinstance(magnetization, dict) else magnetization
        key = "magnetization (Python callable)" if fn is not None else f"{bkey}.magnetization"
        if fn is None:
            fn = make_magnetization(b.magnetization, mat["remanence"], base_dir, f"{bsrc}: {bkey}.magnetization")
        try:
            Br = magprofiles.evaluate(fn, pts)
        except magprofiles.ExpressionError as exc:
            raise SceneError(f"{bsrc}: {key}: {exc}") from None
        except (ValueError, TypeError, ArithmeticError) as exc:
            raise SceneError(f"{bsrc}: {key}: body '{b.name}': {exc}") from None
        if b.magnetic and not np.any(np.linalg.norm(Br, axis=1) > 0):
            raise SceneError(f"{bsrc}: {bkey}.magnetization: body '{b.name}' is marked magnetic but its magnetisation is zero everywhere; give a magnitude (T) or a magnetised library material")
        stim = b.material.stimulus if not isinstance(b.material, str) else None
        if stim is not None:
            stim = make_stimulus(stim, f"{bsrc}: {bkey}.material.stimulus")
        per_body.append(dict(pts=pts, v_each=v_each, mat=mat, Br=Br, key=bkey, src=bsrc, stimulus=stim))
        if axisymmetric:  # rings: the section's area times 2 pi r (the shape's volume about its particles' mean radius)
            filled = float(ring_volumes(pts, v_each).sum())
            shape_volume = shape.volume() * 2.0 * np.pi * float(pts[:, 0].mean())
        else:
            filled = len(pts) * v_each * (depth if dim == 2 else 1.0)
            shape_volume = shape.volume() * (depth if dim == 2 else 1.0)
        report.append({"body": b.name, "particles": len(pts), "filled_volume": filled,
                       "shape_volume": shape_volume, "density": mat["density"], "mass": filled * mat["density"]})
    _resolve_overlaps(scene, per_body, report, lo, h, source)
    n_total = sum(len(pb["pts"]) for pb in per_body)
    if n_total == 0:
        raise SceneError(f"{source}: bodies: no particle left after resolving overlaps")
    X = np.concatenate([pb["pts"] for pb in per_body])
    body_id = np.concatenate([np.full(len(pb["pts"]), i, dtype=np.int32) for i, pb in enumerate(per_body)])
    clamped = np.concatenate([np.full(len(pb["pts"]), bool(b.clamped)) for b, pb in zip(scene.bodies, per_body)])

    def per(f, dtype=np.float64):
        return np.concatenate([np.full(len(pb["pts"]), f(pb), dtype=dtype) for pb in per_body])

    vel = np.concatenate([
        np.tile(np.asarray(b.velocity if b.velocity is not None else np.zeros(dim), dtype=np.float64), (len(pb["pts"]), 1))
        for b, pb in zip(scene.bodies, per_body)
    ])
    pressure_area, pressure_row, pressures = np.zeros((len(X), dim)), np.full(len(X), -1, dtype=np.int32), []
    start = 0
    for i, (b, pb) in enumerate(zip(scene.bodies, per_body)):
        n_b = len(pb["pts"])
        if b.pressure is not None:
            key = f"{pb['src']}: {pb['key']}.pressure.cavity"
            base_dir = b.base_dir or scene.base_dir
            try:
                cavity = make_shape(b.pressure.cavity, base_dir, dim)
            except MeshError as exc:
                raise SceneError(f"{key}.file: {exc}") from None
            except ValueError as exc:
                raise SceneError(f"{key}: {exc}") from None
            area = pressure_faces(pb["pts"], X, cavity, lo[:dim], h, depth, axisymmetric)
            if not np.any(area != 0.0):
                raise SceneError(f"{key}: no particle face of body '{b.name}' looks into the cavity: it must border the "
                                 f"body's surface within one particle spacing ({h:g} m)")
            loaded = np.any(area != 0.0, axis=1)
            pressure_area[start : start + n_b] = area
            pressure_row[start : start + n_b][loaded] = len(pressures)
            pressures.append((float(b.pressure.value), float(b.pressure.ramp)))
        start += n_b
    displacement = deformation = None
    if any(b.initial_displacement is not None for b in scene.bodies):
        displacement = np.zeros((len(X), dim))
        deformation = np.broadcast_to(np.eye(dim), (len(X), dim, dim)).copy()
        start = 0
        for b, pb in zip(scene.bodies, per_body):
            n_b = len(pb["pts"])
            if b.initial_displacement is not None and n_b:
                try:
                    u, F = initial_displacement(b.initial_displacement.expression, pb["pts"], 1e-3 * h)
                except (ValueError, TypeError, ArithmeticError) as exc:  # ExpressionError included
                    raise SceneError(f"{pb['src']}: {pb['key']}.initial_displacement.expression: body '{b.name}': {exc}") from None
                displacement[start : start + n_b], deformation[start : start + n_b] = u, F
            start += n_b
    stimuli, pronies = [], []
    for pb in per_body:  # one row per body whose material has a stimulus, one per body with a Prony series
        pb["stimulus_row"] = -1 if pb["stimulus"] is None else len(stimuli)
        if pb["stimulus"] is not None:
            stimuli.append(pb["stimulus"])
        pb["prony_row"] = -1 if pb["mat"].get("prony") is None else len(pronies)
        if pb["mat"].get("prony") is not None:
            pronies.append(pb["mat"]["prony"])
    return Particles(
        positions=X,
        volumes=(np.concatenate([ring_volumes(pb["pts"], pb["v_each"]) for pb in per_body]) if axisymmetric
                 else per(lambda pb: pb["v_each"] * depth)),
        density=per(lambda pb: pb["mat"]["density"]),
        shear_modulus=per(lambda pb: pb["mat"]["shear_modulus"]),
        bulk_modulus=per(lambda pb: pb["mat"]["bulk_modulus"]),
        remanence=np.concatenate([pb["Br"] for pb in per_body]),
        body=body_id,
        clamped=clamped,
        material_model=per(lambda pb: pb["mat"]["model"], np.int32),
        material_params=np.concatenate([np.tile(pb["mat"]["params"], (len(pb["pts"]), 1)) for pb in per_body]),
        velocity=vel,
        body_names=names,
        report=report,
        stimulus=per(lambda pb: pb["stimulus_row"], np.int32),
        stimuli=stimuli,
        magnetization_follows=per(lambda pb: pb["mat"]["follows"], np.int32),
        prony=per(lambda pb: pb["prony_row"], np.int32),
        pronies=pronies,
        pressure_area=pressure_area,
        pressure_row=pressure_row,
        pressures=pressures,
        displacement=displacement,
        deformation=deformation,
    )


def _resolve_overlaps(scene, per_body, report, lo, h, source):
    """All bodies share one lattice, so overlapping bodies have particles at identical sites: find them exactly."""
    if len(per_body) < 2:
        return
    idx = [_lattice_index(pb["pts"], lo[: pb["pts"].shape[1]], h) for pb in per_body]
    code = _site_coder(idx)
    codes = [code(i) for i in idx]
    bodies = scene.bodies
    for a in range(len(per_body)):
        for b in range(a + 1, len(per_body)):
            shared = np.isin(codes[a], codes[b])
            if not shared.any():
                continue
            pa, pb_ = bodies[a].priority, bodies[b].priority
            if pa == pb_:  # both unset, or the same: the file does not say which wins
                raise SceneError(
                    f"{per_body[b]['src']}: {per_body[b]['key']}.priority: bodies '{bodies[a].name}' and '{bodies[b].name}' overlap "
                    f"({int(shared.sum())} particles); give them different priorities (the higher one keeps the overlap) or move them apart"
                )
            lowest = -float("inf")  # an unset priority loses against any set one
            pa, pb_ = lowest if pa is None else pa, lowest if pb_ is None else pb_
            loser, lose_mask = (b, np.isin(codes[b], codes[a])) if pa > pb_ else (a, shared)
            keep = ~lose_mask
            for k in ("pts", "Br"):
                per_body[loser][k] = per_body[loser][k][keep]
            codes[loser] = codes[loser][keep]
            r = report[loser]
            r["particles"] = len(per_body[loser]["pts"])
            factor = r["particles"] / max(r["particles"] + int(lose_mask.sum()), 1)
            r["filled_volume"] *= factor
            r["mass"] *= factor
            r["overlap_removed"] = r.get("overlap_removed", 0) + int(lose_mask.sum())
            if r["particles"] == 0:
                raise SceneError(f"{per_body[loser]['src']}: {per_body[loser]['key']}.shape: body '{bodies[loser].name}' lies entirely inside a body of higher priority")


@dataclass
class ProbeSpec:
    """A probe resolved to particle indices."""

    name: str
    kind: str  # centroid | point | bbox | field | collider_force
    indices: np.ndarray
    weights: np.ndarray | None = None
    position: np.ndarray | None = None  # field probe at a fixed point (m); else at the mean of ``indices``
    collider: int | None = None  # collider_force: the collider's index in [[colliders]]
    pair: tuple[int, int] | None = None  # collider_force between bodies: contact groups (A, B), the force A exerts on B

    def columns(self, dim: int) -> list[str]:
        axes = "xyz"[:dim]
        if self.kind == "collider_force":
            return [f"{self.name}_F{a}" for a in axes]
        if self.kind == "field":
            return [f"{self.name}_B{a}" for a in "xyz"]
        if self.kind == "bbox":
            return [f"{self.name}_min_{a}" for a in axes] + [f"{self.name}_max_{a}" for a in axes]
        return [f"{self.name}_{a}" for a in axes]

    def where(self, x: np.ndarray) -> np.ndarray:
        """Position of a field probe (m) for particle positions ``x``."""
        return self.position if self.position is not None else x[self.indices].astype(np.float64).mean(axis=0)

    def evaluate(self, x: np.ndarray) -> np.ndarray:
        """Value of a geometric probe (field probes: :meth:`magsoro.simulation.Simulation.probe_values`)."""
        p = x[self.indices].astype(np.float64)
        if self.kind == "bbox":
            return np.concatenate([p.min(axis=0), p.max(axis=0)])
        if self.weights is not None:
            return (self.weights[:, None] * p).sum(axis=0) / self.weights.sum()
        return p.mean(axis=0)


@dataclass
class Built:
    """Everything a run needs, made from a scene."""

    model: Model
    control: Control
    settings: SolverSettings
    probes: list[ProbeSpec]
    body_names: list[str]
    initial_velocity: np.ndarray
    fill_report: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what the build decided that run.json should say


#: an axisymmetric scene's contact stays this many cells off the axis: the nodes there are mirrored one field each
AXIS_CONTACT_CELLS = 3.0


def check_axisymmetric_contact(scene: Scene, X: np.ndarray, group: np.ndarray, names: list, body_id: np.ndarray,
                               source: str) -> None:
    """Contact between bodies in an axisymmetric scene: no contact near the axis, where the mirrored nodes carry one
    velocity field (AXIS_CONTACT_CELLS cells): at most one piece reaches there. Refused in one line naming the key.
    What only the explicit engine lacks (the total form with contact, self-contact) is refused when it steps
    (:func:`axisymmetric_explicit_refusal`): the Newton solvers take both."""
    sim = scene.simulation
    near = X[:, 0] < AXIS_CONTACT_CELLS * sim.dx
    pieces = np.unique(group[near])
    if len(pieces) > 1:
        who = sorted({names[b] for b in np.unique(body_id[near])})
        raise SceneError(f"{source}: bodies: {', '.join(repr(n) for n in who)} reach within {AXIS_CONTACT_CELLS:g} cells "
                         f"of the axis as separate pieces; contact that close to the axis is not built in an axisymmetric "
                         f"scene (keep all but one piece {AXIS_CONTACT_CELLS * sim.dx:g} m off it, or glue them)")


def axisymmetric_explicit_refusal(scene: Scene, formulation: str, contact_active: bool, source: str) -> str | None:
    """Why the explicit engine cannot step this axisymmetric scene with contact (None when it can): the total form
    with contact and self-contact are built in the Newton solvers only (magsoro run --static,
    simulation.integrator = 'implicit')."""
    if scene.simulation.plane != "axisymmetric" or not contact_active:
        return None
    newton = "; the static solver (magsoro run --static) and the implicit integrator (simulation.integrator = 'implicit') take it"
    if scene.contact.self_contact:
        return (f"{source}: contact.self_contact: the explicit engine has no self-contact in an axisymmetric scene "
                f"(contact between bodies it has){newton}")
    if formulation == "total":
        return (f"{source}: simulation.formulation: the explicit engine has no contact in the total form in an "
                f"axisymmetric scene; use 'updated' or 'auto'{newton}")
    return None


def contact_groups(scene: Scene, X: np.ndarray, body_id: np.ndarray, touching: list | None = None) -> np.ndarray:
    """Contact group of each body, numbered from 0 in the order of their first body: the parts of a robot are one
    group, and so are the bodies of a [[contact.pairs]] entry with ``bonded = true`` and, with ``[contact] bonded =
    'touching'``, bodies that touch or overlap in the reference configuration (particles on neighbouring lattice
    sites). Other bodies are groups of their own, in contact with each other from the first step when they touch.
    ``touching``: a list that receives the pairs (a, b) of separate [[bodies]] (not parts of one robot) that touch at
    the start. Returns (n_bodies,) int."""
    sim = scene.simulation
    dim = sim.dim
    h = sim.dx / sim.particles_per_cell
    lo = np.asarray(sim.domain_lo, dtype=np.float64)[:dim]
    n = len(scene.bodies)
    parent = list(range(n))

    def root(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    def unite(a, b):
        parent[root(b)] = root(a)

    parts = [i for i, b in enumerate(scene.bodies) if not (b.key or "bodies[").startswith("bodies[")]
    for i in parts[1:]:
        unite(parts[0], i)
    names = [b.name for b in scene.bodies]
    for pair in scene.contact.pairs:
        if pair.bonded and all(nm in names for nm in pair.bodies):  # unknown names: contact_settings says so
            unite(names.index(pair.bodies[0]), names.index(pair.bodies[1]))
    sites = [_lattice_index(X[body_id == i], lo, h) for i in range(n)]
    code = _site_coder(sites)
    codes = [code(s) for s in sites]
    steps = np.concatenate([np.eye(dim, dtype=np.int64), -np.eye(dim, dtype=np.int64)])
    # each body's face neighbours: the sites one lattice step away from one of its particles
    halo = [np.unique(code((s[:, None, :] + steps[None]).reshape(-1, dim))) for s in sites]
    part_set = set(parts)
    by_touch = scene.contact.bonded == "touching"
    for a in range(n):
        for b in range(a + 1, n):
            if a in part_set and b in part_set:
                continue  # parts of one robot: one piece already
            if (touching is not None or (by_touch and root(a) != root(b))) and np.isin(halo[b], codes[a]).any():
                if touching is not None:
                    touching.append((a, b))
                if by_touch:
                    unite(a, b)
    roots = {}
    return np.array([roots.setdefault(root(i), len(roots)) for i in range(n)], dtype=np.int32)


#: touching pairs named in a note before it says "and N more"
TOUCHING_NAMED = 6


def touching_notes(scene: Scene, names: list[str], groups: np.ndarray, pairs: list, contact: ContactSettings) -> list[str]:
    """run.json notes on the separate bodies that touch at the start (``pairs`` from :func:`contact_groups`): which
    are bonded into one piece and why, and which are in contact (with their friction)."""
    def listed(items):
        shown = ", ".join(f"'{names[a]}'-'{names[b]}'" for a, b in items[:TOUCHING_NAMED])
        return shown + (f" and {len(items) - TOUCHING_NAMED} more" if len(items) > TOUCHING_NAMED else "")

    bonded = [(a, b) for a, b in pairs if groups[a] == groups[b]]
    apart = [(a, b) for a, b in pairs if groups[a] != groups[b]]
    notes = []
    if bonded:
        why = ("contact.bonded = 'touching'" if scene.contact.bonded == "touching"
               else "their [[contact.pairs]] entries say bonded = true")
        notes.append(f"bodies that touch at the start are bonded into one piece ({why}): {listed(bonded)}")
    if apart:
        laws = set()
        for a, b in apart:
            f = float(contact.friction[groups[a], groups[b]])
            laws.add("sticky" if f < 0 else f"friction {f:g}")
        notes.append(f"bodies that touch at the start are separate bodies in contact from the first step "
                     f"({', '.join(sorted(laws))}; they slide by Coulomb's law and separate freely): {listed(apart)}; to "
                     f"glue a pair, give its [[contact.pairs]] entry bonded = true, or set contact.bonded = 'touching'")
    return notes


def contact_settings(scene: Scene, groups: np.ndarray, names: list[str], source: str) -> ContactSettings:
    """Friction table between contact groups from the [contact] table ('sticky' -> ContactSettings.STICKY)."""
    c = scene.contact

    def value(f):
        return ContactSettings.STICKY if f == "sticky" else float(f)

    g = int(groups.max()) + 1 if len(groups) else 1
    table = np.full((g, g), value(c.friction))
    for i, pair in enumerate(c.pairs):
        key = f"contact.pairs[{i}].bodies"
        for name in pair.bodies:
            if name not in names:
                raise SceneError(f"{source}: {key}: no body named '{name}'; bodies: {', '.join(names)}")
        if pair.bonded:
            continue  # one group (contact_groups)
        a, b = (names.index(nm) for nm in pair.bodies)
        ga, gb = int(groups[a]), int(groups[b])
        if a != b and ga == gb:
            why = ("contact.bonded = 'touching' bonds bodies that touch at the start; set it to 'pairs' (the default) "
                   "for contact between them" if c.bonded == "touching" else
                   "they are parts of one robot, or bonded by another pair, and move as one piece; remove the pair")
            raise SceneError(f"{source}: {key}: bodies '{pair.bodies[0]}' and '{pair.bodies[1]}' move as one piece: {why}")
        table[ga, gb] = table[gb, ga] = value(pair.friction)
    return ContactSettings(table, self_contact=c.self_contact, fold_spread=c.fold_spread)


def held_particles(scene: Scene, p: Particles, source: str = "scene", paths: list | None = None) -> np.ndarray:
    """(N,) bool: the particles of ``p`` (from :func:`fill_bodies`) that are held, those of clamped bodies and
    those inside a ``[[clamps]]`` region (of its body, when it names one). SceneError for a region that holds no
    particle. ``paths``: a list that receives the moving clamps, (row (N,) int: each particle's path or -1,
    [(times, displacements), ...]); a particle in two clamps follows the later one."""
    base_dir = scene.base_dir
    clamped = p.clamped.copy()
    dim = scene.simulation.dim
    rows = np.full(len(clamped), -1, dtype=np.int32)
    tables = []
    for i, c in enumerate(scene.clamps):
        try:
            region = make_shape(c.region, base_dir, scene.simulation.dim)
        except ValueError as exc:  # MeshError included
            raise SceneError(f"{source}: clamps[{i}].region: {exc}") from None
        inside = region.contains(p.positions)
        if c.body is not None:
            inside &= p.body == p.body_names.index(c.body)
        if not inside.any():
            raise SceneError(f"{source}: clamps[{i}].region: holds no particle; check the region against the bodies")
        clamped |= inside
        if c.path is not None:
            disp = np.zeros((len(c.path.positions), dim))
            for j, v in enumerate(c.path.positions):
                if len(v) != dim:
                    raise SceneError(f"{source}: clamps[{i}].path.positions[{j}]: needs {dim} components in a {dim}D scene, got {len(v)}")
                disp[j] = v
            times = np.asarray(c.path.times, dtype=np.float64)
            start = [np.interp(0.0, times, disp[:, a]) for a in range(dim)]
            if np.any(np.abs(start) > 0.0):
                raise SceneError(f"{source}: clamps[{i}].path: the displacement at t = 0 is {start} m; it must be zero "
                                 f"(the held particles start at their reference positions)")
            rows[inside] = len(tables)
            tables.append((times, disp))
        else:
            rows[inside] = -1
    if paths is not None:
        paths[:] = [rows, tables]
    return clamped


def build(scene: Scene, device: str | None = None, source: str = "scene", magnetization=None) -> Built:
    """Fill bodies with particles and assemble Model, Control, SolverSettings and probes.

    ``magnetization``: optional callable X (N, 3) m -> Br (N, 3) T (all bodies) or {body name: callable}, replacing
    the scene's magnetisation (see :func:`fill_bodies`). Raises SceneError when a body has no particle at this
    resolution, lies (partly) outside the domain, or overlaps another without a priority rule.
    """
    sim = scene.simulation
    dim, dx = sim.dim, sim.dx
    lo, hi = model_domain(sim)
    p = fill_bodies(scene, source, magnetization)
    X, body_id = p.positions, p.body
    names = p.body_names
    base_dir = scene.base_dir
    def region_shape(spec, key):
        try:
            return make_shape(spec, base_dir, dim)
        except ValueError as exc:  # MeshError included
            raise SceneError(f"{source}: {key}: {exc}") from None

    moving = []
    clamped = held_particles(scene, p, source, moving)
    clamp_row, clamp_paths = moving
    touch_pairs: list = []
    body_group = contact_groups(scene, X, body_id, touch_pairs)
    contact = contact_settings(scene, body_group, names, source)
    notes = touching_notes(scene, names, body_group, touch_pairs, contact)
    model = Model(
        X, p.volumes, p.density, p.shear_modulus, p.bulk_modulus, p.remanence, body_id, clamped,
        dx=dx, domain_lo=lo, domain_hi=hi, precision=sim.precision, device=device or sim.device,
        material_model=p.material_model, material_params=p.material_params, contact_group=body_group[body_id],
        stimulus=p.stimulus, stimuli=p.stimuli, magnetization_follows=p.magnetization_follows,
        prony=p.prony, pronies=p.pronies, pressure_area=p.pressure_area, pressure_row=p.pressure_row,
        pressures=p.pressures, clamp_row=clamp_row, clamp_paths=clamp_paths,
        initial_displacement=p.displacement, initial_deformation=p.deformation, plane=sim.plane,
    )
    model.spacing = dx / sim.particles_per_cell
    report = p.report
    p_vel = p.velocity
    sources = []
    for i, f in enumerate(scene.fields):
        try:
            sources.append(make_field(f, scene.base_dir, f"{source}: fields[{i}]"))
        except ValueError as exc:
            raise SceneError(f"{source}: fields[{i}]: {exc}") from None
    colliders = [make_collider(c, dim, sim.plane_z) for c in scene.colliders]
    touching = contact.active(int(body_group.max()) + 1)
    if touching and sim.plane == "axisymmetric":
        check_axisymmetric_contact(scene, X, body_group[body_id], names, body_id, source)
    # 'auto': the form that settles, unless bodies (or parts of one) touch each other
    formulation = ("updated" if touching else "total") if sim.formulation == "auto" else sim.formulation
    if clamp_paths and formulation == "updated" and sim.integrator == "explicit":
        i = next(i for i, c in enumerate(scene.clamps) if c.path is not None)
        raise SceneError(f"{source}: clamps[{i}].path: a moving clamp needs the total formulation in the explicit engine "
                         f"(simulation.formulation = 'total'; 'auto' chose 'updated' because bodies touch)"
                         if sim.formulation == "auto" else
                         f"{source}: clamps[{i}].path: a moving clamp needs simulation.formulation = 'total' in the explicit engine")
    settings = SolverSettings(
        damping=sim.damping,
        gravity=tuple(sim.gravity) if sim.gravity is not None else (0.0,) * dim,
        walls=sim.walls,
        wall_friction=sim.wall_friction,
        cfl=sim.cfl,
        plane_z=sim.plane_z,
        velocity_gradient=sim.velocity_gradient,
        formulation=formulation,
        formulation_auto=sim.formulation == "auto",
        threads=sim.threads,
        contact=contact,
        magnetic_interaction=sim.magnetic_interaction,
        interaction_every=sim.interaction_every,
        depth=sim.depth if dim == 2 else 1.0,
    )
    probes = []
    masses = model.host["mass"]
    for i, p in enumerate(scene.probes):
        if p.type == "collider_force":  # its index is checked with the scene (load.check_scene)
            pair = None
            if p.bodies is not None:
                groups = [int(model.host["contact_group"][body_id == names.index(n)][0]) for n in p.bodies]
                if groups[0] == groups[1]:
                    raise SceneError(f"{source}: probes[{i}].bodies: '{p.bodies[0]}' and '{p.bodies[1]}' are bonded into "
                                     f"one piece ([contact] bonded), so no contact force acts between them")
                pair = (groups[0], groups[1])
            probes.append(ProbeSpec(p.name, "collider_force", np.zeros(0, dtype=np.int64), collider=p.collider, pair=pair))
            continue
        if p.type == "field" and p.position is not None:
            probes.append(ProbeSpec(p.name, "field", np.zeros(0, dtype=np.int64), position=np.asarray(p.position[:dim], dtype=np.float64)))
            continue
        sel = np.flatnonzero(body_id == names.index(p.body))
        if p.type in ("tip", "point", "field"):
            region = region_shape(p.region, f"probes[{i}].region")
            sel = sel[region.contains(X[sel])]
            if len(sel) == 0:
                raise SceneError(f"{source}: probes[{i}].region: holds no particle of body '{p.body}'")
            probes.append(ProbeSpec(p.name, "field" if p.type == "field" else "point", sel))
        elif p.type == "centroid":
            probes.append(ProbeSpec(p.name, "centroid", sel, masses[sel]))
        else:
            probes.append(ProbeSpec(p.name, "bbox", sel))
    return Built(model, Control(sources, colliders), settings, probes, names, p_vel, report, notes)
