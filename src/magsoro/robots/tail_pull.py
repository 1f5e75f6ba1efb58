"""Pulling test of the everted growing robot's tail (seed 004 sec III-B, Fig 4): 20 mm segments of the everted robot,
the tail pulled at 0.2 mm/s through the outer wall held on a fixed base, no lubricant; "the cruciform shape reduces
the required pulling force by a factor of five".

A reduced model, in plane strain: the force needed to slide the tail along the wall is the Coulomb friction of the
contact that holds the tail in the wall, F = mu N, with N the normal force between tail and wall over the segment's
length (plane strain: N per unit length times 20 mm). N is computed by MPM on the cross-section: the tail, whose
natural shape does not fit the wall's bore, is grown to it inside the wall (a tangential eigenstretch from a
shrunken copy: the wall thickness stays the wall's) and settles against the elastic wall, frictionless while it
settles; N is then read from the wall's hoop force (below). What is left out: the axial stretch of the pulled tail
(its Poisson contraction loosens the grip), the contact's history along the segment, adhesion.

- Cylindrical tail: the same tube as the wall (1.8 mm outer diameter, 100 um; seed 004) in the wall's 1.6 mm bore:
  its mid-line perimeter is 17 % too long, and it stretches the wall (at two cells through the wall the pair buckles
  into a rounded square, at four it stays nearly round).
- Cruciform tail: a thin-walled plus (arm half-width as in tail_crush, our assumption). With the tube's perimeter
  its arm tips stop 82 um short of the bore (nothing holds it: N = 0); the seed gives the cruciform's size nowhere,
  so the tips' natural radius is swept, from touching the bore (0.80 mm) to the robot's own 0.90 mm.

Reading N: for a thin ring, radial equilibrium dQ/ds - kappa T + p = 0 integrated once round (the shear force Q
closes) gives the total contact force as the integral of the hoop force T over the turning angle of the mid-line,
N = int T dphi, whatever the loads' distribution and tangential parts. T is summed from the wall particles'
Cauchy hoop stress in bins of their reference angle (tests/test_robot_tail_pull.py checks the reading on a ring
under a known pressure).
"""

from __future__ import annotations

import math

import numpy as np

from magsoro.robots.base import Context, FrameRecorder, ReproduceResult, Robot, RobotError, plot_curve, simulation, write_csv
from magsoro.robots.continuum_soft import Row
from magsoro.robots.tail_crush import ARM_HALF_WIDTH, GAP, MATERIAL, WALL, WALL_RADIUS

NAME = "tail_pull"

FRICTION = 1.0           # Coulomb coefficient for the pull force: the gripper's for dry silicone on silicone (no source)
LENGTH = 20e-3           # m, the seed's segments
SEGMENTS = 36            # the cylindrical tail's arcs, each growing along its own tangent
PAPER_RATIO = 5.0        # seed 004: cylindrical / cruciform pulling force
#: the cruciform's natural arm-tip radius (outer surface), m: from touching the bore to the robot's 0.9 mm
CRU_TIPS = (0.80e-3, 0.85e-3, 0.90e-3)
PREVIEW_TIPS = (0.90e-3,)  # the preview: the cylindrical tail and the robot-sized cruciform (under 3 minutes)
HOOP_BINS = 120          # reference-angle bins of the hoop-force reading


# -- geometry ----------------------------------------------------------------------------------------------
def _grown(stretch: float, direction, grow: float) -> dict:
    """The material: the library composite with a tangential eigenstretch ramped 1 -> ``stretch`` over ``grow``
    seconds along ``direction`` (reference frame)."""
    return {"library": MATERIAL, "stimulus": {
        "profile": {"type": "ramp", "duration": grow, "initial": 0.0, "final": 1.0},
        "stretch": [[0.0, 1.0], [1.0, float(stretch)]], "direction": [float(direction[0]), float(direction[1])]}}


def inner_radius() -> float:
    """The shrunken tails' outer reach, m: GAP inside the wall's bore."""
    return WALL_RADIUS - WALL / 2.0 - GAP


