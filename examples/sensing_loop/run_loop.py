"""Closed shape-sensing loop in MPM: bend a magnetic-tip robot from 0 to 90 degrees, read its Hall sensor,
reconstruct the tip with ``magsoro sense`` (seed 004 eqs 17-23) and compare with the MPM tip.

    python examples/sensing_loop/run_loop.py --out DIR [--quick] [--dx M]

The scene, sensing_tip.toml, describes the robot and the station; README.md says why the station looks the way
it does. For each bend the robot is solved to static equilibrium under the field of the scene's ramp at a chosen
time (Simulation.solve_static: Newton on the engine's own discretisation, each bend from the one before). Then:

- sensor: the camera cable is anchored at the clamp face, does not stretch, and follows the deformed material
  line y = y_cable (the channel). The sensor sits at cable length L_S from the anchor. Its axis is the cable's
  normal there;
- reading: B_z = (B_total - B_applied) . n. B_total is Simulation.field_at at the sensor: the applied field
  plus the field of the bodies' magnetisation, computed by the engine's lattice-of-dipoles FFT, the same call
  a field probe makes. B_applied is the scene's sources evaluated exactly at the same point; subtracting it is
  what the real device's calibration does;
- truth: the neutral fibre (the marker's line, y = y_marker) and the tip probe, the mean position of the
  particles at the robot's end on that line.

Calibrations. "operator" follows seed 004 sec III-E: B0 is the straight reading (measured after fabrication),
and the lever arm comes from the bend near 90 degrees (calibrate_lever_arm, the +-90 degree procedure; the
reading is even in the bend, so +90 and -90 give the same point). "geometry" is calib.toml next to this file:
B0 is the exact 2D field of the marker (a uniformly magnetised rectangle), h is the cable-marker distance, and
d = h L_S / L_R. One station senses the slide over the first L_S of the robot, and under constant curvature the
whole robot bends L_R / L_S times as much.

Writes into DIR: readings.csv (t, hall: B_z in T, the format ``magsoro sense`` reads), truth.csv (t, s, x, y,
z: the MPM neutral fibre), calib.toml (operator calibration), sense/ and sense_geometry/ (``magsoro sense``
output with each calibration, with --truth), loop.csv (one row per bend: MPM and reconstructed tips,
errors, station diagnostics), loop.png and summary.json. Prints the largest tip error.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SCENE = HERE / "sensing_tip.toml"
GEOMETRY_CALIB = HERE / "calib.toml"
COLUMN = "hall"  # the station's column in readings.csv (calib.toml names it)

#: bend angles (degrees) the field levels aim at, after a first small field level (FIRST_FRACTION of the
#: ramp), which gives a bend of a few degrees: the dead zone of the sensor (seed 004 sec V)
TARGETS = {"full": (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0),
           "quick": (15.0, 30.0, 45.0, 60.0, 75.0, 90.0)}
FIRST_FRACTION = 0.02
TIP_BOUND = 1e-3  # m: issue acceptance, reconstructed tip within 1 mm of the MPM tip over 0-90 degrees
SETTLED = 0.2e-6  # m: with dynamic relaxation, a bend is static once another relaxation moves the tip less
MAX_RELAXATIONS = 5
LAST_TOLERANCE_DEG = 1.0  # the last level (the 90 degree calibration bend) is aimed again if it misses by more


# ------------------------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class StationGeometry:
    """Where the station is, read from the scene (m; reference configuration)."""

    x_base: float  # clamp face: the cable's anchor and the segment's base
    y_cable: float  # the material line the cable follows (the "station" probe's row)
    y_neutral: float  # the marker's line, the neutral fibre by design (tip probe row)
    cable_length: float  # L_S: anchor to sensor along the cable
    robot_length: float  # L_R: base to the tip probe along the neutral fibre
    marker_size: tuple[float, float]  # (along the robot, across), m
    marker_remanence: float  # T, along the sensor axis

    @property
    def gap(self) -> float:
        """h: sensor to marker centre along the sensor axis."""
        return abs(self.y_cable - self.y_neutral)

    @property
    def lever_arm(self) -> float:
        """d: cable to neutral fibre; the marker sits on the neutral fibre, so d = h (seed 004 eq 22)."""
        return abs(self.y_cable - self.y_neutral)

    def marker_field_2d(self, offset):
        """B_z (T) of the marker as the 2D engine sees it, at lateral ``offset`` rho (m) and distance h: a uniformly
        magnetised slab (w x t, Br across, infinitely deep). Its pole faces are strips of charge +-Br/mu0, width
        w = 2a; a strip gives B_z = Br/(2 pi) [atan((a - rho)/z) + atan((a + rho)/z)] at distance z, and the
        faces are at z = h -+ t/2. Seed 004 eq 18 is the 3D point dipole instead."""
        w, t = self.marker_size
        h, a = self.gap, w / 2
        rho = np.asarray(offset, dtype=float)

        def strip(z):
            return np.arctan((a - rho) / z) + np.arctan((a + rho) / z)

        return self.marker_remanence / (2 * math.pi) * (strip(h - t / 2) - strip(h + t / 2))

    def peak_field_2d(self) -> float:
        """B0 (T): :meth:`marker_field_2d` aligned (rho = 0)."""
        return float(self.marker_field_2d(0.0))


def station_geometry(scene) -> StationGeometry:
    bodies = {b.name: b for b in scene.bodies}
    probes = {p.name: p for p in scene.probes}
    marker, station, tip = bodies["marker"], probes["station"], probes["tip"]
    clamp = scene.clamps[0].region
    x_base = clamp.center[0] + clamp.size[0] / 2
    br = np.asarray(marker.magnetization, dtype=float)
    geo = StationGeometry(
        x_base=x_base,
        y_cable=station.region.center[1],
        y_neutral=tip.region.center[1],
        cable_length=station.region.center[0] - x_base,
        robot_length=tip.region.center[0] - x_base,
        marker_size=(marker.shape.size[0], marker.shape.size[1]),
        marker_remanence=float(br[1]),
    )
    # the station faces its marker at rest and the marker sits on the tip probe's line (the neutral fibre)
    assert abs(marker.shape.center[0] - station.region.center[0]) < 1e-9
    assert abs(marker.shape.center[1] - geo.y_neutral) < 1e-9
    assert br[0] == 0 and br[1] > 0, "the marker is magnetised along +y, the sensor axis at rest"
    return geo


# ------------------------------------------------------------------------------------------- the loop
def _polar_angle(F_mean: np.ndarray) -> float:
    """Rotation angle (rad) of the polar decomposition of a 2x2 deformation gradient."""
    u, _, vt = np.linalg.svd(F_mean)
    r = u @ vt
    return float(np.arctan2(r[1, 0], r[0, 0]))


class Loop:
    """The simulation and the particle sets the station is measured on."""

    def __init__(self, quick: bool, scene_path: Path = SCENE, dx: float | None = None):
        from magsoro.scene.load import apply_preview, parse_scene, read_scene_toml
        from magsoro.simulation import Simulation

        data = read_scene_toml(scene_path)
        if quick:
            data = apply_preview(data, str(scene_path))
        if dx is not None:
            data["simulation"]["dx"] = float(dx)
        self.scene = parse_scene(data, str(scene_path), Path(scene_path).parent)
        self.sim = Simulation(self.scene, source=str(scene_path))
        if self.sim.dim != 2:
            raise SystemExit("run_loop.py expects the 2D scene")
        self.geo = station_geometry(self.scene)
        sim, geo = self.sim, self.geo
        self.spacing = sim.model.dx / self.scene.simulation.particles_per_cell
        self.X = sim.model.host["positions"].astype(np.float64)
        body = sim.model.host["body"]
        bid = {n: i for i, n in enumerate(sim.built.body_names)}
        near = 0.6 * self.spacing  # the particle rows nearest a line (rows sit symmetrically about it)
        X = self.X
        self.cable_rows = np.flatnonzero((body == bid["core"]) & (np.abs(X[:, 1] - geo.y_cable) < near)
                                         & (X[:, 0] < geo.x_base + geo.cable_length + 1e-3))
        self.neutral_rows = np.flatnonzero(np.isin(body, [bid["wall"], bid["marker"]])
                                           & (np.abs(X[:, 1] - geo.y_neutral) < near)
                                           & (X[:, 0] > geo.x_base) & (X[:, 0] < geo.x_base + geo.robot_length))
        self.marker = np.flatnonzero(body == bid["marker"])
        # the far end of the magnet cap on the neutral fibre: the last two particle columns of the wall
        wall = next(b for b in self.scene.bodies if b.name == "wall")
        wall_end = wall.shape.center[0] + wall.shape.size[0] / 2
        self.cap_end = np.flatnonzero((body == bid["wall"]) & (np.abs(X[:, 1] - geo.y_neutral) < near)
                                      & (X[:, 0] > wall_end - 2 * self.spacing))
        self.cap_length = float(X[self.cap_end, 0].mean() - geo.x_base - geo.robot_length)  # tip to cap end
        probes = {p.name: p for p in sim.probes}
        self.tip, self.station = probes["tip"].indices, probes["station"].indices
        ref_tip = X[self.tip].mean(axis=0)
        assert abs(ref_tip[0] - geo.x_base - geo.robot_length) < 1e-9 and abs(ref_tip[1] - geo.y_neutral) < 1e-9
        self.static = sim.solver.interaction is None  # the Newton solver; else dynamic relaxation (solve_at)
        self.effort = "Newton iterations" if self.static else "relaxation steps"
        if len(sim.control.sources) != 1:
            raise SystemExit("run_loop.py expects one uniform field source (the ramp)")
        source = sim.control.sources[0]
        b_full = np.asarray(source.B(np.zeros((1, 3)), 1.0), dtype=float).ravel()
        self.field_max = float(np.hypot(b_full[0], b_full[1]))  # T, at the end of the ramp
        self.field_angle = float(np.arctan2(b_full[1], b_full[0]))  # rad from the robot axis

    # -- geometry of the current state ----------------------------------------------------------------
    def _line(self, rows: np.ndarray, x: np.ndarray):
        """(reference arc position (K,), current points (K, 2)) of a material line: its rows averaged per column."""
        cols = np.round(self.X[rows, 0] / self.spacing * 2).astype(np.int64)
        order = np.unique(cols)
        s = np.array([self.X[rows[cols == c], 0].mean() for c in order]) - self.geo.x_base
        p = np.array([x[rows[cols == c]].mean(axis=0) for c in order])
        return s, p

    def sensor(self, x: np.ndarray):
        """Position (2,) and axis (2,) of the Hall sensor: the point at cable length L_S along the deformed cable
        line from its anchor (the line's point at the clamp face); the axis is the cable's normal there."""
        s, p = self._line(self.cable_rows, x)
        k = int(np.searchsorted(s, 0.0))
        anchor = p[k - 1] + (0.0 - s[k - 1]) / (s[k] - s[k - 1]) * (p[k] - p[k - 1])
        poly = np.vstack([anchor, p[k:]])
        seg = np.diff(poly, axis=0)
        length = np.linalg.norm(seg, axis=1)
        arc = np.concatenate([[0.0], np.cumsum(length)])
        j = int(np.searchsorted(arc, self.geo.cable_length)) - 1
        point = poly[j] + (self.geo.cable_length - arc[j]) / length[j] * seg[j]
        tangent = seg[j] / length[j]
        return point, np.array([-tangent[1], tangent[0]])

    def applied(self, point: np.ndarray) -> np.ndarray:
        """The scene's sources at ``point`` now (T, (3,)), evaluated exactly."""
        sim = self.sim
        p3 = np.array([[point[0], point[1], sim.solver.settings.plane_z]])
        return sum(np.asarray(s.B(p3, sim.time), dtype=float).reshape(3) for s in sim.control.sources)

    def measure(self) -> dict:
        sim, geo = self.sim, self.geo
        x = sim.state.x.numpy().astype(np.float64)
        F = sim.state.F.numpy().astype(np.float64)
        point, axis = self.sensor(x)
        bodies_field = sim.field_at(point[None])[0] - self.applied(point)
        reading = float(bodies_field[:2] @ axis)
        # the slide: sensor relative to the marker centre along the sensor's tangent (model: d beta_S, beta_S the
        # rotation of the marker's cross-section)
        offset = point - x[self.marker].mean(axis=0)
        tangent = np.array([axis[1], -axis[0]])
        # control: a sensor glued to the material point facing the marker at rest, turning with the body there
        values = sim.probe_values()
        glued_at = x[self.station].mean(axis=0)
        glued_field = np.array([values[f"station_B{a}"] for a in "xyz"]) - self.applied(glued_at)
        glued_angle = _polar_angle(F[self.station].mean(axis=0))
        glued = float(glued_field[0] * -math.sin(glued_angle) + glued_field[1] * math.cos(glued_angle))
        s, p = self._line(self.neutral_rows, x)
        tip = x[self.tip].mean(axis=0)
        base = np.array([geo.x_base, geo.y_neutral])  # clamped
        return {
            "t": sim.time,
            "field": self.field_max * min(sim.time, 1.0),
            "bend": _polar_angle(F[self.tip].mean(axis=0)),
            "station_bend": _polar_angle(F[self.marker].mean(axis=0)),  # beta_S: the cross-section at L_S
            "reading": reading,
            "glued": glued,
            "slide": float(offset @ tangent),
            "gap": float(offset @ axis),
            "tip": tip,
            "cap_end": x[self.cap_end].mean(axis=0),
            "centreline_s": np.concatenate([[0.0], s, [geo.robot_length]]),
            "centreline": np.vstack([base, p, tip]),
        }

    def solve_at(self, fraction: float) -> int:
        """Static equilibrium under the field of the scene's ramp at time ``fraction`` (B = fraction x 25 mT), from
        the current state; returns the Newton iterations (or relaxation steps).

        The engine's Newton solver (Simulation.solve_static, ``magsoro run --static``) does it. It has no
        magnetic interaction between bodies yet, so a scene variant with ``magnetic_interaction = "dipole"``
        is relaxed dynamically instead (Simulation.relax, kinetic damping). Kinetic damping zeroes every
        velocity at each kinetic-energy peak, so the magnet cap's fast local mode can freeze the slow bending
        mode short of equilibrium while the relaxation reports convergence (measured: 5 % short on the first
        bend). The relaxation is therefore repeated until the tip moves less than SETTLED between two of them."""
        sim = self.sim
        if self.static:
            result = sim.solve_static(levels=[1.0], t=float(fraction))
            if not result.converged:
                raise RuntimeError(f"static solve at t = {fraction:.4g} failed: {result.message}")
            return sum(level.iterations for level in result.levels)
        sim.state.time = float(fraction)
        steps, before = 0, sim.state.x.numpy()[self.tip].astype(np.float64).mean(axis=0)
        for attempt in range(MAX_RELAXATIONS):
            steps += sim.relax(cfl=0.8).steps
            after = sim.state.x.numpy()[self.tip].astype(np.float64).mean(axis=0)
            if attempt > 0 and np.linalg.norm(after - before) < SETTLED:
                return steps
            before = after
        raise RuntimeError(f"relaxation at t = {fraction:.4g} still moved the tip after {MAX_RELAXATIONS} rounds")


def sweep(loop: Loop, targets, log=print) -> list[dict]:
    """Straight state, then a small field level, then levels aimed at ``targets`` (degrees): each from the
    couple balance k beta = f sin(psi - beta) (f: fraction of the ramp, psi: field angle) with k taken from the
    level before, so the levels land near the targets."""
    rows = []
    t0 = time.perf_counter()
    loop.sim.state.time = 0.0
    rows.append({**loop.measure(), "iterations": 0, "wall": 0.0})
    fraction, stiffness = FIRST_FRACTION, None  # stiffness: from the first level on
    for target in [None, *targets]:
        if target is not None:
            beta = math.radians(target)
            fraction = stiffness * beta / math.sin(loop.field_angle - beta)
            if fraction > 1.0:
                log(f"  the {target:g} degree bend needs {fraction:.3g} of the ramp; holding at its end")
                fraction = 1.0
        w0 = time.perf_counter()
        iterations = loop.solve_at(fraction)
        row = {**loop.measure(), "iterations": iterations, "wall": time.perf_counter() - w0}
        rows.append(row)
        stiffness = fraction * math.sin(loop.field_angle - row["bend"]) / row["bend"]
        log(f"  B = {1e3 * row['field']:6.3f} mT: bend {math.degrees(row['bend']):6.2f} deg, reading "
            f"{1e3 * row['reading']:.4f} mT, {iterations} {loop.effort}, {row['wall']:.1f} s "
            f"(total {time.perf_counter() - t0:.0f} s)")
    # the last bend is the operator's 90 degree calibration: aim again, with k from the bend that missed
    beta = math.radians(targets[-1])
    if abs(math.degrees(beta - rows[-1]["bend"])) > LAST_TOLERANCE_DEG and rows[-1]["t"] < 1.0:
        fraction = stiffness * beta / math.sin(loop.field_angle - beta)
        w0 = time.perf_counter()
        iterations = loop.solve_at(min(fraction, 1.0))
        rows.append({**loop.measure(), "iterations": iterations, "wall": time.perf_counter() - w0})
        log(f"  B = {1e3 * rows[-1]['field']:6.3f} mT: bend {math.degrees(rows[-1]['bend']):6.2f} deg (aimed again at "
            f"{targets[-1]:g}), reading {1e3 * rows[-1]['reading']:.4f} mT, {iterations} {loop.effort}")
    return rows


# ------------------------------------------------------------------------------------------- files
def write_readings(path: Path, rows) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", COLUMN])
        for r in rows:
            w.writerow([f"{r['t']:.9g}", f"{r['reading']:.12e}"])


def write_truth(path: Path, rows) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "s", "x", "y", "z"])
        for r in rows:
            for s, (x, y) in zip(r["centreline_s"], r["centreline"]):
                w.writerow([f"{r['t']:.9g}", f"{s:.9e}", f"{x:.9e}", f"{y:.9e}", "0"])


