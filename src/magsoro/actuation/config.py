"""TOML inputs of the actuation tools, validated by pydantic v2 (unknown keys refused, every key with its unit).

- DESIGN.toml for ``magsoro evert`` (:class:`EversionDesign`),
- CALIB.toml for ``magsoro sense`` (:class:`SensingCalibration`),
- PLAN.toml for ``magsoro plan`` (:class:`PlanConfig`).

Errors are raised as :class:`magsoro.errors.MagsoroError` subclasses with one line that names the file and the
bad key (and, for an unknown key, the allowed ones).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from magsoro.config_errors import check_nesting, format_config_error
from magsoro.errors import MagsoroError
from magsoro.io.files import read_toml_file


class ActuationInputError(MagsoroError):
    """An actuation input file (design, calibration, plan, readings) is invalid; the message names file and key."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


# ------------------------------------------------------------------------------------------- eversion
class TubeConfig(_Strict):
    """``[tube]``: the reference tube and its magnetoelastic shear modulus mu(I4) = mu (1 + alpha tanh(I4/I4_sat))."""

    inner_radius: float = Field(..., gt=0, description="Reference inner radius A, m. Required.")
    outer_radius: float = Field(..., gt=0, description="Reference outer radius B (> A), m. Required.")
    shear_modulus: float = Field(..., gt=0, description="Zero-field shear modulus mu, Pa. Required.")
    magnetic_stiffening: float = Field(0.0, gt=-1, description=(
        "alpha in mu(I4) = mu (1 + alpha tanh(I4 / I4_sat)), dimensionless. Default 0 (field-independent)."))
    saturation_field: float = Field(0.1, gt=0, description="B_sat with I4_sat = (B_sat / mu0)^2, T. Default 0.1.")
    remanence: float = Field(0.0, ge=0, description=(
        "|Br| of the tail wall's axial remanent magnetisation, T; the design's fields point against it (the "
        "direction in which the reversal of the everting wall's magnetisation helps growth). Default 0 (none)."))
    magnetization_follows: Literal["F", "R"] = Field("F", description=(
        'How the deformation carries the remanence: "F" (Zhao\'s law, the engine\'s default) or "R" (the '
        'rotation of F). Default "F".'))

    @model_validator(mode="after")
    def _radii(self):
        if not self.inner_radius < self.outer_radius:
            raise ValueError(f"inner_radius ({self.inner_radius} m) must be < outer_radius ({self.outer_radius} m)")
        return self


class FrictionConfig(_Strict):
    """``[friction]``: tail-wall sliding losses of seed 004 eqs 12-13."""

    tail: Literal["cylindrical", "cruciform"] = Field("cylindrical", description=(
        'Tail cross-section, "cylindrical" or "cruciform"; sets the default perimeter and capstan factors. '
        'Default "cylindrical".'))
    contact_length: float = Field(0.0, ge=0, description="Sliding contact length l, m. Default 0 (no friction).")
    friction_coefficient: float = Field(0.0, ge=0, description="Kinetic friction coefficient mu_k, dimensionless. Default 0.")
    contact_factor: float = Field(1.0, ge=0, le=1, description=(
        "alpha_c: fraction of the internal pressure carried as normal contact load, in [0, 1]. Default 1."))
    perimeter_factor: float | None = Field(None, ge=0, le=1, description=(
        "phi: effective fraction of the perimeter 2 pi b in contact, in [0, 1]. Default from `tail` "
        "(cylindrical 1.0, cruciform 0.2)."))
    capstan_factor: float | None = Field(None, ge=0, le=1, description=(
        "gamma in g = exp(gamma mu_k Theta), in [0, 1]. Default from `tail` (cylindrical 1.0, cruciform 0.5)."))


