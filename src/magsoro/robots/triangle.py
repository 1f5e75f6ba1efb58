"""Triangular robot of seed 002 sec 4 (Figs. 3-9): a hollow 40 mm triangle whose six magnetised trapezoids
warp its three vertices up when the N35 magnet under the plate comes closer. Reproduces the centroid height H_t
(Fig. 6) and the vertex warp height W_t (Fig. 9) against the flux density at the robot, 0 to 45 mT.

The field level is set the way the paper sets it: by the magnet's distance. For each level the magnet (the exact
field of the N35 cylinder of seed 002 sec 3) is placed, centred under the robot, at the distance where B_z at
the robot's centre equals the level. Figs. 6 and 9 are static curves: the reproduction solves each level as an
equilibrium of the static solver (Simulation.solve_static along the magnet's path, [static] times: each level
from the last, the magnet moving with the load increments, the plate's friction anchors carried along), the
robot first settled on the plate under gravity with the magnet 1 m away. The scene file's path is the dynamic
version of the same sweep (`magsoro run scenes/triangle.toml`: holds of HOLD s at each level), which the preview
runs (PREVIEW_DYNAMIC) and the full reproduction ran before (benchmarks/triangle_sweep.py compares the two).

The module also holds the few helpers the other robots of seed 002 share (magnet distance for a field level,
stepped magnet paths, reading settled values).
"""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np

from magsoro.robots.base import (
    Context, FrameRecorder, ReproduceResult, Robot, RobotError, plot_curve, scene_data, simulation, write_csv,
)

NAME = "triangle"
LEVELS_MT = [0, 5, 10, 15, 20, 25, 30, 35, 40, 45]   # seed 002 Figs. 6 and 9 span 0..45 mT
PREVIEW_LEVELS_MT = [0, 15, 30, 45]
# the dynamic sweep of the scene file's magnet path (magsoro run scenes/triangle.toml)
SETTLE = 0.04    # s at zero field (level 0): the robot settles on the plate under gravity
HOLD = 0.08      # s per level: the magnet moves in the first MOVE seconds, the robot settles in the rest
MOVE = 0.02      # s
FRAME_EVERY = 0.02  # s between animation frames (the level reads fall on this grid)
# Levels (mT) the static sweep solves on its way without reading them: they split the robot's lift-off from the
# plate (1-5 mT), which the load increments along the magnet's path follow badly in one step (the field at the
# robot rises steeply only at the end of a move). Full grid (benchmarks/triangle_sweep.py, 2026-11-28): 0 to 5 mT
# in one step took 229 Newton iterations (153 s); through 1, 2, 3 and 4 mT, 83 (60 s).
BETWEEN_MT = [1, 2, 3, 4]
# PREVIEW_DYNAMIC: the preview sweeps by the dynamics. On its grid (dx 2 mm: one cell through the 2 mm plate) the
# static solve's total-Lagrangian form bends far softer than the dynamics (W_t 9.8 against 3.7 mm at 15 mT, 14.2
# against 9.0 at 45 mT; at the full grid the two agree within 0.7 % from 15 to 45 mT) and took 31 s against 6.5 s
# (measured 2026-11-28 with 1, 2, 3, 4, 5 and 10 mT on the way).
#: room (m) added below the domain for the static sweep: on the preview grid (dx 2 mm) the domain's floor, 4 mm
#: under the plate, is two cells away, so the nodes under the robot start in the band of the domain wall, which the
#: static solver then models as a collider at the nodes (StaticSolver._starting_walls): the wall, frictionless,
#: carries the robot instead of the friction plate, and the robot, free to slide, drifted 51 mm along y on a
#: 1e-9 N imbalance. (The dynamics' wall would carry it there too; 4 mm is room enough at the full grid's 1 mm.)
STATIC_ROOM = 0.01
FAR = 1.0        # m: magnet distance standing for "no magnet" (field at the robot below 0.01 mT)

