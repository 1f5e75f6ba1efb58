"""Strip of periodic thickness pulled by a disc magnet (seed 000 sec 4.3, Fig 3): strain against the distance
to the magnet, against a one-dimensional bar model with the same (seed 000 eq 13, 15-16) magnetic energy.

The strip hangs from a clamp, magnetised along its length, on the axis of an axially magnetised disc magnet
below it, so the field is aligned with the magnetisation (seed 000: "no magnetic torque") and the field
gradient pulls the strip towards the magnet. The magnet comes closer in steps ("linear steps", seed 000). Fig 3
is a static curve: at each gap the strip's equilibrium comes from the static solver (Simulation.solve_static),
from the straight strip with the magnet held at that gap. Measured 2026-11-26 at the full grid (25596
particles): about 33 s per gap on this CPU, against 579 s for the dynamic sweep of the same gaps (ramps and
holds); at the preview grid the static strain at a 40 mm gap is 1.6 % below the engine's dynamic settling in
the scene's (total-Lagrangian) form and 0.9 % above the updated form's (tests/test_static_solver.py).
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass

import numpy as np

from magsoro.constants import MU0
from magsoro.robots.base import Context, FrameRecorder, ReproduceResult, Robot, RobotError, plot_curve, scene_data, simulation, write_csv
from magsoro.robots.continuum_soft import (
    Row, Schedule, StaticSweep, body_mask, body_material, drive, mape, settle_row, static_row,
)

NAME = "strip_magnet"


# -- one-dimensional bar model ---------------------------------------------------------------------------
def uniaxial_stress(shear_modulus: float, bulk_modulus: float, stretches) -> np.ndarray:
    """Nominal stress (Pa) of the engine's compressible Neo-Hookean solid (seed 000 eq 10, energy
    G/2 (J^-2/3 I1 - 3) + K/2 (J - 1)^2) in uniaxial tension with free lateral faces, for axial stretches."""
    from scipy.optimize import brentq

    G, K = shear_modulus, bulk_modulus
    out = []
    for lam in np.atleast_1d(stretches):
        def lateral(mu):
            J, I1 = mu * mu * lam, 2 * mu * mu + lam * lam
            return G * J ** (-2 / 3) * (mu - I1 / (3 * mu)) + K * J * (J - 1) / mu

        mu = brentq(lateral, 0.2, 2.0)
        J, I1 = mu * mu * lam, 2 * mu * mu + lam * lam
        out.append(G * J ** (-2 / 3) * (lam - I1 / (3 * lam)) + K * J * (J - 1) / lam)
    return np.array(out)


@dataclass(frozen=True)
class BarSection:
    """A stretch ``start`` <= Z < ``end`` (m below the clamp) of the bar with a rectangular cross-section
    ``thickness`` x ``width`` (m) centred on the magnet's axis."""

    start: float
    end: float
    thickness: float
    width: float


