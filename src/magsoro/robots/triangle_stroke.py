"""Triangular robot of seed 002 (sec 4.2, Fig. 4c) taking one stroke of the paper's actuator at a hand's speed, by
the implicit integrator (scenes/triangle_stroke.toml).

The paper moves the actuator by hand "from one of the vertex to its opposite side" and reports a locomotion speed
of 1.5 mm/s, with neither the magnet's path nor its speed. Read as a stroke (magsoro.robots._seed002_speeds.
stroke_run): the magnet rises under the top vertex from 80 mm below the plate, moves level to under the middle of
the opposite side and goes down again, every leg at one speed. The reproduction runs the stroke at 5, 10 and 20
mm/s (the preview: 20 mm/s on the coarse grid) and reads

- how far the robot's centroid goes along the stroke (the magnet down again), and while the magnet moves level;
- how fast the top vertex rises while the magnet rises under it (the warping run of ``magsoro reproduce
  triangle``, seed 002 sec 4.3: 9 mm/s);
- the robot's speed the paper's 1.5 mm/s compares with: the displacement per stroke over the stroke's time, at
  the magnet speed that makes the paper's warping speed (the vertex's rise rate grows in proportion to the magnet's
  speed, so that speed follows from the three runs).

The full run also strokes at 20 mm/s on the preview grid, for the convergence row.
"""

from __future__ import annotations

import math

import numpy as np

from magsoro.robots.base import Context, ReproduceResult, Robot, plot_courses, plot_curve, scene_data, write_csv

NAME = "triangle_stroke"
SPEEDS = [0.005, 0.01, 0.02]   # m/s (preview: the last)
#: magnet travel per implicit step (m): the first step and the largest the steps grow to after easy ones. On the
#: preview grid 0.25 to 1 mm gave the displacements of 0.25 mm throughout to 0.01 mm (benchmarks/README.md); the
#: preview itself steps 0.5 to 2 mm (4 to 7 % off those) to stay within a few minutes
STEPS = (0.25e-3, 1.0e-3)
PREVIEW_STEPS = (0.5e-3, 2.0e-3)
PAPER_LOCO_SPEED = 1.5   # mm/s, seed 002 sec 4.2 (Fig. 4c)
PAPER_WARP_SPEED = 9.0   # mm/s, seed 002 sec 4.3 (Fig. 7c)
#: the robot's speed is checked against the paper's within this factor either way (the paper gives neither the
#: magnet's path nor its speed, so a stroke's length and time are ours)
SPEED_FACTOR = 2.0
#: the displacement per stroke at 5 and 20 mm/s within this fraction of each other: at hand speeds the robot's
#: inertia is negligible and the stroke is quasi-static
QUASI_STATIC_TOL = 0.10
#: the displacement per stroke on the two grids within this fraction (issue "The seeds' slow experiments")
CONVERGENCE_TOL = 0.10


def _ends(data: dict):
    """The stroke's start (the top vertex) and end (the middle of the opposite side), (x, y) in m."""
    from magsoro.robots.triangle import outer_vertices

    corners = outer_vertices(data)
    i = int(np.argmax(corners[:, 1]))
    return corners[i], 0.5 * (corners[(i + 1) % 3] + corners[(i + 2) % 3])


def _near(X0, centre, radius: float) -> dict:
    """The material within ``radius`` (m) of ``centre`` (x, y) in the plane: the top vertex (stroke_run's markers)."""
    return {"top": np.linalg.norm(X0[:, :2] - np.asarray(centre), axis=1) < radius}


def stroke(ctx: Context, data: dict, speed: float, steps, pictures: int = 0) -> dict:
    """One stroke at ``speed`` (m/s) on ``ctx``'s grid, the top vertex's height sampled; ``steps`` (first, largest)
    in m of magnet travel. The result gains ``warp_rate`` (the top vertex's largest rise rate while the magnet
    rises, m/s) and ``warp_rise`` (its rise by the top of the stroke, m)."""
    from functools import partial

    from magsoro.robots import _seed002_speeds as sp

    top, side = _ends(data)
    S = data["simulation"]
    # the scene's floor already has the Newton solvers' room under the plate (stroke_run lowers it once more)
    domain = (list(S["domain_lo"]), list(S["domain_hi"]))
    r = sp.stroke_run(NAME, data, top, side, speed, +1.0, domain, ctx, "stroke" + (" (preview grid)" if ctx.preview else ""),
                      implicit_step=steps[0], implicit_max_step=steps[1], markers=partial(_near, centre=top, radius=0.002),
                      snapshots=pictures)
    i0, i1 = int(np.searchsorted(r["t"], sp.SETTLE)), int(np.searchsorted(r["t"], r["t_up"]))
    r["warp_rate"] = sp.moving_rate(r["t"][: i1 + 1], r["top"][: i1 + 1], speed)
    r["warp_rise"] = float(r["top"][i1] - r["top"][i0])
    return r