# seed 002 values drawn as paper points (mm at 45 mT)
PAPER_WT = {"exp.": 11.0, "sim.": 12.0}    # sec 4.3, Fig. 9
PAPER_HT = {"exp.": 3.5, "sim.": 3.7}      # sec 4.2, Fig. 6
TOL_PAPER = 0.30   # relative: thickness and remanence are our assumptions (scenes/triangle.toml)
# speeds under the moving actuator (robots/_seed002_speeds.py); seed 002 gives no magnet speed, so a range
PAPER_WARP_SPEED = 9.0     # mm/s, sec 4.3 (Fig. 7c)
PAPER_LOCO_SPEED = 1.5     # mm/s, sec 4.4 (Fig. 4c)
WARP_MAGNET_SPEEDS = [0.05, 0.1, 0.2]    # m/s (preview: the last only)
LOCO_MAGNET_SPEEDS = [0.1, 0.2]          # m/s (preview: the last only)
LOCO_DOMAIN = ((-0.036, -0.170, -0.004), (0.036, 0.044, 0.040))   # room for the pass along -y (m)


# -- helpers shared by the seed 002 robots ------------------------------------------------------------------
def cylinder_magnet(table: dict, position=(0.0, 0.0, 0.0)):
    """The host :class:`~magsoro.fields.CylinderMagnet` of a scene's ``cylinder_magnet`` field table, at
    ``position`` (m)."""
    from magsoro.fields import CylinderMagnet

    return CylinderMagnet(diameter=table["diameter"], length=table["length"], remanence=table["remanence"],
                          position=tuple(position), axis=tuple(table.get("axis", (0.0, 0.0, 1.0))))


def magnet_distance(table: dict, level: float, point=(0.0, 0.0, 0.0), far: float = FAR) -> float:
    """Distance d (m) from ``point`` down to the centre of the magnet of field table ``table`` (placed at
    point - d e_z) at which |B_z| at ``point`` equals ``level`` (T). ``level`` 0 gives ``far``. The field of
    the cylinder falls monotonically along its axis beyond its face, so the root is unique."""
    from scipy.optimize import brentq

    if level <= 0:
        return far
    p = np.asarray(point, float)

    def bz(d):
        return abs(cylinder_magnet(table, p - np.array([0.0, 0.0, d])).B([p])[0, 2])

    lo, hi = 0.5 * table["length"] + 1e-4, far
    if not bz(hi) < level < bz(lo):
        raise RobotError(f"a field of {level * 1e3:.1f} mT is out of reach of this magnet "
                         f"({bz(hi) * 1e3:.3g}..{bz(lo) * 1e3:.3g} mT)")
    return float(brentq(lambda d: bz(d) - level, lo, hi, xtol=1e-7))


def stepped_path(offsets: list, first_hold: float, hold: float, move: float):
    """Keyframes (times, positions) of a source that stays ``first_hold`` s at ``offsets[0]``, then goes to each
    further position in ``move`` s and stays there until ``hold`` s after it set off. Returns (times,
    positions, read_times): read_times are the ends of the holds, one per offset."""
    times, positions = [0.0, first_hold], [list(offsets[0]), list(offsets[0])]
    t = first_hold
    reads = [t]
    for pos in offsets[1:]:
        times += [round(t + move, 9), round(t + hold, 9)]
        positions += [list(pos), list(pos)]
        t = round(t + hold, 9)
        reads.append(t)
    return times, positions, reads


def path_position(t: float, times: list, positions: list) -> np.ndarray:
    """Position (m) of a keyframed path at time t (linear, held outside), as the engine interpolates it."""
    P = np.asarray(positions, float)
    return np.array([np.interp(t, times, P[:, k]) for k in range(P.shape[1])])


def advance(sim, t_end: float, frames: FrameRecorder | None, frame_every: float) -> None:
    """Step ``sim`` to ``t_end`` recording ``frames`` on the ``frame_every`` grid; a failed step raises
    RobotError naming the time."""
    from magsoro.errors import SimulationError

    try:
        while sim.time < t_end - 1e-9:
            nxt = min(t_end, (math.floor(sim.time / frame_every + 1e-6) + 1) * frame_every)
            sim.advance_to(nxt)
            if frames is not None and abs(nxt / frame_every - round(nxt / frame_every)) < 1e-6:
                frames.record(sim)
    except SimulationError as exc:
        raise RobotError(f"{sim.scene.name}: run failed at step {exc.step}, t = {exc.time:.4g} s: {exc}") from None


