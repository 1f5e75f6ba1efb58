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
"""

from __future__ import annotations

import copy
import time

import numpy as np

from magsoro.robots.base import (
    Context, FrameRecorder, ReproduceResult, Robot, plot_curve, scene_data, simulation, write_csv,
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


def _parts(sim, kind: str) -> list[np.ndarray]:
    """Particle indices of part ``kind`` ('p1', 'p2', 'p3') of each of the five strips."""
    body = sim.model.host["body"]
    return [np.flatnonzero(body == sim.built.body_names.index(f"s{k}_{kind}")) for k in range(1, 6)]


def _grip(ctx: Context, data: dict, levels, frames: FrameRecorder):
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

    frames.label = caption
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
    return rows, sim, time.perf_counter() - w0


def _crawl(ctx: Context, data: dict, frames: FrameRecorder):
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    times, positions = magnet["path"]["times"], magnet["path"]["positions"]
    # the whole pass also in preview (at the preview's resolution): a shorter one would not show the crawl
    sim = simulation(NAME, _with_dx(data) if ctx.preview else data, preview=False, device=ctx.device)
    mass = sim.model.host["mass"]
    frames.label = lambda s: (f"crawling: magnet centre at x = "
                              f"{path_position(s.time, times, positions)[0] * 1e3:+.0f} mm")
    frames.record(sim)
    track, w0 = [], time.perf_counter()
    t_end = float(times[-1])
    while sim.time < t_end - 1e-9:
        advance(sim, min(t_end, sim.time + FRAME_EVERY), frames, FRAME_EVERY)
        x = sim.state.x.numpy().astype(np.float64)
        c = (mass[:, None] * x).sum(0) / mass.sum()
        track.append((sim.time, path_position(sim.time, times, positions)[0], c[0], c[1], c[2], float(x[:, 2].max())))
    ctx.log(f"  crawl: centroid moved {(track[-1][2] - track[0][2]) * 1e3:+.1f} mm along x "
            f"({time.perf_counter() - w0:.0f} s wall)")
    return np.array(track), sim, time.perf_counter() - w0


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
    frames = FrameRecorder(axes=(0, 2))
    crawl_data = _faster_pass(base, PREVIEW_PASS_SPEEDUP) if ctx.preview else copy.deepcopy(base)
    track, sim_c, wall_c = _crawl(ctx, crawl_data, frames)
    grip, sim, wall_g = _grip(ctx, copy.deepcopy(base), levels, frames)

    B = np.array(levels, float)
    r0 = grip[0][0]
    closure = np.array([(r0 - r).mean() for r, _, _ in grip]) * 1e3          # mm, strips moving inwards
    closure_each = np.array([r0 - r for r, _, _ in grip]) * 1e3
    lift = np.array([(z - grip[0][1]).mean() for _, z, _ in grip]) * 1e3       # mm, outer parts rising
    top = np.array([g[2] for g in grip]) * 1e3
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
                     note=f"dx = {sim.model.dx * 1e3:.1f} mm; 90 % of the closure at {sat:.0f} mT "
                          f"(seed 002 sec 5.2: maximum deformation at 35 mT)")
    plot_curve(ctx.out / f"{NAME}_crawl.png", track[:, 1] * 1e3,
               {"centroid x": (track[:, 2] - track[0, 2]) * 1e3, "centroid height": track[:, 4] * 1e3},
               "magnet centre x (mm)", "mm", "Pentagram robot: one pass of the magnet (downward field)",
               note="displacement of the robot's centroid along the pass")
    gif = frames.write_gif(ctx.out / f"{NAME}.gif", title="pentagram, side view (x-z)", fps=8)

    from magsoro.validation.registry import Row

    case = f"robot-{NAME}"
    disp = float((track[-1, 2] - track[0, 2]) * 1e3)
    pass_s, magnet_speed = _pass(crawl_data)
    speed = disp / pass_s                          # mm/s: the displacement over the time the magnet moves
    end_z = float(track[-1, 4] * 1e3)
    passed = np.flatnonzero(track[:, 1] >= track[:, 2])      # frames after the magnet's centre passed the centroid
    trailing = float((track[-1, 2] - track[passed[0], 2]) * 1e3) if len(passed) else 0.0
    spread = float((closure_each[-1].max() - closure_each[-1].min()) / max(closure[-1], 1e-9))
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
    ]
    shape = ("lies flat again" if end_z < FLAT_CENTROID_Z else
             f"ends folded in a heap (centroid {end_z:.0f} mm high, 1.4 mm when flat), not the paper's gait of Fig. 14a")
    # most of the displacement after the magnet's centre passed the robot's: its trailing rim carried the robot
    carried = " (carried by its trailing rim)" if trailing > 0.5 * disp > 0.0 else ""
    summary = (f"Gripping: the strips close by {closure[-1]:.1f} mm at 45 mT and reach 90 % of that at {sat:.0f} mT "
               f"(paper: maximum deformation at 35 mT); crawling: one pass of the magnet along the underside of the "
               f"plate at {magnet_speed * 1e3:.0f} mm/s moves the robot {disp:+.1f} mm along the pass (mean "
               f"{speed:.0f} mm/s over the pass; paper: {PAPER_CRAWL_SPEED} mm/s at a magnet speed it does not give), "
               f"{trailing:+.1f} mm of it after the magnet's centre has passed the robot's{carried}; it folds (peak "
               f"height {track[:, 5].max() * 1e3:.0f} mm) and {shape}. Hinge lengths, the robot's remanence, the "
               f"magnet's speed and exact placement are our assumptions.")
    info = {"particles": int(len(sim.model.host["positions"])), "dx_m": sim.model.dx, "levels_mT": list(map(float, B)),
            "crawl_displacement_mm": disp, "crawl_peak_height_mm": float(track[:, 5].max() * 1e3),
            "crawl_magnet_speed_mm_s": magnet_speed * 1e3, "crawl_mean_speed_mm_s": speed,
            "paper_crawl_speed_mm_s": PAPER_CRAWL_SPEED, "crawl_end_centroid_z_mm": end_z,
            "crawl_displacement_after_magnet_passed_mm": trailing,
            "saturation_level_mT": sat, "run_wall_s": round(wall_c + wall_g, 1), "gif_bytes": gif.stat().st_size,
            "crawl_csv": crawl_csv.name}
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info)


ROBOT = Robot(
    name=NAME,
    title="Pentagram-shaped robot (gripping and crawling)",
    source="seed 002 sec 5.2",
    quantity="grip closure vs flux density (saturation level, Fig. 14b) and displacement in one magnet pass (Fig. 14a)",
    sentence="Five strips of thick magnetised parts on thin hinges curl into a gripper under an upward field and "
             "are dragged by a magnet passed beneath them; closure against the field and displacement per pass.",
    reproduce=reproduce,
)
