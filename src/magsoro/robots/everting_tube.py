"""Seed 004's soft growing robot everted by an axial field alone (sec II-B, eqs 10-13; sec IV-B: "magnetic growth
requires a minimum field magnitude of 43 mT"), simulated in axisymmetric MPM with the implicit integrator
(scenes/everting_tube.toml: the tube drawn straight, started partly everted, its everted end on a sticky floor).

Two measurements.

- Growth threshold, with the tail's free end held (a clamp on its lowest rows): the everted wall and its fold settle
  in the field, and the clamp's axial force on the tail is what keeps the front where it is. By virtual work the
  tail's end moves twice as far as the front (the front advances by dl, the tail gives up dl of material and the
  wall grows by dl), so the force N the front pushes with is -2 times the clamp's force along the axis (positive:
  the front would advance). With both ends held (the clamp, and the everted end on its sticky floor) the field's
  energy, -|Br| B pi (B^2 - A^2) / mu0 times the distance between the ends for a remanence carried by F, cannot
  change: the field loads the two ends and leaves the held shape as it is. So N = N_el + 2 |Br| pi (B^2 - A^2) B /
  mu0, the flip term (docs/actuation.md), where N_el is the held shape's elastic push (the clamp's force with the
  field's forces left out), and growth starts at B = -N_el / (2 |Br| pi (B^2 - A^2) / mu0). Held runs at two
  fields check both halves: N - N_el against the flip term, N_el the same at both. Growth runs with the tail free
  below and above that field check it directly.
- Growth: the tail free, the field above the threshold, the front (the body's top) followed in time until the tail
  is used up; its speed is set by the mass damping of the scene (the model has no air, no friction and no other
  losses), so it is a pace, not a prediction of the seed's growth rate.

The reduced model (magsoro evert, :class:`magsoro.actuation.eversion.EversionModel`) gives 20.3 mT without friction
for this tube resting on a rigid tail; the seed measured 43 mT. Left out here: the tube's length (the seed's 60 mm
robot has a longer tail sliding inside the wall, and with it friction; this tube's contact is frictionless), and
pressure-assisted growth.
"""

from __future__ import annotations

import numpy as np

from magsoro.robots.base import (Context, FrameRecorder, ReproduceResult, Robot, RobotError, plot_curve, scene_data,
                                 simulation, write_csv)
from magsoro.robots.continuum_soft import Row

NAME = "everting_tube"

A, B = 0.8e-3, 0.9e-3            # m, the tube's inner and outer radius (seed 004: 1.8 mm diameter, 100 um wall)
SEED_FIELD = 0.043               # T, seed 004 sec IV-B: the smallest field that grew the robot
#: T, held-tail runs (N_el, the held shape's elastic push, from each: it should not depend on the field) and growth
#: runs with the tail free, one below the threshold the held runs give (about 29 mT) and two above; the same fields
#: in the preview
HOLD_FIELDS = (0.0, 0.04)
GROW_FIELDS = (0.025, 0.035, 0.045)
PREVIEW_HOLD = HOLD_FIELDS
PREVIEW_GROW = GROW_FIELDS
SAMPLES = 40                     # records per run (each run lasts the scene's duration: the field ramped over 5 ms, then held)
CLAMP_ROWS = 4                   # the tail's lowest particle rows held in the held-tail runs (cells: rows / 2)


def _remanence(data: dict) -> float:
    return float(data["bodies"][0]["magnetization"][1])


def _with_field(data: dict, field: float) -> dict:
    """The scene with its uniform field set to ``field`` (T) down the axis, keeping its ramp."""
    for f in data.get("fields", []):
        if f.get("type") == "uniform":
            f["B"] = [0.0, -float(field), 0.0]
            return data
    raise RobotError(f"{NAME}: the scene has no uniform field to set")


def _tail_end(data: dict) -> float:
    """The tail's free end (m): the bottom of the tube as drawn."""
    shape = data["bodies"][0]["shape"]
    return float(shape["center"][1]) - 0.5 * float(shape["size"][1])