# -- the triangle -----------------------------------------------------------------------------------------
def outer_vertices(data: dict) -> np.ndarray:
    """Outer vertices (3, 2) of the triangle, from the baseplate polygons of the scene (the points shared by two
    side strips)."""
    pts = [tuple(np.round(v, 6)) for b in data["bodies"] if b["name"].startswith("base_")
           for v in b["shape"]["vertices"]]
    counts = {p: pts.count(p) for p in pts}
    shared = [p for p, c in counts.items() if c == 2]
    # outer corners are the shared points farthest from the centre
    shared.sort(key=lambda p: -math.hypot(*p))
    return np.array(shared[:3])


def _midpoints(corners: np.ndarray) -> np.ndarray:
    return np.array([(corners[i] + corners[(i + 1) % 3]) / 2 for i in range(3)])


def measure(sim, X0: np.ndarray, mass: np.ndarray, corners: np.ndarray, radius: float = 0.002) -> dict:
    """Heights (m) of the current state: centroid (mass-weighted), each vertex (mean z of the material within
    ``radius`` in plan of an outer corner, reference frame) and each side midpoint (same, at the outer edge's
    midpoint)."""
    x = sim.state.x.numpy().astype(np.float64)
    out = {"centroid": float(np.sum(mass * x[:, 2]) / mass.sum())}
    for key, pts in (("vertex", corners), ("mid", _midpoints(corners))):
        out[key] = [float(x[np.linalg.norm(X0[:, :2] - p, axis=1) < radius, 2].mean()) for p in pts]
    return out


ROBOT_MID_Z = 0.001  # m: mid-plane of the 2 mm robot lying on the plate (z = 0..2 mm in scenes/triangle.toml)


def magnet_offsets(magnet: dict, levels_mt) -> list:
    """Magnet centre positions (m), centred under the robot, giving B_z = level at the robot's centre
    (mid-plane, at rest) for each level (mT)."""
    return [[0.0, 0.0, ROBOT_MID_Z - magnet_distance(magnet, lv * 1e-3, (0.0, 0.0, ROBOT_MID_Z))]
            for lv in levels_mt]


def speeds(ctx: Context, data: dict, corners: np.ndarray) -> dict:
    """Warping and locomotion speeds under the paper's actuator (module docstring of robots/_seed002_speeds.py):
    the magnet rising under the top vertex (largest rise rate of that vertex) and passing along -y from beyond
    the top vertex to beyond the opposite side (mean speed of the centroid along the pass, positive with the
    magnet). North face up, as in the field sweep."""
    from magsoro.robots import _seed002_speeds as sp

    i_top = int(np.argmax(corners[:, 1]))
    top, key = corners[i_top], f"v{i_top}"

    def vertices(X0):
        return {f"v{i}": np.linalg.norm(X0[:, :2] - c, axis=1) < 0.002 for i, c in enumerate(corners)}

    warp_v = WARP_MAGNET_SPEEDS[-1:] if ctx.preview else WARP_MAGNET_SPEEDS
    loco_v = LOCO_MAGNET_SPEEDS[-1:] if ctx.preview else LOCO_MAGNET_SPEEDS
    warp = [sp.rising_run(NAME, data, top, v, +1.0, vertices, ctx, "warping") for v in warp_v]
    loco = [sp.passing_run(NAME, data, v, +1.0, LOCO_DOMAIN, ctx, "locomotion") for v in loco_v]
    mags = sorted(set(warp_v) | set(loco_v))
    warp_rate = {r["speed"]: sp.largest_rate(r["t"], r[key])[0] for r in warp}
    loco_rate = {r["speed"]: -r["mean_speed"] for r in loco}   # the magnet moves along -y
    table = {
        "magnet_speed_mm_s": [v * 1e3 for v in mags],
        "warping_vertex_rise_rate_mm_s": [warp_rate.get(v, float("nan")) * 1e3 for v in mags],
        "locomotion_centroid_speed_along_magnet_mm_s": [loco_rate.get(v, float("nan")) * 1e3 for v in mags],
        "vertex_rise_over_run_mm": [1e3 * (next((r[key][-1] - r[key][np.searchsorted(r["t"], sp.SETTLE)]
                                                 for r in warp if r["speed"] == v), float("nan"))) for v in mags],
        "centroid_along_magnet_in_pass_mm": [1e3 * -next((r["dy"] for r in loco if r["speed"] == v), float("nan"))
                                             for v in mags],
    }
    dx = warp[0]["dx"]
    csv, png = sp.write_speeds(ctx.out, NAME, table, {"warping 9 mm/s (sec 4.3)": PAPER_WARP_SPEED,
                                                      "locomotion 1.5 mm/s (sec 4.4)": PAPER_LOCO_SPEED},
                               note=f"dx = {dx * 1e3:.1f} mm; the paper gives no magnet speed")
    wv = sorted(warp_rate)
    return {"table": table, "csv": csv, "png": png, "key": key, "warp": warp, "loco": loco,
            "wall_s": sum(r["wall_s"] for r in warp + loco),
            "warp_magnet_speed_for_paper_mm_s": sp.magnet_speed_for(PAPER_WARP_SPEED, [v * 1e3 for v in wv],
                                                                    [warp_rate[v] * 1e3 for v in wv]),
            "dx": dx}