class OperatingConfig(_Strict):
    """``[operating]``: the state at which the minimum field for pressure-free growth is sought."""

    axial_stretch: float = Field(1.0, gt=0, description="Axial stretch lambda_z of the everted body, dimensionless. Default 1.")
    bend_angle: float = Field(0.0, ge=0, description="Cumulative bending angle Theta of the body, rad. Default 0.")
    contact_radius: float | None = Field(None, gt=0, description=(
        "Everted inner radius a where the wall rests on the tail, m. Default max(a0, B), a0 the zero-pressure radius."))
    required_tip_force: float = Field(0.0, description="Tip load N_load the front must overcome, N. Default 0.")
    max_field: float = Field(1.0, gt=0, description="Largest axial field searched for the minimum growth field, T. Default 1.")
    measured_growth_field: float | None = Field(None, gt=0, description=(
        "A measured smallest growing field, T (seed 004: 0.043). When given, the summary reports the friction "
        "coefficient mu_k that makes it the model's minimum growth field, the other friction factors kept. "
        "Default none."))


class PlotConfig(_Strict):
    """``[plot]``: the P(a), N(a) curves (seed 004 Fig. 2)."""

    fields: list[float] = Field([0.0, 0.02, 0.04, 0.06], min_length=1, description=(
        "Axial field magnitudes of the curves, T. Default [0, 0.02, 0.04, 0.06]."))
    axial_stretch: float = Field(1.0, gt=0, description="lambda_z of the curves, dimensionless. Default 1 (as Fig. 2).")
    radius_min: float | None = Field(None, gt=0, description="Smallest inner radius a plotted, m. Default 0.5 A.")
    radius_max: float | None = Field(None, gt=0, description="Largest inner radius a plotted, m. Default 1.5 B.")
    points: int = Field(200, ge=2, le=100_000, description="Samples along a. Default 200.")

    @model_validator(mode="after")
    def _range(self):
        if any(f < 0 for f in self.fields):
            raise ValueError("fields must be >= 0 T (magnitudes)")
        if self.radius_min is not None and self.radius_max is not None and not self.radius_min < self.radius_max:
            raise ValueError(f"radius_min ({self.radius_min} m) must be < radius_max ({self.radius_max} m)")
        return self


class EversionDesign(_Strict):
    """DESIGN.toml of ``magsoro evert`` (SI units)."""

    name: str | None = Field(None, description="Title of the design.")
    tube: TubeConfig = Field(..., description="Reference tube and material. Required.")
    friction: FrictionConfig = Field(default_factory=FrictionConfig, description="Friction table. Default none.")
    operating: OperatingConfig = Field(default_factory=OperatingConfig, description="Operating point table.")
    plot: PlotConfig = Field(default_factory=PlotConfig, description="Curves to plot.")

    def model(self, axial_stretch: float | None = None):
        """The :class:`~magsoro.actuation.eversion.EversionModel` of this design at ``axial_stretch``
        (default the operating stretch)."""
        from magsoro.actuation.eversion import EversionModel, Friction

        f = self.friction
        friction = Friction.for_tail(f.tail, f.contact_length, f.friction_coefficient, f.contact_factor,
                                     f.perimeter_factor, f.capstan_factor)
        t = self.tube
        return EversionModel(
            t.inner_radius, t.outer_radius, t.shear_modulus, t.magnetic_stiffening, t.saturation_field,
            self.operating.axial_stretch if axial_stretch is None else axial_stretch, friction,
            t.remanence, t.magnetization_follows,
        )


# ------------------------------------------------------------------------------------------- sensing
class StationConfig(_Strict):
    """``[[stations]]``: one Hall sensor and its marker, from the base to the tip."""

    column: str = Field(..., min_length=1, description="Column of READINGS.csv holding this sensor's H_z reading, T. Required.")
    segment_length: float = Field(..., gt=0, description="Arc length L of the constant-curvature segment it senses, m. Required.")
    peak_field: float = Field(..., gt=0, description=(
        "H0 = mu0 m / (2 pi h^3): the reading with marker and sensor aligned (straight segment), measured "
        "after fabrication (seed 004 eq 19), T. Required."))
    gap: float = Field(..., gt=0, description="Sensor-marker gap h along the sensor axis, m. Required.")
    lever_arm: float | None = Field(None, gt=0, description=(
        "Distance d from the neutral axis of the fibre carrying the marker; bending by beta slides the marker "
        "by d beta, m. Default the gap h (seed 004 eq 22)."))