def operator_calibration(geo: StationGeometry, rows, template: dict) -> tuple[dict, dict]:
    """Seed 004 sec III-E: B0 measured straight, the lever arm from the bend closest to 90 degrees. Returns the
    calibration (``template`` with those two values) and the row it was calibrated on."""
    from magsoro.actuation.sensing import SensingStation, calibrate_lever_arm

    straight = rows[0]
    cal = min(rows[1:], key=lambda r: abs(r["bend"] - math.pi / 2))
    station = SensingStation(geo.robot_length, straight["reading"], geo.gap, column=COLUMN)
    lever = calibrate_lever_arm(station, [cal["bend"]], [cal["reading"]])
    data = json.loads(json.dumps(template))
    data["name"] = "sensing loop: operator calibration (B0 straight, lever arm at 90 degrees)"
    data["stations"][0].update(peak_field=straight["reading"], lever_arm=lever)
    return data, cal


def model_floor(geo: StationGeometry, bends, calibration_bend: float) -> tuple[list[float], float]:
    """Tip errors (m) the loop would give with exact mechanics, and the lever arm (m) the operator calibration
    would find. The robot is an exact constant-curvature arc,
    the cable slides exactly d beta L_S / L_R, and the gap stays h. The readings are the closed-form 2D marker
    field, calibrated the operator's way. What is left is the gap between the engine's 2D slab field and seed
    004 eq 20, the floor the MPM loop converges to as dx shrinks."""
    from magsoro.actuation.sensing import (
        SensingStation,
        calibrate_lever_arm,
        reconstruct_centreline,
    )

    bends = np.asarray(bends, dtype=float)
    b0 = geo.peak_field_2d()

    def reading(beta):
        return geo.marker_field_2d(geo.lever_arm * np.asarray(beta) * geo.cable_length / geo.robot_length)

    station = SensingStation(geo.robot_length, b0, geo.gap)
    lever = calibrate_lever_arm(station, [calibration_bend], [reading(calibration_bend)])
    sensed = SensingStation(geo.robot_length, b0, geo.gap, lever).bend_angle(reading(bends))
    _, true_pts = reconstruct_centreline(bends[:, None], [geo.robot_length], 2)
    _, sensed_pts = reconstruct_centreline(sensed[:, None], [geo.robot_length], 2)
    return np.linalg.norm(sensed_pts[:, -1] - true_pts[:, -1], axis=1).tolist(), float(lever)


