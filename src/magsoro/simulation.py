"""High-level scripting API: build a run from a scene, step it, read probes and particles as numpy.

>>> sim = Simulation.from_file("scenes/cantilever_2d.toml")      # doctest: +SKIP
>>> sim.run(duration=0.01, callback=lambda s: print(s.time))     # doctest: +SKIP
>>> sim.probe_values()["tip_y"]                                   # doctest: +SKIP
>>> sim.run(duration=0.01).metrics["tip_y"]                       # doctest: +SKIP (every record, as metrics.csv)
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from magsoro.errors import OutputError, SceneError, SimulationError, Terminated
from magsoro.limits import check_time_step, plausibility_notes, time_step_problem
from magsoro.mpm.colliders import WALL_CELLS
from magsoro.mpm.interaction import MagneticInteraction
from magsoro.mpm.solver import Solver
from magsoro.mpm.newton.static import StaticResult
from magsoro.mpm.timestep import cfl_time_step
from magsoro.scene import Scene, load_scene
from magsoro.scene.build import Built, build
from magsoro.scene.schema import MAX_RECORDS

#: cells from a domain face within which a particle may be held by that wall: the walls stop nodes within
#: WALL_CELLS of the face (magsoro.mpm.kernels.grid), and a particle's mass reaches nodes up to 1.5 cells from it
WALL_REACH_CELLS = WALL_CELLS + 1.5
#: a body whose particles fill more than this fraction more or less than its shape's volume is noted in run.json
LATTICE_FILL_NOTE = 0.02
#: a body with a part (plate, hinge, wall) fewer than this many grid cells thick is noted in run.json: bending there
#: is under-resolved (docs/how-to/convergence.md)
THIN_PART_CELLS = 3.0


def _prepare_implicit(scene: Scene) -> list[str]:
    """simulation.integrator = 'implicit' solves the total-Lagrangian form in float64: set them on ``scene`` (an
    'updated' formulation is refused). Returns the notes for run.json."""
    sim = scene.simulation
    if sim.integrator != "implicit":
        return []
    return _newton_float64_total(
        scene, "simulation.formulation = 'updated': the implicit integrator (simulation.integrator = 'implicit') "
        "solves the total-Lagrangian form; set simulation.formulation = 'total' or 'auto'",
        "simulation.integrator = 'implicit' runs in float64 (simulation.precision = 'float32' is not used: Newton's "
        "tolerance needs the digits)")


def _newton_float64_total(scene: Scene, refusal: str, note: str) -> list[str]:
    """The Newton solvers' precision and form on ``scene``: an 'updated' formulation raises SceneError(``refusal``);
    float64 and the total-Lagrangian form are set, with ``note`` returned when the scene asked for float32."""
    sim = scene.simulation
    if sim.formulation == "updated":
        raise SceneError(refusal)
    notes = [note] if sim.precision != "float64" else []
    sim.precision, sim.formulation = "float64", "total"
    return notes


def prepare_static(scene: Scene) -> list[str]:
    """The static solver's precision and form, one rule for ``magsoro run --static`` and
    :meth:`Simulation.solve_static`: float64 (Newton's tolerance, 1e-8 of the first residual by default, lies below
    float32's round-off, so float32 Newton steps stall short of it) and the total-Lagrangian form. Sets them on
    ``scene`` (an 'updated' formulation is refused) and returns the notes for run.json."""
    return _newton_float64_total(
        scene, "simulation.formulation: the static solver (magsoro run --static, Simulation.solve_static) solves the "
        "total-Lagrangian form; set it to 'auto' or 'total'",
        "the static solver runs in float64 (simulation.precision = 'float32' is not used: Newton's tolerance needs "
        "the digits)")


def prepare_relax(scene: Scene) -> list[str]:
    """Dynamic relaxation (``magsoro run --equilibrium``, :meth:`Simulation.relax`) runs in float64, the static
    solver's precision: float32 forces of a stiff or slender body stall the kinetic-energy peaks at round-off
    (a float32 arch stalled 14 % above its float64 rise, issue 56). Sets it on ``scene``; returns the notes."""
    sim = scene.simulation
    if sim.precision == "float64":
        return []
    sim.precision = "float64"
    return ["dynamic relaxation runs in float64 (simulation.precision = 'float32' is not used: float32 round-off "
            "stalls a relaxation short of the equilibrium)"]


class DriftWatch:
    """How far the bodies move while the kinetic energy stays tiny: the precision report of a dynamic run.

    At each record it takes the free particles' positions and kinetic energy. A record is quiet when its kinetic
    energy is at most ``quiet`` (SETTLE_ENERGY) times the largest seen so far; over the quiet records at the run's
    end (the last stretch, at least ``min_records`` of them) the drift is the largest particle displacement from
    the first of them to the last, and the late drift that over the stretch's second half. A body coming to rest
    moves less and less (a decaying motion: the late drift a small part of the drift); one that keeps creeping at a
    steady rate although almost none of its motion's energy is left (the late drift at least ``steady`` of the
    drift) was seen in float32 near a bifurcation (a pre-buckled arch's rise 3.70 -> 4.34 mm in 0.5 s where float64
    held 3.70 mm, issue 56). :meth:`report` gives the numbers (run.json 'drift') and, for a float32 run whose drift
    is steady and exceeds ``tolerance`` of the bodies' displacement from the reference (and 1e-6 of a cell), the
    note that says so."""

    KEEP = 64  # positions kept of a quiet stretch (every other one dropped when full: the first and last stay)

    def __init__(self, dx: float, precision: str, quiet: float = 1e-4, min_records: int = 3, tolerance: float = 1e-3,
                 steady: float = 0.25):
        self.dx, self.precision = float(dx), precision
        self.quiet, self.min_records, self.tolerance, self.steady = quiet, min_records, tolerance, steady
        self.peak = 0.0
        self.stretch: list = []  # (time, positions) of the current quiet stretch's records (thinned)
        self.count = 0  # records in it
        self.reference = None

    def sample(self, sim) -> None:
        energy, _ = sim.kinetic_energy()
        free = sim.model.host["clamped"] == 0
        self.add(sim.time, sim.state.x.numpy().astype(np.float64)[free], energy, sim.model.host["positions"][free])

    def add(self, t: float, x: np.ndarray, energy: float, reference: np.ndarray) -> None:
        """One record: time (s), free particles' positions (m), kinetic energy (J), their reference positions."""
        self.peak = max(self.peak, energy)
        self.reference = np.asarray(reference, dtype=np.float64)[:, : x.shape[1]]
        if not (self.peak > 0.0 and energy <= self.quiet * self.peak):
            self.stretch, self.count = [], 0
            return
        if len(self.stretch) >= self.KEEP:
            self.stretch = self.stretch[:1] + self.stretch[2::2]
        self.stretch.append((t, np.array(x, dtype=np.float64)))
        self.count += 1

    def report(self) -> tuple[dict, str | None]:
        """(run.json 'drift', a note or None)."""
        if self.count < self.min_records or len(self.stretch) < 2:
            return {"judged": False, "why": f"the run did not end with {self.min_records} records whose kinetic energy "
                                            f"was at most {self.quiet:g} of its peak"}, None
        (t0, x0), (t1, x1) = self.stretch[0], self.stretch[-1]
        tm = 0.5 * (t0 + t1)
        _, xm = min(self.stretch, key=lambda r: abs(r[0] - tm))
        moved = float(np.max(np.linalg.norm(x1 - x0, axis=1), initial=0.0))
        late = float(np.max(np.linalg.norm(x1 - xm, axis=1), initial=0.0))
        scale = float(np.max(np.linalg.norm(x0 - self.reference, axis=1), initial=0.0))
        relative = moved / scale if scale > 0 else (0.0 if moved == 0 else math.inf)
        steady = moved > 0 and late >= self.steady * moved
        out = {"judged": True, "from": t0, "to": t1, "records": self.count, "max_displacement": moved,
               "late_displacement": late, "cells": moved / self.dx, "of_displacement": relative, "steady": steady,
               "precision": self.precision}
        note = None
        if self.precision == "float32" and steady and moved > 1e-6 * self.dx and relative > self.tolerance:
            note = (f"precision: from t = {t0:.6g} to {t1:.6g} s the kinetic energy stayed below {self.quiet:g} of its "
                    f"peak, yet the bodies kept moving at a steady rate, up to {moved:.3g} m ({100 * relative:.2g} % of "
                    f"their displacement from the reference, {moved / self.dx:.2g} cells): float32 may not hold this "
                    f"settled state (slender bodies near a bifurcation creep); unless the loads still change, rerun "
                    f"with simulation.precision = 'float64' (run.json 'drift')")
        return out, note


