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
from magsoro.geometry.primitives import Box, Cylinder, Polygon, Rectangle, Sphere, fill_lattice
from magsoro.mpm.colliders import Collider
from magsoro.mpm.solver import Control, Model, SolverSettings
from magsoro.scene.schema import Scene


def make_shape(spec):
    """Geometry object for a shape table of the scene."""
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
    raise SceneError(f"unknown shape type {t!r}")


def _pad3(v, fill=0.0):
    out = np.full(3, fill, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64).ravel()
    out[: len(v)] = v
    return out


def make_field(spec, base_dir: Path | None):
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
                raise SceneError(f"fields: {exc}") from None
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


ENGINE_MODELS = {"neo-hookean": 0, "mooney-rivlin": 1, "yeoh": 2}


def resolve_material(spec, base_dir, key: str) -> dict:
    """Material of a body as engine numbers: model id, initial shear modulus, bulk modulus, params, density.

    Reads ``spec.file`` (a `magsoro fit-material` entry) when given; inline keys override it.
    """
    values = {}
    if spec.file is not None:
        import tomllib

        path = Path(spec.file) if base_dir is None else Path(base_dir) / spec.file
        if not path.is_file():
            raise SceneError(f"{key}.file: material file '{path}' not found")
        try:
            entry = tomllib.loads(path.read_text())
        except tomllib.TOMLDecodeError as exc:
            raise SceneError(f"{key}.file: '{path}' is not valid TOML: {exc}") from None
        model = entry.get("model")
        if model not in ENGINE_MODELS:
            raise SceneError(f"{key}.file: '{path}' holds model {model!r}; the engine supports {', '.join(ENGINE_MODELS)}")
        values["model"] = model
        if "density" in entry:
            values["density"] = entry["density"]
        params = entry.get("parameters", {})
        if model == "neo-hookean":
            values["shear_modulus"] = 2.0 * params["C10"] if "C10" in params else entry.get("shear_modulus")
        else:
            for name in ("C10", "C01", "C20", "C30"):
                if name in params:
                    values[name] = params[name]
    for name in ("model", "density", "shear_modulus", "C10", "C01", "C20", "C30", "bulk_modulus"):
        v = getattr(spec, name)
        if v is not None:
            values[name] = v
    model = values.get("model", "neo-hookean")
    if values.get("density") is None:
        raise SceneError(f"{key}.density: required (kg/m^3), inline or in the material file")
    try:
        if model == "neo-hookean":
            G = float(values["shear_modulus"])
            params = (0.0, 0.0, 0.0)
        elif model == "mooney-rivlin":
            params = (float(values["C10"]), float(values.get("C01", 0.0)), 0.0)
            G = 2.0 * (params[0] + params[1])
        else:
            params = (float(values["C10"]), float(values.get("C20", 0.0)), float(values.get("C30", 0.0)))
            G = 2.0 * params[0]
    except (KeyError, TypeError) as exc:
        raise SceneError(f"{key}: model '{model}' lacks parameter {exc}") from None
    if not G > 0:
        raise SceneError(f"{key}: the initial shear modulus must be > 0 Pa, got {G}")
    K = float(values.get("bulk_modulus") or 20.0 * G)
    return {"model": ENGINE_MODELS[model], "shear_modulus": G, "bulk_modulus": K, "params": params, "density": float(values["density"])}


@dataclass
class ProbeSpec:
    """A probe resolved to particle indices."""

    name: str
    kind: str  # centroid | point | bbox
    indices: np.ndarray
    weights: np.ndarray | None = None

    def columns(self, dim: int) -> list[str]:
        axes = "xyz"[:dim]
        if self.kind == "bbox":
            return [f"{self.name}_min_{a}" for a in axes] + [f"{self.name}_max_{a}" for a in axes]
        return [f"{self.name}_{a}" for a in axes]

    def evaluate(self, x: np.ndarray) -> np.ndarray:
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


