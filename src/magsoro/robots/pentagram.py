"""Pentagram-shaped robot of seed 002 sec 5.2 (Figs. 13-14): five 40 mm strips of thick (3 mm) parts joined by
thin (1 mm) hinges, the parts magnetised up / outwards / down from the centre out. Two behaviours:

- gripping (Fig. 14b): under an upward field the strips curl into a gripper, fully deformed at 35 mT according
  to the paper. Reproduced as a field sweep (the N35 magnet of seed 002 sec 3, north face up, centred under the
  robot at the distance giving each level, as for the triangle and the cross); the deformation is the closure of
  the strips (how far the outermost parts move in towards the centre), and the level at which it saturates is
  compared with the paper's 35 mT.
- crawling (Fig. 14a): a downward field passed under the robot; the paper reports a crawl in the magnet's
  direction (3.5 mm/s). Reproduced by one pass of the scene's magnet (south face up) along the underside of the
  plate, as in the paper's experiment (seed 002 sec 4.1: 50 mT at the centre of the magnet's face); the quantities
  are the robot's displacement along the pass and its mean speed over the pass (the paper gives no magnet speed).
  The grip sweep uses the N35 of sec 3 instead (``GRIP_REMANENCE``), not the scene's crawl magnet.

The paper describes the crawl's gait on one strip (Fig. 14a): with the magnet under the strip's outermost part
(part 3) the middle part (part 2) is lifted into an arch; with the magnet under the robot's centre the strip
stands as a centrosymmetric table, part 2 upright between parts 1 and 3 lying parallel. The paper gives no hinge
lengths, so the full run looks for that gait with hinges of 1, 3 and 5 mm (the thick parts sharing the rest of
the 40 mm strip) at the scene's 200 mm/s and at 50 mm/s: six crawls, each read on strip 1 (along -x, the first
the magnet meets) at the four moments of the figure, with side views of each.
"""

from __future__ import annotations

import copy
import math
import time

import numpy as np

from magsoro.robots.base import (
    Context, FrameRecorder, Job, ReproduceResult, Robot, RobotError, _save, plot_curve, run_jobs, scene_data,
    simulation, write_csv,
)
from magsoro.robots.triangle import advance, cylinder_magnet, magnet_distance, path_position, stepped_path

NAME = "pentagram"
LEVELS_MT = [0, 5, 10, 15, 20, 25, 30, 35, 40, 45]
PREVIEW_LEVELS_MT = [0, 15, 35, 45]
#: the preview's crawl runs the magnet's pass this many times faster (400 mm/s; _faster_pass)
PREVIEW_PASS_SPEEDUP = 2.0
FIRST_HOLD, HOLD, MOVE = 0.04, 0.06, 0.02   # s (grip sweep)
FRAME_EVERY = 0.04
MID_Z = 0.0015       # m: mid-plane of the 3 mm thick parts lying on the plate
PAPER_SATURATION_MT = 35.0   # seed 002 sec 5.2: "maximum deformation when the magnetic density is 35 mT"
SATURATION_FRACTION = 0.9    # the level where the closure first reaches 90 % of its largest value
TOL_SATURATION_MT = 10.0
GRIP_REMANENCE = 1.21        # T: the grip sweep's magnet, the N35 of seed 002 sec 3 (the scene's magnet is the crawl's)
PAPER_CRAWL_SPEED = 3.5      # mm/s, seed 002 sec 5.2 (magnet speed not given)
FLAT_CENTROID_Z = 3.0        # mm: above this the robot's centroid is not lying flat (1.4 mm when flat)
STRIP_LENGTH = 0.040         # m: each strip, thick parts and hinges (seed 002 sec 5.2)
HUB_INRADIUS = 0.003441      # m: where the strips start (the central pentagon of 5 mm sides; scenes/pentagram.toml)
#: the gait study (full run): hinge lengths (m; the paper gives none) and magnet speeds (m/s; the scene's 200 and a
#: quarter of it), every pair; the preview looks for the gait in its one crawl
HINGE_LENGTHS = [1.0e-3, 3.0e-3, 5.0e-3]
GAIT_SPEEDS = [0.2, 0.05]
GAIT_SAMPLE = 0.002          # m of magnet travel between a crawl's samples
#: Fig. 14a1's arch: part 2 lifted by a part's thickness or more while part 3 stays within one cell of where it lay
#: (the grid's contact with the plate sets a part that lands again down up to a cell above it)
ARCH_LIFT = 3.0e-3
#: Fig. 14a3's table: part 2 "approximately perpendicular" to part 1 (deg) and part 1 "parallel" to part 3 (deg)
TABLE_RIGHT = (60.0, 120.0)
TABLE_PARALLEL = 30.0
#: the displacement per pass at the two magnet speeds within this fraction: the pass is quasi-static
SPEED_TOL = 0.10