def cylindrical_tail(grow: float) -> list[dict]:
    """The tube as SEGMENTS arcs of mid-line radius inner_radius() - WALL/2, each stretched along its own
    tangent to the tube's mid-line radius WALL_RADIUS."""
    r0 = inner_radius() - WALL / 2.0
    stretch = WALL_RADIUS / r0
    parts = []
    for k in range(SEGMENTS):
        a0, a1 = 360.0 * k / SEGMENTS, 360.0 * (k + 1) / SEGMENTS
        m = math.radians(0.5 * (a0 + a1))
        parts.append({"name": f"tail_{k:02d}", "material": _grown(stretch, (-math.sin(m), math.cos(m)), grow),
                      "shape": {"type": "arc", "center": [0.0, 0.0], "radius": r0, "width": WALL,
                                "start_angle": a0, "end_angle": a1}})
    return parts


def cruciform_tail(tip: float, grow: float) -> list[dict]:
    """The plus with arm tips (outer surface) at radius ``tip`` when grown: arms along +-x and +-y, each arm's two
    side walls stretched along the arm from a shrunken plus that fits the bore, the tip caps and the four
    inner corners unstretched. Walls WALL thick, arm mid-line half-width ARM_HALF_WIDTH."""
    a, t = ARM_HALF_WIDTH, WALL
    # outer surface of the caps, shrunken: the caps' outer corners, which come nearest the round bore, 2 GAP
    # inside it (closer, the lattice puts them on sites next to the wall's and bonds tail and wall)
    reach0 = math.sqrt((inner_radius() - GAP) ** 2 - (a + t / 2.0) ** 2)
    side0 = reach0 - t - (a + t / 2.0)            # a side wall's length between the corner square and the cap
    stretch = (tip - t - (a + t / 2.0)) / side0
    if stretch < 1.0:
        raise RobotError(f"{NAME}: a cruciform tip at {tip * 1e3:.3f} mm fits the bore already (no contact to grow)")
    parts = []

    def rect(name, cx, cy, sx, sy, material):
        parts.append({"name": name, "material": material,
                      "shape": {"type": "rectangle", "center": [cx, cy], "size": [sx, sy]}})

    mid = a + t / 2.0 + side0 / 2.0
    for k, (ux, uy) in enumerate(((1, 0), (0, 1), (-1, 0), (0, -1))):
        grown = _grown(stretch, (ux, uy), grow)
        for side in (-1, 1):  # the arm's two side walls
            px, py = -uy * side * a, ux * side * a  # offset across the arm
            if ux:
                rect(f"arm{k}_side{side + 1}", ux * mid + px, py, side0, t, grown)
            else:
                rect(f"arm{k}_side{side + 1}", px, uy * mid + py, t, side0, grown)
        cap = reach0 - t / 2.0
        if ux:
            rect(f"arm{k}_cap", ux * cap, 0.0, t, 2.0 * a + t, MATERIAL)
        else:
            rect(f"arm{k}_cap", 0.0, uy * cap, 2.0 * a + t, t, MATERIAL)
    for k, (sx, sy) in enumerate(((1, 1), (-1, 1), (-1, -1), (1, -1))):
        rect(f"corner{k}", sx * a, sy * a, t, t, MATERIAL)
    return parts


# -- reading the contact force ------------------------------------------------------------------------------
def cauchy_stress(sim) -> np.ndarray:
    """(n, dim, dim) Cauchy stress of every particle now (elastic part of its law, Pa)."""
    import warp as wp

    from magsoro.mpm.kernels import launch_body_stress
    from magsoro.mpm.runtime import bodies_array

    m = sim.model
    k = m.kernels
    P = wp.zeros(m.n_particles, dtype=k["mat"], device=m.device)
    W = wp.zeros(m.n_particles, dtype=m.scalar, device=m.device)
    launch_body_stress(k, m.n_particles, F=sim.state.F, bodies=bodies_array(m), P=P, psi=W, device=m.device)
    F = sim.state.F.numpy().astype(np.float64)
    J = np.linalg.det(F)
    return np.einsum("nij,nkj->nik", P.numpy().astype(np.float64), F) / J[:, None, None]


