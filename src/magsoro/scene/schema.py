"""Scene file schema (TOML), validated by pydantic v2.

Every key carries its unit and default in its description; docs/scenes.md is generated from these models
(``magsoro docs scenes``), so the reference cannot drift from the code. Unknown keys are refused.
Vectors have 3 components in 3D scenes and 2 in 2D scenes, except field and magnetisation vectors, which
always have 3 (the field is three-dimensional even when the body is planar).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, Optional, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Discriminator, Field, PlainValidator, PrivateAttr, Tag, model_validator

from magsoro.mpm.laws.elastic import DEFAULT_LAW, LAW_NAMES, LAWS, LIST_KEYS, PARAMETER_KEYS
from magsoro.mpm.laws.prony import prony_problem

Vec = list[float]


def _nonzero(v: list[float]) -> list[float]:
    if not any(c != 0.0 for c in v):
        raise ValueError(f"must be a direction of non-zero length (got {v})")
    return v


def _positive(v: list[float]) -> list[float]:
    if not all(c > 0.0 for c in v):
        raise ValueError(f"every edge length must be > 0 m (got {v})")
    return v


Direction = Annotated[list[float], AfterValidator(_nonzero)]  # a direction: any non-zero length
Axis3 = Annotated[list[float], Field(min_length=3, max_length=3), AfterValidator(_nonzero)]  # a 3D axis
Sizes = Annotated[list[float], AfterValidator(_positive)]  # edge lengths, m


def _identifier(v: str) -> str:
    import re

    if not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_\-]{0,63}", v):
        raise ValueError("a name of letters, digits, '_' and '-' (at most 64; it becomes a metrics.csv column "
                         "or a sweep key)")
    return v


Identifier = Annotated[str, AfterValidator(_identifier)]  # body, probe and field-source names


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_default=True, allow_inf_nan=False, strict=True)


def _check_len(v, name, n):
    if v is not None and len(v) != n:
        raise ValueError(f"{name} must have {n} components, got {len(v)}")


# ---------------------------------------------------------------- shapes
class BoxShape(Strict):
    """Solid box (3D)."""

    type: Literal["box"]
    center: Vec = Field(description="Centre of the box, m.")
    size: Sizes = Field(description="Full edge lengths along x, y, z, m.")


class CylinderShape(Strict):
    """Solid cylinder (3D)."""

    type: Literal["cylinder"]
    center: Vec = Field(description="Centre of the cylinder, m.")
    radius: float = Field(gt=0, description="Radius, m.")
    length: float = Field(gt=0, description="Length along the axis, m.")
    axis: Axis3 = Field(default=[0.0, 0.0, 1.0], description="Axis direction (3 components, any non-zero length).")


class SphereShape(Strict):
    """Solid sphere (3D)."""

    type: Literal["sphere"]
    center: Vec = Field(description="Centre, m.")
    radius: float = Field(gt=0, description="Radius, m.")


class RectangleShape(Strict):
    """Rectangle (2D scenes)."""

    type: Literal["rectangle"]
    center: Vec = Field(description="Centre, m (2 components).")
    size: Sizes = Field(description="Full edge lengths along x and y, m.")
    angle: float = Field(default=0.0, description="Rotation about z, degrees.")


class PolygonShape(Strict):
    """Simple polygon (2D scenes)."""

    type: Literal["polygon"]
    vertices: list[Vec] = Field(description="Vertices [[x, y], ...] in m, either winding order.")


class MeshShape(Strict):
    """Closed triangle mesh from a CAD file (STL, OBJ, PLY), filled on the grid-aligned lattice (3D).

    world = R(rotation) (scale x file coordinates) + position. A mesh that is not watertight is repaired when
    trimesh can (merged vertices, filled holes); otherwise the scene is refused naming the file.
    """

    type: Literal["mesh"]
    file: str = Field(description="Mesh file, relative to the scene (or robot) file.")
    scale: float = Field(default=1.0, gt=0, description="Metres per file unit (1e-3 for a file in mm).")
    position: Vec = Field(default=[0.0, 0.0, 0.0], description="Translation applied after scaling and rotation, m.")
    rotation: Vec = Field(default=[0.0, 0.0, 0.0], description="Rotation [rx, ry, rz] about the fixed x, y, z axes, degrees (R = Rz Ry Rx).")


class TubeShape(Strict):
    """Hollow cylinder (3D)."""

    type: Literal["tube"]
    center: Vec = Field(description="Centre, m.")
    outer_radius: float = Field(gt=0, description="Outer radius, m.")
    inner_radius: float = Field(ge=0, description="Inner radius, m (< outer_radius).")
    length: float = Field(gt=0, description="Length along the axis, m.")
    axis: Axis3 = Field(default=[0.0, 0.0, 1.0], description="Axis direction (3 components, any non-zero length).")


class ExtrusionShape(Strict):
    """2D polygon (local x-y) extruded along local z, centred on the local z = 0 plane, then placed (3D)."""

    type: Literal["extrusion"]
    vertices: list[Vec] = Field(description="Polygon vertices [[x, y], ...] in m, in the local frame, either winding order.")
    thickness: float = Field(gt=0, description="Extrusion length along local z, m.")
    position: Vec = Field(default=[0.0, 0.0, 0.0], description="Where the local origin goes, m.")
    rotation: Vec = Field(default=[0.0, 0.0, 0.0], description="Rotation [rx, ry, rz] about the fixed x, y, z axes, degrees (R = Rz Ry Rx).")


class ArcShape(Strict):
    """Arc (arch) strip: an annular sector of mid radius ``radius`` and radial ``width`` about ``center``,
    spanning polar angles start_angle..end_angle in the local x-y plane. In 3D it has ``thickness`` along local z
    and is turned by ``rotation``; in 2D it lies in the scene plane."""

    type: Literal["arc"]
    center: Vec = Field(description="Centre of curvature, m.")
    radius: float = Field(gt=0, description="Mid-line radius, m.")
    width: float = Field(gt=0, description="Radial width of the strip, m (<= 2 radius).")
    start_angle: float = Field(default=0.0, description="Start polar angle, degrees.")
    end_angle: float = Field(default=180.0, description="End polar angle, degrees (> start_angle, span <= 360).")
    thickness: float | None = Field(default=None, gt=0, description="3D only (required there): thickness along local z, m.")
    rotation: Vec = Field(default=[0.0, 0.0, 0.0], description="3D only: rotation [rx, ry, rz] about the fixed x, y, z axes, degrees.")


Shape3D = Annotated[Union[BoxShape, CylinderShape, SphereShape, MeshShape, TubeShape, ExtrusionShape, ArcShape], Field(discriminator="type")]
AnyShape = Annotated[
    Union[BoxShape, CylinderShape, SphereShape, RectangleShape, PolygonShape, MeshShape, TubeShape, ExtrusionShape, ArcShape],
    Field(discriminator="type"),
]
SHAPES_3D = ("box", "cylinder", "sphere", "mesh", "tube", "extrusion", "arc")
SHAPES_2D = ("rectangle", "polygon", "arc")


# ---------------------------------------------------------------- bodies
MaterialModel = Literal[LAW_NAMES]  # the laws of magsoro.mpm.laws.elastic


def _terms(v: list[float]) -> list[float]:
    n = LIST_KEYS["mu"]
    if not 1 <= len(v) <= n:
        raise ValueError(f"must be a list of 1 to {n} numbers (one per Ogden term), got {len(v)}")
    return v


OgdenTerms = Annotated[list[float], AfterValidator(_terms)]


def _prony(v: list[list[float]]) -> list[list[float]]:
    problem = prony_problem(v)
    if problem is not None:
        raise ValueError(problem)
    return v


PronyTable = Annotated[list[list[float]], AfterValidator(_prony)]


class StimulusRamp(Strict):
    """Stimulus going linearly from ``initial`` to ``final`` over [start, start + duration], held before and after."""

    type: Literal["ramp"]
    duration: float = Field(gt=0, description="Ramp duration, s.")
    start: float = Field(default=0.0, ge=0, description="Ramp start time, s.")
    initial: float = Field(default=0.0, description="Stimulus before the ramp (in the stimulus' own unit, e.g. degC).")
    final: float = Field(default=1.0, description="Stimulus after the ramp.")


def _check_time_table(times: list[float], values: list[float]) -> None:
    """A table of values at times: one value per time, the times strictly increasing (ValueError otherwise)."""
    if len(times) != len(values):
        raise ValueError(f"times and values must have the same length, got {len(times)} and {len(values)}")
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ValueError("times must be strictly increasing")


class StimulusKeyframes(Strict):
    """Stimulus interpolated linearly between values at increasing times, held outside the table (e.g. a measured
    temperature history)."""

    type: Literal["keyframes"]
    times: list[float] = Field(min_length=1, description="Strictly increasing times, s.")
    values: list[float] = Field(min_length=1, description="Stimulus at those times (one per time).")

    @model_validator(mode="after")
    def _rows(self):
        _check_time_table(self.times, self.values)
        return self


class StimulusSine(Strict):
    """s(t) = offset + amplitude sin(2 pi frequency t + phase): cyclic heating and cooling."""

    type: Literal["sine"]
    frequency: float = Field(gt=0, description="Frequency, Hz.")
    amplitude: float = Field(default=1.0, description="Amplitude (stimulus unit).")
    offset: float = Field(default=0.0, description="Mean value (stimulus unit).")
    phase: float = Field(default=0.0, description="Phase, degrees.")


class StimulusConstant(Strict):
    """A stimulus that does not change (a pre-shrunk or pre-swollen material)."""

    type: Literal["constant"]
    value: float = Field(description="The stimulus (stimulus unit).")


StimulusProfile = Annotated[Union[StimulusRamp, StimulusKeyframes, StimulusSine, StimulusConstant], Field(discriminator="type")]


def _table(name: str):
    def check(rows: list[list[float]]) -> list[list[float]]:
        from magsoro.mpm.laws.eigenstrain import table_problem

        problem = table_problem(rows, name)
        if problem is not None:
            raise ValueError(problem)
        return rows

    return check


class Stimulus(Strict):
    """Stimulus-driven eigenstrain (docs/engine.md, "Stimulus-driven eigenstrain"): the material's stress-free
    shape follows a scalar stimulus s(t) (temperature, swelling ratio, ...): F = F_e F_s with F_s = lambda(s) I, or
    I + (lambda - 1) a a^T along the unit direction a, and energy f(s) det(F_s) W(F_e) with the material's own law
    W, so a free body shrinks (lambda < 1) or swells (> 1) stress-free and its moduli scale by f. The tables are
    interpolated linearly in s and held constant outside it. 2D (plane strain): the stretch acts in the plane only.
    Bodies with different materials (a bilayer) each follow their own table."""

    profile: StimulusProfile = Field(description="Time profile of the stimulus: a table [StimulusRamp](#stimulusramp), [StimulusKeyframes](#stimuluskeyframes), [StimulusSine](#stimulussine) or [StimulusConstant](#stimulusconstant).")
    stretch: Annotated[list[list[float]], AfterValidator(_table("lambda"))] = Field(description="Eigenstretch table [[s, lambda], ...]: s strictly increasing, lambda > 0 (1: unchanged; 0.8: shrunk to 80 % of its length).")
    modulus_factor: Optional[Annotated[list[list[float]], AfterValidator(_table("f"))]] = Field(default=None, description="Table [[s, f], ...] scaling every elastic modulus (G or the law's constants, and K) by f > 0. Default: f = 1.")
    direction: Optional[Direction] = Field(default=None, description="Direction a of the stretch in the reference frame (3 components in 3D, 2 in 2D; any non-zero length). Default: isotropic.")


class Material(Strict):
    """Material of a body: a compressible hyperelastic solid with volumetric energy K/2 (J - 1)^2.

    model 'neo-hookean' (seed 000 eq 10) takes shear_modulus; 'mooney-rivlin' takes C10 and C01; 'yeoh' takes
    C10, C20, C30 (W = sum Ci0 (I1b - 3)^i); 'ogden' takes the lists mu and alpha of 1 to 3 terms (W = sum_i 2 mu_i /
    alpha_i^2 (lb1^alpha_i + lb2^alpha_i + lb3^alpha_i - 3), Abaqus's form, with initial shear modulus sum mu_i;
    one term with alpha = 2 is Neo-Hookean with G = mu; every alpha_i non-zero and sum mu_i > 0; Ogden's
    sufficient condition for stability, mu_i alpha_i > 0 in every term, which fit-material's fits keep, is not
    required); 'polynomial' takes C10, C01, C20, C11, C02 (W = sum over 1 <= i + j <= 2 of Cij (I1b - 3)^i
    (I2b - 3)^j, initial shear modulus 2 (C10 + C01)). I1b, I2b and lb_k are the isochoric invariants and
    principal stretches (J^(-2/3) I1, J^(-4/3) I2, J^(-1/3) lam_k). Instead of inline values, ``file`` may name a
    material entry written by ``magsoro fit-material --save-material`` (keys given here override the file's); its
    model ogden3 is read as 'ogden', polynomial5 as 'polynomial' and linear (P = E strain, which has no strain
    energy) as 'neo-hookean' with G = E/3, the same small-strain stiffness.
    """

    library: str | None = Field(default=None, description="Name of a material library entry (magsoro materials list); keys given here override it. A bare string `material = \"NAME\"` means the same.")
    file: str | None = Field(default=None, description="Material entry TOML (from magsoro fit-material), relative to the scene file.")
    model: MaterialModel | None = Field(default=None, description=f"Constitutive model. Default '{DEFAULT_LAW}' (or the file's).")
    density: float | None = Field(default=None, gt=0, description="Mass density, kg/m^3 (required here or in the file).")
    shear_modulus: float | None = Field(default=None, gt=0, description="Neo-Hookean shear modulus G, Pa.")
    C10: float | None = Field(default=None, description="Mooney-Rivlin / Yeoh / polynomial C10, Pa (Yeoh: > 0; Mooney-Rivlin, polynomial: C10 + C01 > 0).")
    C01: float | None = Field(default=None, description="Mooney-Rivlin / polynomial C01, Pa (C10 + C01 > 0). Polynomial default 0.")
    C20: float | None = Field(default=None, description="Yeoh / polynomial C20, Pa. Default 0.")
    C30: float | None = Field(default=None, description="Yeoh C30, Pa. Default 0.")
    mu: Optional[OgdenTerms] = Field(default=None, description="Ogden moduli mu_i, Pa: a list of 1 to 3 (sum > 0, the initial shear modulus).")
    alpha: Optional[OgdenTerms] = Field(default=None, description="Ogden exponents alpha_i (dimensionless, non-zero), one per mu_i.")
    C11: float | None = Field(default=None, description="Polynomial C11, Pa. Default 0.")
    C02: float | None = Field(default=None, description="Polynomial C02, Pa. Default 0.")
    bulk_modulus: float | None = Field(default=None, gt=0, description="Bulk modulus K, Pa. Default 20 x the initial shear modulus (seed 000).")
    stimulus: Stimulus | None = Field(default=None, description="Optional [Stimulus](#stimulus): a stretch and modulus factor following a stimulus in time (thermo-responsive hydrogels, swelling, LCEs).")
    prony: Optional[PronyTable] = Field(default=None, description="Optional viscoelasticity: a Prony series [[g1, tau1], ...] of 1 to 3 terms relaxing the isochoric stress (finite-strain generalised Maxwell): g_i > 0 the fraction of the instantaneous shear modulus relaxing with time constant tau_i > 0 s, sum g_i < 1. The law's moduli are the instantaneous ones; the long-term ones are (1 - sum g_i) times those. Not with a stimulus; see docs/engine.md, Viscoelasticity.")
    magnetization_follows: Literal["F", "R"] = Field(default="F", description="How the remanence is carried by the deformation: 'F' (Zhao's law, m = F Br V / mu0: a stretch along Br raises the moment) or 'R' (the rotation of F = R U, m = R Br V / mu0: only rotations turn it). The two coincide for rigid rotations; see docs/engine.md, Magnetisation kinematics.")

    @model_validator(mode="after")
    def _complete(self):
        if self.file is not None and self.library is not None:
            raise ValueError("give either library or file, not both")
        if self.prony is not None and self.stimulus is not None:
            raise ValueError("a material cannot have both prony and stimulus (not supported yet)")
        if self.file is not None or self.library is not None:
            return self  # completed against the file or library entry when the scene is built
        model = self.model or DEFAULT_LAW
        law = LAWS[model]
        if self.density is None:
            raise ValueError("density is required (kg/m^3)")
        missing = [k for k in law.required if getattr(self, k) is None]
        if missing:
            raise ValueError(f"model '{model}' needs {', '.join(missing)}")
        given = [k for k in PARAMETER_KEYS if k not in law.keys and getattr(self, k) is not None]
        if given:
            raise ValueError(f"model '{model}' does not use {', '.join(given)}")
        values = {k: getattr(self, k) for k in law.keys if getattr(self, k) is not None}
        problem = law.problem(values)
        if problem is not None:
            raise ValueError(problem)
        if not law.initial_shear_modulus(values) > 0:
            raise ValueError(f"{model} needs {law.constraint}")
        return self


class UniformMagnetization(Strict):
    """The same remanence everywhere in the body: magnitude x unit(direction)."""

    type: Literal["uniform"]
    direction: Vec = Field(description="Direction of Br in the reference frame (any non-zero length).")
    magnitude: float | None = Field(default=None, ge=0, description="|Br|, T. Default: the remanence of the body's library material.")

    @model_validator(mode="after")
    def _dir(self):
        _check_len(self.direction, "direction", 3)
        if all(c == 0 for c in self.direction):
            raise ValueError("direction must be non-zero")
        return self


class RotatingMagnetization(Strict):
    """Direction turning along an axis: Br(s) = magnitude [cos(2 pi s/period + phase) u + sin(2 pi s/period + phase) v],
    s = (X - origin) . axis. With period = body length it is the sinusoidal profile of Hu et al.'s walker (seed 000 sec 4.5)."""

    type: Literal["rotating"]
    axis: Vec = Field(default=[1.0, 0.0, 0.0], description="Axis along which the direction turns.")
    origin: Vec = Field(default=[0.0, 0.0, 0.0], description="Where s = 0, m (3 components).")
    period: float = Field(gt=0, description="Length over which the direction turns once, m.")
    u: Vec = Field(default=[1.0, 0.0, 0.0], description="Direction at phase 0.")
    v: Vec = Field(default=[0.0, 0.0, 1.0], description="Direction a quarter period later (orthogonalised against u).")
    phase: float = Field(default=0.0, description="Phase at s = 0, degrees.")
    magnitude: float | None = Field(default=None, ge=0, description="|Br|, T. Default: the remanence of the body's library material.")

    @model_validator(mode="after")
    def _len(self):
        for k in ("axis", "origin", "u", "v"):
            _check_len(getattr(self, k), k, 3)
        return self


class TableMagnetization(Strict):
    """Br tabulated along an axis (e.g. one vector per segment of a tentacle, Pittiglio et al., seed 000 sec 4.5)."""

    type: Literal["table"]
    axis: Vec = Field(default=[1.0, 0.0, 0.0], description="Axis along which s is measured.")
    origin: Vec = Field(default=[0.0, 0.0, 0.0], description="Where s = 0, m (3 components).")
    positions: list[float] = Field(min_length=1, description="Increasing s values, m ('step': where each row starts).")
    vectors: list[Vec] = Field(min_length=1, description="Br at each position, T; with magnitude given, only their directions count.")
    interpolation: Literal["step", "linear"] = Field(default="step", description="'step' (piecewise constant) or 'linear'.")
    magnitude: float | None = Field(default=None, ge=0, description="If given, every vector is scaled to this |Br|, T (zero rows stay zero).")

    @model_validator(mode="after")
    def _rows(self):
        for k in ("axis", "origin"):
            _check_len(getattr(self, k), k, 3)
        if len(self.positions) != len(self.vectors):
            raise ValueError("positions and vectors must have the same length")
        for i, v in enumerate(self.vectors):
            _check_len(v, f"vectors[{i}]", 3)
        if any(b <= a for a, b in zip(self.positions, self.positions[1:])):
            raise ValueError("positions must be strictly increasing")
        return self


class FileMagnetization(Strict):
    """Br sampled at points in an array file (.csv or .npy, columns x, y, z, Brx, Bry, Brz in m and T); each
    particle takes the nearest sample."""

    type: Literal["file"]
    file: str = Field(description="Array file, relative to the scene (or robot) file.")


class ExpressionMagnetization(Strict):
    """Br components as expressions in the reference position x, y, z (m), giving T. Allowed: numbers, x, y, z,
    pi, e, + - * / ** %, comparisons (giving 0 or 1) and sin cos tan asin acos atan atan2 sinh cosh tanh exp log
    log10 sqrt abs hypot floor ceil sign min max where. In 2D scenes z = 0."""

    type: Literal["expression"]
    x: str = Field(default="0", description="Brx(x, y, z), T.")
    y: str = Field(default="0", description="Bry(x, y, z), T.")
    z: str = Field(default="0", description="Brz(x, y, z), T.")


AnyMagnetization = Annotated[
    Union[UniformMagnetization, RotatingMagnetization, TableMagnetization, FileMagnetization, ExpressionMagnetization],
    Field(discriminator="type"),
]


def _is_table(tag_if_dict, tag_else):
    def pick(v):
        return tag_if_dict if isinstance(v, (dict, BaseModel)) else tag_else

    return pick


# Callable discriminators: a vector or a profile table, a library name or a material table; each error then
# comes from the one branch the user meant.
MagnetizationSpec = Annotated[
    Union[Annotated[Vec, Tag("vector")], Annotated[AnyMagnetization, Tag("profile")]], Discriminator(_is_table("profile", "vector"))
]
MaterialSpec = Annotated[Union[Annotated[str, Tag("name")], Annotated[Material, Tag("table")]], Discriminator(_is_table("table", "name"))]


class Pressure(Strict):
    """A gauge pressure on the surface of a body that faces a cavity (an inflated chamber, the inside of an
    everting tube): a follower load, acting on the current surface along its current normal (docs/engine.md,
    "Pressure loads")."""

    cavity: AnyShape = Field(description="The pressurised region, a shape as for bodies ('tube', 'cylinder', 'sphere', 'box', ... in 3D; 'rectangle', 'polygon', 'arc' in 2D). The load acts on the body's particle faces that look into it.")
    value: float = Field(description="Gauge pressure, Pa (negative: suction).")
    ramp: float = Field(default=0.0, ge=0, description="Rise time, s: the pressure grows linearly from 0 to value over [0, ramp], then stays (0: applied at once).")


class InitialDisplacement(Strict):
    """A displacement field the body starts with (an initial imperfection, a pre-strain): components as expressions
    in the reference position x, y, z (m), giving m, with the arithmetic of an expression magnetisation (numbers,
    x, y, z, pi, e, + - * / ** %, comparisons, sin cos tan ... where; in 2D z = 0). Each particle starts at X + u(X)
    with the deformation gradient F = I + grad u (central differences), so the body starts displaced and strained
    accordingly (docs/geometry.md, "Initial displacement")."""

    expression: list[str] = Field(min_length=2, max_length=3, description="Components [ux, uy] (2D) or [ux, uy, uz] (3D) of u(x, y, z), m; e.g. [\"0\", \"1e-5 * sin(pi * x / 0.12)\"].")


class Body(Strict):
    """A body (or a robot part): a shape filled with particles of one material, with a magnetisation profile."""

    name: Identifier = Field(description="Unique name, used by clamps and probes (letters, digits, '_', '-').")
    shape: AnyShape = Field(description="Geometry; 'box', 'cylinder', 'sphere', 'mesh', 'tube', 'extrusion', 'arc' in 3D; 'rectangle', 'polygon', 'arc' in 2D.")
    material: MaterialSpec = Field(description="A table [Material](#material), or the name of a library entry (magsoro materials list).")
    magnetization: MagnetizationSpec = Field(
        default=[0.0, 0.0, 0.0],
        description="Remanent flux density Br in the reference frame: a vector in T (3 components; in 2D only x, y act) or a profile table (uniform, rotating, table, file, expression).",
    )
    magnetic: bool | None = Field(default=None, description="If true, a magnetisation that is zero everywhere is an error (catches a forgotten magnitude).")
    clamped: bool = Field(default=False, description="Hold every particle of this body fixed.")
    priority: int | None = Field(default=None, description="Where bodies overlap, the one with the higher priority keeps the shared particles (unset loses to any set value); overlapping bodies with equal or no priorities are refused.")
    velocity: Vec | None = Field(default=None, description="Initial velocity, m/s. Default at rest.")
    pressure: Pressure | None = Field(default=None, description="A gauge pressure on the body's surface facing a cavity: a table [Pressure](#pressure).")
    initial_displacement: InitialDisplacement | None = Field(default=None, description="A displacement field the body starts with, u(x, y, z) as expressions: a table [InitialDisplacement](#initialdisplacement). Default none.")
    _base_dir: object = PrivateAttr(default=None)
    _key: object = PrivateAttr(default=None)
    _source: object = PrivateAttr(default=None)

    # where the body was read (set by the loader; None for a body made in Python)
    @property
    def key(self) -> str | None:
        """The body's table in error messages: 'bodies[2]', 'robot.parts[0]', 'parts[1]' (of a robot file)."""
        return self._key

    @key.setter
    def key(self, value: str | None) -> None:
        self._key = value

    @property
    def source(self) -> str | None:
        """The scene or robot file the body's table is in (or the scene's source name)."""
        return self._source

    @source.setter
    def source(self, value: str | None) -> None:
        self._source = value

    @property
    def base_dir(self):
        """The directory the body's relative file names (meshes, magnetisation tables) resolve against; None: the
        scene's."""
        return self._base_dir

    @base_dir.setter
    def base_dir(self, value) -> None:
        self._base_dir = value

    @model_validator(mode="after")
    def _lengths(self):
        if isinstance(self.magnetization, list):
            _check_len(self.magnetization, "magnetization", 3)
        return self


class Robot(Strict):
    """A robot made of parts: inline ``[[robot.parts]]`` and/or a robot file. Parts are bodies; they join
    ``[[bodies]]`` under their own names."""

    file: str | None = Field(default=None, description="Robot file (TOML with [[parts]]), relative to the scene file.")
    parts: list[Body] = Field(default_factory=list, description="Parts ([[robot.parts]] tables), as for bodies.")


class RobotFile(Strict):
    """A robot file: parts and optional user material libraries. Relative paths in it resolve against it."""

    name: str | None = Field(default=None, description="Robot name.")
    description: str | None = Field(default=None, description="Free text: origin of the design, sources of the dimensions.")
    material_library: list[str] = Field(default_factory=list, description="User material library TOML files, relative to the robot file.")
    parts: list[Body] = Field(min_length=1, description="Parts ([[parts]] tables), as for bodies.")


# a robot file name, or a [robot] table: told apart by the input's type, so an error inside the table is reported
# at its own key (a plain union reported every part's mistake as "robot.str: Input should be a valid string")
RobotSpec = Annotated[Union[Annotated[str, Tag("name")], Annotated[Robot, Tag("table")]], Discriminator(_is_table("table", "name"))]


# ---------------------------------------------------------------- clamps
def _check_path_table(times, positions) -> None:
    """A path's times and positions (clamps and colliders): one position per time, times strictly increasing."""
    if len(times) != len(positions):
        raise ValueError("times and positions must have the same length")
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ValueError("times must be strictly increasing")


class ClampPath(Strict):
    """A clamp's prescribed translation: its displacement from the reference place at times, linearly interpolated,
    held outside the table (zero at t = 0)."""

    times: list[Annotated[float, Field(allow_inf_nan=False)]] = Field(min_length=1, description="Increasing times, s.")
    positions: list[Vec] = Field(min_length=1, description="Displacements of the clamped region at those times, m (dim components); the held particles sit at their reference position plus this.")

    @model_validator(mode="after")
    def _same_len(self):
        _check_path_table(self.times, self.positions)
        return self


class Clamp(Strict):
    """Particles whose reference position lies in ``region`` are held (with their grid nodes): fixed, or moved
    along ``path`` (docs/engine.md, "Moving clamps")."""

    region: AnyShape = Field(description="Region in the reference configuration (a shape, as for bodies).")
    body: str | None = Field(default=None, description="Only clamp particles of this body. Default: all bodies.")
    path: ClampPath | None = Field(default=None, description="Optional translation of the held particles: a table [ClampPath](#clamppath) of times and displacements; they sit at reference + displacement and move at its rate. The explicit engine (total formulation), the static solver (the clamps move with each level's load increments) and the implicit integrator. Default: held in place.")


# ---------------------------------------------------------------- colliders
class Path(Strict):
    """Prescribed motion: positions at times, linearly interpolated, held outside the table."""

    times: list[float] = Field(description="Increasing times, s.")
    positions: list[Vec] = Field(description="Positions at those times, m.")

    @model_validator(mode="after")
    def _same_len(self):
        _check_path_table(self.times, self.positions)
        return self


class ColliderBase(Strict):
    mode: Literal["sticky", "slip", "friction", "symmetry"] = Field(default="slip", description="Contact law: sticky, slip (frictionless), friction (Coulomb) or symmetry (a frictionless mirror plane that also holds material from leaving it: half of a symmetric body, or a wedge of an axisymmetric one; half-space colliders only).")
    friction: float = Field(default=0.0, ge=0, description="Coulomb friction coefficient (mode = 'friction').")
    path: Path | None = Field(default=None, description="Optional motion of the collider's reference point.")


class HalfSpaceCollider(ColliderBase):
    """Half-space (floor or wall): material stays on the side the normal points to."""

    type: Literal["half_space"]
    point: Vec = Field(description="A point on the plane, m.")
    normal: Direction = Field(description="Outward normal (towards the free side).")


class _SolidCollider(ColliderBase):
    @model_validator(mode="after")
    def _no_symmetry(self):
        if self.mode == "symmetry":
            raise ValueError("mode 'symmetry' is for half_space colliders (a mirror plane); allowed here: 'sticky', 'slip', 'friction'")
        return self


class BoxCollider(_SolidCollider):
    """Rigid box."""

    type: Literal["box"]
    center: Vec = Field(description="Centre, m.")
    size: Sizes = Field(description="Full edge lengths, m.")


class SphereCollider(_SolidCollider):
    """Rigid sphere (a disc in 2D)."""

    type: Literal["sphere"]
    center: Vec = Field(description="Centre, m.")
    radius: float = Field(gt=0, description="Radius, m.")


class CylinderCollider(_SolidCollider):
    """Rigid cylinder."""

    type: Literal["cylinder"]
    center: Vec = Field(description="Centre, m.")
    radius: float = Field(gt=0, description="Radius, m.")
    length: float = Field(gt=0, description="Length, m.")
    axis: Axis3 = Field(default=[0.0, 0.0, 1.0], description="Axis direction (3 components, any non-zero length).")


AnyCollider = Annotated[Union[HalfSpaceCollider, BoxCollider, SphereCollider, CylinderCollider], Field(discriminator="type")]


# ---------------------------------------------------------------- fields
class FieldBase(Strict):
    name: Identifier | None = Field(default=None, description="Optional name, so sweeps can address the source (fields.NAME.key).")


class RampProfile(Strict):
    """Linear ramp from zero to the full field over ``duration``, starting at ``start``."""

    type: Literal["ramp"]
    duration: float = Field(gt=0, description="Ramp duration, s.")
    start: float = Field(default=0.0, ge=0, description="Ramp start time, s.")


class SineProfile(Strict):
    """B(t) = B (offset + sin(2 pi f t + phase))."""

    type: Literal["sine"]
    frequency: float = Field(gt=0, description="Frequency, Hz.")
    phase: float = Field(default=0.0, description="Phase, degrees.")
    offset: float = Field(default=0.0, description="Constant offset, in units of B.")


Profile = Annotated[Union[RampProfile, SineProfile], Field(discriminator="type")]


class UniformField(FieldBase):
    """Spatially uniform field, constant or scaled by a time profile."""

    type: Literal["uniform"]
    B: Vec = Field(description="Field vector, T.")
    profile: Profile | None = Field(default=None, description="Optional time profile: ramp or sine.")

    @model_validator(mode="after")
    def _len(self):
        _check_len(self.B, "B", 3)
        return self


class RotatingField(FieldBase):
    """Uniform field of constant magnitude rotating in the plane spanned by u and v (from u towards v)."""

    type: Literal["rotating"]
    magnitude: float = Field(description="Field magnitude, T.")
    frequency: float = Field(description="Rotation frequency, Hz (negative reverses the sense).")
    u: Vec = Field(default=[1.0, 0.0, 0.0], description="Direction at t = 0 (phase 0).")
    v: Vec = Field(default=[0.0, 1.0, 0.0], description="Second in-plane direction.")
    phase: float = Field(default=0.0, description="Phase at t = 0, degrees.")
    ramp: float = Field(default=0.0, ge=0, description="Magnitude ramp-up time, s (0: none).")

    @model_validator(mode="after")
    def _len(self):
        _check_len(self.u, "u", 3)
        _check_len(self.v, "v", 3)
        return self


class KeyframedField(FieldBase):
    """Uniform field interpolated linearly between keyframes, given inline or as a CSV file (t,Bx,By,Bz)."""

    type: Literal["keyframes"]
    times: list[float] | None = Field(default=None, description="Keyframe times, s.")
    values: list[Vec] | None = Field(default=None, description="Field vectors at the keyframes, T.")
    file: str | None = Field(default=None, description="CSV with header t,Bx,By,Bz (s, T); relative to the scene file.")

    @model_validator(mode="after")
    def _one_source(self):
        inline = self.times is not None or self.values is not None
        if inline == (self.file is not None):
            raise ValueError("give either times and values, or file")
        if inline and (self.times is None or self.values is None):
            raise ValueError("inline keyframes need both times and values")
        return self


class DipoleField(FieldBase):
    """Point dipole (a small permanent magnet), optionally moving along a path."""

    type: Literal["dipole"]
    moment: Vec = Field(description="Magnetic moment, A m^2.")
    position: Vec = Field(default=[0.0, 0.0, 0.0], description="Position, m (3 components).")
    path: Path | None = Field(default=None, description="Optional motion of the dipole (3-component positions).")

    @model_validator(mode="after")
    def _len(self):
        _check_len(self.moment, "moment", 3)
        _check_len(self.position, "position", 3)
        return self


class CylinderMagnetField(FieldBase):
    """Axially magnetised cylindrical permanent magnet: exact closed form or the multipole expansion of seed 001."""

    type: Literal["cylinder_magnet"]
    diameter: float = Field(gt=0, description="Diameter, m.")
    length: float = Field(gt=0, description="Length along the axis, m.")
    remanence: float = Field(description="Remanence Br along the axis, T (negative flips it).")
    position: Vec = Field(default=[0.0, 0.0, 0.0], description="Centre, m (3 components).")
    axis: Vec = Field(default=[0.0, 0.0, 1.0], description="Magnetisation axis.")
    model: Literal["exact", "multipole"] = Field(default="exact", description="'exact' closed form or 'multipole' (valid outside the bounding sphere).")
    order: int = Field(default=17, ge=1, le=17, description="Highest odd multipole order (model = 'multipole').")
    path: Path | None = Field(default=None, description="Optional motion of the centre (3-component positions).")

    @model_validator(mode="after")
    def _len(self):
        _check_len(self.position, "position", 3)
        _check_len(self.axis, "axis", 3)
        return self


class CuboidMagnetField(FieldBase):
    """Homogeneously magnetised cuboid permanent magnet (closed form)."""

    type: Literal["cuboid_magnet"]
    dimensions: Vec = Field(description="Edge lengths along its local x, y, z, m.")
    remanence: Vec = Field(description="Remanence vector in its local frame, T.")
    position: Vec = Field(default=[0.0, 0.0, 0.0], description="Centre, m (3 components).")
    orientation: list[Vec] | None = Field(default=None, description="Rotation matrix local -> world (3 rows). Default identity.")
    path: Path | None = Field(default=None, description="Optional motion of the centre (3-component positions).")

    @model_validator(mode="after")
    def _len(self):
        _check_len(self.dimensions, "dimensions", 3)
        _check_len(self.remanence, "remanence", 3)
        _check_len(self.position, "position", 3)
        return self


class CoilField(FieldBase):
    """Circular current loop, or a Helmholtz (uniform) or Maxwell (gradient) pair of loops."""

    type: Literal["loop", "helmholtz", "maxwell"]
    radius: float = Field(gt=0, description="Loop radius, m.")
    current: float = Field(description="Current per turn, A (right-handed about the axis).")
    turns: float = Field(default=1.0, gt=0, description="Number of turns.")
    position: Vec = Field(default=[0.0, 0.0, 0.0], description="Centre of the loop or pair, m (3 components).")
    axis: Vec = Field(default=[0.0, 0.0, 1.0], description="Coil axis.")

    @model_validator(mode="after")
    def _len(self):
        _check_len(self.position, "position", 3)
        _check_len(self.axis, "axis", 3)
        return self


AnyField = Annotated[
    Union[UniformField, RotatingField, KeyframedField, DipoleField, CylinderMagnetField, CuboidMagnetField, CoilField],
    Field(discriminator="type"),
]


# ---------------------------------------------------------------- probes
class CentroidProbe(Strict):
    """Mass-weighted centroid of a body (columns NAME_x, NAME_y[, NAME_z])."""

    type: Literal["centroid"]
    name: Identifier = Field(description="Column prefix in metrics.csv (letters, digits, '_', '-').")
    body: str = Field(description="Body name.")


class PointProbe(Strict):
    """Mean position of the particles of a body whose reference position lies in ``region`` (e.g. a tip)."""

    type: Literal["tip", "point"]
    name: Identifier = Field(description="Column prefix in metrics.csv (letters, digits, '_', '-').")
    body: str = Field(description="Body name.")
    region: AnyShape = Field(description="Region in the reference configuration.")


class BoundsProbe(Strict):
    """Axis-aligned bounding box of a body (columns NAME_min_x, ..., NAME_max_z)."""

    type: Literal["bbox"]
    name: Identifier = Field(description="Column prefix in metrics.csv (letters, digits, '_', '-').")
    body: str = Field(description="Body name.")


class FieldProbe(Strict):
    """A magnetometer: the total flux density B (applied fields plus the bodies' own field) at a fixed ``position``
    or at a body point (the mean position of the particles of ``body`` whose reference position lies in
    ``region``), columns NAME_Bx, NAME_By, NAME_Bz in T. The bodies' field is recorded whether or not
    simulation.magnetic_interaction lets it act on them."""

    type: Literal["field"]
    name: Identifier = Field(description="Column prefix in metrics.csv (letters, digits, '_', '-').")
    position: Vec | None = Field(default=None, description="Fixed sensor position, m (2D: x, y; the plane is simulation.plane_z).")
    body: str | None = Field(default=None, description="Body the sensor is attached to (with region).")
    region: AnyShape | None = Field(default=None, description="Region of the body in the reference configuration whose particles carry the sensor.")

    @model_validator(mode="after")
    def _one_place(self):
        fixed, attached = self.position is not None, self.body is not None or self.region is not None
        if fixed == attached:
            raise ValueError("give either position (a fixed sensor) or body and region (a sensor on a body), not both")
        if attached and (self.body is None or self.region is None):
            raise ValueError("a sensor on a body needs both body and region")
        return self


class ColliderForceProbe(Strict):
    """The force the bodies exert on a rigid collider (columns NAME_Fx, NAME_Fy[, NAME_Fz], N; in 2D for the
    scene's depth): in a run, the momentum the collider takes from the grid nodes it touches, per unit time, averaged
    over each output interval (at rest: the load it carries); with --static, the reaction of the contact at each
    level's equilibrium. With ``bodies`` instead of ``collider``: the contact force one body exerts on another,
    measured by the static solver (--static) and the implicit integrator."""

    type: Literal["collider_force"]
    name: Identifier = Field(description="Column prefix in metrics.csv (letters, digits, '_', '-').")
    collider: int | None = Field(default=None, ge=0, description="The collider: its index in [[colliders]], from 0.")
    bodies: list[str] | None = Field(default=None, min_length=2, max_length=2, description="Instead of collider: two body names [A, B], the force A exerts on B through their contact (static solver and implicit integrator).")

    @model_validator(mode="after")
    def _one_target(self):
        if (self.collider is None) == (self.bodies is None):
            raise ValueError("a collider_force probe takes either collider (an index in [[colliders]]) or bodies "
                             "(two body names), not both or neither")
        if self.bodies is not None and self.bodies[0] == self.bodies[1]:
            raise ValueError(f"bodies: two different bodies, not '{self.bodies[0]}' twice")
        return self


AnyProbe = Annotated[Union[CentroidProbe, PointProbe, BoundsProbe, FieldProbe, ColliderForceProbe], Field(discriminator="type")]


# ---------------------------------------------------------------- settings
class DampingProfile(Strict):
    """Grid damping that changes in time: c(t) interpolated linearly between values at increasing times, held
    outside the table (heavy damping to settle, none for the motion that follows)."""

    times: list[float] = Field(min_length=1, description="Strictly increasing times, s (the run's time: a run started with --from continues the time of the run it starts from).")
    values: list[float] = Field(min_length=1, description="Damping c at those times, 1/s (each >= 0).")

    @model_validator(mode="after")
    def _rows(self):
        _check_time_table(self.times, self.values)
        if any(v < 0.0 for v in self.values):
            raise ValueError(f"every damping value must be >= 0 1/s (got {self.values})")
        return self


DampingSpec = Annotated[Union[Annotated[float, Field(ge=0), Tag("number")], Annotated[DampingProfile, Tag("profile")]],
                        Discriminator(_is_table("profile", "number"))]


class Simulation(Strict):
    """Numerical settings."""

    dim: Literal[2, 3, "axisymmetric"] = Field(default=3, description="2 (the x-y plane: plane strain or plane stress, simulation.plane), 3, or 'axisymmetric': bodies of revolution about the y axis, drawn in the (r, z) half-plane (x the radius r >= 0, y the axis z; positions, sizes and vectors are written [r, z]; domain_lo[0] = 0, the axis), with the hoop stretch r / R in every law (docs/engine.md, 'Axisymmetric bodies'). Read as dim 2 with plane 'axisymmetric'.")
    dx: float = Field(gt=0, description="Grid spacing, m.")
    particles_per_cell: int = Field(default=2, ge=1, le=4, description="Particles per cell along each axis.")
    domain_lo: Vec = Field(description="Lower corner of the domain, m.")
    domain_hi: Vec = Field(description="Upper corner of the domain, m.")
    duration: float = Field(gt=0, description="Simulated time, s.")
    dt: float | None = Field(default=None, gt=0, description="Fixed time step, s. Default: automatic CFL bound.")
    cfl: float = Field(default=0.4, gt=0, le=1, description="Safety factor of the automatic time step.")
    check_every: int = Field(default=200, ge=1, le=100000, description=(
        "Steps between the host's checks of the state (non-finite values, inverted elements, particles leaving the "
        "grid block or the domain, more than a cell per step): the steps in between run without reading anything "
        "back from the device, with the time step fixed; a window that fails a check is run again step by step "
        "from its first state, so errors still name their exact step. 1: check every step."))
    damping: DampingSpec = Field(default=0.0, description="Grid damping c in f = -c p, 1/s: a number, or a time profile { times = [...], values = [...] } (linear between the times, held outside them), used by the explicit engine at each step's start time and by the implicit integrator at each step's load time.")
    gravity: Vec | None = Field(default=None, description="Gravity, m/s^2. Default none.")
    walls: Literal["sticky", "slip", "friction"] = Field(default="slip", description="Contact law at the domain walls.")
    wall_friction: float = Field(default=0.0, ge=0, description="Friction coefficient of the domain walls.")
    depth: float = Field(default=1e-3, gt=0, description="2D only: out-of-plane thickness giving particle volumes, m.")
    plane_z: float = Field(default=0.0, description="2D only: z coordinate of the plane for field sources, m.")
    plane: Literal["strain", "stress", "axisymmetric"] = Field(
        default="strain",
        description="2D only: 'strain' (plane strain, F_zz = 1: long bodies, the section of a prism) or 'stress' (plane "
        "stress, zero normal stress with the thickness stretch solved per particle: thin plates loaded in their plane, "
        "wide strips bending like beams, with E rather than E / (1 - nu^2)); every elastic law, Prony viscoelasticity "
        "and stimulus eigenstrain (docs/engine.md, 'Plane stress'). 'axisymmetric' is what simulation.dim = "
        "'axisymmetric' sets.",
    )
    device: str = Field(default="cpu", pattern=r"^(cpu|cuda(:\d+)?)$", description="'cpu', 'cuda' or 'cuda:N'.")
    precision: Literal["float32", "float64"] = Field(default="float32", description="Floating-point precision of the kernels.")
    velocity_gradient: Literal["remap", "grid"] = Field(
        default="remap",
        description="Velocity gradient of the F update: 'remap' (particles' new affine velocities transferred back to "
        "the grid; no creep of loaded bodies) or 'grid' (momentum-update node velocities; about half the cost per step on CPU, "
        "stressed bodies creep at a rate set by the time step, docs/engine.md).",
    )
    formulation: Literal["auto", "updated", "total"] = Field(
        default="auto",
        description="MPM formulation: 'total' (total Lagrangian: the grid stays on the reference configuration, so "
        "loaded bodies settle to a static shape that does not depend on the time step; colliders and walls act at the "
        "nodes' current positions; a clamp holds the nodes whose mass is mostly clamped, i.e. acts at the clamped "
        "region's face; contact between bodies and self-contact by a pass over a current-configuration grid, less "
        "accurate than the updated form's), 'updated' (updated Lagrangian: the grid weights follow the particles; the "
        "most accurate contact; loaded slender bodies creep slowly) or 'auto' (total, unless the scene has contact "
        "between bodies or self-contact, then updated; run.json names the one used). docs/engine.md.",
    )
    integrator: Literal["explicit", "implicit"] = Field(
        default="explicit",
        description="Time integration: 'explicit' (MLS-MPM steps bounded by the elastic wave crossing a cell, "
        "microseconds for silicone) or 'implicit' (each step solved by Newton's method on the static solver's "
        "total-Lagrangian discretisation with inertia: steps of milliseconds, set by the [implicit] table; float64 "
        "and the total form; docs/engine.md, 'Implicit integration').",
    )
    magnetic_interaction: Literal["none", "dipole"] = Field(
        default="none",
        description="'dipole': the field of the bodies' own magnetisation (m = F Br V / mu0 per particle) acts on every "
        "magnetised particle, added to the applied field in the magnetic stress and the gradient force: magnets attract "
        "each other, segments pull, a body's own field exerts no net force on it (a lattice of dipoles on the grid, "
        "summed by FFT; 2D: line dipoles of the plane-strain slab; docs/engine.md, 'Magnetic interaction'). 'none': "
        "applied fields only.",
    )
    interaction_every: int = Field(
        default=1,
        ge=1,
        le=10000,
        description="Steps between refreshes of the bodies' field when simulation.magnetic_interaction = 'dipole' (it is "
        "held at the particles in between; docs/engine.md states the error of refreshing every 10 steps).",
    )
    threads: int | None = Field(
        default=None,
        ge=1,
        le=256,
        description="CPU threads a step is split over. Default: automatic, one per 4000 particles up to the usable "
        "cores (the environment variable MAGSORO_THREADS overrides it; sweep workers use 1). Ignored on CUDA.",
    )

    @model_validator(mode="before")
    @classmethod
    def _axisymmetric_is_2d(cls, data):
        """dim = 'axisymmetric' is read as dim 2 with plane 'axisymmetric' (the kernels' 2D idealisation)."""
        if isinstance(data, dict) and data.get("dim") == "axisymmetric":
            if data.get("plane", "axisymmetric") != "axisymmetric":
                raise ValueError(f"simulation.plane = {data['plane']!r} and dim = 'axisymmetric': an axisymmetric body "
                                 f"has no plane idealisation; leave plane out")
            data = {**data, "dim": 2, "plane": "axisymmetric"}
        return data

    @model_validator(mode="after")
    def _plane_needs_2d(self):
        if self.plane == "stress" and self.dim != 2:
            raise ValueError('simulation.plane = "stress" needs simulation.dim = 2 (plane stress is a 2D idealisation)')
        return self


def _friction(value):
    """A Coulomb coefficient (finite, >= 0) or 'sticky', with one message for both forms."""
    if value == "sticky":
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value >= 0:
        return float(value)
    raise ValueError("must be a finite Coulomb coefficient >= 0 or 'sticky'")


Friction = Annotated[Union[float, Literal["sticky"]], PlainValidator(_friction, json_schema_input_type=Union[float, Literal["sticky"]])]


class ContactPair(Strict):
    """Friction of one pair of bodies (or, with the same name twice, of a body's self-contact), or a pair bonded
    into one piece."""

    bodies: list[str] = Field(min_length=2, max_length=2, description="The two body (or robot part) names.")
    friction: Friction | None = Field(default=None, description="Coulomb coefficient (>= 0) or 'sticky'. Required unless bonded.")
    bonded: bool = Field(default=False, description="The two bodies move as one piece (glued where they touch): one contact group, no friction. Default false: they touch by contact.friction or this pair's friction, and separate freely.")

    @model_validator(mode="after")
    def _friction_or_bonded(self):
        if self.bonded and self.friction is not None:
            raise ValueError("give friction or bonded = true, not both: bonded bodies do not slide on each other")
        if not self.bonded and self.friction is None:
            raise ValueError("friction is required (a Coulomb coefficient >= 0 or 'sticky'), or bonded = true")
        if self.bonded and self.bodies[0] == self.bodies[1]:
            raise ValueError("bonded = true needs two different bodies")
        return self


class Contact(Strict):
    """Contact between bodies and between parts of one body that fold onto each other: two velocity fields per
    grid node, Coulomb friction, free separation (docs/engine.md, "Contact"). Separate [[bodies]] touch by contact,
    also when they touch at the start, unless the scene bonds them (``bonded``, or a pair's ``bonded = true``); the
    parts of a [robot] always move as one piece. run.json's notes say which bodies touch at the start and what the
    engine does with them."""

    friction: Friction = Field(default=0.0, description="Coulomb coefficient for every pair of bodies (and for self-contact). Default 0: frictionless, not sticky; 'sticky' gives one velocity field for all (the behaviour before contact existed).")
    self_contact: bool = Field(default=False, description="Let layers of one body that fold onto each other touch with friction instead of merging (costs one more pass over the particles per step).")
    fold_spread: float = Field(default=1.5, gt=0, le=10, allow_inf_nan=False, description="Self-contact: a node is split into two layers when the reference positions of the body's particles there spread (largest standard deviation) more than this many cells, i.e. layers more than about twice as far apart before folding.")
    pairs: list[ContactPair] = Field(default_factory=list, description="Per-pair overrides ([[contact.pairs]] tables).")
    bonded: Literal["pairs", "touching"] = Field(default="pairs", description="Which separate bodies move as one piece: 'pairs' (default): only the pairs given bonded = true in [[contact.pairs]]; 'touching': also every pair of bodies that touch or overlap at the start (a robot built from several [[bodies]] glued together). The parts of a [robot] are always one piece.")


class Static(Strict):
    """[static] table: what `magsoro run --static` (and Simulation.solve_static) solves: the equilibria under the
    loads at t = simulation.duration, with the fields scaled by each level in turn (docs/engine.md, "Static
    solver")."""

    levels: list[Annotated[float, Field(allow_inf_nan=False)]] = Field(default_factory=lambda: [1.0], min_length=1, max_length=10000, description="Field scale factors, solved in this order, each from the previous equilibrium. Default [1.0].")
    times: list[Annotated[float, Field(allow_inf_nan=False, ge=0)]] | None = Field(default=None, min_length=1, max_length=10000, description="Instead of levels: times (s, increasing) along the scene's field and collider paths, solved in this order with the fields in full; the first from the unloaded body, each later one from the last equilibrium with the fields and colliders moving along their paths (a magnet brought closer step by step). One metrics row and frame per time.")
    tolerance: float = Field(default=1e-8, gt=0, lt=1, description="Newton tolerance: largest node force over the out-of-balance force of the undeformed body under the level's load.")
    max_iterations: int = Field(default=40, ge=1, le=1000, description="Newton iterations per load increment before the increment is halved.")
    arc_length: bool = Field(default=False, description="Follow the equilibrium path from each level to the next by arc length (the load factor an unknown) instead of load increments: passes limit points (a snap-through) and reports the field levels where the path turned back (run.json static.levels[].limit_levels). Scenes without colliders. Where load increments fail, the solver takes it anyway.")
    collider_contact: Literal["surface", "nodes"] = Field(default="surface", description="Where rigid colliders meet the bodies in the static solve: 'surface' (default): each particle is a ball of half its lattice spacing, so the bodies' surface rests on the collider's; 'nodes': the grid nodes at the engine's contact skin, the law of a dynamic run, which holds a body that moves onto a collider about one cell off it (docs/engine.md). Domain walls always act at the nodes.")
    linear_solver: Literal["auto", "direct", "iterative"] = Field(default="auto", description="How the Newton steps' linear systems are solved: 'direct' (sparse LU: exact, its cost and memory grow faster than the unknowns), 'iterative' (conjugate gradients, or GMRES with friction colliders, preconditioned by smoothed-aggregation multigrid with the rigid-body modes: memory and time per iteration in proportion to the unknowns, for large 3D bodies) or 'auto' (default): direct up to magsoro.mpm.newton.linear.DIRECT_MAX_UNKNOWNS (8,000) unknowns, iterative above. run.json reports each level's linear solves and Krylov iterations (static.levels[].linear_iterations). docs/engine.md, 'Static solver'.")
    soft_penalty: float | None = Field(default=None, gt=0, lt=1, allow_inf_nan=False, description="Penalty continuation for sweeps where bodies peel off colliders or off each other (off by default): each level (time) is first solved by a predictor whose contact penalty (colliders' and between bodies) is this fraction of the solver's, in a chain of its own from its last equilibrium. From the second level on, the level's solve starts from the predictor's equilibrium and contact set. A soft penalty lets a peeling front move several cells per Newton iteration instead of about one; the answer is the full penalty's. The predictor's states sink p / (soft_penalty 10 (K + 4G/3)) cells into what they rest on under a contact pressure p (1e-4: 0.02 cells under a 2 mm silicone plate's weight; more under a magnet's pull), which the level's full penalty then pushes back out. run.json reports the predictor's iterations per level (static.levels[].predictor_iterations). docs/engine.md, 'Static solver'.")

    @model_validator(mode="after")
    def _times_or_levels(self):
        if self.times is not None:
            if "levels" in self.model_fields_set:
                raise ValueError("give static.levels (field scale factors) or static.times (times along the paths), not both")
            bad = [f"{a:g} then {b:g}" for a, b in zip(self.times[:-1], self.times[1:]) if b <= a]
            if bad:
                raise ValueError(f"static.times must increase ({bad[0]})")
        return self


class Implicit(Strict):
    """[implicit] table: the implicit integrator's scheme and step control (simulation.integrator = 'implicit';
    docs/engine.md, "Implicit integration")."""

    scheme: Literal["generalized_alpha", "backward_euler"] = Field(default="generalized_alpha", description="'generalized_alpha' (second order, numerical damping of unresolved modes set by rho_inf; Chung and Hulbert 1993) or 'backward_euler' (first order, robust, damps every mode: use it to settle).")
    rho_inf: float = Field(default=0.0, ge=0, le=1, allow_inf_nan=False, description="generalized_alpha: spectral radius for steps much longer than a mode's period. 0 (default) removes the modes a step does not resolve at once (robust with contact and sudden loads; a mode of period 20 dt loses 6.7 % of its amplitude per period); 0.8 keeps resolved vibrations (0.015 % per period at 20 steps a period) but lets unresolved ones ring, which costs Newton iterations; 1 is the trapezoidal rule.")
    dt: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="First time step, s. Default: simulation.duration / 200.")
    dt_min: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="Smallest step, s: a step that fails at it ends the run. Default: dt / 1000.")
    dt_max: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="Largest step, s (steps also land on every output time). Default: dt.")
    grow: float = Field(default=1.5, ge=1, le=10, allow_inf_nan=False, description="Factor a step grows by after one that converged within easy_iterations Newton iterations (up to dt_max).")
    easy_iterations: int = Field(default=4, ge=1, le=100, description="Newton iterations of a step that counts as easy.")
    max_move: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="Largest particle motion per step, in cells (off by default). After each step dt is scaled by max_move over the step's largest particle motion, never below half the step, never above the growth the easy_iterations rule allows: a body that moves fast, such as a fold running along a tube, takes steps it can converge in at once instead of growing until a step fails.")
    tolerance: float = Field(default=1e-6, gt=0, lt=1, allow_inf_nan=False, description="Newton tolerance: largest node force left over the step's force scale (the loads on the undeformed body, the internal forces of the last state, the nodes' weight and inertia).")
    max_iterations: int = Field(default=20, ge=1, le=1000, description="Newton iterations of a step before it is retried at half the step.")
    linear_solver: Literal["auto", "direct", "iterative"] = Field(default="auto", description="How each Newton iteration's linear system is solved, as static.linear_solver: 'direct' (sparse LU), 'iterative' (multigrid-preconditioned conjugate gradients or GMRES) or 'auto' (default): direct up to 8,000 unknowns; up to magsoro.mpm.newton.implicit.DIRECT_MAX_UNKNOWNS (50,000) direct while a factorisation serves many Newton iterations and steps, iterative from the point where contacts make a new one for more than half the iterations; iterative above. run.json's integrator entry counts the linear solves and their Krylov iterations.")

    @model_validator(mode="after")
    def _step_bounds(self):
        if self.dt is not None and self.dt_max is not None and self.dt > self.dt_max:
            raise ValueError(f"implicit.dt = {self.dt:g} s is above implicit.dt_max = {self.dt_max:g} s")
        if self.dt is not None and self.dt_min is not None and self.dt < self.dt_min:
            raise ValueError(f"implicit.dt = {self.dt:g} s is below implicit.dt_min = {self.dt_min:g} s")
        return self