def reduced_model(remanence: float, shear: float):
    """magsoro evert's EversionModel of this tube (frictionless, lambda_z = 1): its growth field
    (``minimum_growth_field()``), its front force at zero field on a rigid tail (``pressure_free_tip_force(0.0)``) and
    the flip term's slope 2 |Br| pi (B^2 - A^2) / mu0 (``flip_force_per_tesla()``)."""
    from magsoro.actuation.eversion import EversionModel

    return EversionModel(A, B, shear, remanence=remanence)


def _front(sim) -> float:
    return float(sim.state.x.numpy()[:, 1].max())


def held_tail(ctx: Context, field: float) -> dict:
    """The tube in ``field`` with its tail's end clamped: the clamp's axial force (N) on the tail over the run's last
    quarter, N = -2 F (the front's push), and its elastic part N_el: the same with the field's forces left out at
    each recorded state (the rest, N - N_el, is the field's end loads, the flip term exactly)."""
    data = _with_field(scene_data(NAME), field)
    data.setdefault("output", {})["particles"] = False
    end = _tail_end(data)
    dx = float(data["preview"]["dx"] if ctx.preview else data["simulation"]["dx"])
    rows = CLAMP_ROWS * dx / 2.0
    data["clamps"] = [{"body": "tube", "region": {"type": "rectangle", "center": [0.5 * (A + B), end + rows / 2.0],
                                                  "size": [2.0 * (B - A), rows]}}]
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    forces = []

    def clamp_force(s):
        integ = s.implicit
        if integ is None:  # the start, before the integrator's first step
            return
        f = integ.node_forces(integ.u_nodes, 1.0, 1.0)  # the balance at the current state (no inertia)
        f_el = integ.node_forces(integ.u_nodes, 0.0, 1.0)  # the same without the field
        held = integ.held_nodes
        forces.append((s.time, -float(f[held, 1].sum()), -float(f_el[held, 1].sum())))  # the clamp's force on the tail

    duration = sim.scene.simulation.duration
    res = sim.run(duration, record=clamp_force, record_every=duration / SAMPLES)
    if res.status != "completed":
        raise RobotError(f"{NAME}: held tail at {field * 1e3:g} mT: run {res.status}: {res.message}")
    t, F, F_el = np.array(forces).T
    late = t >= 0.75 * duration
    return {"field": field, "time": t, "clamp_force": F, "N": -2.0 * float(F[late].mean()),
            "N_el": -2.0 * float(F_el[late].mean()), "N_el_spread": 2.0 * float(np.ptp(F_el[late])),
            "drift": float(np.ptp(F[late])), "particles": sim.model.n_particles, "steps": res.steps,
            "wall_s": res.wall_time, "dx": sim.scene.simulation.dx, "front": _front(sim)}


def grow(ctx: Context, field: float, frames: FrameRecorder | None = None) -> dict:
    """The tube in ``field`` with its tail free: the front (the body's top) and the tail's end over time, and the
    smallest det F and largest neighbour stretch seen (tearing)."""
    data = _with_field(scene_data(NAME), field)
    data.setdefault("output", {})["particles"] = False
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    X = sim.model.host["positions"].astype(np.float64)
    tail = np.flatnonzero(X[:, 1] < X[:, 1].min() + 0.5 * sim.model.spacing)
    pairs = _neighbour_pairs(X, sim.model.spacing)
    rec = {"t": [], "front": [], "tail": [], "det_min": np.inf, "stretch_max": 0.0}

    def record(s):
        x = s.state.x.numpy().astype(np.float64)
        rec["t"].append(s.time)
        rec["front"].append(float(x[:, 1].max()))
        rec["tail"].append(float(x[tail, 1].mean()))
        F = s.state.F.numpy().astype(np.float64)
        rec["det_min"] = min(rec["det_min"], float(np.linalg.det(F).min()))
        d = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1) / np.linalg.norm(X[pairs[:, 0]] - X[pairs[:, 1]], axis=1)
        rec["stretch_max"] = max(rec["stretch_max"], float(d.max()))
        if frames is not None:
            frames.record(s)

    duration = sim.scene.simulation.duration
    res = sim.run(duration, record=record, record_every=duration / SAMPLES)
    if res.status != "completed":
        raise RobotError(f"{NAME}: growth at {field * 1e3:g} mT: run {res.status}: {res.message}")
    out = {k: np.array(v) if isinstance(v, list) else v for k, v in rec.items()}
    out.update(field=field, particles=sim.model.n_particles, steps=res.steps, wall_s=res.wall_time,
               dx=sim.scene.simulation.dx, final=sim.state.x.numpy().astype(np.float64), X=X)
    return out