def bar_strain(sections: list[BarSection], magnet_at, remanence: float, shear_modulus: float, bulk_modulus: float,
               density: float, gravity: float = 9.81, nodes_per_section: int = 40, samples: int = 3,
               follows: str = "F"):
    """Equilibrium of a bar hanging from z = 0 along -z, magnetised along +z with ``remanence`` (T), in the field
    of ``magnet_at`` (a magsoro.fields source), for the engine's magnetic energy -(F Br) . B / mu0 per reference
    volume (seed 000 eqs 13, 15-16) and its Neo-Hookean solid. Per reference length Z:

        d/dZ [A (P(lambda) - Br Bz / mu0)] = -A (lambda Br dBz/dd / mu0 + rho g),   A (P - Br Bz / mu0) = 0 at the tip,

    d the depth below the clamp, P the uniaxial nominal stress (:func:`uniaxial_stress`); Bz and its gradient
    are averaged over ``samples`` x ``samples`` points of each cross-section. Solved by damped fixed-point
    iteration on lambda(Z). Returns (tip depth (m), section stretches (mean lambda per section)), or None when
    no equilibrium is found (the strip is pulled onto the magnet).

    ``follows`` "R" (material.magnetization_follows): the moment follows the rotation of F = R U, here R = I, so
    the energy is -Br Bz / mu0: the moment does not grow with lambda and there is no magnetic stress,
    d/dZ [A P(lambda)] = -A (Br dBz/dd / mu0 + rho g)."""
    if follows not in ("F", "R"):
        raise ValueError(f"follows must be 'F' or 'R', got {follows!r}")
    carried = 1.0 if follows == "F" else 0.0  # the power of lambda in the moment, and whether the stress is there
    lam_tab = np.linspace(0.5, 4.0, 701)
    P_tab = uniaxial_stress(shear_modulus, bulk_modulus, lam_tab)
    Z, dZ, A, sec_id, offs = [], [], [], [], []
    for k, s in enumerate(sections):
        n = nodes_per_section
        h = (s.end - s.start) / n
        Z.append(s.start + (np.arange(n) + 0.5) * h)
        dZ.append(np.full(n, h))
        A.append(np.full(n, s.thickness * s.width))
        sec_id.append(np.full(n, k))
        u = (np.arange(samples) + 0.5) / samples - 0.5
        ox, oy = np.meshgrid(u * s.thickness, u * s.width)
        offs.append(np.repeat(np.stack([ox.ravel(), oy.ravel()], 1)[None], n, axis=0))
    Z, dZ, A, sec_id, offs = (np.concatenate(a) for a in (Z, dZ, A, sec_id, offs))
    lam = np.ones_like(Z)
    npts = offs.shape[1]
    for _ in range(400):
        depth = np.cumsum(lam * dZ) - lam * dZ / 2
        pts = np.zeros((len(Z), npts, 3))
        pts[:, :, :2] = offs
        pts[:, :, 2] = -depth[:, None]
        flat = pts.reshape(-1, 3)
        Bz = magnet_at.B(flat)[:, 2].reshape(len(Z), npts).mean(axis=1)
        dBz_dd = -magnet_at.grad_B(flat)[:, 2, 2].reshape(len(Z), npts).mean(axis=1)
        f = A * (lam ** carried * remanence * dBz_dd / MU0 + density * gravity)
        T = np.cumsum((f * dZ)[::-1])[::-1] - f * dZ / 2
        target = T / A + carried * remanence * Bz / MU0
        if target.max() >= P_tab[-1]:
            return None
        new = np.interp(target, P_tab, lam_tab)
        if np.max(np.abs(new - lam)) < 1e-9:
            lam = new
            break
        lam = 0.5 * lam + 0.5 * new
    else:
        return None
    stretch = np.array([np.sum((lam * dZ)[sec_id == k]) / np.sum(dZ[sec_id == k]) for k in range(len(sections))])
    return float(np.sum(lam * dZ)), stretch


# -- this robot ------------------------------------------------------------------------------------------
#: gaps (m) between the magnet's face and the strip's undeformed free end; seed 000 gives none. The 1D bar model
#: has no equilibrium clear of the magnet below ~33 mm (pull-in), so the sweep stops at 37 mm.
GAPS = (0.07, 0.055, 0.045, 0.04, 0.037)
PREVIEW_GAPS = (0.055, 0.04)
FAR = 0.5                                  # m: magnet gap for the strip hanging under gravity alone
# the dynamic sweep (a scene the static solver refuses, e.g. magnetization_follows = "R"): the magnet rises gap by gap
SETTLE, RAMP, HOLD = 0.1, 0.03, 0.1        # s: gravity settling, magnet move, hold per distance
WINDOW = 0.02                              # s: settling check over the end of each hold
LENGTH = 0.1                               # m: free length of the strip below the clamp face z = 0


def _magnet(data: dict) -> dict:
    for f in data.get("fields", []):
        if f.get("type") == "cylinder_magnet":
            return f
    raise RobotError(f"{NAME}: the scene has no cylinder_magnet field")


def _sections(sim, names) -> list[BarSection]:
    """The bar sections of the parts ``names`` (from the clamp down) as the engine has them: the particles'
    extents along z and their cross-section (x by y extents, each particle a cube of side h)."""
    sc = sim.scene.simulation
    h = sc.dx / sc.particles_per_cell
    X = sim.model.host["positions"]
    out = []
    for n in names:
        p = X[body_mask(sim, n)]
        ext = p.max(axis=0) - p.min(axis=0) + h
        out.append(BarSection(float(-(p[:, 2].max() + h / 2)), float(-(p[:, 2].min() - h / 2)), float(ext[0]), float(ext[1])))
    return out