class SensingCalibration(_Strict):
    """CALIB.toml of ``magsoro sense`` (SI units)."""

    name: str | None = Field(None, description="Title of the calibration.")
    inverse: Literal["exact", "closed-form"] = Field("exact", description=(
        '"exact": numerical inverse of eq 20 for every q; "closed-form": eq 21 (valid for q > 0.7). Default "exact".'))
    time_column: str = Field("t", description='Time column of READINGS.csv, s. Default "t".')
    base_position: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="Base point of the robot, m. Default origin.")
    base_tangent: tuple[float, float, float] = Field((0.0, 0.0, 1.0), description=(
        "Unit tangent of the robot at its base. Default [0, 0, 1] (seed 004 eq 23: the robot grows along z)."))
    bend_normal: tuple[float, float, float] = Field((1.0, 0.0, 0.0), description=(
        "In-plane normal towards which a positive bend (H_z > 0) turns the robot. Default [1, 0, 0] (eq 23)."))
    points_per_segment: int = Field(20, ge=2, le=10_000, description="Centreline samples per segment. Default 20.")
    smoothing_time: float = Field(0.0, ge=0, description=(
        "Time constant of a causal first-order low-pass applied to the bend angles (not to the readings, "
        "whose sign flips at beta = 0), s. Default 0 (none)."))
    stations: list[StationConfig] = Field(..., min_length=1, description="Sensing stations, base to tip. Required.")

    @model_validator(mode="after")
    def _frame(self):
        t, n = self.base_tangent, self.bend_normal
        nt = math.sqrt(sum(v * v for v in t))
        nn = math.sqrt(sum(v * v for v in n))
        if nt == 0 or nn == 0:
            raise ValueError("base_tangent and bend_normal must be non-zero vectors")
        if abs(sum(a * b for a, b in zip(t, n))) > 1e-6 * nt * nn:
            raise ValueError("bend_normal must be perpendicular to base_tangent")
        cols = [s.column for s in self.stations]
        if len(set(cols)) != len(cols):
            raise ValueError(f"stations use a column twice: {cols}")
        if self.time_column in cols:
            raise ValueError(f"time_column {self.time_column!r} is also a station column")
        return self


# ------------------------------------------------------------------------------------------- planning
class PlanRobotConfig(_Strict):
    """``[robot]``: a planar strip robot (plane strain in x-y, the MPM replay's body) clamped at its base."""

    length: float = Field(..., gt=0, description="Fully everted length L, m. Required.")
    n_links: int = Field(..., ge=2, le=200, description="Pseudo-rigid-body links. Required.")
    thickness: float = Field(..., gt=0, description="In-plane thickness t of the strip, m. Required.")
    depth: float = Field(..., gt=0, description="Out-of-plane depth of the strip, m. Required.")
    shear_modulus: float = Field(..., gt=0, description="Shear modulus G, Pa. Required.")
    bulk_modulus: float | None = Field(None, gt=0, description="Bulk modulus K, Pa. Default 3 G.")
    density: float = Field(1000.0, gt=0, description="Density, kg/m^3 (replay only). Default 1000.")
    remanence: float | list[float] = Field(..., description=(
        "Remanent flux density magnitude Br, T: one value for every link or one per link (0 = unmagnetised). "
        "Required."))
    magnetisation_angles: list[float] | None = Field(None, description=(
        "Direction of each link's remanence in the link frame (0 = along the link towards the tip, positive "
        "counter-clockwise), rad, one per link. Default all 0 (axial); chosen by the plan with "
        "target.design_profile."))
    base_position: tuple[float, float] = Field((0.0, 0.0), description="Clamp point, m. Default origin.")

    @model_validator(mode="after")
    def _lists(self):
        if self.magnetisation_angles is not None and len(self.magnetisation_angles) != self.n_links:
            raise ValueError(f"magnetisation_angles has {len(self.magnetisation_angles)} values, n_links = {self.n_links}")
        if isinstance(self.remanence, list):
            if len(self.remanence) != self.n_links:
                raise ValueError(f"remanence has {len(self.remanence)} values, n_links = {self.n_links}")
            values = self.remanence
        else:
            values = [self.remanence]
        if any(v < 0 for v in values) or not any(v > 0 for v in values):
            raise ValueError("remanence must be >= 0 T with at least one magnetised link")
        return self

    @property
    def bulk(self) -> float:
        return self.bulk_modulus if self.bulk_modulus is not None else 3.0 * self.shear_modulus