class Initial(Strict):
    """Where a run starts: the bodies' reference configuration at rest (default), or the final state of another
    run (its final.npz): positions, velocities, affine velocities, deformation gradients, Prony internal stresses and
    its time, which the run continues (fields, paths and keyframes see the continued time)."""

    from_: str | None = Field(default=None, alias="from", description="final.npz (or the folder) of an earlier run to start from, relative to the scene file. The bodies must match (particle count, body names, reference positions, clamped particles, precision); `magsoro run --from RUN_DIR` overrides it.")


class Output(Strict):
    """What a run writes."""

    every: float | None = Field(default=None, gt=0, description="Interval between recorded frames and metrics rows, s. Default: duration / 50.")
    particles: bool = Field(default=True, description="Write the ParaView particle series (.vtp + .pvd).")


class Preview(Strict):
    """Coarser settings used by ``magsoro run --preview`` (and ``magsoro reproduce --preview``): each key given
    replaces the same key of [simulation] (``every``: of [output]) so the scene runs in a fraction of the time."""

    dx: float | None = Field(default=None, gt=0, description="Grid spacing for the preview, m.")
    particles_per_cell: int | None = Field(default=None, ge=1, le=4, description="Particles per cell along each axis for the preview.")
    duration: float | None = Field(default=None, gt=0, description="Simulated time for the preview, s.")
    cfl: float | None = Field(default=None, gt=0, le=1, description="Time-step safety factor for the preview.")
    every: float | None = Field(default=None, gt=0, description="Output interval for the preview, s.")