def metrics_table(columns: list[str], rows: list) -> np.ndarray:
    """A numpy structured array (one float64 field per column, one record per row): the metrics.csv table."""
    table = np.zeros(len(rows), dtype=[(c, np.float64) for c in columns])
    for i, row in enumerate(rows):
        table[i] = tuple(row)
    return table


def _as_frame(table: np.ndarray):
    """``table`` (a structured array) as a pandas DataFrame, with one line naming pandas when it is missing."""
    try:
        import pandas
    except ImportError:
        raise ImportError("a DataFrame needs pandas (pip install pandas); the numpy table is .metrics") from None
    return pandas.DataFrame(table)


@dataclass
class RunResult:
    """Outcome of :meth:`Simulation.run`. ``metrics``: the probe values at t = 0 and at each record time (the rows
    of metrics.csv) as a numpy structured array, column 'time' (s) then the probe columns (m; field probes T;
    collider_force probes N): ``result.metrics["tip_y"]``; :meth:`dataframe` gives it as a pandas DataFrame."""

    status: str  # completed | failed | interrupted
    steps: int
    time: float
    wall_time: float
    message: str = ""
    signal: int | None = None  # the signal that stopped an interrupted run (SIGTERM); None for Ctrl-C or none
    metrics: np.ndarray | None = None  # None where the result was not made by Simulation.run

    def dataframe(self):
        """:attr:`metrics` as a pandas DataFrame (needs pandas)."""
        return _as_frame(self.metrics)


@dataclass
class StaticRun(StaticResult):
    """Outcome of :meth:`Simulation.solve_static` (a :class:`~magsoro.mpm.newton.static.StaticResult`) with ``metrics``:
    the probe values at each converged level as a numpy structured array, column 'level' (or 'time', s, when
    solved at times along the paths) then the probe columns (m; field probes T at the level's field; collider_force
    probes N, the contact's reaction); :meth:`dataframe` gives it as a pandas DataFrame."""

    metrics: np.ndarray | None = None

    def dataframe(self):
        """:attr:`metrics` as a pandas DataFrame (needs pandas)."""
        return _as_frame(self.metrics)


@dataclass
class RelaxResult:
    """Outcome of :meth:`Simulation.relax`. Energies in J, speeds in m/s."""

    converged: bool
    steps: int
    resets: int  # kinetic-energy peaks at which the velocities were zeroed
    kinetic_energy: float  # at the last kinetic-energy peak (the converged cycle's peak when converged)
    max_speed: float  # largest particle speed at that peak
    first_peak_energy: float  # largest kinetic energy seen (the scale the tolerance is relative to)
    first_peak_speed: float  # largest particle speed seen
    wall_time: float
    message: str = ""
    stalled: bool = False  # the cycle peaks stopped falling above the tolerance (round-off floor)

def check_run_length(duration: float, every: float | None = None) -> float:
    """The record interval of a run of ``duration`` s (``every``, default duration / 50), refusing a duration or
    interval that is not a finite positive number and more than MAX_RECORDS records (an unbounded output)."""
    every = every or duration / 50.0
    if not (math.isfinite(duration) and duration > 0 and math.isfinite(every) and every > 0):
        raise SceneError(f"run: duration ({duration!r} s) and the record interval ({every!r} s) must be finite and > 0")
    if duration / every > MAX_RECORDS:
        raise SceneError(f"run: {duration / every:.3g} records of {every:g} s over {duration:g} s; at most {MAX_RECORDS:.0e} "
                         f"are allowed: raise output.every to at least {duration / MAX_RECORDS:.3g} s")
    return every


#: a static level that fails with its residual within this factor of static.tolerance is reported as stalled at the
#: rounding floor (solve_static's message), not as a load that needs smaller increments
STALL_NEAR_TOLERANCE = 5.0


def graph_off_note(device: str, reason: str) -> str:
    """The note run.json gets (``notes``) when a run's check windows cannot run from drive tables, so not as CUDA
    graphs, for ``reason`` (docs/engine.md, "CUDA graph windows")."""
    if device.startswith("cuda"):
        return f"CUDA graph capture off: {reason}"
    return f"graph windows off (plain step loop): {reason}"