def _parts(sim, kind: str) -> list[np.ndarray]:
    """Particle indices of part ``kind`` ('p1', 'p2', 'p3') of each of the five strips."""
    body = sim.model.host["body"]
    return [np.flatnonzero(body == sim.built.body_names.index(f"s{k}_{kind}")) for k in range(1, 6)]


def with_hinges(data: dict, hinge: float) -> dict:
    """The scene with hinges ``hinge`` (m) long: each 40 mm strip split into three thick parts of (40 mm - 2
    hinge) / 3 and two hinges, from the hub's edge out (the scene's own: 10 mm parts, 5 mm hinges)."""
    length = (STRIP_LENGTH - 2.0 * hinge) / 3.0
    if not 0.0 < hinge < STRIP_LENGTH / 2.0 or length <= 0.0:
        raise RobotError(f"{NAME}: hinge length {hinge * 1e3:g} mm leaves no thick parts in a "
                         f"{STRIP_LENGTH * 1e3:g} mm strip")
    edges = np.cumsum([HUB_INRADIUS, length, hinge, length, hinge, length])
    kinds = ["p1", "h1", "p2", "h2", "p3"]
    d = copy.deepcopy(data)
    for b in d["bodies"]:
        kind = b["name"].split("_")[-1]
        if b["name"] == "hub" or kind not in kinds:
            continue
        i = kinds.index(kind)
        a, c = float(edges[i]), float(edges[i + 1])
        w = max(abs(v[1]) for v in b["shape"]["vertices"])
        b["shape"]["vertices"] = [[a, -w], [c, -w], [c, w], [a, w]]
    return d