class PlanTargetConfig(_Strict):
    """``[target]``: the retroflexion-like shape sequence (seed 004 sec III-D)."""

    kind: Literal["follow-the-leader", "grow-then-bend"] = Field("follow-the-leader", description=(
        '"follow-the-leader": grow into a constant-curvature arc, every everted link on the final arc at every '
        'step; "grow-then-bend": grow straight, then curl the full length into arcs. Default "follow-the-leader".'))
    tip_angle: float = Field(..., description="Final tip-tangent angle from the base direction, rad (pi: retroflexion). Required.")
    initial_links: int = Field(2, ge=1, description="Links everted at the first step. Default 2.")
    links_per_step: int = Field(1, ge=1, description="Links added per growth step. Default 1.")
    bend_steps: int = Field(3, ge=1, description='Bending steps after growth (kind "grow-then-bend"). Default 3.')
    design_profile: bool = Field(False, description=(
        "Choose each link's magnetisation direction when it everts, with that step's pose (seed 004 sec II-C). "
        "Default false (use robot.magnetisation_angles)."))


class PlanMagnetConfig(_Strict):
    """``[magnet]``: the external permanent magnet (point dipole, seed 004 eq 14)."""

    moment: float = Field(..., gt=0, description="Dipole moment magnitude |m|, A m^2. Required.")
    field_scale: float = Field(0.02, gt=0, description="Typical field at the robot used for scaling and the first guess, T. Default 0.02.")
    min_distance: float = Field(0.08, gt=0, description="Smallest magnet-to-robot distance allowed, m. Default 0.08.")
    max_distance: float = Field(0.5, gt=0, description="Largest magnet distance from the robot base, m. Default 0.5.")
    fixed_direction: tuple[float, float, float] | None = Field(None, description=(
        "Keep the moment along this direction (only the position moves; the plan then also loads as a scene "
        "dipole field with a path). Default free."))
    approach_factor: float = Field(3.0, ge=1, description=(
        "The magnet reaches its first pose from this many times as far along the same line. Default 3."))

    @model_validator(mode="after")
    def _range(self):
        if not self.min_distance < self.max_distance:
            raise ValueError(f"min_distance ({self.min_distance} m) must be < max_distance ({self.max_distance} m)")
        if self.fixed_direction is not None and not any(self.fixed_direction):
            raise ValueError("fixed_direction must be a non-zero vector")
        return self


class PlanWeightsConfig(_Strict):
    """``[weights]``: terms of the per-step least-squares cost (dimensionless; see docs/actuation.md)."""

    shape: float = Field(1.0, ge=0, description="Link-angle error, per rad (RMS over links). Default 1.")
    tip: float = Field(3.0, ge=0, description="Tip-angle error, per rad. Default 3.")
    out_of_plane: float = Field(0.3, ge=0, description="B_z at the links relative to field_scale. Default 0.3.")
    smoothness: float = Field(0.3, ge=0, description="Pose change between steps relative to the magnet distance. Default 0.3.")
    profile: float = Field(0.1, ge=0, description="Direction change between neighbouring links, per rad (design_profile). Default 0.1.")
    stability: float = Field(1.0, ge=0, description="Penalty below the stiffness margin. Default 1.")
    stability_margin: float = Field(0.5, ge=0, description="Smallest Hessian eigenvalue wanted, in units of EI / l. Default 0.5.")
    path: float = Field(1.0, ge=0, description="Angle error of the already everted links during the magnet's move, per rad. Default 1.")
    robustness: float = Field(1.0, ge=0, description="Tip displacement per robot length for a stiffness error. Default 1.")
    stiffness_uncertainty: float = Field(0.1, ge=0, lt=1, description="Relative bending-stiffness error of the robustness term. Default 0.1.")