def build(scene: Scene, device: str | None = None, source: str = "scene") -> Built:
    """Fill bodies with particles and assemble Model, Control, SolverSettings and probes.

    Raises SceneError when a body has no particle at this resolution or lies (partly) outside the domain.
    """
    sim = scene.simulation
    dim, dx, ppc = sim.dim, sim.dx, sim.particles_per_cell
    lo, hi = np.asarray(sim.domain_lo, dtype=np.float64), np.asarray(sim.domain_hi, dtype=np.float64)
    depth = sim.depth if dim == 2 else 1.0
    pos, vol, rho, G, K, Br, body, vel, mat_model, mat_params = [], [], [], [], [], [], [], [], [], []
    report = []
    for i, b in enumerate(scene.bodies):
        shape = make_shape(b.shape)
        try:
            pts, v_each = fill_lattice(shape, dx, ppc, lo, dim)
        except ValueError as exc:
            raise SceneError(f"{source}: bodies[{i}].shape: {exc}") from None
        if len(pts) == 0:
            raise SceneError(f"{source}: bodies[{i}].shape: body '{b.name}' holds no particle at dx = {dx} m; refine simulation.dx or enlarge the shape")
        blo, bhi = shape.bounds()
        blo, bhi = np.asarray(blo)[:dim], np.asarray(bhi)[:dim]
        margin = 2 * dx  # walls act on the outer two cells
        if np.any(blo < lo + margin) or np.any(bhi > hi - margin):
            raise SceneError(
                f"{source}: bodies[{i}].shape: body '{b.name}' spans {blo.tolist()} to {bhi.tolist()} m, outside the domain "
                f"[{lo.tolist()}, {hi.tolist()}] shrunk by two cells ({margin} m); move it or enlarge simulation.domain_lo/domain_hi"
            )
        n = len(pts)
        mat = resolve_material(b.material, getattr(scene, "_base_dir", None), f"{source}: bodies[{i}].material")
        pos.append(pts)
        vol.append(np.full(n, v_each * depth))
        rho.append(np.full(n, mat["density"]))
        G.append(np.full(n, mat["shear_modulus"]))
        K.append(np.full(n, mat["bulk_modulus"]))
        mat_model.append(np.full(n, mat["model"], dtype=np.int32))
        mat_params.append(np.tile(mat["params"], (n, 1)))
        Br.append(np.tile(np.asarray(b.magnetization, dtype=np.float64), (n, 1)))
        body.append(np.full(n, i, dtype=np.int32))
        vel.append(np.tile(np.asarray(b.velocity if b.velocity is not None else np.zeros(dim), dtype=np.float64), (n, 1)))
        report.append({"body": b.name, "particles": n, "filled_volume": n * v_each, "shape_volume": shape.volume()})
    X = np.concatenate(pos)
    body_id = np.concatenate(body)
    clamped = np.zeros(len(X), dtype=bool)
    names = [b.name for b in scene.bodies]
    for i, c in enumerate(scene.clamps):
        region = make_shape(c.region)
        inside = region.contains(X)
        if c.body is not None:
            inside &= body_id == names.index(c.body)
        if not inside.any():
            raise SceneError(f"{source}: clamps[{i}].region: holds no particle; check the region against the bodies")
        clamped |= inside
    model = Model(
        X, np.concatenate(vol), np.concatenate(rho), np.concatenate(G), np.concatenate(K), np.concatenate(Br), body_id, clamped,
        dx=dx, domain_lo=lo, domain_hi=hi, precision=sim.precision, device=device or sim.device,
        material_model=np.concatenate(mat_model), material_params=np.concatenate(mat_params),
    )
    sources = []
    for i, f in enumerate(scene.fields):
        try:
            sources.append(make_field(f, getattr(scene, "_base_dir", None)))
        except ValueError as exc:
            raise SceneError(f"{source}: fields[{i}]: {exc}") from None
    colliders = [make_collider(c, dim, sim.plane_z) for c in scene.colliders]
    settings = SolverSettings(
        damping=sim.damping,
        gravity=tuple(sim.gravity) if sim.gravity is not None else (0.0,) * dim,
        walls=sim.walls,
        wall_friction=sim.wall_friction,
        cfl=sim.cfl,
        plane_z=sim.plane_z,
    )
    probes = []
    masses = model.host["mass"]
    for i, p in enumerate(scene.probes):
        sel = np.flatnonzero(body_id == names.index(p.body))
        if p.type in ("tip", "point"):
            region = make_shape(p.region)
            sel = sel[region.contains(X[sel])]
            if len(sel) == 0:
                raise SceneError(f"{source}: probes[{i}].region: holds no particle of body '{p.body}'")
            probes.append(ProbeSpec(p.name, "point", sel))
        elif p.type == "centroid":
            probes.append(ProbeSpec(p.name, "centroid", sel, masses[sel]))
        else:
            probes.append(ProbeSpec(p.name, "bbox", sel))
    return Built(model, Control(sources, colliders), settings, probes, names, np.concatenate(vel), report)