def static_magnet_sweep(ctx: Context, name: str, data: dict, magnet: dict, offsets: Callable, levels_mt, between_mt,
                        on_read: Callable, on_start: Callable | None = None):
    """Equilibria of scene ``name`` (table ``data``, its field table ``magnet``) along the magnet's path through
    the levels ``levels_mt`` (read) and ``between_mt`` (solved on the way, not read), by the static solver
    ([static] times: one pseudo-second per level, each from the last, the magnet moving with the load increments;
    the first, the lowest level, from the unloaded robot, which settles under gravity there). ``offsets(levels)``:
    the magnet's positions (m) for levels (mT). ``on_start(sim)`` before the solve (the unloaded robot);
    ``on_read(sim, level, level_result)`` at each read level. The domain's floor is lowered by STATIC_ROOM.
    Returns (sim, StaticSweep of every level solved); a level that does not converge raises RobotError with the
    solver's message."""
    from magsoro.robots.continuum_soft import StaticSweep

    levels = sorted(set(levels_mt) | set(between_mt))
    read = set(levels_mt)
    times = [float(k) for k in range(len(levels))]
    magnet["path"] = {"times": times, "positions": [list(map(float, o)) for o in offsets(levels)]}
    magnet["position"] = magnet["path"]["positions"][0]
    table = data["simulation"]
    table["precision"] = "float64"  # the static solver's tolerance needs it
    table["duration"] = times[-1]
    table["domain_lo"][2] -= STATIC_ROOM
    data.setdefault("output", {})["particles"] = False
    sim = simulation(name, data, preview=ctx.preview, device=ctx.device)
    if on_start is not None:
        on_start(sim)
    results = []
    w0 = time.perf_counter()

    def on_level(s, res):
        lv = levels[len(results)]
        results.append(res)
        if lv in read:
            on_read(s, lv, res)
        else:
            ctx.log(f"  ({lv:g} mT on the way: {res.iterations} Newton iterations, {time.perf_counter() - w0:.0f} s wall)")

    out = sim.solve_static(times=times, on_level=on_level)
    if not out.converged:
        raise RobotError(f"{name}: static solve failed: {out.message}")
    return sim, StaticSweep([], results, int(sim.model.n_particles), time.perf_counter() - w0)