#: Most frames and metrics rows one run may record (output.every against the duration)
MAX_RECORDS = 100_000


class Scene(Strict):
    """A magsoro scene: bodies, clamps, colliders, fields, probes, numerical settings and output."""

    simulation: Simulation
    bodies: list[Body] = Field(default_factory=list, description="Bodies ([[bodies]] tables). A scene needs at least one body or robot part.")
    robot: Optional[RobotSpec] = Field(default=None, description="A robot file name (relative to the scene), or a [robot] table with file and/or [[robot.parts]]; its parts become bodies.")
    material_library: list[str] = Field(default_factory=list, description="User material library TOML files ([[materials]] entries, as in magsoro/data/materials.toml), relative to the scene file.")
    clamps: list[Clamp] = Field(default_factory=list, description="Clamped regions ([[clamps]] tables).")
    colliders: list[AnyCollider] = Field(default_factory=list, description="Rigid colliders ([[colliders]] tables).")
    fields: list[AnyField] = Field(default_factory=list, description="Field sources ([[fields]] tables); they add up.")
    probes: list[AnyProbe] = Field(default_factory=list, description="Recorded quantities ([[probes]] tables).")
    output: Output = Field(default_factory=Output)
    contact: Contact = Field(default_factory=Contact, description="[contact] table: friction between bodies and self-contact.")
    name: str | None = Field(default=None, description="Scene title.")
    preview: Preview | None = Field(default=None, description="[preview] table: coarser settings for `magsoro run --preview`.")
    static: Static = Field(default_factory=Static, description="[static] table: load levels and tolerance of `magsoro run --static`.")
    implicit: Implicit = Field(default_factory=Implicit, description="[implicit] table: scheme and time steps of simulation.integrator = 'implicit'.")
    initial: Initial = Field(default_factory=Initial, description="[initial] table: start from another run's final state (from = \"RUN/final.npz\").")
    _base_dir: object = PrivateAttr(default=None)
    _source_path: object = PrivateAttr(default=None)
    _material_libraries: object = PrivateAttr(default_factory=list)
    _magnetization: object = PrivateAttr(default_factory=dict)

    # where the scene was read (set by the loader; None for a scene made in Python)
    @property
    def base_dir(self):
        """The directory relative file names resolve against (the scene file's); None: the working directory."""
        return self._base_dir

    @base_dir.setter
    def base_dir(self, value) -> None:
        self._base_dir = value

    @property
    def source_path(self):
        """The scene file the scene was loaded from (None: made from a dict)."""
        return self._source_path

    @source_path.setter
    def source_path(self, value) -> None:
        self._source_path = value

    @property
    def material_library_paths(self) -> list:
        """The material library files as paths resolved by the loader: the scene's material_library, then those of
        its robot file (a list the loader appends to)."""
        return self._material_libraries

    @material_library_paths.setter
    def material_library_paths(self, value: list) -> None:
        self._material_libraries = value

    @property
    def magnetization_functions(self) -> dict:
        """Body name -> the callable :meth:`set_magnetization` gave it (a copy)."""
        return dict(self._magnetization)

    @model_validator(mode="after")
    def _bounded_output(self):
        every = self.output.every
        if every is not None and self.simulation.duration / every > MAX_RECORDS:
            raise ValueError(
                f"output.every = {every:g} s gives {self.simulation.duration / every:.3g} records over simulation.duration = "
                f"{self.simulation.duration:g} s; at most {MAX_RECORDS:.0e} are allowed: raise output.every to at least "
                f"{self.simulation.duration / MAX_RECORDS:.3g} s"
            )
        return self

    def set_magnetization(self, fn, body: str | None = None) -> "Scene":
        """Give a body (or, with ``body=None``, every body) a magnetisation computed by a Python callable.

        ``fn(X)`` receives the reference positions X (N, 3) in m (z = 0 in 2D scenes) and returns Br (N, 3) in T.
        It replaces the scene file's magnetisation of that body when the scene is built (e.g. by
        ``magsoro.simulation.Simulation(scene)``). Returns the scene, for chaining.
        """
        if not callable(fn):
            raise TypeError("fn must be callable: X (N, 3) m -> Br (N, 3) T")
        names = [b.name for b in self.bodies]
        if body is not None and body not in names:
            from magsoro.errors import SceneError

            raise SceneError(f"set_magnetization: no body named '{body}'; bodies: {', '.join(names)}")
        for name in names if body is None else [body]:
            self._magnetization[name] = fn
        return self

    def to_toml(self, relative_to=None) -> str:
        """The scene as the text of a TOML scene file that loads back to an equal scene (keys at their defaults
        left out, floats bit-exact). File names stay as they are, relative to :attr:`base_dir`, unless
        ``relative_to`` names the folder the text will be saved in: then they are rewritten relative to it.
        :func:`magsoro.scene.write_scene` saves the text and says what is refused."""
        from magsoro.scene.write import scene_toml

        return scene_toml(self, relative_to)