def _neighbour_pairs(X: np.ndarray, spacing: float) -> np.ndarray:
    """Pairs of particles that are lattice neighbours in the reference (the tearing check's bonds)."""
    from scipy.spatial import cKDTree

    return cKDTree(X).query_pairs(1.05 * spacing, output_type="ndarray")


def growth_speed(t: np.ndarray, front: np.ndarray) -> float:
    """The front's mean speed (m/s) over the middle of its advance (a quarter to three quarters of the way)."""
    gain = front - front[0]
    total = gain.max()
    if total <= 0.0:
        return float((front[-1] - front[0]) / (t[-1] - t[0]))
    a, b = np.searchsorted(gain, 0.25 * total), np.searchsorted(gain, 0.75 * total)
    b = max(b, a + 1)
    return float((front[min(b, len(t) - 1)] - front[a]) / (t[min(b, len(t) - 1)] - t[a]))


def _section(path, runs: list, title: str):
    """Snapshots of a growth run's (r, z) section: the start and end of each run side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(runs), figsize=(2.2 * len(runs) + 1.0, 5.0), dpi=120, squeeze=False)
    for ax, (label, X, x) in zip(axes[0], runs):
        ax.scatter(x[:, 0] * 1e3, x[:, 1] * 1e3, s=0.2, c=X[:, 1], cmap="viridis", linewidths=0)
        ax.set_aspect("equal")
        ax.set_xlim(0.6, 1.2)
        ax.set_xticks([0.7, 1.1])
        ax.set_title(label, fontsize=8)
        ax.set_xlabel("r (mm)")
    axes[0][0].set_ylabel("z (mm)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def reproduce(ctx: Context) -> ReproduceResult:
    data = scene_data(NAME)
    br = _remanence(data)
    from magsoro.materials.library import get_material

    shear = float(get_material(data["bodies"][0]["material"]).shear_modulus)
    model = reduced_model(br, shear)
    model_field = float(model.minimum_growth_field())
    slope_closed = float(model.flip_force_per_tesla())
    n_el = float(model.pressure_free_tip_force(0.0))

    held = []
    for field in (PREVIEW_HOLD if ctx.preview else HOLD_FIELDS):
        r = held_tail(ctx, field)
        held.append(r)
        ctx.log(f"{NAME}: tail held at {field * 1e3:g} mT: N = {r['N'] * 1e3:.3f} mN, its elastic part "
                f"{r['N_el'] * 1e3:.3f} mN ({r['particles']} particles, {r['steps']} steps, {r['wall_s']:.0f} s)")
    Bs = np.array([r["field"] for r in held])
    Ns = np.array([r["N"] for r in held])
    Nel = np.array([r["N_el"] for r in held])
    # With both ends held (the clamp, the sticky floor) the field's energy -|Br| B pi (B^2 - A^2) / mu0 times the
    # ends' distance is fixed: the field adds the ends' loads, the flip term, and leaves the held shape as it is.
    # So N = N_el + slope_closed B, N_el the held shape's elastic push, and growth starts at -N_el / slope_closed.
    n_el_sim = float(Nel.mean())
    threshold = -n_el_sim / slope_closed
    flip_error = float(np.max(np.abs((Ns - Nel) - slope_closed * Bs))) / (slope_closed * float(np.max(Bs)))
    spread = float(np.ptp(Nel) / abs(n_el_sim)) if len(held) > 1 else 0.0

    grown = []
    frames = FrameRecorder(axes=(0, 1))
    for k, field in enumerate(PREVIEW_GROW if ctx.preview else GROW_FIELDS):
        last = k == len(PREVIEW_GROW if ctx.preview else GROW_FIELDS) - 1
        r = grow(ctx, field, frames if last else None)
        r["advance"] = float(r["front"].max() - r["front"][0])
        r["speed"] = growth_speed(r["t"], r["front"])
        grown.append(r)
        ctx.log(f"{NAME}: free tail at {field * 1e3:g} mT: front advanced {r['advance'] * 1e3:.3f} mm at "
                f"{r['speed'] * 1e3:.1f} mm/s ({r['steps']} steps, {r['wall_s']:.0f} s)")

    csv = write_csv(ctx.out / f"{NAME}.csv", {"field_mT": Bs * 1e3, "front_force_N_mN": Ns * 1e3,
                                              "elastic_part_N_el_mN": Nel * 1e3,
                                              "clamp_force_mN": np.array([-0.5 * n for n in Ns]) * 1e3})
    grid = np.linspace(0.0, max(0.05, float(Bs.max())), 11)
    png = plot_curve(ctx.out / f"{NAME}.png", grid * 1e3, {"N = N_el + flip term": (n_el_sim + slope_closed * grid) * 1e3},
                     "axial field against the tail's remanence (mT)", "N, the front's push (mN)",
                     "Everting tube: growth threshold (seed 004)",
                     note=f"N = 0 where growth starts: {threshold * 1e3:.1f} mT (N_el from the held-tail runs)",
                     points={"held-tail runs": (Bs * 1e3, Ns * 1e3),
                             "reduced model (magsoro evert: rigid tail, no friction)": ([model_field * 1e3], [0.0])},
                     paper={"seed 004: grows from 43 mT": ([SEED_FIELD * 1e3], [0.0])})
    grow_csv = write_csv(ctx.out / f"{NAME}_growth.csv", {
        "field_mT": [r["field"] * 1e3 for r in grown], "advance_mm": [r["advance"] * 1e3 for r in grown],
        "speed_mm_per_s": [r["speed"] * 1e3 for r in grown]})
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.2, 3.8), dpi=120)
    for r in grown:
        ax.plot(r["t"] * 1e3, (r["front"] - r["front"][0]) * 1e3, label=f"{r['field'] * 1e3:g} mT")
    ax.axhline(2.0 * B * 1e3, ls="--", color="0.4", lw=1, label="one tube diameter")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("front advance (mm)")
    ax.set_title("Everting tube: growth with the tail free (pace set by the scene's damping)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    grow_png = ctx.out / f"{NAME}_growth.png"
    fig.savefig(grow_png)
    plt.close(fig)
    last = grown[-1]
    section = _section(ctx.out / f"{NAME}_section.png",
                       [("start", last["X"], frames.frames[0][0] if frames.frames else last["X"])]
                       + [(f"{r['field'] * 1e3:g} mT, end", r["X"], r["final"]) for r in grown],
                       "(r, z) sections: the starting shape and each growth run's end")
    gif = frames.write_gif(ctx.out / f"{NAME}.gif", title=f"everting tube, {last['field'] * 1e3:g} mT",
                           lims=((0.5, 1.3), (-0.2, (last["front"].max() + 0.2e-3) * 1e3)))

    case = f"robot-{NAME}"
    wrong_side = [r for r in grown if (r["field"] < threshold and r["advance"] > B - A)
                  or (r["field"] > threshold and r["advance"] < 2 * B)]
    dx = held[0]["dx"]
    inp = {"dx_um": round(dx * 1e6, 3), "cells_through_wall": round((B - A) / dx, 2)}
    rows = [
        Row(case, "the field's part of the held tail's push, N - N_el, vs the flip term 2 |Br| pi (B^2 - A^2) B / mu0 "
            "(largest error over the runs, relative to the strongest field's)", inp, 0.0, flip_error, flip_error, 1e-3),
        Row(case, "the held shape's elastic push N_el does not depend on the field (spread over the runs / |mean|)",
            dict(inp, fields_mT=[round(b * 1e3, 3) for b in Bs]), 0.0, spread, spread, 0.1),
        Row(case, f"front advances past one tube diameter ({2 * B * 1e3:.1f} mm) at {last['field'] * 1e3:g} mT, "
            "mm (at least)", dict(inp, field_mT=last["field"] * 1e3), 2 * B * 1e3, last["advance"] * 1e3,
            max(0.0, 2 * B * 1e3 - last["advance"] * 1e3), 0.0),
        Row(case, "growth runs on their side of the threshold: runs below it whose front advances more than a wall "
            "thickness, runs above it whose front does not pass one tube diameter (count)",
            dict(inp, fields_mT=[round(r["field"] * 1e3, 3) for r in grown], threshold_mT=round(threshold * 1e3, 2)),
            0.0, float(len(wrong_side)), float(len(wrong_side)), 0.0),
        Row(case, "no tearing: smallest det F over the growth runs (above 0) ", inp, 0.0,
            min(r["det_min"] for r in grown), 0.0 if min(r["det_min"] for r in grown) > 0 else 1.0, 0.0),
    ]
    if ctx.preview:
        rows = rows[:2] + rows[3:]  # the preview's tube is the full one at half the resolution: growth is checked in full
    summary = (f"Seed 004's tube (1.8 mm, 100 um wall, |Br| {br:g} T along the tail) in axisymmetric MPM at "
               f"{(B - A) / dx:.0f} cells through the wall, implicit: with the tail's end held, the front's push N is "
               f"the held shape's elastic push N_el = {n_el_sim * 1e3:.2f} mN (reduced model, wall on a rigid tail: "
               f"{n_el * 1e3:.2f} mN) plus the flip term, {slope_closed * 1e3 / 1e3:.4f} mN/mT, so growth starts at "
               f"{threshold * 1e3:.1f} mT without friction, against the reduced model's {model_field * 1e3:.1f} mT and "
               f"the seed's measured {SEED_FIELD * 1e3:.0f} mT. With the tail free the front advances "
               + ", ".join(f"{r['advance'] * 1e3:.2f} mm at {r['field'] * 1e3:g} mT" for r in grown)
               + ", the material turning round the fold (smallest det F "
               f"{min(r['det_min'] for r in grown):.2f}).")
    info = {"particles": held[0]["particles"], "dx_m": dx, "threshold_T": round(float(threshold), 5),
            "reduced_model_threshold_T": round(model_field, 5), "seed_threshold_T": SEED_FIELD,
            "flip_slope_closed_N_per_T": round(slope_closed, 6),
            "elastic_push_N_el_N": round(n_el_sim, 7),
            "reduced_model_front_force_at_zero_field_N": round(n_el, 7),
            "held": {f"{r['field'] * 1e3:g} mT": {"N_N": round(r["N"], 7), "N_el_N": round(r["N_el"], 7),
                                                  "N_el_spread_N": round(r["N_el_spread"], 8),
                                                  "drift_N": round(r["drift"], 8),
                                                  "steps": r["steps"], "wall_s": round(r["wall_s"], 1)} for r in held},
            "growth": {f"{r['field'] * 1e3:g} mT": {"advance_m": round(r["advance"], 7), "speed_m_per_s": round(r["speed"], 5),
                                                    "det_F_min": round(r["det_min"], 4),
                                                    "neighbour_stretch_max": round(r["stretch_max"], 3),
                                                    "steps": r["steps"], "wall_s": round(r["wall_s"], 1)} for r in grown}}
    figures = [{"csv": grow_csv, "png": grow_png, "caption": "Front advance with the tail free, at each field."},
               {"csv": grow_csv, "png": section, "caption": "The (r, z) section at the start and at each run's end."}]
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info, figures)


ROBOT = Robot(
    name=NAME,
    title="Everting tube grown by an axial field (axisymmetric)",
    source="seed 004 sec II-B, IV-B",
    quantity="the front's push against the field with the tail held (growth threshold), and the growth with it free",
    sentence=("Seed 004's 1.8 mm tube, its tail magnetised along the axis, turned inside out by a field alone in "
              "axisymmetric MPM: the field at which the front starts to advance, against the reduced model and the "
              "seed's 43 mT, and the growth past one tube diameter above it."),
    reproduce=reproduce,
)