def static_sweep(ctx: Context, levels_mt, between_mt):
    """The triangle's equilibria along the magnet's path through ``levels_mt`` (read) and ``between_mt`` (solved
    on the way, not read), by :func:`static_magnet_sweep`. Returns (sim, X0, mass, corners, rest measure,
    [(level, measure)], StaticSweep, the frames)."""
    data = scene_data(NAME)
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    corners = outer_vertices(data)
    current = {"level": 0.0}
    frames = FrameRecorder(axes=(0, 2), label=lambda s: f"equilibrium, B_z at the robot centre = {current['level']:.0f} mT")
    rows_out, ref = [], {}
    w0 = time.perf_counter()

    def on_start(sim):
        ref["X0"] = sim.model.host["positions"].astype(np.float64)
        ref["mass"] = sim.model.host["mass"].astype(np.float64)
        ref["rest"] = measure(sim, ref["X0"], ref["mass"], corners)
        frames.record(sim)
        ctx.log(f"triangle: {len(ref['X0'])} particles, dx = {sim.model.dx * 1e3:.2f} mm, levels {levels_mt} mT "
                f"(and {between_mt} mT on the way), static solver along the magnet's path")

    def on_read(s, lv, res):
        m = measure(s, ref["X0"], ref["mass"], corners)
        rows_out.append((lv, m))
        current["level"] = lv
        frames.record(s)
        ctx.log(f"  {lv:4.0f} mT: W_t = {1e3 * (np.mean(m['vertex']) - np.mean(ref['rest']['vertex'])):.2f} mm, "
                f"centroid {1e3 * m['centroid']:.2f} mm high ({res.iterations} Newton iterations, "
                f"{time.perf_counter() - w0:.0f} s wall)")

    sim, sweep = static_magnet_sweep(ctx, NAME, data, magnet, lambda lv: magnet_offsets(magnet, lv), levels_mt,
                                     between_mt, on_read, on_start)
    return sim, ref["X0"], ref["mass"], corners, ref["rest"], rows_out, sweep, frames