def _strip_axis(x: np.ndarray, s: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Unit axis of a part (particles ``idx`` at positions ``x``): the slope dx/ds of the straight line fitted
    through them against their reference coordinate ``s`` along the strip, outwards."""
    A = np.stack([np.ones(len(idx)), s[idx]], axis=1)
    coef = np.linalg.lstsq(A, x[idx], rcond=None)[0]
    return coef[1] / max(float(np.linalg.norm(coef[1])), 1e-300)


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (deg) between unit vectors."""
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def crawl(ctx: Context, data: dict, hinge: float | None = None, animate: bool = False) -> dict:
    """One pass of the scene's magnet under the robot (hinges ``hinge`` m long, the scene's when None), sampled
    every GAIT_SAMPLE of magnet travel: the centroid, the highest point and the moments of seed 002 Fig. 14a on
    strip 1 (along -x, the first the magnet meets): the magnet's centre under its outermost part (a1), under its
    hinge between parts 1 and 2 (a2), under the hub (a3) and under the first hinges of the two strips on the far
    side (a4). At each moment: the particles' positions, the three parts' heights and axes and the angles between
    them. ``animate``: frames for the GIF every FRAME_EVERY (``frames``, without its caption function)."""
    d = copy.deepcopy(data) if hinge is None else with_hinges(data, hinge)
    magnet = next(f for f in d["fields"] if f.get("name") == "magnet")
    times, positions = magnet["path"]["times"], magnet["path"]["positions"]
    _, speed = _pass(d)
    # the whole pass also in preview (at the preview's resolution): a shorter one would not show the crawl
    sim = simulation(NAME, _with_dx(d) if ctx.preview else d, preview=False, device=ctx.device)
    mass = sim.model.host["mass"].astype(np.float64)
    X0 = sim.model.host["positions"].astype(np.float64)
    s = -X0[:, 0]  # strip 1 points along -x: its reference coordinate outwards
    body, names = sim.model.host["body"], sim.built.body_names
    ids = {n: np.flatnonzero(body == names.index(n)) for n in names}
    parts = [ids[f"s1_{k}"] for k in ("p1", "p2", "p3")]
    z0 = [float(X0[i, 2].mean()) for i in parts]
    targets = {"a1": ids["s1_p3"], "a2": ids["s1_h1"], "a3": ids["hub"],
               "a4": np.concatenate([ids["s3_h1"], ids["s4_h1"]])}
    frames = None
    if animate:
        frames = FrameRecorder(axes=(0, 2))
        frames.label = lambda sm: (f"crawling: magnet centre at x = "
                                   f"{path_position(sm.time, times, positions)[0] * 1e3:+.0f} mm")
        frames.record(sim)
    moments, track, w0 = {}, [], time.perf_counter()
    t_end, sample = float(times[-1]), GAIT_SAMPLE / speed
    while True:
        x = sim.state.x.numpy().astype(np.float64)
        c = (mass[:, None] * x).sum(0) / mass.sum()
        mx = path_position(sim.time, times, positions)[0]
        track.append((sim.time, mx, c[0], c[1], c[2], float(x[:, 2].max())))
        for key, idx in targets.items():
            if key not in moments and mx >= float(x[idx, 0].mean()):
                axes = [_strip_axis(x, s, i) for i in parts]
                moments[key] = {
                    "t": sim.time, "magnet_x": mx, "x": x.astype(np.float32),
                    "rise": [float(x[i, 2].mean()) - z for i, z in zip(parts, z0)],
                    "tilt": [float(np.degrees(np.arcsin(np.clip(a[2], -1.0, 1.0)))) for a in axes],
                    "angle_12": _angle(axes[0], axes[1]), "angle_13": _angle(axes[0], axes[2]),
                    "angle_23": _angle(axes[1], axes[2])}
        if sim.time >= t_end - 1e-9:
            break
        advance(sim, min(t_end, sim.time + sample), frames, FRAME_EVERY)
    label = f"hinges {hinge * 1e3:g} mm, " if hinge is not None else ""
    ctx.log(f"  crawl ({label}magnet at {speed * 1e3:g} mm/s): centroid moved "
            f"{(track[-1][2] - track[0][2]) * 1e3:+.1f} mm along x ({time.perf_counter() - w0:.0f} s wall)")
    if frames is not None:
        frames.label = None  # the run's result travels back from a worker process
    return {"track": np.array(track), "moments": moments, "hinge": hinge if hinge is not None else _hinge(data),
            "speed": speed, "dx": sim.model.dx, "particles": int(len(mass)), "wall_s": time.perf_counter() - w0,
            "body": body.copy(), "strip1": {k: ids[f"s1_{k}"] for k in ("p1", "h1", "p2", "h2", "p3")},
            "frames": frames}


def _hinge(data: dict) -> float:
    """The scene's hinge length (m): strip 1's first hinge."""
    b = next(b for b in data["bodies"] if b["name"] == "s1_h1")
    xs = [v[0] for v in b["shape"]["vertices"]]
    return float(max(xs) - min(xs))


def gait(run: dict) -> dict:
    """Whether a :func:`crawl` shows seed 002's gait of Fig. 14a on strip 1: the arch (a1: the magnet under part 3,
    part 2 lifted by ARCH_LIFT or more while part 3 stays within a cell of where it lay) and the centrosymmetric
    table (a3: the magnet under the hub, part 2 at TABLE_RIGHT to part 1, parts 1 and 3 within TABLE_PARALLEL of
    parallel). A moment the magnet never reached counts as not shown."""
    a1, a3 = run["moments"].get("a1"), run["moments"].get("a3")
    arch = a1 is not None and a1["rise"][1] >= ARCH_LIFT and abs(a1["rise"][2]) <= run["dx"]
    table = (a3 is not None and TABLE_RIGHT[0] <= a3["angle_12"] <= TABLE_RIGHT[1]
             and a3["angle_13"] <= TABLE_PARALLEL)
    return {"arch": bool(arch), "table": bool(table)}


def gait_views(png, runs: list[dict], title: str):
    """PNG: one row per :func:`crawl` in ``runs``, one column per moment of Fig. 14a (a1 to a4), the robot seen
    from the side (x, z), strip 1's parts coloured, the rest grey, the magnet's face drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = ["a1", "a2", "a3", "a4"]
    where = {"a1": "under strip 1's part 3", "a2": "under its hinge 1", "a3": "under the hub",
             "a4": "under the far hinges"}
    colours = {"p1": "tab:blue", "h1": "0.35", "p2": "tab:orange", "h2": "0.35", "p3": "tab:green"}
    fig, axes = plt.subplots(len(runs), 4, figsize=(13.0, 2.3 * len(runs)), squeeze=False)
    for row, run in zip(axes, runs):
        strip = np.concatenate(list(run["strip1"].values()))
        rest = np.setdiff1d(np.arange(run["particles"]), strip)
        for ax, key in zip(row, keys):
            m = run["moments"].get(key)
            ax.set_xlim(-70, 70), ax.set_ylim(-12, 32), ax.set_aspect("equal"), ax.tick_params(labelsize=7)
            ax.axhline(0.0, color="0.5", lw=0.8)
            if m is None:
                ax.set_title(f"hinges {run['hinge'] * 1e3:g} mm: magnet never {where[key]}", fontsize=8)
                continue
            x = 1e3 * m["x"].astype(np.float64)
            centre = float(x[:, 0].mean())
            ax.scatter(x[rest, 0] - centre, x[rest, 2], s=0.6, c="0.78", linewidths=0)
            for k, idx in run["strip1"].items():
                ax.scatter(x[idx, 0] - centre, x[idx, 2], s=1.2, c=colours[k], linewidths=0)
            ax.add_patch(plt.Rectangle((1e3 * m["magnet_x"] - centre - 50.0, -11.0), 100.0, 10.0, color="0.85", zorder=0))
            ax.set_title(f"hinges {run['hinge'] * 1e3:g} mm, {run['speed'] * 1e3:g} mm/s: magnet {where[key]}\n"
                         f"parts 1-2 {m['angle_12']:.0f} deg, 1-3 {m['angle_13']:.0f} deg, rise of part 2 "
                         f"{1e3 * m['rise'][1]:.1f} mm", fontsize=7)
    fig.suptitle(f"{title}; side view (x about the robot's centre, z; mm): strip 1's parts 1 (blue), 2 (orange), "
                 f"3 (green), hinges dark grey, the other strips light grey", fontsize=9)
    fig.set_dpi(100)
    fig.tight_layout()
    _save(fig, png)
    plt.close(fig)
    return png


def grip(ctx: Context, data: dict, levels) -> dict:
    """The gripping sweep: the N35 magnet (north face up) centred under the robot at the distance of each field
    level; per level the outer parts' distances from the centre and heights and the highest point. Returns those
    with the run's frames (without their caption function) and facts."""
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    magnet["remanence"] = GRIP_REMANENCE                      # north face up: upward field (Fig. 14b)
    offsets = [[0.0, 0.0, MID_Z - magnet_distance(magnet, lv * 1e-3, (0.0, 0.0, MID_Z))] for lv in levels]
    times, positions, reads = stepped_path(offsets, FIRST_HOLD, HOLD, MOVE)
    magnet["path"] = {"times": times, "positions": positions}
    data["simulation"]["duration"] = reads[-1]
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    p3, mass = _parts(sim, "p3"), sim.model.host["mass"]

    def caption(s):
        bz = cylinder_magnet(magnet, path_position(s.time, times, positions)).B([[0.0, 0.0, MID_Z]])[0, 2]
        return f"gripping: B_z at the centre = {bz * 1e3:+.0f} mT"

    frames = FrameRecorder(axes=(0, 2), label=caption)
    frames.record(sim)
    rows, w0 = [], time.perf_counter()
    for lv, t_read in zip(levels, reads):
        advance(sim, t_read, frames, FRAME_EVERY)
        x = sim.state.x.numpy().astype(np.float64)
        centre = (mass[:, None] * x).sum(0) / mass.sum()
        c3 = np.array([x[i].mean(axis=0) for i in p3])               # outermost parts' centres
        radius = np.linalg.norm(c3[:, :2] - centre[:2], axis=1)
        rows.append((radius, c3[:, 2], float(x[:, 2].max())))
        ctx.log(f"  grip {lv:4.0f} mT: outer parts at {radius.mean() * 1e3:.1f} mm from the centre, "
                f"{c3[:, 2].mean() * 1e3:.1f} mm high ({time.perf_counter() - w0:.0f} s wall)")
    frames.label = None
    return {"rows": rows, "frames": frames, "dx": sim.model.dx, "particles": int(len(mass)),
            "wall_s": time.perf_counter() - w0}


def _pass(data: dict) -> tuple[float, float]:
    """Duration (s) and speed (m/s) of the magnet's pass: the path's longest leg along x (the scene waits, passes
    under the robot and rests)."""
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    t, x = np.asarray(magnet["path"]["times"], float), np.asarray(magnet["path"]["positions"], float)[:, 0]
    k = int(np.argmax(np.abs(np.diff(x))))
    return float(t[k + 1] - t[k]), float(abs(x[k + 1] - x[k]) / (t[k + 1] - t[k]))


def _faster_pass(data: dict, factor: float) -> dict:
    """The scene with the magnet's path ``factor`` times faster after its first keyframe interval (the wait before
    the pass keeps its length). The preview's crawl: the displacement per pass hardly depends on the magnet's speed
    (+54.7 / +55.3 / +54.4 mm at 200 / 100 / 50 mm/s, full runs), so a faster pass shows the same crawl in less
    time."""
    d = copy.deepcopy(data)
    magnet = next(f for f in d["fields"] if f.get("name") == "magnet")
    times = [float(t) for t in magnet["path"]["times"]]
    t1 = times[1]
    magnet["path"]["times"] = times[:2] + [t1 + (t - t1) / factor for t in times[2:]]
    return d


def _with_dx(data: dict) -> dict:
    """The scene with its [preview] dx and particles per cell (the crawl always runs the whole pass)."""
    d = copy.deepcopy(data)
    for key in ("dx", "particles_per_cell"):
        if key in d.get("preview", {}):
            d["simulation"][key] = d["preview"][key]
    return d


def reproduce(ctx: Context) -> ReproduceResult:
    levels = PREVIEW_LEVELS_MT if ctx.preview else LEVELS_MT
    base = scene_data(NAME)
    _, scene_speed = _pass(base)
    scene_hinge = _hinge(base)
    # the crawls: (hinge length or None for the scene's, magnet speed); the first is the main one (the GIF's)
    if ctx.preview:
        plan = [(None, scene_speed * PREVIEW_PASS_SPEEDUP)]
    else:
        plan = [(None if math.isclose(h, scene_hinge) else h, v) for v in GAIT_SPEEDS for h in HINGE_LENGTHS]
        plan.sort(key=lambda hv: (hv[0] is not None or not math.isclose(hv[1], scene_speed), hv[0] or scene_hinge))
    jobs = [Job(crawl, ctx, (_faster_pass(base, v / scene_speed), h), {"animate": k == 0},
                label=f"crawl, hinges {(h or scene_hinge) * 1e3:g} mm, {v * 1e3:g} mm/s") for k, (h, v) in enumerate(plan)]
    # the longest first: the slow passes, then the grip sweep, then the fast passes
    order = sorted(range(len(jobs)), key=lambda k: plan[k][1])
    jobs = [jobs[k] for k in order] + [Job(grip, ctx, (copy.deepcopy(base), levels), label="grip")]
    done = run_jobs(ctx, jobs)
    g = done.pop()
    crawls = [None] * len(plan)
    for k, run in zip(order, done):
        crawls[k] = run
    main = crawls[0]
    track, grip_rows, frames = main["track"], g["rows"], main["frames"]
    frames.frames += g["frames"].frames          # one animation: the crawl, then the grip (same particle order)

    B = np.array(levels, float)
    r0 = grip_rows[0][0]
    closure = np.array([(r0 - r).mean() for r, _, _ in grip_rows]) * 1e3          # mm, strips moving inwards
    closure_each = np.array([r0 - r for r, _, _ in grip_rows]) * 1e3
    lift = np.array([(z - grip_rows[0][1]).mean() for _, z, _ in grip_rows]) * 1e3       # mm, outer parts rising
    top = np.array([row[2] for row in grip_rows]) * 1e3
    sat = float(B[np.argmax(closure >= SATURATION_FRACTION * closure.max())]) if closure.max() > 0 else float("nan")

    csv = write_csv(ctx.out / f"{NAME}.csv", {
        "B_mT": B, "grip_closure_mm": closure, "outer_parts_rise_mm": lift, "highest_point_mm": top,
        **{f"closure_strip{k + 1}_mm": closure_each[:, k] for k in range(5)},
    })
    crawl_csv = write_csv(ctx.out / f"{NAME}_crawl.csv", {
        "t_s": track[:, 0], "magnet_x_mm": track[:, 1] * 1e3, "centroid_x_mm": track[:, 2] * 1e3,
        "centroid_y_mm": track[:, 3] * 1e3, "centroid_z_mm": track[:, 4] * 1e3, "highest_point_mm": track[:, 5] * 1e3,
        "centroid_speed_x_mm_s": np.gradient(track[:, 2], track[:, 0]) * 1e3,
    })
    png = plot_curve(ctx.out / f"{NAME}.png", B, {"grip closure (outer parts towards the centre)": closure,
                                                  "rise of the outer parts": lift},
                     "flux density at the robot B (mT)", "deformation (mm)", "Pentagram robot: gripping (upward field)",
                     note=f"dx = {g['dx'] * 1e3:.1f} mm; 90 % of the closure at {sat:.0f} mT "
                          f"(seed 002 sec 5.2: maximum deformation at 35 mT)")
    crawl_png = plot_curve(ctx.out / f"{NAME}_crawl.png", track[:, 1] * 1e3,
                           {"centroid x": (track[:, 2] - track[0, 2]) * 1e3, "centroid height": track[:, 4] * 1e3},
                           "magnet centre x (mm)", "mm", "Pentagram robot: one pass of the magnet (downward field)",
                           note="displacement of the robot's centroid along the pass")
    gif = frames.write_gif(ctx.out / f"{NAME}.gif", title="pentagram, side view (x-z)", fps=8)

    # the gait study: every crawl's moments of Fig. 14a on strip 1
    gaits = [gait(r) for r in crawls]
    disp_of = [float((r["track"][-1, 2] - r["track"][0, 2]) * 1e3) for r in crawls]

    def at(r, key, f):
        m = r["moments"].get(key)
        return f(m) if m is not None else float("nan")

    gait_csv = write_csv(ctx.out / f"{NAME}_gait.csv", {
        "hinge_mm": [r["hinge"] * 1e3 for r in crawls], "magnet_speed_mm_s": [r["speed"] * 1e3 for r in crawls],
        "displacement_mm": disp_of, "end_centroid_z_mm": [r["track"][-1, 4] * 1e3 for r in crawls],
        "peak_height_mm": [r["track"][:, 5].max() * 1e3 for r in crawls],
        "a1_part2_rise_mm": [at(r, "a1", lambda m: 1e3 * m["rise"][1]) for r in crawls],
        "a1_part3_rise_mm": [at(r, "a1", lambda m: 1e3 * m["rise"][2]) for r in crawls],
        "a3_angle_parts12_deg": [at(r, "a3", lambda m: m["angle_12"]) for r in crawls],
        "a3_angle_parts13_deg": [at(r, "a3", lambda m: m["angle_13"]) for r in crawls],
        "a3_part1_rise_mm": [at(r, "a3", lambda m: 1e3 * m["rise"][0]) for r in crawls],
        "arch_a1": [int(q["arch"]) for q in gaits], "table_a3": [int(q["table"]) for q in gaits],
        "wall_s": [r["wall_s"] for r in crawls],
    })
    views = gait_views(ctx.out / f"{NAME}_gait.png", crawls, "Pentagram robot: strip 1 at the moments of Fig. 14a")

    from magsoro.validation.registry import Row

    case = f"robot-{NAME}"
    disp = disp_of[0]
    pass_s, magnet_speed = _pass(_faster_pass(base, main["speed"] / scene_speed))
    speed = disp / pass_s                          # mm/s: the displacement over the time the magnet moves
    end_z = float(track[-1, 4] * 1e3)
    passed = np.flatnonzero(track[:, 1] >= track[:, 2])      # samples after the magnet's centre passed the centroid
    trailing = float((track[-1, 2] - track[passed[0], 2]) * 1e3) if len(passed) else 0.0
    spread = float((closure_each[-1].max() - closure_each[-1].min()) / max(closure[-1], 1e-9))
    tables = sum(q["table"] for q in gaits)
    arches = sum(q["arch"] for q in gaits)
    studied = sorted({r["hinge"] * 1e3 for r in crawls})
    gait_inputs = {"hinges_mm": studied, "magnet_speeds_mm_s": sorted({r["speed"] * 1e3 for r in crawls})}
    rows = [
        Row(case, "gripping: lowest level reaching 90 % of the closure (mT) vs seed 002 sec 5.2 (35 mT)",
            {"levels_mT": list(map(float, B))}, PAPER_SATURATION_MT, sat, abs(sat - PAPER_SATURATION_MT),
            TOL_SATURATION_MT),
        # the five strips close alike (symmetric gripper, Fig. 14b): spread of their closure / mean at 45 mT
        Row(case, "gripping: spread of the five strips' closure at 45 mT / mean", {"B_mT": float(B[-1])}, 0.0,
            spread, spread, 0.25),
        # the outer parts rise off the plate (the strips curl up into a gripper), at least 5 mm at 45 mT
        Row(case, "gripping: rise of the outer parts at 45 mT (mm), at least 5 mm", {"B_mT": float(B[-1])}, 5.0,
            float(lift[-1]), float(max(0.0, 5.0 - lift[-1])), 0.0),
        # crawling: the robot moves along with the magnet (seed 002 sec 5.2), by at least 1 mm in one pass
        Row(case, "crawling: centroid displacement along the magnet's pass (mm), at least +1 mm",
            {"pass_mm": float((track[-1, 1] - track[0, 1]) * 1e3), "magnet_speed_mm_s": magnet_speed * 1e3},
            1.0, disp, float(max(0.0, 1.0 - disp)), 0.0),
        # the paper's gait (Fig. 14a3): strip 1 a centrosymmetric table with the magnet under the hub, in at least
        # one of the crawls (hinge lengths and magnet speeds: the paper gives neither)
        Row(case, "crawling: crawls showing the table shape of Fig. 14a3 (magnet under the hub: part 2 at 60-120 deg "
                  "to part 1, parts 1 and 3 within 30 deg of parallel), at least 1",
            gait_inputs | {"crawls": len(crawls)}, 1.0, float(tables), float(max(0, 1 - tables)), 0.0),
    ]
    if not ctx.preview:
        slow = next(k for k, (h, v) in enumerate(plan) if h is None and not math.isclose(v, scene_speed))
        gap = abs(disp_of[slow] - disp) / max(abs(disp), 1e-9)
        rows.append(Row(case, f"crawling: displacement per pass at {plan[slow][1] * 1e3:g} against "
                              f"{scene_speed * 1e3:g} mm/s (the scene's hinges), |difference| / the latter",
                        {"displacements_mm": [disp_of[slow], disp]}, 0.0, gap, gap, SPEED_TOL))
    shape = ("lies flat again" if end_z < FLAT_CENTROID_Z else
             f"ends folded in a heap (centroid {end_z:.0f} mm high, 1.4 mm when flat), not the paper's gait of Fig. 14a")
    # most of the displacement after the magnet's centre passed the robot's: its trailing rim carried the robot
    carried = " (carried by its trailing rim)" if trailing > 0.5 * disp > 0.0 else ""
    study = (f"; the gait of Fig. 14a on strip 1 over {len(crawls)} crawl{'s' if len(crawls) > 1 else ''} (hinges "
             f"{', '.join(f'{h:g}' for h in studied)} mm"
             + (f", magnet at {', '.join(f'{v:g}' for v in gait_inputs['magnet_speeds_mm_s'])} mm/s" if len(crawls) > 1 else "")
             + f"): the arch of a1 in {arches}, the table of a3 in {tables}")
    summary = (f"Gripping: the strips close by {closure[-1]:.1f} mm at 45 mT and reach 90 % of that at {sat:.0f} mT "
               f"(paper: maximum deformation at 35 mT); crawling: one pass of the magnet along the underside of the "
               f"plate at {magnet_speed * 1e3:.0f} mm/s moves the robot {disp:+.1f} mm along the pass (mean "
               f"{speed:.0f} mm/s over the pass; paper: {PAPER_CRAWL_SPEED} mm/s at a magnet speed it does not give), "
               f"{trailing:+.1f} mm of it after the magnet's centre has passed the robot's{carried}; it folds (peak "
               f"height {track[:, 5].max() * 1e3:.0f} mm) and {shape}{study}. Hinge lengths, the robot's remanence, "
               f"the magnet's speed and exact placement are our assumptions.")
    info = {"particles": g["particles"], "dx_m": g["dx"], "levels_mT": list(map(float, B)),
            "crawl_displacement_mm": disp, "crawl_peak_height_mm": float(track[:, 5].max() * 1e3),
            "crawl_magnet_speed_mm_s": magnet_speed * 1e3, "crawl_mean_speed_mm_s": speed,
            "paper_crawl_speed_mm_s": PAPER_CRAWL_SPEED, "crawl_end_centroid_z_mm": end_z,
            "crawl_displacement_after_magnet_passed_mm": trailing,
            "saturation_level_mT": sat, "run_wall_s": round(sum(r["wall_s"] for r in crawls) + g["wall_s"], 1),
            "gif_bytes": gif.stat().st_size, "crawl_csv": crawl_csv.name,
            "gait": [{"hinge_mm": r["hinge"] * 1e3, "magnet_speed_mm_s": r["speed"] * 1e3, "displacement_mm": dd,
                      **q} for r, dd, q in zip(crawls, disp_of, gaits)]}
    figures = [{"csv": crawl_csv, "png": crawl_png, "caption": "the scene's crawl: the centroid along the pass"},
               {"csv": gait_csv, "png": views,
                "caption": "strip 1 (along -x, the first the magnet meets) at the moments of Fig. 14a, per hinge "
                           "length and magnet speed: the magnet under its outermost part (a1), under its first hinge "
                           "(a2), under the hub (a3) and under the far strips' first hinges (a4)"}]
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info, figures)


ROBOT = Robot(
    name=NAME,
    title="Pentagram-shaped robot (gripping and crawling)",
    source="seed 002 sec 5.2",
    quantity="grip closure vs flux density (saturation level, Fig. 14b) and displacement in one magnet pass (Fig. 14a)",
    sentence="Five strips of thick magnetised parts on thin hinges curl into a gripper under an upward field and "
             "are dragged by a magnet passed beneath them; closure against the field and displacement per pass.",
    reproduce=reproduce,
)