class PlanReplayConfig(_Strict):
    """``[replay]``: the MPM replay of the plan (2D plane strain, or 3D in the magnet's whole field)."""

    dx: float = Field(..., gt=0, description="Grid spacing, m; link length and thickness must be multiples of dx / 2. Required.")
    step_duration: float | None = Field(None, gt=0, description="Simulated time per plan step, s. Default one first bending period of the full strip.")
    move_fraction: float = Field(0.5, gt=0, lt=1, description="Part of a step during which the magnet moves. Default 0.5.")
    damping_ratio: float = Field(1.0, ge=0, description="Grid damping as a fraction of critical for the first bending mode. Default 1.")
    dim: Literal[2, 3] = Field(2, description="2: plane strain in the plan's plane (the field's in-plane part); 3: a free beam of section thickness x depth in the magnet's whole field, B_z and the pull towards the magnet included. Default 2.")
    floor: bool = Field(False, description="dim = 3 only: a frictionless floor under the robot, with gravity. Default false (no floor, no gravity).")

    @model_validator(mode="after")
    def _floor_3d(self):
        if self.floor and self.dim != 3:
            raise ValueError("floor = true needs dim = 3 (the floor lies under the robot, out of the 2D plane)")
        return self


class PlanConfig(_Strict):
    """PLAN.toml of ``magsoro plan`` (SI units)."""

    name: str | None = Field(None, description="Title of the plan.")
    robot: PlanRobotConfig = Field(..., description="Robot table. Required.")
    target: PlanTargetConfig = Field(..., description="Target table. Required.")
    magnet: PlanMagnetConfig = Field(..., description="Magnet table. Required.")
    weights: PlanWeightsConfig = Field(default_factory=PlanWeightsConfig, description="Cost weights.")
    replay: PlanReplayConfig | None = Field(None, description="MPM replay settings. Default none (no replay).")

    @model_validator(mode="after")
    def _links(self):
        if self.target.initial_links > self.robot.n_links:
            raise ValueError(f"target.initial_links ({self.target.initial_links}) exceeds robot.n_links ({self.robot.n_links})")
        return self

    def build(self):
        """(robot, target, planner, strip) for this plan: :class:`~magsoro.actuation.planning.PlanarPRB`,
        :class:`~magsoro.actuation.planning.GrowthTarget`, :class:`~magsoro.actuation.planning.MagnetPlanner`
        and the :class:`~magsoro.actuation.replay.StripSpec` of the replay."""
        from magsoro.actuation.planning import GrowthTarget, MagnetPlanner, PlanarPRB, PlanWeights
        from magsoro.actuation.replay import StripSpec

        r = self.robot
        robot = PlanarPRB.strip(r.length, r.n_links, r.thickness, r.depth, r.shear_modulus, r.bulk, r.remanence,
                                r.magnetisation_angles, r.base_position)
        t = self.target
        if t.kind == "follow-the-leader":
            target = GrowthTarget.arc(robot, t.tip_angle, t.initial_links, t.links_per_step)
        else:
            target = GrowthTarget.grow_then_bend(robot, t.tip_angle, t.initial_links, t.links_per_step, t.bend_steps)
        m = self.magnet
        planner = MagnetPlanner(robot, m.moment, m.field_scale, m.min_distance, m.max_distance, m.fixed_direction,
                                PlanWeights(**self.weights.model_dump()), design_profile=t.design_profile,
                                approach_factor=m.approach_factor)
        strip = StripSpec(r.thickness, r.depth, r.shear_modulus, r.bulk, r.density)
        return robot, target, planner, strip


# ------------------------------------------------------------------------------------------- loading
def parse(model: type[BaseModel], data: dict, source: str = "input"):
    """Validate ``data`` against ``model``; raises :class:`ActuationInputError` with a one-line message."""
    check_nesting(data, source, ActuationInputError)
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ActuationInputError(format_config_error(exc, model, source)) from None


def load(model: type[BaseModel], path):
    """Read a TOML file and validate it against ``model``."""
    path = Path(path)
    data = read_toml_file(path, ActuationInputError)
    return parse(model, data, str(path))