def run_sense(readings: Path, calib: Path, out: Path, truth: Path) -> dict:
    cmd = [sys.executable, "-m", "magsoro", "sense", str(readings), "--calib", str(calib), "--out", str(out),
           "--truth", str(truth), "--json"]
    done = subprocess.run(cmd, check=False, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"magsoro sense failed ({done.returncode}): {done.stderr.strip()}")
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    with (out / "angles.csv").open() as fh:
        angles = list(csv.DictReader(fh))
    summary["beta"] = [float(a[f"beta_{COLUMN}"]) for a in angles]
    summary["tips"] = np.array([[float(a["tip_x"]), float(a["tip_y"])] for a in angles])
    return summary


def plot(path: Path, rows, sensed: dict, geo: StationGeometry, lever: float, floor) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from magsoro.actuation.sensing import normalised_ratio, read_centrelines

    bend = np.degrees([r["bend"] for r in rows])
    b0 = rows[0]["reading"]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.6))
    cmap = plt.get_cmap("viridis")
    for k, r in enumerate(rows):
        c = cmap(k / max(1, len(rows) - 1))
        ax[0].plot(1e3 * r["centreline"][:, 0], 1e3 * r["centreline"][:, 1], color=c, lw=2.5, alpha=0.45)
        tip = sensed["operator"]["tips"][k]
        ax[0].plot(1e3 * tip[0], 1e3 * tip[1], "x", color=c, ms=8)
    for _, p in read_centrelines(sensed["operator"]["dir"] / "centreline.csv").values():
        ax[0].plot(1e3 * p[:, 0], 1e3 * p[:, 1], "k--", lw=0.8)
    ax[0].set_aspect("equal")
    ax[0].set_xlabel("x [mm]")
    ax[0].set_ylabel("y [mm]")
    ax[0].set_title("MPM neutral fibre (thick), reconstruction (dashed, x: tip)")
    grid = np.linspace(0, max(bend.max(), 90), 200)
    ax[1].plot(bend, [r["reading"] / b0 for r in rows], "o", label="sliding sensor on the cable (MPM)")
    ax[1].plot(bend, [r["glued"] / rows[0]["glued"] for r in rows], "s", mfc="none",
               label="sensor glued to the body (control)")
    ax[1].plot(grid, normalised_ratio(lever * np.radians(grid) / geo.gap), "-",
               label=f"seed 004 eq 20, d = {1e3 * lever:.3f} mm (operator)")
    ax[1].set_xlabel("MPM bend angle [deg]")
    ax[1].set_ylabel("q = B_z / B0")
    ax[1].legend(fontsize=8)
    for name, style in (("operator", "o-"), ("geometry", "s--")):
        ax[2].plot(bend, 1e3 * np.asarray(sensed[name]["errors"]), style, label=f"{name} calibration")
    ax[2].plot(bend, 1e3 * np.asarray(floor), "k:", label="exact mechanics, operator calibration (2D field vs eq 20)")
    ax[2].axhline(1e3 * TIP_BOUND, color="r", lw=1, label="1 mm acceptance")
    ax[2].set_xlabel("MPM bend angle [deg]")
    ax[2].set_ylabel("|reconstructed - MPM tip| [mm]")
    ax[2].set_ylim(bottom=0)
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(out, quick: bool = False, log=print, scene: Path = SCENE, dx: float | None = None) -> dict:
    """The whole loop into folder ``out``; returns the summary (also written as summary.json). ``quick``: the
    scene's [preview] grid and fewer bends; ``scene``: a variant of sensing_tip.toml (same body and probe names);
    ``dx``: another grid spacing, m. Use dx = 0.6 mm / n for an integer n (0.3, 0.2, 0.15, 0.1 mm): with two
    particles per cell, that keeps the scene's boundaries (multiples of 0.3 mm) between particle rows and its
    regions centred on them."""
    from magsoro.actuation.config import SensingCalibration, load
    from magsoro.io.tomlwrite import dumps
    from magsoro.io.files import read_toml_file

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    wall0 = time.perf_counter()
    loop = Loop(quick, Path(scene), dx)
    geo = loop.geo
    mode = "quick" if quick else "full"
    log(f"sensing loop ({mode}): {loop.sim.model.n_particles} particles, dx = {1e3 * loop.sim.model.dx:g} mm; "
        f"station at L_S = {1e3 * geo.cable_length:g} mm of L_R = {1e3 * geo.robot_length:g} mm, "
        f"gap h = {1e3 * geo.gap:g} mm")
    rows = sweep(loop, TARGETS[mode], log)
    sweep_wall = time.perf_counter() - wall0

    readings, truth = out / "readings.csv", out / "truth.csv"
    write_readings(readings, rows)
    write_truth(truth, rows)
    template = read_toml_file(GEOMETRY_CALIB, RuntimeError)
    load(SensingCalibration, GEOMETRY_CALIB)  # the committed calibration is valid as it stands
    calib, cal_row = operator_calibration(geo, rows, template)
    header = "# written by run_loop.py: seed 004 operator calibration from the MPM run\n"
    (out / "calib.toml").write_text(header + dumps(calib))
    load(SensingCalibration, out / "calib.toml")
    sensed = {}
    for name, path, folder in (("operator", out / "calib.toml", out / "sense"),
                               ("geometry", GEOMETRY_CALIB, out / "sense_geometry")):
        s = run_sense(readings, path, folder, truth)
        s["dir"] = folder
        s["errors"] = [float(np.linalg.norm(tip - r["tip"])) for tip, r in zip(s["tips"], rows)]
        # the cap is not part of the sensed segment: append it straight along the reconstructed end tangent
        beta = np.asarray(s["beta"])
        ends = s["tips"] + loop.cap_length * np.stack([np.cos(beta), np.sin(beta)], axis=1)
        s["cap_errors"] = [float(np.linalg.norm(e - r["cap_end"])) for e, r in zip(ends, rows)]
        sensed[name] = s
    lever = calib["stations"][0]["lever_arm"]

    with (out / "loop.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "field_T", "bend_deg", "station_bend_deg", "slide_m", "slide_model_m", "gap_m",
                    "reading_T", "q", "q_glued", "beta_operator_deg", "beta_geometry_deg", "mpm_tip_x", "mpm_tip_y",
                    "rec_tip_x", "rec_tip_y", "tip_error_m", "rec_tip_geometry_x", "rec_tip_geometry_y",
                    "tip_error_geometry_m", "cap_end_error_m", "solver_iterations", "solve_wall_s"])
        for k, r in enumerate(rows):
            op, ge = sensed["operator"], sensed["geometry"]
            w.writerow([f"{r['t']:.6g}", f"{r['field']:.6e}", f"{math.degrees(r['bend']):.4f}",
                        f"{math.degrees(r['station_bend']):.4f}", f"{r['slide']:.6e}",
                        f"{geo.lever_arm * r['station_bend']:.6e}", f"{r['gap']:.6e}", f"{r['reading']:.9e}",
                        f"{r['reading'] / rows[0]['reading']:.6f}", f"{r['glued'] / rows[0]['glued']:.6f}",
                        f"{math.degrees(op['beta'][k]):.4f}", f"{math.degrees(ge['beta'][k]):.4f}",
                        f"{r['tip'][0]:.6e}", f"{r['tip'][1]:.6e}",
                        f"{op['tips'][k][0]:.6e}", f"{op['tips'][k][1]:.6e}",
                        f"{op['errors'][k]:.6e}", f"{ge['tips'][k][0]:.6e}", f"{ge['tips'][k][1]:.6e}",
                        f"{ge['errors'][k]:.6e}", f"{op['cap_errors'][k]:.6e}", r["iterations"], f"{r['wall']:.2f}"])

    floor, floor_lever = model_floor(geo, [r["bend"] for r in rows], cal_row["bend"])
    summary = {
        "mode": mode,
        "particles": int(loop.sim.model.n_particles),
        "dx_m": float(loop.sim.model.dx),
        "bend_deg": [math.degrees(r["bend"]) for r in rows],
        "tip_error_m": sensed["operator"]["errors"],
        "tip_error_geometry_m": sensed["geometry"]["errors"],
        "max_tip_error_m": max(sensed["operator"]["errors"]),
        "max_tip_error_geometry_m": max(sensed["geometry"]["errors"]),
        "tip_error_model_floor_m": floor,
        "cap_end_error_m": sensed["operator"]["cap_errors"],
        "cap_length_m": loop.cap_length,
        "centreline_rmse_m": sensed["operator"].get("rmse_m"),
        "peak_field_measured_T": rows[0]["reading"],
        "peak_field_2d_closed_form_T": geo.peak_field_2d(),
        "lever_arm_operator_m": lever,
        "lever_arm_geometry_m": geo.lever_arm * geo.cable_length / geo.robot_length,
        "lever_arm_exact_mechanics_m": floor_lever,
        "calibration_bend_deg": math.degrees(cal_row["bend"]),
        "slide_m": [r["slide"] for r in rows],
        "slide_model_m": [geo.lever_arm * r["station_bend"] for r in rows],
        "gap_m": [r["gap"] for r in rows],
        "q": [r["reading"] / rows[0]["reading"] for r in rows],
        "q_glued": [r["glued"] / rows[0]["glued"] for r in rows],
        "solver_iterations": [r["iterations"] for r in rows],  # Newton iterations (relaxation steps if dynamic)
        "sweep_wall_s": sweep_wall,
        "wall_s": time.perf_counter() - wall0,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot(out / "loop.png", rows, sensed, geo, lever, summary["tip_error_model_floor_m"])
    log(f"{'bend [deg]':>10} {'q':>8} {'tip error [mm]':>15} {'geometry calib [mm]':>20} "
        f"{'exact-mechanics floor [mm]':>27}")
    for b, q, e, g, f in zip(summary["bend_deg"], summary["q"], summary["tip_error_m"], summary["tip_error_geometry_m"],
                             summary["tip_error_model_floor_m"]):
        log(f"{b:10.2f} {q:8.5f} {1e3 * e:15.3f} {1e3 * g:20.3f} {1e3 * f:27.3f}")
    log(f"largest tip error: {1e3 * summary['max_tip_error_m']:.3f} mm (operator calibration), "
        f"{1e3 * summary['max_tip_error_geometry_m']:.3f} mm (geometry calibration); bound {1e3 * TIP_BOUND:g} mm")
    log(f"wall time {summary['wall_s']:.0f} s (sweep {sweep_wall:.0f} s); results in {out}")
    return summary


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--quick", action="store_true", help="coarser grid and fewer bends (the test's version)")
    p.add_argument("--scene", default=str(SCENE), help="scene file (default: sensing_tip.toml next to this script)")
    p.add_argument("--dx", type=float, help="grid spacing in m instead of the scene's (resolution check: 1.5e-4)")
    args = p.parse_args(argv)
    summary = run(args.out, quick=args.quick, scene=Path(args.scene), dx=args.dx)
    return 0 if summary["max_tip_error_m"] <= TIP_BOUND else 1


if __name__ == "__main__":
    sys.exit(main())