class Simulation:
    """A scene made runnable: Model, Control, Solver and the current State.

    ``device`` overrides the scene's ``simulation.device``. :meth:`solve_static` needs float64 and the
    total-Lagrangian form (:func:`prepare_static`); a Simulation built otherwise is rebuilt so at that call.
    """

    _keyframes = None  # the scene's keyframe times (_keyframe_times), found on the first implicit advance

    def __init__(self, scene: Scene, device: str | None = None, source: str = "scene"):
        self.scene = scene
        self.source = source
        implicit_notes = _prepare_implicit(scene)
        self.built: Built = build(scene, device=device, source=source)
        self.model = self.built.model
        self.control = self.built.control
        self.solver = Solver(self.model, self.built.settings)
        self.state = self.solver.new_state(self.built.initial_velocity)
        self._spare = self.solver.new_state()
        self.probes = self.built.probes
        self._probe_interaction = None  # the bodies' field for field probes (the solver's when it has one)
        self.field_scale = 1.0  # the applied fields' scale in field_at and the field probes: a static solve's level
        # the colliders' forces (collider_forces): the solver's impulse since _impulse_time, the last value read,
        # and a static solve's reactions (until the next step)
        self._impulse_time = self.state.time
        self._collider_force = np.zeros((len(self.control.colliders), 3))
        self._static_forces = None
        self._pair_forces = None  # (groups, groups, 3) N: the body contact's forces of the Newton solvers
        sim = scene.simulation
        self.fixed_dt = sim.dt
        with np.errstate(all="ignore"):  # a field that is not finite is named by check_time_step below
            self._field_peak = self.solver.field_magnitude(self.control)
            self._wave_speed = self.model.wave_speed(self._field_peak)
        v0 = self.built.initial_velocity
        # the first step's bound counts the initial velocities (later steps: the speeds the last step reached)
        self._initial_speed = float(np.max(np.linalg.norm(v0, axis=1))) if v0 is not None and len(v0) else 0.0
        self.dt = (self.fixed_dt if self.fixed_dt is not None
                   else cfl_time_step(self.solver.settings.cfl, self.model.dx, self._wave_speed, self._initial_speed))
        self.dt_min = self.dt_max = self.dt
        self.check_every = int(sim.check_every)  # steps per check window (advance_to, run)
        self.windows = self.reruns = 0  # check windows run, and those run again step by step
        # notes for run.json: why a window's steps run through the plain step loop, or are not captured as a graph
        self.notes: list[str] = []
        # the notes on what the scene may not mean (a body in the domain walls' reach, a body the lattice rounds):
        # also in ``notes``; magsoro run prints them, magsoro reproduce collects them
        self.scene_notes: list[str] = []
        self._checkpoint = None  # the first state of the current check window
        self.started_from: dict | None = None  # where the state came from (start_from): run.json's 'initial'
        self.steps = 0
        self.last_good_time = 0.0
        # particles that start out of the domain walls' reach (check_wall_reach): a body that moves into it meets
        # a wall the scene may not mean to have
        self._wall_far = self._wall_distances(self.model.host["positions"]) > WALL_REACH_CELLS * self.model.dx
        self._wall_far &= (self.model.host["clamped"] == 0)[:, None]
        # what the explicit engine cannot step (an axisymmetric scene's contact in the total form, its self-contact):
        # refused when it steps, so that the Newton solvers, which take it, can
        from magsoro.scene.build import axisymmetric_explicit_refusal

        self._explicit_refusal = axisymmetric_explicit_refusal(scene, self.solver.settings.formulation,
                                                               self.solver.contact_active, source)
        self._walls_reached: set = set()
        self._note_lattice_fill()
        self._note_thin_parts()
        for text in self.built.notes:
            self._note(text, scene=True)
        # simulation.integrator = 'implicit': the integrator is made at the first step (after set_sources)
        self.integrator = scene.simulation.integrator
        self.implicit = None
        if self.integrator == "implicit":
            cfg = scene.implicit
            self.dt = cfg.dt if cfg.dt is not None else scene.simulation.duration / 200.0
            self.implicit_dt_max = cfg.dt_max if cfg.dt_max is not None else self.dt
            self.implicit_dt_min = cfg.dt_min if cfg.dt_min is not None else self.dt / 1000.0
            self.dt_min, self.dt_max = math.inf, 0.0
            for text in implicit_notes:
                self._note(text)
        # a field or a step that is not finite would sit at t = 0 for ever; values no robot meets are noted
        peaks = check_time_step(self, source)
        for text in plausibility_notes(self, peaks) + ([self.solver.threads_note] if self.solver.threads_note else []):
            self._note(text, scene=True)

    def _check_explicit(self) -> None:
        """Raise SimulationError where the explicit engine cannot step the scene (Simulation.__init__)."""
        if self._explicit_refusal is not None:
            raise SimulationError(self._explicit_refusal)

    def set_sources(self, sources) -> None:
        """Replace the field sources (call between steps) and bound the time step anew for the largest field they
        give at the particles: the wave speed, and so the CFL step, counts the magnetic stiffening of that peak
        (a fixed ``simulation.dt`` is kept as given)."""
        self.control.sources = list(sources)
        self._field_peak = self.solver.field_magnitude(self.control)
        self._wave_speed = self.model.wave_speed(self._field_peak)
        if self.fixed_dt is None:
            self.dt = self._cfl_dt(self._checked_speed())
            if not (self.dt > 0.0 and math.isfinite(self.dt)):
                raise SimulationError(time_step_problem(self, self.dt), self.steps, self.state.time)
            self.dt_min, self.dt_max = min(self.dt_min, self.dt), max(self.dt_max, self.dt)

    @classmethod
    def from_file(cls, path, device: str | None = None) -> "Simulation":
        """The Simulation of the scene file ``path`` (TOML), on ``device`` ('cpu', 'cuda', 'cuda:N'; default the
        scene's simulation.device); errors name the file and the key."""
        return cls(load_scene(path), device=device, source=str(path))

    # -- reading -------------------------------------------------------------------------------------------
    @property
    def time(self) -> float:
        """The simulated time of the current state, s."""
        return self.state.time

    @property
    def dim(self) -> int:
        """The scene's dimension: 2 or 3."""
        return self.model.dim

    def probe_columns(self) -> list[str]:
        """The names of the probes' columns in metrics.csv and :meth:`probe_values`, in order (a position probe
        gives NAME_x, NAME_y (, NAME_z) in m)."""
        cols = []
        for p in self.probes:
            cols.extend(p.columns(self.dim))
        return cols

    def probe_values(self) -> dict[str, float]:
        """Current value of every probe column (m; field probes: T; collider_force probes: N, see
        :meth:`collider_forces`)."""
        x = self.state.x.numpy()
        sensors = [p for p in self.probes if p.kind == "field"]
        # every field probe from one solve of the bodies' field
        fields = dict(zip((p.name for p in sensors), self.field_at(np.array([p.where(x) for p in sensors])))) if sensors else {}
        forces = self.collider_forces() if any(p.kind == "collider_force" for p in self.probes) else None
        out = {}
        for p in self.probes:
            if p.kind == "collider_force" and p.pair is not None:
                value = self._pair_force(p)
            elif p.kind == "collider_force":
                value = forces[p.collider, : self.dim]
            else:
                value = fields[p.name] if p.kind == "field" else p.evaluate(x)
            out.update(zip(p.columns(self.dim), value.tolist()))
        return out

    def _pair_force(self, probe) -> np.ndarray:
        """The contact force (N, dim) one body exerts on another for a collider_force probe between bodies: the
        static solver's at the last level solved, the implicit integrator's at the last step (zero before it)."""
        if self._pair_forces is not None:
            return self._pair_forces[probe.pair[0], probe.pair[1], : self.dim].copy()
        if self.scene.simulation.integrator == "implicit":
            return np.zeros(self.dim)
        raise SimulationError(f"probe '{probe.name}': the force between bodies is measured by the static solver "
                              f"(magsoro run --static) and the implicit integrator (simulation.integrator = "
                              f"'implicit'), not yet by the explicit engine; remove the probe or use one of them")

    def collider_forces(self) -> np.ndarray:
        """The force (N, (n_colliders, 3); 2D: z = 0, for the scene's depth) the bodies exert on each rigid collider.
        After steps: the momentum each collider took from the grid nodes it touched since the last call, per unit
        of simulated time (a mean over the interval; the value of the last call when no time has passed). After
        :meth:`relax`: the same over its last kinetic-energy cycle. After :meth:`solve_static`: the contact's
        reaction at the last level solved."""
        if self._static_forces is not None:
            return self._static_forces.copy()
        n = len(self.control.colliders)
        elapsed = self.state.time - self._impulse_time
        if n and elapsed > 0.0:
            self._collider_force = self._take_impulse(n) / elapsed
            self._impulse_time = self.state.time
        return self._collider_force.copy()

    def _take_impulse(self, n: int) -> np.ndarray:
        """The impulse (N s, (n, 3)) the colliders took since it was last taken, and zero it."""
        imp = self.solver.collider_impulse
        if imp.shape[0] < 3 * n:  # no step has run yet: the solver sizes it for the colliders at the first one
            return np.zeros((n, 3))
        out = imp.numpy()[: 3 * n].astype(np.float64).reshape(n, 3)
        imp.zero_()
        return out

    def field_at(self, points) -> np.ndarray:
        """Total flux density B (T, (P, 3)) at ``points`` (P, dim) m now: the applied fields plus the field of the
        bodies' current magnetisation (whether or not simulation.magnetic_interaction lets it act on them). In 2D
        the points lie in the plane z = simulation.plane_z."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))[:, : self.dim]
        p3 = np.zeros((len(pts), 3))
        p3[:, : self.dim] = pts
        if self.dim == 2:
            p3[:, 2] = self.solver.settings.plane_z
        B = np.zeros((len(pts), 3))
        for s in self.control.sources:
            B += self.field_scale * np.asarray(s.B(p3, self.time), dtype=np.float64).reshape(len(pts), 3)
        if self._probe_interaction is None:
            self._probe_interaction = self.solver.interaction or MagneticInteraction(self.model, self.solver.settings.depth)
        return B + self._probe_interaction.field_at(pts, self.state.x, self.state.F)

    def particles(self) -> dict[str, np.ndarray]:
        """Particle arrays as numpy: x, v, F, body, clamped, J = det F, I1bar = J^(-2/3) tr(F^T F) (the
        isochoric stretch invariant, 3 when undeformed), magnetization (current direction of F Br, unit)."""
        s = self.state.numpy()
        F = s["F"].astype(np.float64)
        J = np.linalg.det(F)
        I1 = np.einsum("nij,nij->n", F, F) + (1.0 if self.dim == 2 else 0.0)
        Br = self.model.host["remanence"]
        m = np.einsum("nij,nj->ni", F, Br[:, : self.dim])
        if self.dim == 2:
            m = np.concatenate([m, Br[:, 2:3]], axis=1)
        norm = np.linalg.norm(m, axis=1, keepdims=True)
        direction = np.divide(m, norm, out=np.zeros_like(m), where=norm > 0)
        return {
            "x": s["x"],
            "v": s["v"],
            "F": s["F"],
            "body": self.model.host["body"],
            "clamped": self.model.host["clamped"].astype(np.uint8),
            "J": J,
            "I1bar": np.abs(J) ** (-2.0 / 3.0) * I1,
            "magnetization": direction,
        }

    # -- phases --------------------------------------------------------------------------------------------
    def restart_arrays(self) -> dict[str, np.ndarray]:
        """What final.npz holds besides :meth:`particles`, so that another run can start from it
        (:meth:`start_from`): C, H (Prony materials), the reference positions, the body names, the precision, the
        state's step count and the particle speed the next time step is bounded by."""
        s = self.state
        out = {"C": s.C.numpy(), "reference_positions": np.asarray(self.model.host["positions"], dtype=np.float64),
               "body_names": np.array([str(n) for n in self.built.body_names]),
               "precision": np.array(self.model.precision), "step": np.array(int(s.step), dtype=np.int64),
               "speed_bound": np.array(float(self._checked_speed()))}
        if s.H is not None:
            out["H"] = s.H.numpy()
        return out

    def start_from(self, path, key: str = "--from") -> list[str]:
        """Start from the final state of another run (its final.npz, or its folder): positions, velocities, affine
        velocities, deformation gradients, Prony internal stresses, the step count and the time, which this run
        continues (fields, collider paths, keyframes and a damping profile see the continued time; :meth:`run`'s
        duration counts from it). The bodies must match (:func:`magsoro.io.start.read_start`: particle count, body
        names and ids, reference positions to rounding, clamped particles, precision, Prony terms); a mismatch
        raises SceneError in one line naming the file and what differs. The next time step is bounded by the speed
        the last one was (saved with the state), so an explicit run split in two takes the same steps as in one
        piece. Call before the first step. Returns the notes (also in :attr:`notes`)."""
        from magsoro.io.start import read_start, start_file

        if self.steps:
            raise SimulationError(f"start_from: this simulation has taken {self.steps} steps; start from a state "
                                  f"before the first step", self.steps, self.state.time)
        data, notes = read_start(path, self.model, self.built.body_names, key)
        st, sc = self.state, self.model.np_scalar
        for name in ("x", "v", "C", "F") + (("H",) if st.H is not None else ()):
            getattr(st, name).assign(np.ascontiguousarray(data[name], dtype=sc))
        st.time = float(data["time"])
        st.step = int(data["step"]) if "step" in data else 0
        v = np.asarray(data["v"], dtype=np.float64)
        speed = float(np.max(np.linalg.norm(v, axis=1), initial=0.0))
        self._initial_speed = float(data["speed_bound"]) if "speed_bound" in data else speed
        if self.fixed_dt is None and self.integrator != "implicit":
            self.dt = self._cfl_dt(self._initial_speed)
            self.dt_min = self.dt_max = self.dt
        self._impulse_time = self.last_good_time = st.time
        # walls the bodies are within reach of at the start are the scene's (check_wall_reach)
        self._wall_far = self._wall_distances(np.asarray(data["x"])) > WALL_REACH_CELLS * self.model.dx
        self._wall_far &= (self.model.host["clamped"] == 0)[:, None]
        self.started_from = {"from": str(start_file(path, key)), "time": st.time, "step": st.step,
                             "precision": str(data["precision"]) if "precision" in data else str(data["x"].dtype)}
        for text in notes:
            self._note(text)
        return notes

    # -- statics -------------------------------------------------------------------------------------------
    def solve_static(self, levels=None, t: float | None = None, on_level: Callable | None = None, times=None,
                     watch: Callable | None = None):
        """Equilibria by Newton's method (:mod:`magsoro.mpm.newton.static`) under the loads at time ``t`` (default
        simulation.duration), the fields scaled by each of ``levels`` in turn (default [static] levels) and
        gravity in full; each level starts from the previous equilibrium and the state holds the last converged
        one. ``on_level(sim, level_result)`` after each converged level; ``watch(solver)`` once before the first
        level, given the :class:`~magsoro.mpm.newton.static.StaticSolver` whose counters (``linear_solves``: one per
        Newton iteration; ``residual_evaluations``) a progress display may read while a level solves. Returns a :class:`StaticRun` (its ``metrics``
        the probe values per level); stops at the
        first level that does not converge (its message names the level). Afterwards :meth:`field_at` and the
        field probes read the applied fields scaled by the last level solved.

        ``times`` (default [static] times) sweeps along the scene's paths instead: the equilibrium under the loads
        at each of these times (s, increasing) in turn, the fields in full; the first from the unloaded body, each
        later one from the last, the fields and colliders moving along their paths with the load increments
        (:meth:`~magsoro.mpm.newton.static.StaticSolver.move_to`; a magnet brought closer step by step). ``levels`` and
        ``t`` do not apply then; each result's ``level`` is 1 and ``time`` its time. The state's time is the last
        time solved.

        Precision: as ``magsoro run --static``, the solve runs in float64 and the total-Lagrangian form
        (:func:`prepare_static`). A Simulation built in float32 (the scenes' default) is rebuilt in float64 at the
        first call, keeping its state, field sources and device, and :attr:`notes` says so; one that has already
        taken steps is refused (a rebuild would restart its motion): set ``scene.simulation.precision =
        'float64'`` before building it."""
        from magsoro.mpm.newton.static import StaticSolver

        self._rebuild_for_static()
        cfg = self.scene.static
        times = cfg.times if times is None and levels is None and t is None else times
        if times is not None:
            times = [float(v) for v in times]
            if levels is not None or t is not None:
                raise ValueError("solve_static: give times, or levels (and t), not both")
            if not times or any(b <= a for a, b in zip(times[:-1], times[1:])):
                raise ValueError(f"solve_static: times must be a non-empty increasing list, not {times}")
            levels = [1.0] * len(times)
        t = (times[0] if times is not None else self.scene.simulation.duration) if t is None else float(t)
        levels = cfg.levels if levels is None else list(levels)
        t0 = _time.perf_counter()
        solver = StaticSolver(self, t, tolerance=cfg.tolerance, max_iterations=cfg.max_iterations, arc_length=cfg.arc_length)
        self._static_guess(solver)
        # static.soft_penalty: a predictor chain with a soft contact penalty, whose equilibrium starts each level
        predictor = None
        if cfg.soft_penalty is not None and solver.contact is not None:
            predictor = StaticSolver(self, t, tolerance=cfg.tolerance, max_iterations=cfg.max_iterations,
                                     penalty_scale=cfg.soft_penalty, check_stability=False)
            predictor.u_nodes = solver.u_nodes.copy()  # the same unknowns: the solver's start, not fitted again
        self.state.time = t
        if watch is not None:
            watch(solver)
        out = StaticRun(True)
        columns = ["time" if times is not None else "level"] + self.probe_columns()
        rows = []
        for k, level in enumerate(levels):
            if times is not None:
                solver.move_to(times[k])
                self.state.time = times[k]
            prev = None  # the last equilibrium, while the level starts from the predictor's
            if predictor is not None:
                if times is not None:
                    predictor.move_to(times[k])
                pre = predictor.solve_level(level)
                if pre.converged and k > 0:
                    # from the second level on (the first starts from the reference, where the predictor's state
                    # only adds its deeper sinking into the colliders); the variants measured on the hexahedron
                    # are in benchmarks/README.md, "Penalty continuation"
                    prev = (solver.u_nodes.copy(), solver.field_level, solver.gravity_level)
                    solver.start_from(predictor)
                elif not pre.converged:  # the chain goes on from its last equilibrium; the level from the solver's
                    self._note(f"static.soft_penalty: the predictor did not converge at {'time' if times is not None else 'level'} "
                               f"{times[k] if times is not None else level:g} ({pre.message}); the level started from the last equilibrium")
            res = solver.solve_level(level)
            if predictor is not None:
                res.predictor_iterations, res.predictor_linear_solves = pre.iterations, pre.linear_solves
                res.predictor_converged = pre.converged
                if not res.converged and prev is not None:  # the state stays the last equilibrium, not the start
                    solver.u_nodes, solver.field_level, solver.gravity_level = prev
            res.time = self.state.time
            out.levels.append(res)
            solver.write_state()
            self._static_forces = solver.collider_reactions()
            self._pair_forces = None if solver.body_contact is None else solver.body_contact.pair_force.copy()
            self.field_scale = solver.field_level  # field probes read the applied field of the level solved
            if not res.converged:
                out.converged = False
                kind = "time" if times is not None else "level"
                what = f"time {times[k]:g} s" if times is not None else f"level {level:g}"
                out.message = f"{what} did not converge ({res.message}); the state is the last converged {kind}'s"
                tol = solver.tolerance
                stalled = res.residual_relative
                if res.wall_crossing is None and not res.no_equilibrium and math.isfinite(stalled) and stalled <= STALL_NEAR_TOLERANCE * tol:
                    # Newton got within a few times the tolerance and no further: a small load (gravity alone on a
                    # stiff body) next to large internal forces, whose float64 rounding is above the tolerance
                    out.message += (f": its residual stalled at {stalled:.3g} of the force scale, {stalled / tol:.2g} times "
                                    f"static.tolerance = {tol:g}, where float64 rounding of the body's internal forces "
                                    f"sits for a load this small; loosen static.tolerance (to {10 * tol:g}, say)")
                elif res.wall_crossing is None and not res.no_equilibrium:
                    out.message += f": insert intermediate {kind}s, raise static.max_iterations, or check the loads"
                break
            row = self._metrics_row(columns)
            rows.append(row if times is not None else [level] + row[1:])
            if on_level is not None:
                on_level(self, res)
        out.metrics = metrics_table(columns, rows)
        out.wall_time = _time.perf_counter() - t0
        out.residual_evaluations = solver.residual_evaluations
        if out.converged:
            out.message = f"{len(levels)} {'time' if times is not None else 'level'}(s) converged"
        return out

    def _static_guess(self, solver) -> None:
        """A state away from the reference (one started from another run's, :meth:`start_from`, or bodies given an
        initial_displacement) is where the static solver's Newton iterations start: its displacements and
        deformation gradients projected on the grid nodes as the implicit integrator projects its start (least
        squares; where the solver slaves light nodes, on the unknowns through the slaving map), so that the solve
        stays on the state's branch (a pre-buckled arch, an imperfection)."""
        if self.started_from is None and "initial_displacement" not in self.model.host:
            return
        dim = self.dim
        x = self.state.x.numpy().astype(np.float64)[:, :dim]
        d = x - self.model.host["positions"][:, :dim]
        if not np.any(d != 0.0):
            return
        F = self.state.F.numpy().astype(np.float64)[:, :dim, :dim]
        # the implicit integrator's start, the same fit; the moving clamps' nodes where the clamps start
        solver.u_nodes = solver.hold(solver.fit_nodes(d, F - np.eye(dim)))

    def _rebuild_for_static(self) -> None:
        """Rebuild in float64 and the total form (:func:`prepare_static`) when built otherwise, keeping the state,
        the field sources and the device."""
        if self.model.np_scalar == np.float64 and self.solver.settings.formulation == "total":
            return
        if self.steps:
            raise SimulationError(f"solve_static: this simulation was built in {np.dtype(self.model.np_scalar).name} "
                                  f"and the {self.solver.settings.formulation} form and has taken {self.steps} steps; "
                                  "the static solver needs float64 and the total-Lagrangian form (as magsoro run "
                                  "--static): set scene.simulation.precision = 'float64' and formulation = 'total' "
                                  "before building the Simulation")
        self._rebuild(prepare_static)

    def _rebuild(self, prepare: Callable) -> None:
        """Rebuild with the settings ``prepare`` (prepare_static, prepare_relax) sets on the scene, keeping the
        state, its start, the field sources and the device."""
        notes = prepare(self.scene)
        state, t, sources = self.state.numpy(), self.state.time, list(self.control.sources)
        start, speed, step = self.started_from, self._initial_speed, self.state.step
        self.__init__(self.scene, device=self.model.device, source=self.source)
        for name, values in state.items():
            getattr(self.state, name).assign(values.astype(self.model.np_scalar))
        self.state.time, self.state.step = t, step
        self.started_from, self._initial_speed = start, speed
        self.set_sources(sources)
        for text in notes:
            self._note(text)

    # -- stepping ------------------------------------------------------------------------------------------
    def _next_dt(self, remaining: float, speed: float | None = None) -> float:
        """The next step: the fixed dt, or the CFL bound for the top speed of the last check (``speed`` when
        given), shortened to land on the end of ``remaining`` without a sliver step."""
        if self.fixed_dt is None:
            self.dt = self._cfl_dt(self._checked_speed() if speed is None else speed)
        dt = self.dt
        if not (dt > 0.0 and math.isfinite(dt)):  # a NaN step would never reach the end of the interval
            raise SimulationError(time_step_problem(self, dt), self.steps, self.state.time)
        if remaining < dt * (1 + 1e-9):
            dt = remaining
        elif remaining < 2 * dt:
            dt = 0.5 * remaining  # avoid a sliver step at the end of an interval
        self.dt_min, self.dt_max = min(self.dt_min, dt), max(self.dt_max, dt)
        return dt

    def _checked_speed(self) -> float:
        """Top particle speed the next time step is bounded by: the last check's, the initial speeds before any."""
        return self.solver.last_max_speed() if self.steps else self._initial_speed

    def _cfl_dt(self, speed: float) -> float:
        return cfl_time_step(self.solver.settings.cfl, self.model.dx, self._wave_speed, speed)

    def step(self, dt: float | None = None) -> None:
        """One step of ``dt`` seconds (default: the current automatic or fixed step)."""
        dt = self._next_dt(math.inf) if dt is None else dt
        self._step(dt)

    def _step(self, dt: float) -> None:
        """Step the current state into the spare buffer and swap. When the step refuses its input (the state the
        previous step reached is outside the domain or not finite: checked at the start of a step), the state
        before it, still in the spare buffer, becomes current again: the state kept after a failure (written as
        last_good.npz) is always one that passed the checks."""
        self._static_forces = None
        self._pair_forces = None  # (groups, groups, 3) N: the body contact's forces of the Newton solvers
        self._check_explicit()
        try:
            self.solver.step(self.state, self._spare, self.control, dt)
        except SimulationError as exc:
            if exc.input_rejected and self.steps > 0:
                self.state, self._spare = self._spare, self.state
                self.steps -= 1
                self.solver.forget_bounds()
            raise
        self.state, self._spare = self._spare, self.state
        self.steps += 1

    def advance_to(self, t_end: float, callback: Callable | None = None, heartbeat: Callable | None = None) -> None:
        """Step until simulated time ``t_end`` (s), landing on it exactly, in check windows of up to
        ``check_every`` steps (:meth:`_window`); ``callback(sim)`` after every step, ``heartbeat(sim)`` after every
        window (and every step outside windows). Without a callback a window's steps run from drive tables
        (:meth:`magsoro.mpm.solver.Solver.run_window`; on CUDA a captured graph) where the scene allows it."""
        eps = 1e-12 * max(1.0, t_end)
        if self.integrator == "implicit":
            self._advance_implicit(t_end, eps, callback, heartbeat)
            self.check_wall_reach()
            return
        self._check_explicit()
        while self.state.time < t_end - eps:
            if self.check_every <= 1:
                self._step(self._next_dt(t_end - self.state.time))
                if callback is not None:
                    callback(self)
                if heartbeat is not None:
                    heartbeat(self)
            else:
                self._window(t_end, eps, callback, heartbeat)
                if heartbeat is not None:
                    heartbeat(self)
        self.check_wall_reach()

    def implicit_integrator(self):
        """The :class:`magsoro.mpm.newton.implicit.ImplicitIntegrator` of simulation.integrator = 'implicit' (made on the
        first call, from the current state and sources)."""
        if self.implicit is None:
            from magsoro.mpm.newton.implicit import ImplicitIntegrator

            cfg = self.scene.implicit
            self.implicit = ImplicitIntegrator(self, cfg.scheme, cfg.rho_inf, cfg.tolerance, cfg.max_iterations,
                                               linear_solver=cfg.linear_solver)
        return self.implicit

    def _advance_implicit(self, t_end: float, eps: float, callback: Callable | None, heartbeat: Callable | None) -> None:
        """Implicit steps until ``t_end``: each at the current step size (landing on ``t_end``), halved and retried
        when Newton fails down to implicit.dt_min, grown by implicit.grow after an easy one up to implicit.dt_max."""
        integ = self.implicit_integrator()
        cfg = self.scene.implicit
        keys = self._keyframe_times()
        while self.state.time < t_end - eps:
            # steps land on the keyframes of the scene's paths and tables (where a load's rate jumps), and are evened
            # out to there: not a full step and a sliver (84 + 16 ms where 100 ms remain)
            k = int(np.searchsorted(keys, self.state.time + eps, side="right"))
            turn = k > 0 and abs(self.state.time - float(keys[k - 1])) <= eps  # the step starts on a keyframe
            stop = min(t_end, float(keys[k])) if k < len(keys) else t_end
            remaining = stop - self.state.time
            dt = remaining / max(1, math.ceil(remaining / self.dt - 1e-3))
            planned = dt
            u_before = integ.u_nodes
            while True:
                result = integ.try_step(dt, turn=turn)
                if result.converged:
                    break
                if result.fatal:
                    raise SimulationError(result.message, self.steps, self.state.time)
                if dt <= self.implicit_dt_min * (1 + 1e-9):
                    raise SimulationError(
                        f"the implicit step did not converge at implicit.dt_min = {self.implicit_dt_min:.3g} s "
                        f"({result.message}; |R| at {result.relative_residual:.3g} of the step's force scale): lower "
                        f"implicit.dt_min, raise implicit.max_iterations, or check the loads", self.steps, self.state.time)
                dt = max(0.5 * dt, self.implicit_dt_min)
                self.dt = dt
            integ.write_state()
            self.steps += 1
            self.last_newton_iterations = result.iterations
            self.dt_min, self.dt_max = min(self.dt_min, dt), max(self.dt_max, dt)
            self._static_forces = integ.collider_reactions()
            self._pair_forces = None if integ.body_contact is None else integ.body_contact.pair_force.copy()
            if not all(np.isfinite(np.asarray(integ.u_nodes)).ravel()):
                raise SimulationError("the implicit step produced non-finite displacements", self.steps, self.state.time)
            nxt = self.dt
            if result.iterations <= cfg.easy_iterations and dt >= planned * (1 - 1e-9) and dt >= 0.5 * self.dt:
                nxt = self.dt * cfg.grow  # an easy step not halved (nor a short one, to land on t_end)
            if cfg.max_move is not None:  # the step sized by how far the particles moved in this one (not the
                # nodes: a light node at a body's edge carries little of the body and may swing far)
                du = integ.interpolation() @ (np.asarray(integ.u_nodes) - np.asarray(u_before))
                move = float(np.abs(du).max(initial=0.0)) / self.model.dx
                if move > 0.0:
                    nxt = min(nxt, max(0.5 * dt, dt * cfg.max_move / move))
            self.dt = min(max(nxt, self.implicit_dt_min), self.implicit_dt_max)
            if callback is not None:
                callback(self)
            if heartbeat is not None:
                heartbeat(self)

    def _keyframe_times(self) -> np.ndarray:
        """The times (s, sorted) of every keyframe table of the scene (paths of fields, colliders and clamps, field
        and stimulus tables, damping profiles; not [static] times): the loads' rates jump there."""
        from pydantic import BaseModel

        if self._keyframes is None:
            times = set()

            def walk(obj):
                if isinstance(obj, BaseModel):
                    for name in type(obj).model_fields:
                        value = getattr(obj, name)
                        if name == "times" and isinstance(value, list):
                            times.update(float(t) for t in value)
                        elif not (obj is self.scene and name == "static"):
                            walk(value)
                elif isinstance(obj, (list, tuple)):
                    for item in obj:
                        walk(item)

            walk(self.scene)
            self._keyframes = np.array(sorted(times), dtype=np.float64)
        return self._keyframes

    def integrator_info(self) -> dict:
        """run.json's ``integrator`` entry: which integrator ran; the implicit one's scheme, steps, rejected steps and
        Newton iterations."""
        if self.integrator != "implicit":
            return {"kind": "explicit"}
        from magsoro.mpm.newton.implicit import integrator_summary

        cfg = self.scene.implicit
        return {"kind": "implicit", **integrator_summary(self.implicit, cfg),
                "dt_first": cfg.dt if cfg.dt is not None else self.scene.simulation.duration / 200.0,
                "dt_min_allowed": self.implicit_dt_min, "dt_max_allowed": self.implicit_dt_max}

    def _wall_distances(self, x: np.ndarray) -> np.ndarray:
        """Distances (m) of the points ``x`` to the domain's faces, columns lo_0, hi_0, lo_1, hi_1, ..."""
        dim = self.model.dim
        lo = np.asarray(self.model.domain_lo, dtype=np.float64)[:dim]
        hi = np.asarray(self.model.domain_hi, dtype=np.float64)[:dim]
        x = np.asarray(x, dtype=np.float64)[:, :dim]
        return np.stack([v for a in range(dim) for v in (x[:, a] - lo[a], hi[a] - x[:, a])], axis=1)

    def check_wall_reach(self) -> list[str]:
        """Note (run.json ``notes``, once per body and wall) each body whose particles moved from outside the
        domain walls' reach into it: the walls stop nodes two cells inside the domain's edge, and a particle's mass
        reaches nodes 1.5 cells from it, so a particle nearer than WALL_REACH_CELLS cells to a face may be held by
        that wall. Bodies that start there (a robot on the domain's floor) are not noted. Returns the new notes."""
        if not self._wall_far.any():
            return []
        near = self._wall_distances(self.state.x.numpy()) <= WALL_REACH_CELLS * self.model.dx
        hit = near & self._wall_far
        new = []
        if not hit.any():
            return new
        body = self.model.host["body"]
        names = self.built.body_names
        axes = "xyz"
        for face in np.flatnonzero(hit.any(axis=0)):
            a, side = divmod(int(face), 2)
            bound = (self.model.domain_hi if side else self.model.domain_lo)[a]
            for b in np.unique(body[hit[:, face]]):
                key = (int(b), int(face))
                if key in self._walls_reached:
                    continue
                self._walls_reached.add(key)
                text = (f"body '{names[int(b)]}' reached the domain wall at {axes[a]} = {float(bound):.6g} m "
                        f"(simulation.domain_{'hi' if side else 'lo'}[{a}]) by t = {self.state.time:.6g} s: the walls "
                        f"({self.scene.simulation.walls}) hold nodes two cells inside the domain's edge; enlarge the "
                        f"domain unless the wall is part of the scene")
                self._note(text, scene=True)
                new.append(text)
        return new

    def _note_lattice_fill(self) -> None:
        """Note the bodies whose particles fill a volume more than LATTICE_FILL_NOTE away from their shape's: the
        particles sit on one lattice (spacing dx / particles_per_cell), so a size that is not a whole number of
        spacings is rounded (a 0.84 mm beam at spacing 0.1 mm is 8 rows, 0.8 mm), and the engine simulates the
        rounded body (a beam's bending stiffness goes with the cube of its thickness). Particles given up to a body
        of higher priority are counted as filled. Bodies rounded by the same amount share one note."""
        sim = self.scene.simulation
        h = sim.dx / sim.particles_per_cell
        groups: dict = {}
        for r in self.built.fill_report:
            shape, n = r.get("shape_volume") or 0.0, r["particles"]
            if shape <= 0.0 or n == 0:
                continue
            change = r["filled_volume"] * (n + r.get("overlap_removed", 0)) / n / shape - 1.0
            if abs(change) > LATTICE_FILL_NOTE:
                groups.setdefault(f"{100 * abs(change):.1f} % {'more' if change > 0 else 'less'}", []).append(r["body"])
        for amount, names in groups.items():
            who = (f"body '{names[0]}': its particles fill {amount} than its shape's volume" if len(names) == 1 else
                   f"bodies {', '.join(repr(n) for n in names)}: their particles fill {amount} than their shapes' volumes")
            self._note(scene=True, text=f"{who} (particle spacing {h:g} m = simulation.dx / particles_per_cell): sizes "
                                        f"that are not whole numbers of spacings are rounded, and the engine simulates "
                                        f"the rounded body (make them whole numbers of spacings, or refine "
                                        f"simulation.dx)")

    def _note_thin_parts(self) -> None:
        """Note each piece (a body, or the bodies bonded into one: a robot's parts) whose thinnest part has fewer
        than THIN_PART_CELLS grid cells through it (:func:`magsoro.geometry.thickness.thin_parts`): such a plate,
        hinge or wall bends too stiffly or too softly depending on dx, so results that depend on it change with the
        grid; ``magsoro converge`` measures by how much. Bodies clamped whole are left out."""
        from magsoro.geometry.thickness import thin_parts

        sim = self.scene.simulation
        dx = float(sim.dx)
        dim = self.model.dim
        host = self.model.host
        X = np.asarray(host["positions"], dtype=np.float64)[:, :dim]
        body = np.asarray(host["body"])
        group = np.asarray(host["contact_group"]) if "contact_group" in host else body
        lo = np.asarray(self.model.domain_lo, dtype=np.float64)[:dim]
        names = self.built.body_names
        clamped = {b for b, name in enumerate(names)
                   if any(c.name == name and getattr(c, "clamped", False) for c in self.scene.bodies)}
        keep = ~np.isin(body, list(clamped)) if clamped else np.ones(len(body), dtype=bool)
        for g in np.unique(group[keep]):
            sel = keep & (group == g)
            res = thin_parts(X[sel], dx / sim.particles_per_cell, THIN_PART_CELLS * dx, origin=lo)
            if res is None or res.thin_particles == 0:
                continue
            members = [names[b] for b in np.unique(body[sel])]
            where = [names[b] for b in np.unique(body[sel][res.thin])]
            if len(members) == 1:
                who = f"body '{members[0]}'"
            else:
                shown = ", ".join(repr(n) for n in where[:4]) + (f" and {len(where) - 4} more" if len(where) > 4 else "")
                who = f"the piece of {len(members)} bonded bodies ({'all of them' if len(where) == len(members) else shown})"
            cells = res.thinnest / dx
            share = (f"all its {res.particles} particles" if res.thin_particles == res.particles else
                     f"{res.thin_particles} of its {res.particles} particles")
            self._note(scene=True, text=(
                f"{who}: its thinnest part is about {cells:.2g} cell{'s' if cells >= 1.05 else ''} through "
                f"({res.thinnest:.3g} m at simulation.dx {dx:g} m), and {share} lie in parts fewer than "
                f"{THIN_PART_CELLS:g} cells through: bending there is under-resolved and results that depend on it "
                f"change with dx (measure how much with magsoro converge, or refine simulation.dx to "
                f"{res.thinnest / THIN_PART_CELLS:.3g} m)"))

    def note(self, text: str, scene: bool = False) -> None:
        """Add ``text`` to the run's notes (run.json, printed; ``scene``: a note about the scene as given)."""
        self._note(text, scene=scene)

    def _note(self, text: str, scene: bool = False) -> None:
        if text not in self.notes:
            self.notes.append(text)
            if scene:
                self.scene_notes.append(text)

    def _graph_window(self, callback: Callable | None) -> bool:
        """Whether this window's steps run from drive tables (Solver.run_window); notes why not, once per reason."""
        reason = self.solver.graph_refusal(self.control)
        if reason is None and callback is not None:
            reason = "a callback after every step (Simulation.run / advance_to callback) needs the host at every step"
        if reason is not None:
            self._note(graph_off_note(self.model.device, reason))
            return False
        self._note_capture()
        return True

    def _note_capture(self) -> None:
        """On CUDA, note why a window's steps are launched one by one instead of replayed as graphs, once."""
        if self.model.device.startswith("cuda"):
            capture = self.solver.capture_refusal()
            if capture is not None:
                self._note(f"CUDA graph capture off: {capture}")

    def _plan_window(self, t_end: float, eps: float, speed: float) -> list[float]:
        """The time steps of a window, as the step-by-step loop of :meth:`_window` takes them."""
        dts, t = [], self.state.time
        while len(dts) < self.check_every and t < t_end - eps:
            dt = self._next_dt(t_end - t, speed)
            dts.append(dt)
            t = t + dt
        return dts

    def _window(self, t_end: float, eps: float, callback: Callable | None, heartbeat: Callable | None = None) -> None:
        """Up to ``check_every`` steps towards ``t_end`` with one host read at the end (the solver accumulates its
        checks on the device; the time step is fixed from the top speed of the previous check). When the window
        fails a check (a particle left the grid block or the domain, an invalid state, more than a cell in a
        step) or the speeds reached needed a shorter step, its first state comes back and the same span of time
        runs again in checked steps, each with its own time step as without windows: a refit happens where it is
        due, and an error stops at its exact step with the state before it kept. Callbacks are called after every step, again for the steps run again."""
        if self._checkpoint is None:
            self._checkpoint = self.solver.new_state()
        self._checkpoint.assign(self.state)
        steps0 = self.steps
        speed = self._checked_speed()
        # room in the grid block for the window's motion: twice the distance at the last check's top speed
        reach = 2.0 * self.check_every * (self.fixed_dt or self._cfl_dt(speed)) * speed + self.model.dx
        dts = []
        self.windows += 1
        graph = self._graph_window(callback)
        try:
            if graph:  # the same steps from drive tables: launched one by one, or replayed as graphs
                plan = self._plan_window(t_end, eps, speed)
                self.solver.start_window(self.state, reach)
                tick = (lambda: heartbeat(self)) if heartbeat is not None else None
                last = self.solver.run_window(self.state, self._spare, self.control, plan, tick)
                if last is not self.state:
                    self.state, self._spare = self._spare, self.state
                self.steps += len(plan)
                dts = plan
                self._note_capture()  # a capture that failed in this window
            while not graph and len(dts) < self.check_every and self.state.time < t_end - eps:
                dt = self._next_dt(t_end - self.state.time, speed)
                self.solver.step(self.state, self._spare, self.control, dt, check=False, reach=reach)
                self.state, self._spare = self._spare, self.state
                self.steps += 1
                dts.append(dt)
                if callback is not None:
                    callback(self)
            problem = self.solver.close_window()
        except SimulationError as exc:
            if not dts:  # refused at the window's start: the state it refused is the checked one, keep it
                self.solver.forget_bounds()
                raise
            problem = str(exc)
        except BaseException:  # Ctrl-C, SIGTERM, a callback's error: keep the window's first (checked) state
            self._rewind(steps0)
            raise
        if problem is None and self.fixed_dt is None:
            # the time step was fixed for the window from the speed at its start; the speeds it reached must
            # not have needed a step shorter than the one taken (Courant number (c + |v|) dt / dx at most 1)
            if (self._wave_speed + self.solver.last_max_speed()) * max(dts) > self.model.dx:
                problem = "the speeds reached needed a shorter time step"
        if problem is None:
            return
        self.reruns += 1
        t_window = self.state.time
        self._rewind(steps0)
        while self.state.time < t_window - eps:  # the same span again, each step checked (and its dt adapted)
            self._step(self._next_dt(t_window - self.state.time))
            if callback is not None:
                callback(self)

    def _rewind(self, steps: int) -> None:
        """Back to the first state of the current check window (``steps`` steps taken then)."""
        self.state.assign(self._checkpoint)
        self.steps = steps
        self.solver.forget_bounds()

    def kinetic_energy(self) -> tuple[float, float]:
        """(kinetic energy in J, largest particle speed in m/s) of the current state (host read-back)."""
        v = self.state.v.numpy().astype(np.float64)
        m = self.model.host["mass"]
        sq = np.einsum("ni,ni->n", v, v)
        free = self.model.host["clamped"] == 0
        return 0.5 * float(np.dot(m[free], sq[free])), float(np.sqrt(sq[free].max(initial=0.0)))

    def relax(
        self,
        energy_tol: float = 1e-6,
        speed_tol: float = 1e-3,
        max_steps: int = 1_000_000,
        viscous: bool = False,
        cfl: float | None = None,
        patience: int = 50,
        callback: Callable | None = None,
    ) -> RelaxResult:
        """Static equilibrium under the loads of the current time (fields and collider paths frozen there) by
        dynamic relaxation with kinetic damping: the explicit steps run undamped (``viscous=False`` turns the
        scene's grid damping off for the relaxation), and whenever the kinetic energy of the free particles
        passes a peak every particle velocity and affine matrix is set to zero. A peak of a freely moving body
        lies where its potential energy is lowest along the path, so each reset removes the energy of the
        motion at the point nearest the equilibrium.

        Converged when a cycle between two resets peaks below ``energy_tol`` times the largest kinetic energy
        seen and its largest particle speed is below ``speed_tol`` times the largest speed seen (relative, so
        the criterion is independent of units and of the load's size: 1e-6 in energy is 1e-3 of the largest
        velocity amplitude). If ``patience`` cycles in a row peak no lower than the lowest peak so far, the
        peaks have levelled off: below sqrt(``energy_tol``) of the largest kinetic energy that is the floor
        set by round-off (float32 forces of a stiff body under a small load) and the relaxation stops with
        ``stalled=True`` (``converged=False``); above it the motion is not dying out and it stops with neither.
        Time steps are the scene's (fixed, or the automatic CFL bound with the safety factor ``cfl``, default
        the scene's); the simulated time is not advanced. Precision: float64 (:func:`prepare_relax`); a Simulation
        built in float32 that has not stepped is rebuilt so, keeping its state (one that has stepped relaxes in
        float32, noted). Returns a :class:`RelaxResult`; a SimulationError
        (invalid state) propagates."""
        self._check_explicit()
        if self.model.np_scalar != np.float64 and not self.steps:
            self._rebuild(prepare_relax)  # float64, as magsoro run --equilibrium (prepare_relax)
        elif self.model.np_scalar != np.float64:
            self._note("relax: this simulation has taken steps in float32, so it relaxes in float32, whose round-off "
                       "may stall short of the equilibrium (build it with simulation.precision = 'float64')")
        settings = self.solver.settings
        damping, profile, cfl0 = settings.damping, settings.damping_profile, settings.cfl
        if cfl is not None:
            if not 0.0 < cfl <= 1.0:
                raise ValueError(f"relax: cfl must be in (0, 1], got {cfl!r}")
            settings.cfl = float(cfl)
        if not viscous:
            settings.damping, settings.damping_profile = 0.0, None
        t_freeze = self.state.time
        wall0 = _time.perf_counter()
        prev_e, prev_v = 0.0, 0.0
        e_max = v_max = 0.0
        resets, steps = 0, 0
        peak = (0.0, 0.0)
        converged = stalled = levelled = False
        lowest, since_lowest = math.inf, 0
        n_colliders = len(self.control.colliders)
        if n_colliders:  # the colliders' forces are measured over the last cycle (collider_forces)
            self.collider_forces()
            self._take_impulse(n_colliders)
        cycle = 0.0  # pseudo-time of the current kinetic-energy cycle, s
        try:
            while steps < max_steps:
                dt = self._next_dt(math.inf)
                self._step(dt)
                self.state.time = t_freeze
                steps += 1
                cycle += dt
                e, v = self.kinetic_energy()
                if e < prev_e:  # the previous step was a kinetic-energy peak
                    self.state.v.zero_()
                    self.state.C.zero_()
                    if n_colliders and cycle > 0.0:
                        self._collider_force = self._take_impulse(n_colliders) / cycle
                        cycle = 0.0
                    resets += 1
                    peak = (prev_e, prev_v)
                    e_max, v_max = max(e_max, prev_e), max(v_max, prev_v)
                    prev_e, prev_v = 0.0, 0.0
                    if peak[0] <= energy_tol * e_max and peak[1] <= speed_tol * v_max:
                        converged = True
                        break
                    if peak[0] < lowest:
                        lowest, since_lowest = peak[0], 0
                    else:
                        since_lowest += 1
                        if since_lowest >= patience:
                            stalled = lowest <= math.sqrt(energy_tol) * e_max
                            levelled = True
                            break
                elif e == 0.0 and e_max == 0.0 and steps >= 2:  # nothing moves: already in equilibrium
                    converged = True
                    break
                else:
                    prev_e, prev_v = e, v
                if callback is not None:
                    callback(self)
        finally:
            settings.damping, settings.damping_profile, settings.cfl = damping, profile, cfl0
            if n_colliders:
                # the last complete cycle's forces were read at its peak; without one, those of the steps taken
                rest = self._take_impulse(n_colliders)
                if resets == 0 and cycle > 0.0:
                    self._collider_force = rest / cycle
                self._impulse_time = self.state.time
        wall = _time.perf_counter() - wall0
        if converged:
            msg = f"equilibrium after {steps} steps and {resets} kinetic-energy resets"
        elif stalled:
            msg = (f"kinetic-energy peaks stopped falling after {steps} steps at {lowest / max(e_max, 1e-300):.2e} of "
                   f"the largest (tolerance {energy_tol:g}): the round-off floor of this precision; "
                   f"simulation.precision = 'float64' goes lower")
        elif levelled:
            msg = (f"no equilibrium: the kinetic-energy peaks levelled off after {steps} steps at "
                   f"{lowest / max(e_max, 1e-300):.2e} of the largest, too high for round-off; the loads keep the "
                   f"body moving (a contact or field that does not let it settle)")
        else:
            msg = (f"no equilibrium within {max_steps} steps: last cycle peaked at {peak[0] / max(e_max, 1e-300):.2e} "
                   f"of the largest kinetic energy (tolerance {energy_tol:g})")
        return RelaxResult(converged, steps, resets, peak[0], peak[1], e_max, v_max, wall, msg, stalled)

    def run(
        self,
        duration: float | None = None,
        callback: Callable | None = None,
        record: Callable | None = None,
        record_every: float | None = None,
        progress: Callable | None = None,
        heartbeat: Callable | None = None,
    ) -> RunResult:
        """Run for ``duration`` seconds (default: the scene's). ``callback(sim)`` is called after every step (which
        keeps a window's steps in the plain step loop), ``heartbeat(sim)`` after every check window,
        ``record(sim)`` at t = 0 and every ``record_every`` seconds (default: output.every or duration / 50),
        ``progress(sim)`` after each record. SimulationError and KeyboardInterrupt end the run with status
        'failed' / 'interrupted'; the state kept is then the last good one. An OutputError raised by ``record``
        or ``callback`` (a result that could not be written) ends it 'failed' with that reason."""
        duration = self.scene.simulation.duration if duration is None else float(duration)
        every = check_run_length(duration, record_every or self.scene.output.every)
        t0 = self.state.time
        t_end = t0 + duration
        wall0 = _time.perf_counter()
        n_records = int(math.floor(duration / every + 1e-9))
        targets = [t0 + k * every for k in range(1, n_records + 1)]
        if not targets or targets[-1] < t_end - 1e-12 * max(1.0, t_end):
            targets.append(t_end)
        status, message, signum = "completed", "", None
        columns = ["time"] + self.probe_columns()
        rows = []
        try:
            rows.append(self._metrics_row(columns))
            if record is not None:
                record(self)
            for target in targets:
                self.advance_to(target, callback, heartbeat)
                self.last_good_time = self.state.time
                rows.append(self._metrics_row(columns))
                if record is not None:
                    record(self)
                if progress is not None:
                    progress(self)
        except SimulationError as exc:
            status = "failed"
            message = f"step {exc.step}, t = {exc.time:.6g} s: {exc}"
        except OutputError as exc:
            status = "failed"
            message = f"output at t = {self.state.time:.6g} s: {exc}"
        except KeyboardInterrupt as exc:
            status = "interrupted"
            signum = exc.signum if isinstance(exc, Terminated) else None
            who = str(exc) if signum is not None else "interrupted by the user"
            message = f"{who} at t = {self.state.time:.6g} s"
        return RunResult(status, self.steps, self.state.time, _time.perf_counter() - wall0, message, signum,
                         metrics_table(columns, rows))

    def _metrics_row(self, columns: list[str]) -> list[float]:
        """The current time (s) or level and the probe values, in the order of ``columns`` (a metrics.csv row)."""
        values = self.probe_values()
        return [self.state.time] + [values[c] for c in columns[1:]]