def _magnet_patch(half: float, diameter: float):
    """A function drawing the magnet (a grey rectangle in x-z) with its centre at height z_mm on a GIF frame."""
    def draw(ax, z_mm):
        import matplotlib.patches as mpatches

        d, hh = diameter * 1e3, half * 2e3
        ax.add_patch(mpatches.Rectangle((-d / 2, z_mm - hh / 2), d, hh, color="0.35", zorder=0))
    return draw


def _static_sweep(ctx: Context, sim, placed, gaps, centre, half: float, diameter: float, measure):
    """One equilibrium per gap (the static solver), each from the straight, unloaded strip with the magnet held at
    its gap (nothing here depends on the path: no friction, no contact). ``sim`` is the scene at gaps[0];
    ``placed(gap)`` gives the scene data at a gap. Returns (StaticSweep, FrameRecorder, the GIF's magnet patch)."""
    frame_gaps = [gaps[0]]  # the magnet's gap in each frame, the one being recorded last
    frames = FrameRecorder(axes=(0, 2), label=lambda s: f"magnet gap {frame_gaps[-1] * 1e3:.0f} mm (equilibrium)")
    sim.field_scale = 0.0
    frames.record(sim)  # the straight strip before gravity
    ctx.log(f"{NAME}: {sim.model.n_particles} particles, dx = {sim.scene.simulation.dx * 1e3:.3g} mm, "
            f"{len(gaps) - 1} distances, static solver")
    values, levels = [], []
    t0 = time.perf_counter()
    for k, g in enumerate(gaps):
        if k:
            sim = simulation(NAME, placed(g), preview=ctx.preview, device=ctx.device)
        res = sim.solve_static(levels=[1.0])
        if not res.converged:
            raise RobotError(f"{NAME}: static solve at a {g * 1e3:g} mm gap failed: {res.message}")
        values.append(measure(sim))
        levels.extend(res.levels)
        frame_gaps.append(g)
        frames.record(sim)
        ctx.log(f"  {NAME}: gap {g * 1e3:g} mm: length {values[-1]['length_mm']:.3f} mm "
                f"({res.levels[-1].iterations} Newton iterations, {time.perf_counter() - t0:.0f} s)")
    patch = _magnet_patch(half, diameter)
    # the far magnet is drawn just below the frame
    return (StaticSweep(values, levels, int(sim.model.n_particles), time.perf_counter() - t0), frames,
            lambda ax, k: patch(ax, centre(min(frame_gaps[k], 0.1))[2] * 1e3))