def ring_contact_force(sim, body: int, centre=(0.0, 0.0), bins: int = HOOP_BINS) -> float:
    """Total normal force (N, over the scene's depth) that the loads on ring ``body`` (a 2D annulus about
    ``centre`` in its reference configuration) press it with: int T dphi = sum over bins of T kappa ds, with the
    hoop force T, the mid-line's curvature kappa and length ds of each bin of the particles' reference angle.
    Exact for a thin ring in equilibrium under any surface loads (module docstring). The mid-line's direction and
    stretch come from the particles' F (the reference tangent carried forward), not from their positions, whose
    bin centroids jitter by a fraction of a spacing."""
    host = sim.model.host
    sel = host["body"] == body
    X = host["positions"][sel] - np.asarray(centre)
    F = sim.state.F.numpy()[sel].astype(np.float64)
    sigma = cauchy_stress(sim)[sel]
    theta0 = np.arctan2(X[:, 1], X[:, 0])
    t0 = np.stack([-np.sin(theta0), np.cos(theta0)], axis=1)
    ft = np.einsum("nij,nj->ni", F, t0)
    stretch = np.linalg.norm(ft, axis=1)
    t = ft / stretch[:, None]
    s_tt = np.einsum("ni,nij,nj->n", t, sigma, t)
    area = np.linalg.det(F) * host["volumes"][sel] / sim.scene.simulation.depth  # current area of each particle
    k = np.floor((theta0 + math.pi) / (2.0 * math.pi) * bins).astype(int) % bins
    count = np.bincount(k, minlength=bins)
    if np.any(count == 0):
        raise RobotError(f"{NAME}: a hoop-force bin holds no particle: use fewer than {bins} bins")
    mean_t = np.stack([np.bincount(k, weights=t[:, a], minlength=bins) for a in range(2)], axis=1)
    phi = np.unwrap(np.arctan2(mean_t[:, 1], mean_t[:, 0]))
    phi_next = np.concatenate([phi[1:], [phi[0] + 2.0 * math.pi]])
    phi_prev = np.concatenate([[phi[-1] - 2.0 * math.pi], phi[:-1]])
    turn = 0.5 * (phi_next - phi_prev)
    radius = np.bincount(k, weights=np.hypot(X[:, 0], X[:, 1]), minlength=bins) / count
    ds = np.bincount(k, weights=stretch, minlength=bins) / count * radius * (2.0 * math.pi / bins)
    hoop = np.bincount(k, weights=s_tt * area, minlength=bins)  # T times the bin's mid-line length
    return float(np.sum(hoop / ds * turn) * sim.scene.simulation.depth)


# -- the runs -----------------------------------------------------------------------------------------------
def _timing(data: dict) -> tuple[float, float]:
    """(growth time, total time) of a scene dict: the tail's ramp (its first part's material.stimulus) and the
    scene's duration."""
    parts = data.get("robot", {}).get("parts", [])
    ramps = [p["material"]["stimulus"]["profile"]["duration"] for p in parts
             if isinstance(p.get("material"), dict) and "stimulus" in p["material"]]
    if not ramps:
        raise RobotError(f"{NAME}: the scene's tail parts should carry the growth ramp (material.stimulus)")
    return float(ramps[0]), float(data["simulation"]["duration"])


def case_scene(tail: str, tip: float | None = None, data: dict | None = None) -> dict:
    """scenes/tail_pull.toml (the cylindrical tail) with the tail ``tail``: 'cylindrical', or 'cruciform' with its
    arm tips at radius ``tip`` (m) once grown."""
    from magsoro.robots.base import scene_data

    data = scene_data(NAME) if data is None else data
    grow, _ = _timing(data)
    data["robot"] = {"parts": cylindrical_tail(grow) if tail == "cylindrical" else cruciform_tail(tip, grow)}
    return data