def strokes(ctx: Context, data: dict, speeds, steps, pictures: int = 0, coarse: bool = False) -> list[dict]:
    """One stroke (:func:`stroke`) per magnet speed (m/s), and with ``coarse`` the last speed again on the preview
    grid (last in the list), as jobs that run at once where ``ctx.workers`` allows (:func:`run_jobs`)."""
    from magsoro.robots.base import Job, run_jobs

    # the strokes take about as long as each other (20 to 30 minutes), so all run at once where the workers allow
    # (balanced), the coarse grid's (5 minutes) last
    jobs = [Job(stroke, ctx, (data, v, steps, pictures), label=f"{v * 1e3:g} mm/s") for v in reversed(speeds)]
    if coarse:
        jobs.append(Job(stroke, Context(out=ctx.out, preview=True, device=ctx.device, log=ctx.log, workers=1),
                        (data, speeds[-1], steps), label=f"{speeds[-1] * 1e3:g} mm/s, preview grid"))
    done = run_jobs(ctx, jobs, balanced=True)
    return done[: len(speeds)][::-1] + done[len(speeds):]


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.robots import _seed002_speeds as sp
    from magsoro.validation.registry import Row

    data = scene_data(NAME)
    speeds = SPEEDS[-1:] if ctx.preview else SPEEDS
    # the full run's convergence row: the fastest stroke on the preview grid too (with the full grid's steps)
    runs = strokes(ctx, data, speeds, PREVIEW_STEPS if ctx.preview else STEPS, pictures=2, coarse=not ctx.preview)
    coarse = None if ctx.preview else runs.pop()
    v = np.array([r["speed"] for r in runs])
    along = np.array([r["along_stroke"] for r in runs])
    level = np.array([r["along"] for r in runs])
    rate = np.array([r["warp_rate"] for r in runs])
    duration = np.array([r["t_down"] - sp.SETTLE for r in runs])  # the magnet's time on the move
    length = v * duration
    table = {"magnet_speed_mm_s": 1e3 * v, "centroid_along_stroke_mm": 1e3 * along,
             "centroid_along_level_move_mm": 1e3 * level, "centroid_lift_mm": 1e3 * np.array([r["lift"] for r in runs]),
             "vertex_rise_rate_mm_s": 1e3 * rate, "vertex_rise_mm": 1e3 * np.array([r["warp_rise"] for r in runs]),
             "stroke_time_s": duration, "robot_speed_over_stroke_mm_s": 1e3 * along / duration,
             "wall_s": np.array([r["wall_s"] for r in runs])}
    csv = write_csv(ctx.out / f"{NAME}.csv", table)
    dx = runs[0]["dx"]
    png = plot_curve(ctx.out / f"{NAME}.png", 1e3 * v,
                     {"centroid along the stroke": 1e3 * along, "while the magnet moves level": 1e3 * level},
                     "magnet speed (mm/s)", "displacement (mm)", "Triangular robot: displacement per stroke",
                     note=f"dx = {dx * 1e3:.1f} mm; implicit integrator; the paper gives no magnet speed",
                     legend_loc="center right")
    # the course of each stroke against the magnet's travel (the same course at every speed if quasi-static)
    course = {}
    for r in runs:
        travel = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(np.stack([r["mx"], r["my"], r["mz"]], 1),
                                                                           axis=0), axis=1))])
        course[f"{r['speed'] * 1e3:g} mm/s"] = (1e3 * travel, 1e3 * r["course"])
    course_png = plot_courses(ctx.out / f"{NAME}_course.png", course, "magnet travel (mm): up 74, level 34.6, down 74",
                              "centroid along the stroke (mm)", "Triangular robot: course of one stroke",
                              note=f"dx = {dx * 1e3:.1f} mm")
    course_csv = write_csv(ctx.out / f"{NAME}_course.csv", {
        f"{k.replace(' mm/s', 'mms')}_{q}": arr for k, (a, b) in course.items() for q, arr in (("travel_mm", a),
                                                                                          ("along_mm", b))})
    views = sp.stroke_side_views(ctx.out / f"{NAME}_views.png", runs[-1]["frames"], runs[-1],
                                 f"triangle stroke at {runs[-1]['speed'] * 1e3:g} mm/s")

    case = f"robot-{NAME}"
    inputs = {"dx_mm": dx * 1e3, "magnet_speeds_mm_s": list(map(float, 1e3 * v))}
    fast = runs[-1]
    rows = [Row(case, "centroid displacement along the stroke at the fastest magnet speed (mm), at least 0.2 mm "
                      "(a cell's fifth) the magnet's way", inputs | {"magnet_speed_mm_s": fast["speed"] * 1e3},
                0.2, 1e3 * fast["along_stroke"], float(max(0.0, 0.2 - 1e3 * fast["along_stroke"])), 0.0)]
    # the magnet speed that makes the paper's warping speed: the rise rate in proportion to the magnet's speed
    ratio = float(np.sum(rate * v) / np.sum(v * v)) if np.all(np.isfinite(rate)) else float("nan")
    v_paper = PAPER_WARP_SPEED * 1e-3 / ratio if ratio > 0 else float("nan")
    per_stroke = float(np.mean(along))
    robot_speed = 1e3 * per_stroke * v_paper / float(length[0]) if math.isfinite(v_paper) else float("nan")
    if not ctx.preview:
        spread = float(abs(along[0] - along[-1]) / max(abs(along[-1]), 1e-12))
        rows.append(Row(case, "displacement per stroke at 5 mm/s against 20 mm/s, |difference| / at 20 mm/s: the "
                              "stroke is quasi-static", inputs, 0.0, spread, spread, QUASI_STATIC_TOL))
        gap = float(abs(coarse["along_stroke"] - fast["along_stroke"]) / max(abs(fast["along_stroke"]), 1e-12))
        rows.append(Row(case, f"displacement per stroke at 20 mm/s, dx {coarse['dx'] * 1e3:g} mm against "
                              f"{dx * 1e3:g} mm, |difference| / the finer", inputs | {"coarse_mm": 1e3 * coarse["along_stroke"]},
                        0.0, gap, gap, CONVERGENCE_TOL))
    off = abs(math.log(robot_speed / PAPER_LOCO_SPEED) / math.log(SPEED_FACTOR)) if robot_speed > 0 else float("inf")
    rows.append(Row(case, f"robot speed over a stroke at the magnet speed of the paper's warping speed (mm/s) vs "
                          f"seed 002's {PAPER_LOCO_SPEED} mm/s; error: log base {SPEED_FACTOR:g} of the ratio",
                    inputs | {"magnet_speed_for_9_mm_s_warping": 1e3 * v_paper, "stroke_length_mm": 1e3 * float(length[0])},
                    PAPER_LOCO_SPEED, robot_speed, off, 1.0))
    runs_text = ", ".join(f"{1e3 * a:+.2f} mm at {1e3 * s:g} mm/s" for a, s in zip(along, v))
    summary = (f"One stroke (the magnet rising under the top vertex, moving level 34.6 mm to under the opposite side "
               f"and going down) moves the robot {runs_text} along the stroke (dx {dx * 1e3:g} mm, implicit "
               f"integrator); while the magnet moves level it goes {1e3 * level[-1]:+.2f} mm. The top vertex rises at "
               f"{ratio:.2f} times the magnet's speed, so the paper's warping speed (9 mm/s) needs a magnet at "
               f"{1e3 * v_paper:.0f} mm/s; a {1e3 * float(length[0]):.0f} mm stroke at that speed gives the robot "
               f"{robot_speed:.2f} mm/s against the paper's {PAPER_LOCO_SPEED} mm/s"
               + (f"; on the coarse grid (dx {coarse['dx'] * 1e3:g} mm) the stroke moves it "
                  f"{1e3 * coarse['along_stroke']:+.2f} mm" if coarse is not None else "") + ".")
    info = {"particles": fast["particles"], "dx_m": dx, "solver": "implicit (backward Euler)",
            "run_wall_s": round(float(sum(r["wall_s"] for r in runs)), 1),
            "steps_m_of_travel": list(PREVIEW_STEPS if ctx.preview else STEPS),
            "integrators": [r["integrator"] for r in runs],
            "magnet_speed_for_paper_warping_mm_s": 1e3 * v_paper, "robot_speed_at_it_mm_s": robot_speed,
            "stroke_length_m": float(length[0])}
    if coarse is not None:
        info.update(coarse_dx_m=coarse["dx"], coarse_along_stroke_mm=1e3 * coarse["along_stroke"],
                    coarse_wall_s=round(coarse["wall_s"], 1))
    figures = [{"csv": course_csv, "png": course_png,
                "caption": "the centroid's displacement along the stroke against the magnet's travel, per magnet speed"},
               {"csv": csv, "png": views, "caption": "side views of the robot during the fastest stroke (y, z; colour x)"}]
    return ReproduceResult(NAME, csv, png, None, summary, rows, info, figures)


ROBOT = Robot(
    name=NAME,
    title="Triangular robot (a stroke at a hand's speed)",
    source="seed 002 sec 4.2",
    quantity="displacement per stroke of the magnet from a vertex to the opposite side, at 5-20 mm/s (Fig. 4c)",
    sentence="The triangle of seed 002 under one stroke of the paper's actuator at a hand's speed: the magnet rises "
             "under a vertex, moves level to under the opposite side and goes down; how far the robot goes, by the "
             "implicit integrator.",
    reproduce=reproduce,
)