def _dynamic_sweep(ctx: Context, data: dict, gaps, centre, half: float, diameter: float, measure):
    """The engine's dynamics: the magnet waits at gaps[0] while the strip settles under gravity, then rises gap by
    gap, each held HOLD s, the strip read at the end of each hold. Returns (DriveResult, FrameRecorder, the GIF's
    magnet patch)."""
    times, values, reads, t = [0.0, SETTLE], [centre(gaps[0]), centre(gaps[0])], [SETTLE], SETTLE
    for g in gaps[1:]:
        t += RAMP
        times.append(t)
        values.append(centre(g))
        t += HOLD
        times.append(t)
        values.append(centre(g))
        reads.append(t)
    sched = Schedule(times, values, reads, list(gaps))
    path = {"times": sched.times, "positions": sched.values}
    _magnet(data)["path"] = path
    for c in data.get("colliders", []):
        if c.get("type") == "cylinder":
            c["path"] = path
    data["simulation"]["duration"] = sched.duration
    data.setdefault("output", {})["particles"] = False
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    frames = FrameRecorder(axes=(0, 2), label=lambda s: f"t = {s.time:.2f} s, magnet gap "
                                                        f"{(-sched.value_at(s.time)[2] - LENGTH - half) * 1e3:.0f} mm")
    frame_every = 0.01
    ctx.log(f"{NAME}: {sim.model.n_particles} particles, dx = {sim.scene.simulation.dx * 1e3:.3g} mm, "
            f"{len(gaps) - 1} distances, {sched.duration:.2f} s simulated")
    res = drive(sim, sched.reads, measure, WINDOW, frames, frame_every=frame_every, log=ctx.log, label=f"{NAME}: ")
    patch = _magnet_patch(half, diameter)
    return res, frames, lambda ax, k: patch(ax, sched.value_at(k * frame_every)[2] * 1e3)


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.errors import SimulationError
    from magsoro.fields import CylinderMagnet
    from magsoro.mpm.newton.static import check_supported

    gaps = PREVIEW_GAPS if ctx.preview else GAPS
    data = scene_data(NAME)
    mag = _magnet(data)
    half = float(mag["length"]) / 2

    def centre(gap):  # magnet centre for a face gap (m) below the strip's undeformed free end
        return [0.0, 0.0, -LENGTH - gap - half]

    def placed(gap):
        """The scene with the magnet (field and collider) held at ``gap``, float64, for the static solver."""
        d = copy.deepcopy(data)
        m = _magnet(d)
        m.pop("path", None)
        m["position"] = centre(gap)
        for c in d.get("colliders", []):
            if c.get("type") == "cylinder":
                c.pop("path", None)
                c["center"] = centre(gap)
        d["simulation"]["precision"] = "float64"
        d.setdefault("output", {})["particles"] = False
        return d

    sim = simulation(NAME, placed(FAR), preview=ctx.preview, device=ctx.device)
    names = [n for n in sim.built.body_names if n != "stub"]
    names.sort(key=lambda n: -float(sim.model.host["positions"][body_mask(sim, n), 2].max()))
    X = sim.model.host["positions"]
    sc = sim.scene.simulation
    h = sc.dx / sc.particles_per_cell
    masks = [body_mask(sim, n) for n in names]
    tops = [m & (X[:, 2] > X[m, 2].max() - h / 2) for m in masks]       # first and last particle layer of each section
    bots = [m & (X[:, 2] < X[m, 2].min() + h / 2) for m in masks]
    tip = bots[-1]

    def measure(s):
        x = s.state.x.numpy()
        out = {"length_mm": float(-x[tip, 2].mean() * 1e3)}
        for n, a, b in zip(names, tops, bots):
            out[f"{n}_mm"] = float((x[a, 2].mean() - x[b, 2].mean()) * 1e3)
        out["tip_offaxis_mm"] = float(np.hypot(x[tip, 0].mean(), x[tip, 1].mean()) * 1e3)
        return out

    all_gaps = [FAR] + list(gaps)
    try:
        check_supported(sim)
        refused = None
    except SimulationError as exc:  # e.g. materials with magnetization_follows = "R": the dynamics instead
        refused = str(exc)
    if refused is None:
        res, frames, draw_magnet = _static_sweep(ctx, sim, placed, all_gaps, centre, half, float(mag["diameter"]), measure)
    else:
        ctx.log(f"{NAME}: the static solver refuses this scene ({refused}); the dynamic sweep instead")
        res, frames, draw_magnet = _dynamic_sweep(ctx, data, all_gaps, centre, half, float(mag["diameter"]), measure)

    # strain relative to the strip hanging under gravity with the magnet far (the first read)
    L = res.series("length_mm")
    strain = L[1:] / L[0] - 1.0
    seg = {n: res.series(f"{n}_mm") for n in names}
    if refused is not None:
        drift = res.drift("length_mm", 1.0)[1:] * L[1:] / np.maximum(L[1:] - L[0], 1e-3)  # change over the window / stretch
    seg_strain = {n: seg[n][1:] / seg[n][0] - 1.0 for n in names}
    thin = [n for n in names if n.startswith("thin")]
    thick = [n for n in names if n.startswith("thick")]
    ratio = np.mean([seg_strain[n] for n in thin], axis=0) / np.mean([seg_strain[n] for n in thick], axis=0)

    # the bar model with what the engine simulates
    mat = body_material(sim, names[0])
    br = float(np.median(np.linalg.norm(mat["remanence"], axis=1)))
    secs = _sections(sim, names)
    # the moment's kinematics of the strip's material (material.magnetization_follows), for the bar model too
    follows = "R" if np.any(sim.model.host["magnetization_follows"][body_mask(sim, names[0])] != 0) else "F"

    def bar(gap):
        m = CylinderMagnet(float(mag["diameter"]), float(mag["length"]), float(mag["remanence"]), position=centre(gap),
                           axis=tuple(mag.get("axis", (0.0, 0.0, 1.0))))
        r = bar_strain(secs, m, br, mat["G"], mat["K"], mat["density"], follows=follows)
        if r is not None and r[0] >= LENGTH + gap:  # the free end would be inside the magnet: pulled in
            return None
        return r

    far = bar(FAR)
    ref, ref_ratio = [], []
    for g in gaps:
        r = bar(g)
        if r is None or far is None:
            ref.append(np.nan)
            ref_ratio.append(np.nan)
            continue
        ref.append(r[0] / far[0] - 1.0)
        st, st0 = r[1], far[1]
        is_thin = np.array([n.startswith("thin") for n in names])
        ref_ratio.append(np.mean(st[is_thin] / st0[is_thin] - 1) / np.mean(st[~is_thin] / st0[~is_thin] - 1))
    ref, ref_ratio = np.array(ref), np.array(ref_ratio)

    gap_mm = np.array(gaps) * 1e3
    csv = write_csv(ctx.out / f"{NAME}.csv", {"gap_mm": gap_mm, "strain_percent": strain * 100,
                                              "bar_model_strain_percent": ref * 100,
                                              "thin_over_thick_strain": ratio, "bar_model_thin_over_thick": ref_ratio,
                                              **({"newton_iterations": res.iterations[1:]} if refused is None else
                                                 {"settle_drift": drift})})
    png = plot_curve(ctx.out / f"{NAME}.png", gap_mm, {("MPM, static solver" if refused is None else "MPM, dynamics"): strain * 100, "1D bar model": ref * 100},
                     "gap between magnet face and strip end (mm)", "strain of the strip (%)",
                     "Strip of periodic thickness over a disc magnet (seed 000 Fig 3)",
                     note="seed 000 states no strain values")
    gif = frames.write_gif(ctx.out / f"{NAME}.gif", fps=2 if refused is None else 12,
                           title="strip_magnet: " + ("equilibria as the magnet comes closer" if refused is None else
                                                     "the magnet rises in steps"),
                           lims=((-35.0, 35.0), (-160.0, 8.0)), patches=draw_magnet)

    case = f"robot-{NAME}"
    inp = {"dx_mm": round(sc.dx * 1e3, 4), "gaps_mm": [round(g, 2) for g in gap_mm.tolist()]}
    err = mape(strain, ref) if np.all(np.isfinite(ref)) else float("nan")
    rows = [Row(case, "strain of the strip: MAPE vs 1D bar model", inp, 0.0, err, err, 0.15)]
    # seed 000: the thin parts strain more than the thick ones; the bar model says by how much
    r_sim, r_ref = float(np.mean(ratio)), float(np.mean(ref_ratio))
    rows.append(Row(case, "thin / thick section strain (mean over distances) vs 1D bar model", inp, r_ref, r_sim,
                    abs(r_sim - r_ref) / abs(r_ref), 0.25))
    # aligned field and magnetisation: no torque, the strip stays on the axis (off-axis tip over the strip length)
    off = float(np.max(res.series("tip_offaxis_mm")) / (LENGTH * 1e3))
    rows.append(Row(case, "free end off the magnet's axis / length (no bending)", inp, 0.0, off, off, 0.01))
    rows.append(static_row(case, res, inp) if refused is None else settle_row(case, drift, WINDOW, inp))

    summary = (f"At a {gap_mm[-1]:.0f} mm gap the strip stretches {strain[-1] * 100:.1f} % (1D bar model "
               f"{ref[-1] * 100:.1f} %, MAPE over the sweep {err * 100:.1f} %) and its thin sections strain "
               f"{ratio[-1]:.2f}x as much as the thick ones (model {ref_ratio[-1]:.2f}x); seed 000 Fig 3 gives no "
               f"values in its text and not the strip's cross-section or the magnet's size, so no paper number "
               f"is compared.")
    info = {"particles": res.particles, "dx_m": sc.dx, "hanging_length_mm": round(float(L[0]), 3)}
    if refused is None:
        info |= {"solver": "static", "static_wall_s": round(res.wall_s, 1), "newton_iterations": res.iterations.tolist()}
    else:
        info |= {"solver": "dynamic", "static_refused": refused, "steps": res.steps, "sim_wall_s": round(res.wall_s, 1),
                 "dt_min_s": res.dt_min, "dt_max_s": res.dt_max, "hold_s": HOLD, "damping": sc.damping}
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info)


ROBOT = Robot(
    name=NAME,
    title="Strip of periodic thickness over a disc magnet",
    source="seed 000 sec 4.3",
    quantity="strain vs distance to the magnet (MPM static solver)",
    sentence=("A hanging 100 mm Ecoflex 00-30 + NdFeB strip with alternating thick and thin sections is pulled "
              "along its axis by a disc magnet held at a series of gaps: it stretches more the closer the magnet, its thin sections "
              "most, as a one-dimensional bar model with the same magnetic energy predicts."),
    reproduce=reproduce,
    in_ci=False,
)