def settle(ctx: Context, tail: str, tip: float | None = None, frames: list | None = None) -> dict:
    """Grow the tail in the wall and let it settle; returns the contact force N (N, whole segment) read at each
    reading from the end of the growth on, and the run's facts."""
    data = case_scene(tail, tip)
    data.setdefault("output", {})["particles"] = False
    grow, duration = _timing(data)
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    wall = [b.name for b in sim.scene.bodies].index("wall")
    forces = []
    every = duration / 40.0

    def record(s):
        if frames is not None:
            frames.append(s.state.x.numpy().copy())
        if s.time >= grow - 1e-12:
            forces.append(ring_contact_force(s, wall))

    res = sim.run(duration, record=record, record_every=every)
    if res.status != "completed":
        raise RobotError(f"{NAME}: {tail} tail: run {res.status}: {res.message}")
    return {"force": np.array(forces), "particles": sim.model.n_particles,
            "steps": res.steps, "wall_s": res.wall_time, "body": sim.model.host["body"].copy(),
            "dx": sim.scene.simulation.dx, "grow": grow, "every": every}


def _gif(path, runs: dict, keys: list, title: str):
    rec = FrameRecorder(axes=(0, 1))
    n = min(len(runs[k]["frames"]) for k in keys)
    offsets = [np.array([i * 2.4e-3, 0.0]) for i in range(len(keys))]
    for j in range(n):
        pts = np.concatenate([runs[k]["frames"][j] + offsets[i] for i, k in enumerate(keys)])
        rec.frames.append((pts, f"t = {j * runs[keys[0]]['every'] * 1e3:.1f} ms (growth until "
                                f"{runs[keys[0]]['grow'] * 1e3:.0f} ms)"))
    rec.color = np.concatenate([np.minimum(runs[k]["body"], 1) for k in keys])
    return rec.write_gif(path, title=title, lims=((-1.2, 1.2 + 2.4 * (len(keys) - 1)), (-1.2, 1.2)))