def dynamic_sweep(ctx: Context, levels_mt):
    """The sweep by the dynamics (the scene file's stepped magnet path): the magnet holds HOLD s at each level and
    the shape is read at the end of each hold. Returns (sim, X0, mass, corners, rest measure, [(level, measure)],
    wall time, the frames)."""
    data = scene_data(NAME)
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    offsets = magnet_offsets(magnet, levels_mt)
    times, positions, reads = stepped_path(offsets, SETTLE, HOLD, MOVE)
    magnet["path"] = {"times": times, "positions": positions}
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    X0 = sim.model.host["positions"].astype(np.float64)
    mass = sim.model.host["mass"].astype(np.float64)
    corners = outer_vertices(data)
    ctx.log(f"triangle: {len(X0)} particles, dx = {sim.model.dx * 1e3:.2f} mm, levels {levels_mt} mT, "
            f"{reads[-1]:.2f} s simulated (dynamics)")

    def caption(s):
        pos = path_position(s.time, times, positions)
        bz = cylinder_magnet(magnet, pos).B([[0.0, 0.0, ROBOT_MID_Z]])[0, 2]
        return f"t = {s.time:.2f} s, B_z at the robot centre = {bz * 1e3:.0f} mT"

    frames = FrameRecorder(axes=(0, 2), label=caption)
    frames.record(sim)
    rest = measure(sim, X0, mass, corners)
    rows_out = []
    w0 = time.perf_counter()
    for lv, t_read in zip(levels_mt, reads):
        advance(sim, t_read, frames, FRAME_EVERY)
        m = measure(sim, X0, mass, corners)
        rows_out.append((lv, m))
        ctx.log(f"  {lv:4.0f} mT: W_t = {1e3 * (np.mean(m['vertex']) - np.mean(rest['vertex'])):.2f} mm, "
                f"centroid {1e3 * m['centroid']:.2f} mm high (t = {sim.time:.2f} s, "
                f"{time.perf_counter() - w0:.0f} s wall)")
    return sim, X0, mass, corners, rest, rows_out, time.perf_counter() - w0, frames


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.robots.continuum_soft import static_row

    levels_mt = PREVIEW_LEVELS_MT if ctx.preview else LEVELS_MT
    if ctx.preview:  # the dynamics (PREVIEW_DYNAMIC)
        sim, X0, mass, corners, rest, rows_out, wall, frames = dynamic_sweep(ctx, levels_mt)
        sweep = None
    else:
        sim, X0, mass, corners, rest, rows_out, sweep, frames = static_sweep(ctx, levels_mt, BETWEEN_MT)
        wall = sweep.wall_s

    B = np.array([lv for lv, _ in rows_out], float)
    vz0 = np.array(rest["vertex"])
    wt_each = np.array([np.array(m["vertex"]) - vz0 for _, m in rows_out]) * 1e3      # mm, (levels, 3)
    wt = wt_each.mean(axis=1)
    ht_abs = np.array([m["centroid"] for _, m in rows_out]) * 1e3
    ht = ht_abs - rest["centroid"] * 1e3
    mid = np.array([np.array(m["mid"]) - np.array(rest["mid"]) for _, m in rows_out]) * 1e3
    csv = write_csv(ctx.out / f"{NAME}.csv", {
        "B_mT": B, "warp_height_Wt_mm": wt, "Wt_vertex1_mm": wt_each[:, 0], "Wt_vertex2_mm": wt_each[:, 1],
        "Wt_vertex3_mm": wt_each[:, 2], "centroid_rise_Ht_mm": ht, "centroid_height_abs_mm": ht_abs,
        "midpoint_rise_max_mm": mid.max(axis=1),
    })
    png = plot_curve(
        ctx.out / f"{NAME}.png", B, {"vertex warp height W_t": wt, "centroid rise H_t": ht},
        "flux density at the robot B (mT)", "height (mm)", "Triangular robot: warping under the magnet",
        paper={f"W_t {k} (seed 002 Fig. 9)": ([45.0], [v]) for k, v in PAPER_WT.items()}
        | {f"H_t {k} (seed 002 Fig. 6)": ([45.0], [v]) for k, v in PAPER_HT.items()},
        note=f"dx = {sim.model.dx * 1e3:.1f} mm; magnet distance sets B_z at the robot centre; "
             + ("dynamics (preview)" if sweep is None else "equilibria (static solver)"),
    )
    gif = frames.write_gif(ctx.out / f"{NAME}.gif", title="triangle, side view (x-z)", fps=8)

    top = -1
    case = f"robot-{NAME}"
    from magsoro.validation.registry import Row, relative_error

    inputs = {"B_mT": float(B[top]), "dx_mm": sim.model.dx * 1e3}
    increments = np.diff(wt)
    spread = float((wt_each[top].max() - wt_each[top].min()) / max(wt[top], 1e-9))
    rows = [
        Row(case, "vertex warp height W_t at 45 mT (mm) vs seed 002 Fig. 9 experiment", inputs,
            PAPER_WT["exp."], float(wt[top]), relative_error(wt[top], PAPER_WT["exp."]), TOL_PAPER),
        Row(case, "centroid rise H_t at 45 mT (mm) vs seed 002 Fig. 6 experiment", inputs,
            PAPER_HT["exp."], float(ht[top]), relative_error(ht[top], PAPER_HT["exp."]), TOL_PAPER),
        # the three vertices warp by the same amount (seed 002 sec 4.3: "symmetrical deformation")
        Row(case, "spread of the three vertex heights at 45 mT / mean (symmetry)", inputs, 0.0, spread, spread, 0.10),
        # the sides rest on their midpoints (sec 4.3: "equilibrium state through the three midpoints")
        Row(case, "highest side-midpoint rise at 45 mT (mm): the robot stands on its midpoints", inputs, 0.0,
            float(mid[top].max()), float(max(mid[top].max(), 0.0)), 1.0),
        # W_t grows with the field (value: smallest rise from one level to the next, mm; error: how far it falls)
        Row(case, "smallest W_t increase between consecutive levels (mm): warp grows with B",
            {"levels_mT": list(map(float, B))},
            0.0, float(increments.min()), float(max(0.0, -increments.min())), 0.2),
    ]
    if sweep is not None:
        rows.append(static_row(case, sweep, {"levels_mT": list(map(float, B)), "dx_mm": sim.model.dx * 1e3}))
    # speeds under the moving actuator: each at least goes the right way (issue "Robot library II")
    from magsoro.robots._seed002_speeds import SETTLE as MAGNET_WAIT

    sp = speeds(ctx, scene_data(NAME), corners)
    fast = sp["warp"][-1]
    rise = float(fast[sp["key"]][-1] - fast[sp["key"]][np.searchsorted(fast["t"], MAGNET_WAIT)]) * 1e3
    along = float(-sp["loco"][-1]["dy"] * 1e3)
    v_w, v_l = fast["speed"] * 1e3, sp["loco"][-1]["speed"] * 1e3
    rows += [
        Row(case, "warping: rise of the top vertex while the magnet rises under it (mm), at least 1 mm",
            {"magnet_speed_mm_s": v_w, "dx_mm": sp["dx"] * 1e3}, 1.0, rise, float(max(0.0, 1.0 - rise)), 0.0),
        Row(case, "locomotion: centroid displacement along the magnet's pass (mm), at least 1 mm with the magnet",
            {"magnet_speed_mm_s": v_l, "dx_mm": sp["dx"] * 1e3}, 1.0, along, float(max(0.0, 1.0 - along)), 0.0),
    ]
    t = sp["table"]
    speeds_text = "; ".join(
        f"{v:.0f} mm/s: warping {w:.1f}, locomotion {lo:.1f} mm/s" if math.isfinite(lo) else f"{v:.0f} mm/s: warping {w:.1f} mm/s"
        for v, w, lo in zip(t["magnet_speed_mm_s"], t["warping_vertex_rise_rate_mm_s"],
                            t["locomotion_centroid_speed_along_magnet_mm_s"]))
    match = sp["warp_magnet_speed_for_paper_mm_s"]
    rates = t["warping_vertex_rise_rate_mm_s"]
    grows = len(rates) > 1 and bool(np.all(np.diff(rates) > 0))
    low = np.interp(10.0, B, ht) if B.max() >= 10 else float("nan")
    summary = (f"At 45 mT the vertices warp W_t = {wt[top]:.1f} mm (paper 11 mm exp. / 12 mm sim.) and the centroid "
               f"rises H_t = {ht[top]:.1f} mm (paper 3.5 / 3.7 mm); our robot already lifts below 14 mT "
               f"(H_t = {low:.1f} mm at 10 mT) where the paper's experiment stays flat, and its 2 mm thickness and "
               f"44 mT remanence are our assumptions. Under the paper's actuator (50 mT at its face) moving at a "
               f"stated speed (the paper gives none), at magnet speed {speeds_text}"
               + ("; the warping rate grows with the magnet's speed (the shape follows the magnet)"
                  if grows else "")
               + (f", the paper's 9 mm/s at a magnet rising at {match:.0f} mm/s" if match else "")
               + f"; in a pass the robot goes along with the magnet at {along / (v_l * (sp['loco'][-1]['t_pass'] - sp['loco'][-1]['t_start'])):.2f} "
               f"of its speed at {v_l:.0f} mm/s (paper 1.5 mm/s; scenes/triangle.toml describes how it is carried).")
    info = {"particles": int(len(X0)), "dx_m": sim.model.dx, "solver": "dynamics" if sweep is None else "static",
            "run_wall_s": round(wall, 1), "levels_mT": list(map(float, B)), "gif_bytes": gif.stat().st_size,
            "speeds_wall_s": round(sp["wall_s"], 1), "speeds_dx_m": sp["dx"],
            "warping_magnet_speed_for_paper_mm_s": match}
    if sweep is not None:
        info.update({"levels_on_the_way_mT": list(map(float, BETWEEN_MT)), "newton_iterations": sweep.iterations.tolist()})
    else:
        info.update({"steps": sim.steps, "sim_time_s": round(sim.time, 4)})
    figures = [{"csv": sp["csv"], "png": sp["png"],
                "caption": "warping and locomotion speeds against the speed of the magnet (seed 002 secs 4.3-4.4)"}]
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info, figures)


ROBOT = Robot(
    name=NAME,
    title="Triangular robot (warping)",
    source="seed 002 sec 4",
    quantity="vertex warp height W_t and centroid height H_t vs flux density (Figs. 6, 9)",
    sentence="A hollow 40 mm triangle with six magnetised trapezoids warps its vertices up as an N35 magnet "
             "rises under the plate; vertex and centroid heights against the field at the robot, 0 to 45 mT.",
    reproduce=reproduce,
    in_ci=True,
)