def reproduce(ctx: Context) -> ReproduceResult:
    tips = PREVIEW_TIPS if ctx.preview else CRU_TIPS
    cases = [("cylindrical", None)] + [("cruciform", tip) for tip in tips]
    runs = {}
    for tail, tip in cases:
        key = tail if tip is None else f"cruciform_{tip * 1e6:.0f}um"
        frames: list = []
        r = settle(ctx, tail, tip, frames)
        r["frames"] = frames
        runs[key] = r
        ctx.log(f"{NAME}: {key}: {r['particles']} particles, {r['steps']} steps, {r['wall_s']:.0f} s; "
                f"N = {r['force'][-1] * 1e3:.2f} mN, pull force {FRICTION * r['force'][-1] * 1e3:.2f} mN")
    keys = list(runs)
    N = {k: float(runs[k]["force"][-1]) for k in keys}
    cyl = N["cylindrical"]
    cru_keys = keys[1:]
    tips_mm = np.array(tips) * 1e3
    ratio = np.array([cyl / N[k] if N[k] > 0 else np.inf for k in cru_keys])
    pull = {k: FRICTION * N[k] for k in keys}
    csv = write_csv(ctx.out / f"{NAME}.csv", {
        "case": keys, "arm_tip_radius_mm": [np.nan] + tips_mm.tolist(), "contact_force_N": [N[k] for k in keys],
        "pull_force_N": [pull[k] for k in keys], "cylindrical_over_case": [1.0] + ratio.tolist()})
    # the tip radius at which the ratio is the seed's five (ratio falls as the tips press harder)
    order = np.argsort(ratio)
    tip5 = float(np.interp(PAPER_RATIO, ratio[order], tips_mm[order])) if ratio.min() <= PAPER_RATIO <= ratio.max() else float("nan")
    png = plot_curve(ctx.out / f"{NAME}.png", tips_mm,
                     {"cruciform tail": np.array([pull[k] for k in cru_keys]) * 1e3,
                      "cylindrical tail": np.full(len(tips_mm), pull["cylindrical"] * 1e3)},
                     "cruciform arm tips' natural radius (mm; bore 0.80, robot 0.90)",
                     f"pull force mu N, {LENGTH * 1e3:.0f} mm, mu {FRICTION:g} (mN)",
                     "Tail pulled through the everted wall (seed 004 Fig 4)",
                     note="tube-perimeter cruciform (tips 0.718 mm): no contact",
                     hlines={"cruciform 5 x less than our cylindrical": pull["cylindrical"] * 1e3 / PAPER_RATIO},
                     legend_loc="center right")
    gif = _gif(ctx.out / f"{NAME}.gif", runs, ["cylindrical", cru_keys[-1]],
               f"tails growing into the wall: cylindrical, cruciform (tips {tips_mm[-1]:.2f} mm)")

    case = f"robot-{NAME}"
    dx = runs["cylindrical"]["dx"]
    inp = {"dx_mm": round(dx * 1e3, 4), "friction": FRICTION, "length_mm": LENGTH * 1e3}
    rows = []
    for k in keys:
        f = runs[k]["force"]
        drift = abs(f[-1] - f[-5]) / abs(f[-1]) if abs(f[-1]) > 0 else float("inf")
        rows.append(Row(case, f"settled: change of N over the last {4 * runs[k]['every'] * 1e3:.1f} ms / N, {k}",
                        dict(inp, case=k), 0.0, drift, drift, 0.02))
    less = float(ratio.min() - 1.0)
    rows.append(Row(case, "cruciform tail needs less pull force than the cylindrical one at every swept tip radius: "
                    "smallest ratio - 1 (at least 0)", inp, 0.0, less, max(0.0, -less), 0.0))
    r_robot = float(ratio[-1])
    rows.append(Row(case, f"pull force ratio cylindrical / cruciform with the cruciform's tips at the robot's "
                    f"{tips_mm[-1]:.2f} mm, vs seed 004's five (relative)", dict(inp, tip_mm=float(tips_mm[-1])),
                    PAPER_RATIO, r_robot, abs(r_robot - PAPER_RATIO) / PAPER_RATIO, 0.5))
    where = (f"a ratio of five at tips of {tip5:.3f} mm" if math.isfinite(tip5) else
             f"ratios {ratio.min():.1f}-{ratio.max():.1f} over the sweep, five not among them")
    summary = (f"Plane-strain contact force between tail and wall over a {LENGTH * 1e3:.0f} mm segment, pull force "
               f"mu N at mu = {FRICTION:g}: the cylindrical tail (the wall's own tube, 17 % too long for the bore) "
               f"presses with N = {cyl * 1e3:.0f} mN, a pull force of {pull['cylindrical'] * 1e3:.0f} mN. A cruciform "
               f"of the tube's perimeter does not reach the bore (no grip); with its arm tips grown to "
               + ", ".join(f"{t:.2f}" for t in tips_mm) + " mm it presses with "
               + ", ".join(f"{N[k] * 1e3:.1f}" for k in cru_keys) + " mN, the cylindrical tail's force divided by "
               + ", ".join(f"{v:.1f}" for v in ratio) + f" (seed: five; {where}). The cruciform's size, the friction "
               "coefficient and the plane-strain reduction (no Poisson loosening of the pulled tail) are our assumptions.")
    info = {"particles": {k: runs[k]["particles"] for k in keys}, "steps": {k: runs[k]["steps"] for k in keys},
            "wall_s": {k: round(runs[k]["wall_s"], 1) for k in keys}, "dx_m": dx,
            "contact_force_N": {k: round(N[k], 6) for k in keys}, "ratio_cylindrical_over": dict(zip(cru_keys, ratio.round(3).tolist())),
            "tip_for_ratio_5_mm": round(tip5, 4) if math.isfinite(tip5) else None, "friction": FRICTION}
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info)


ROBOT = Robot(
    name=NAME,
    title="Everted growing robot segment, tail pulled through the wall",
    source="seed 004 sec III-B",
    quantity="pull force (Coulomb, mu N) of a cylindrical and a cruciform tail held in the everted wall",
    sentence=("The tail inside a 20 mm segment of the everted 1.8 mm robot is held by the wall it presses on: a "
              "cylindrical tail (the wall's own tube, too long for the bore) against a cruciform one whose arms "
              "touch the wall at their tips; the pull force is the Coulomb friction of that contact."),
    reproduce=reproduce,
)
