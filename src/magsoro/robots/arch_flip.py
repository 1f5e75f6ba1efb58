"""Arch-shaped robot of seed 002 (sec 5.5) flipping over under the paper's actuator rising at a hand's speed, by the
implicit integrator (scenes/arch_flip.toml).

Seed 002: "the arch-shaped robot can flip forward and backward in 0.5 s", under a downward field (Fig. 19e), with
neither the magnet's speed nor where it was. ``magsoro reproduce arch`` flips the arch with the explicit engine
under a magnet brought up from far below in 0.1 s. This reproduction brings the same magnet (turned over, its axis
10 mm to the +x side) up at 5, 10 and 20 mm/s from where it gives 4 mT at the arch to where it gives 45 mT, and
reads, at each speed:

- the field level at the arch (its footprint's centre, 1 mm above the plate, as scenes/arch.toml sets its levels)
  when the flip starts: the vertical part of the arch's net magnetic moment m = sum(F Br V), up at rest, has
  fallen to FLIP_START of its value at the start;
- how long the flip takes: from then until m_y has reached -FLIP_OVER of it (the moment points down, along the
  field: the arch has turned over).

The direction of m is no measure of the flip: under the downward field the arch's feet slide towards each other
and it closes into a loop, whose net moment nearly vanishes, before it tips over. The arch stands until the
field's couple overcomes it (a fold of its equilibria), then snaps. A load rising at a finite rate overshoots a fold
before the jump gets under way, by an amount that grows as the rate to the power 2/3 (slow passage through a
saddle-node, Haberman 1979), so the level at the start of the flip is L0 + c v^(2/3) at magnet speed v, and the
flip's time shrinks as v grows. The checks compare both with the explicit engine's rises on the same grid
(benchmarks/arch_flip_explicit.py): at 20 mm/s directly, and at 5 mm/s against the law fitted to its rises at 50,
100 and 200 mm/s. The full run repeats the 20 mm/s rise on a grid twice as fine (dx 0.25 mm, 8 cells through the
arch) for the convergence row. A run ends AFTER s after the flip, or HOLD s after the magnet reaches the top if the
arch never turns over.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from magsoro.robots.base import (Context, Job, ReproduceResult, Robot, plot_courses, run_jobs, scene_data, simulation,
                                 write_csv)

NAME = "arch_flip"
SPEEDS = [0.005, 0.01, 0.02]  # m/s (preview: the last)
OFFSET = 0.01                 # m: the magnet's axis to +x of the arch's centre (scenes/arch.toml's flipping mode)
Z_START = -0.104              # m: the magnet's centre at the start (4.0 mT at the arch)
Z_TOP = -0.0145               # m: at the top (45 mT at the arch)
SETTLE = 0.2                  # s the magnet waits at Z_START while the arch sags under its weight
AFTER = 0.1                   # s run after the flip (the preview: PREVIEW_AFTER)
PREVIEW_AFTER = 0.02
FRAME_DT = 0.002              # s between the frames kept through the flip
EXPLICIT_SAMPLE = 2.0e-4      # s between the explicit engine's samples (benchmarks/arch_flip_explicit.py)
#: the preview's implicit.max_move (cells): the flip's steps twice as long as the scene's 0.5 cells
PREVIEW_MAX_MOVE = 1.0
HOLD = 0.5                    # s run after the magnet reaches the top when the arch has not flipped
STEP = 1.0e-3                 # m of magnet travel per implicit step at most (the steps are STEP / speed)
FINE_DX = 0.25e-3             # m: the convergence rows' finer grid (8 cells through the 2 mm arch)
FLIP_START = 0.9              # m_y / |m| at the start: the flip has started when m_y falls below this
FLIP_OVER = 0.9               # ... and has ended when m_y falls below minus this (the moment points down)
PAPER_FLIP_S = 0.5            # s (seed 002 sec 5.5)
#: the flip level on the two grids within this fraction (issue "The seeds' slow experiments")
CONVERGENCE_TOL = 0.10
#: the explicit engine's answers to the same rise (scenes/arch_flip.toml, dx 0.5 mm, no mass damping, self-contact;
#: ``python benchmarks/arch_flip_explicit.py``, benchmarks/results/*-arch-flip-explicit.json): the level at the
#: arch when the flip starts (mT) and the flip's time (s) at each magnet speed (mm/s)
EXPLICIT = {"magnet_speed_mm_s": (20.0, 50.0, 100.0, 200.0), "flip_level_mT": (9.90, 10.35, 10.97, 11.86),
            "flip_time_s": (0.319, 0.286, 0.287, 0.249)}
#: the speeds whose explicit rises fix the passage law (the slowest explicit rise is the comparison at 20 mm/s)
LAW_SPEEDS_MM_S = (50.0, 100.0, 200.0)
#: the exponent of the overshoot past the fold against the loading rate (Haberman 1979)
PASSAGE_EXPONENT = 2.0 / 3.0
#: the flip level at 20 mm/s within this fraction of the explicit engine's at 20 mm/s, and at 5 mm/s within it of
#: the passage law through the explicit engine's faster rises
EXPLICIT_TOL = 0.05
#: the flip's time at 20 mm/s within this fraction of the explicit engine's at 20 mm/s
EXPLICIT_TIME_TOL = 0.10


def explicit(speed_mm_s: float, key: str = "flip_level_mT") -> float:
    """The explicit engine's ``key`` at ``speed_mm_s`` from EXPLICIT (KeyError if it has not run that speed)."""
    return float(EXPLICIT[key][list(EXPLICIT["magnet_speed_mm_s"]).index(speed_mm_s)])


def passage_law(speeds_mm_s, levels_mT) -> tuple[float, float]:
    """(L0, c) of the least-squares fit level = L0 + c v^PASSAGE_EXPONENT (mT, v in mm/s)."""
    c, l0 = np.polyfit(np.asarray(speeds_mm_s, float) ** PASSAGE_EXPONENT, np.asarray(levels_mT, float), 1)
    return float(l0), float(c)


def explicit_level_at(speed_mm_s: float) -> float:
    """The flip level (mT) at ``speed_mm_s`` by the passage law through the explicit engine's rises at
    LAW_SPEEDS_MM_S."""
    l0, c = passage_law(LAW_SPEEDS_MM_S, [explicit(v) for v in LAW_SPEEDS_MM_S])
    return l0 + c * speed_mm_s ** PASSAGE_EXPONENT


def rise_path(speed: float) -> tuple[dict, float]:
    """The magnet's path at ``speed`` (m/s): it waits SETTLE s at Z_START, OFFSET to +x, and rises to Z_TOP.
    Returns the path table and the time it reaches the top."""
    t_up = SETTLE + (Z_TOP - Z_START) / speed
    lo, hi = [OFFSET, Z_START, 0.0], [OFFSET, Z_TOP, 0.0]
    return {"times": [0.0, SETTLE, t_up], "positions": [lo, lo, hi]}, t_up


def level_at(entry: dict, path: dict, t) -> np.ndarray:
    """|B_y| (T) at the arch's footprint centre (magsoro.robots.arch.POINT) with the magnet ``entry`` on ``path``
    at times ``t``."""
    from magsoro.robots.arch import POINT, UP
    from magsoro.robots.pentahedron import magnet_source, path_at

    return np.array([abs(magnet_source(entry, path_at(path, s)).B(np.asarray([POINT]))[0][UP])
                     for s in np.atleast_1d(t)])


def crossing(t, y, level: float) -> float:
    """The first time |y| reaches ``level``, linear between samples (nan if never)."""
    a = np.abs(np.asarray(y, float))
    k = np.flatnonzero(a >= level)
    if not len(k):
        return float("nan")
    i = int(k[0])
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - a[i - 1]) / (a[i] - a[i - 1]) * (t[i] - t[i - 1]))


def net_moment(sim) -> np.ndarray:
    """The arch's net magnetic moment sum(F Br V) over its particles (2 components; up at rest)."""
    F = sim.state.F.numpy().astype(np.float64)
    Br = sim.model.host["remanence"][:, :2].astype(np.float64)
    return np.einsum("n,nij,nj->i", sim.model.host["volumes"].astype(np.float64), F[:, :2, :2], Br)


def flip_run(ctx: Context, data: dict, speed: float, dx: float | None = None, label: str = "",
             explicit: bool = False) -> dict:
    """One rise at ``speed`` (m/s) on the scene's grid, or at spacing ``dx`` (m). The net moment is read after
    every implicit step; with ``explicit`` the explicit engine runs the same scene (no mass damping) and the moment
    is read every EXPLICIT_SAMPLE s. Returns the series (times ``t``, ``up`` = m_y over |m| at the start, ``side`` = m_x over
    it, the crown's height ``crown`` and the centroid's x ``cx`` in m, the level at the arch ``B`` in T), the flip's
    start and end times, the level at its start, a few frames ((time, positions) pairs) and run facts."""
    import time

    from magsoro.errors import SimulationError
    from magsoro.robots.base import RobotError
    from magsoro.robots.pentahedron import magnet_entry

    data = copy.deepcopy(data)
    S = data["simulation"]
    scene_dx = float(S["dx"])
    if dx is not None:
        S["dx"] = float(dx)
    path, t_up = rise_path(speed)
    entry = magnet_entry(data)
    entry["path"], entry["position"] = path, list(path["positions"][0])
    S["duration"] = t_up + HOLD
    imp = data["implicit"]
    imp["dt_max"] = STEP / speed
    if explicit:
        S["integrator"] = "explicit"
        del data["implicit"]
    elif ctx.preview:
        imp["max_move"] = PREVIEW_MAX_MOVE
    elif dx is not None:  # max_move is in cells: the same distance per step as on the scene's grid
        imp["max_move"] = float(imp["max_move"]) * scene_dx / float(dx)
    after = PREVIEW_AFTER if ctx.preview else AFTER
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    m0 = net_moment(sim)
    scale = float(np.hypot(*m0))
    rec = {"t": [], "up": [], "side": [], "crown": [], "cx": []}
    frames = []

    def read(s):
        x = s.state.x.numpy().astype(np.float64)
        m = net_moment(s) / scale
        for k, val in zip(rec, (s.time, m[1], m[0], x[:, 1].max(), x[:, 0].mean())):
            rec[k].append(float(val))
        return x

    frames.append((0.0, read(sim)))
    end, over, w0 = S["duration"], None, time.perf_counter()

    def step(s):
        nonlocal end, over
        x = read(s)
        up = rec["up"][-1]
        if up <= FLIP_START + 0.5 * (1.0 - FLIP_START) and s.time >= frames[-1][0] + FRAME_DT:
            frames.append((s.time, x))  # the flip (the picture picks a few)
        if over is None and up <= -FLIP_OVER:
            over = s.time
            end = min(end, s.time + after)

    every = EXPLICIT_SAMPLE if explicit else STEP / speed
    t = 0.0
    try:
        while t < end - 1e-9:
            t = min(end, t + every)
            sim.advance_to(t, callback=None if explicit else step)
            if explicit:
                step(sim)
            if abs(round(t / 0.5) * 0.5 - t) < every / 2:
                ctx.log(f"    t {sim.time:.3f} s: B {1e3 * level_at(entry, path, sim.time)[0]:.2f} mT, m_y "
                        f"{rec['up'][-1]:+.3f} of the start's |m|, crown {1e3 * rec['crown'][-1]:.2f} mm "
                        f"({time.perf_counter() - w0:.0f} s wall)")
    except SimulationError as exc:
        raise RobotError(f"{NAME}{label} at {speed * 1e3:g} mm/s: run failed at t = {exc.time:.4g} s: {exc}") from None
    if frames[-1][0] < sim.time:
        frames.append((sim.time, sim.state.x.numpy().astype(np.float64)))
    out = {k: np.asarray(v) for k, v in rec.items()}
    t_start = crossing(out["t"], np.maximum(1.0 - out["up"], 0.0), 1.0 - FLIP_START)
    t_over = crossing(out["t"], np.minimum(out["up"], 0.0), FLIP_OVER)
    out.update(B=level_at(entry, path, out["t"]), t_start=t_start, t_over=t_over, t_up=t_up, speed=speed,
               dx=sim.model.dx, duration=t_over - t_start, final_up=float(out["up"][-1]), frames=frames,
               particles=int(sim.model.n_particles), wall_s=time.perf_counter() - w0,
               integrator=sim.integrator_info(), steps=int(sim.steps), path=path, entry=entry)
    out["level"] = float(level_at(entry, path, t_start)[0]) if math.isfinite(t_start) else float("nan")
    ctx.log(f"  {NAME}{label} at {speed * 1e3:g} mm/s: flip from {1e3 * out['level']:.2f} mT in "
            f"{out['duration']:.3f} s ({out['wall_s']:.0f} s wall)")
    return out


def pick_frames(run: dict, n: int = 6) -> list:
    """A few of ``run``'s frames: the start, the flip at even steps of m_y from FLIP_START to -FLIP_OVER (the frame
    closest to each), and the end."""
    frames = run["frames"]
    if len(frames) <= n:
        return frames
    inner = frames[1:-1]
    ups = np.interp([f[0] for f in inner], run["t"], run["up"])
    keep = sorted({int(np.argmin(np.abs(ups - target))) for target in np.linspace(FLIP_START, -FLIP_OVER, n - 2)})
    return [frames[0]] + [inner[k] for k in keep] + [frames[-1]]


def flip_views(png, run: dict, title: str):
    """PNG of the arch (x-y, mm) at the frames :func:`pick_frames` picks, the level at the arch and m_y in each
    panel's title, the magnet's top face where it is in view."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from magsoro.robots.base import _save

    frames = pick_frames(run)
    n = len(frames)
    cols = min(n, 3)
    rows = -(-n // cols)
    lo = min(-25.0, min(1e3 * x[:, 0].min() for _, x in frames) - 3.0)
    hi = max(25.0, max(1e3 * x[:, 0].max() for _, x in frames) + 3.0)
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.3 * rows), squeeze=False)
    for ax, (t, x) in zip(axes.ravel(), frames):
        B = 1e3 * float(np.interp(t, run["t"], run["B"]))
        up = float(np.interp(t, run["t"], run["up"]))
        ax.scatter(1e3 * x[:, 0], 1e3 * x[:, 1], s=0.5, c="tab:red")
        ax.axhline(0.0, color="0.5", lw=0.8)  # the plate's top
        mz = float(np.interp(t, run["path"]["times"], np.asarray(run["path"]["positions"])[:, 1]))
        top = 1e3 * (mz + run["entry"]["length"] / 2)
        if top > -8:
            ax.add_patch(plt.Rectangle((1e3 * OFFSET - 50.0, top - 10.0), 100.0, 10.0, color="0.8", zorder=0))
        ax.set_title(f"t {t:.3f} s, {B:.1f} mT, m_y {up:+.2f}", fontsize=8)
        ax.set_xlim(lo, hi), ax.set_ylim(-8, 36), ax.set_aspect("equal"), ax.tick_params(labelsize=7)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    fig.suptitle(f"{title} (x, y in mm; magnet S face up, axis at x = +{1e3 * OFFSET:.0f} mm; m_y: the net "
                 f"moment's vertical part over its start)\ndx = {1e3 * run['dx']:.2f} mm", fontsize=9)
    fig.set_dpi(110)
    fig.tight_layout()
    _save(fig, png)
    plt.close(fig)
    return png


def plot_speeds(png, table: dict, note: str):
    """PNG: the flip's level and its time against the magnet speed, the paper's 0.5 s as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from magsoro.robots.base import _save

    fig, (a, b) = plt.subplots(1, 2, figsize=(8.4, 3.4), dpi=120)
    v = table["magnet_speed_mm_s"]
    ve = np.asarray(EXPLICIT["magnet_speed_mm_s"])
    a.plot(v, table["flip_level_mT"], "o-", label="implicit integrator")
    a.plot(ve, EXPLICIT["flip_level_mT"], "s", label="explicit engine")
    vv = np.geomspace(min(v.min(), ve.min()), ve.max(), 60)
    a.plot(vv, [explicit_level_at(x) for x in vv], ":", color="0.4",
           label=f"L0 + c v^(2/3) through the explicit {', '.join(f'{x:g}' for x in LAW_SPEEDS_MM_S)} mm/s")
    a.set_xscale("log"), a.set_xlabel("magnet speed (mm/s)"), a.set_ylabel("level at the arch when the flip starts (mT)")
    a.legend(fontsize=7)
    b.plot(v, table["flip_time_s"], "o-", label=f"implicit: m_y from {FLIP_START:g} to -{FLIP_OVER:g} of the start's |m|")
    b.plot(ve, EXPLICIT["flip_time_s"], "s", label="explicit engine")
    b.set_xscale("log")
    b.axhline(PAPER_FLIP_S, ls="--", color="k", label="paper: flips in 0.5 s (sec 5.5)")
    b.set_xlabel("magnet speed (mm/s)"), b.set_ylabel("flip time (s)"), b.set_ylim(0, None)
    b.legend(fontsize=7)
    fig.suptitle(f"Arch-shaped robot: flip under a rising magnet\n{note}", fontsize=9)
    fig.tight_layout()
    _save(fig, png)
    plt.close(fig)
    return png


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.validation.registry import Row

    data = scene_data(NAME)
    speeds = SPEEDS[-1:] if ctx.preview else SPEEDS
    # independent rises, in worker processes where ctx.workers allows: the fine grid's, the longest, first
    jobs = [] if ctx.preview else [Job(flip_run, ctx, (data, SPEEDS[-1]), {"dx": FINE_DX, "label": " (dx 0.25 mm)"},
                                       label=f"{SPEEDS[-1] * 1e3:g} mm/s, dx {FINE_DX * 1e3:g} mm")]
    jobs += [Job(flip_run, ctx, (data, v), label=f"{v * 1e3:g} mm/s") for v in reversed(speeds)]
    done = run_jobs(ctx, jobs)
    fine = None if ctx.preview else done.pop(0)
    runs = done[::-1]
    v = np.array(speeds)
    level = np.array([r["level"] for r in runs])
    dur = np.array([r["duration"] for r in runs])
    table = {"magnet_speed_mm_s": 1e3 * v, "flip_level_mT": 1e3 * level, "flip_time_s": dur,
             "flip_start_s": np.array([r["t_start"] for r in runs]),
             "magnet_rise_during_flip_mm": 1e3 * v * dur,
             "flip_over_s": np.array([r["t_over"] for r in runs]),
             "final_moment_up": np.array([r["final_up"] for r in runs]),
             "centroid_shift_mm": np.array([1e3 * (r["cx"][-1] - r["cx"][0]) for r in runs]),
             "wall_s": np.array([r["wall_s"] for r in runs])}
    dx = runs[0]["dx"]
    csv = write_csv(ctx.out / f"{NAME}_speeds.csv", table)
    png = plot_speeds(ctx.out / f"{NAME}_speeds.png", table,
                      f"dx = {dx * 1e3:g} mm; implicit integrator; the paper gives no magnet speed")
    every = runs + ([fine] if fine is not None else [])
    course = {}
    for r in every:
        k = f"{r['speed'] * 1e3:g} mm/s, dx {r['dx'] * 1e3:g} mm"
        course[k] = (r["t"] - r["t_start"], r["up"])
    course_png = plot_courses(ctx.out / f"{NAME}_course.png", course, "time from the flip's start (s)",
                              "m_y / |m| at the start (up 1, down -1)",
                              "Arch-shaped robot: its net moment through the flip",
                              dashed=lambda label: "0.25" in label)
    course_csv = write_csv(ctx.out / f"{NAME}_course.csv", {
        f"{k.replace(' mm/s', 'mms').replace(', dx ', '_dx').replace(' mm', 'mm')}_{q}": arr
        for k, (a, b) in course.items() for q, arr in (("t_from_start_s", a), ("moment_up", b))})
    fast = runs[-1]
    views = flip_views(ctx.out / f"{NAME}_views.png", fast, f"arch flipping at {fast['speed'] * 1e3:g} mm/s")

    case = f"robot-{NAME}"
    inputs = {"dx_mm": dx * 1e3, "magnet_speeds_mm_s": list(map(float, 1e3 * v)), "offset_mm": OFFSET * 1e3}
    rows = [Row(case, f"net moment's vertical part at the end at {1e3 * v[-1]:g} mm/s, over its |m| at the start, "
                      f"at most -{FLIP_OVER:g}: the arch has turned over, its moment along the field",
                inputs | {"magnet_speed_mm_s": 1e3 * v[-1]}, -FLIP_OVER, fast["final_up"],
                float(max(0.0, fast["final_up"] + FLIP_OVER)), 0.0)]
    longest = float(np.max(dur)) if np.all(np.isfinite(dur)) else float("nan")
    rows.append(Row(case, f"longest flip time over the magnet speeds (s, m_y from {FLIP_START:g} to -{FLIP_OVER:g} of "
                          f"the start's |m|), within the paper's {PAPER_FLIP_S:g} s (sec 5.5)",
                    inputs | {"times_s": list(map(float, dur))}, PAPER_FLIP_S, longest,
                    float(max(0.0, longest - PAPER_FLIP_S)) if math.isfinite(longest) else float("inf"), 0.0))
    v20 = 1e3 * v[-1]
    ref = explicit(v20)
    rows.append(Row(case, f"flip level at {v20:g} mm/s against the explicit engine's on the same rise (mT, "
                          f"benchmarks/arch_flip_explicit.py)", inputs, ref, 1e3 * level[-1],
                    float(abs(1e3 * level[-1] - ref) / ref), EXPLICIT_TOL))
    et = explicit(v20, "flip_time_s")
    rows.append(Row(case, f"flip time at {v20:g} mm/s against the explicit engine's on the same rise (s)", inputs,
                    et, dur[-1], float(abs(dur[-1] - et) / et) if math.isfinite(dur[-1]) else float("inf"),
                    EXPLICIT_TIME_TOL))
    if len(runs) > 1:
        v5 = 1e3 * v[0]
        law = explicit_level_at(v5)
        rows.append(Row(case, f"flip level at {v5:g} mm/s against L0 + c v^(2/3) (the overshoot of a fold passed at "
                              f"a finite rate, Haberman 1979) fitted to the explicit engine's rises at "
                              f"{', '.join(f'{x:g}' for x in LAW_SPEEDS_MM_S)} mm/s (mT)",
                        inputs | {"levels_mT": list(map(float, 1e3 * level)),
                                  "explicit_levels_mT": [explicit(x) for x in LAW_SPEEDS_MM_S]},
                        law, 1e3 * level[0], float(abs(1e3 * level[0] - law) / law), EXPLICIT_TOL))
    if fine is not None:
        g = float(abs(level[-1] - fine["level"]) / max(abs(fine["level"]), 1e-12))
        rows.append(Row(case, f"flip level at 20 mm/s, dx {dx * 1e3:g} mm (4 cells through the arch) against "
                              f"{fine['dx'] * 1e3:g} mm (8 cells), |difference| / the finer",
                        inputs | {"fine_mT": 1e3 * fine["level"]}, 0.0, g, g, CONVERGENCE_TOL))
    law0, law_c = passage_law(LAW_SPEEDS_MM_S, [explicit(x) for x in LAW_SPEEDS_MM_S])
    speeds_text = "; ".join(f"{1e3 * s:g} mm/s: from {1e3 * b:.2f} mT in {d:.3f} s" for s, b, d in zip(v, level, dur))
    shift = 1e3 * (fast["cx"][-1] - fast["cx"][0])
    summary = (f"Under the paper's actuator turned over and rising at a hand's speed {OFFSET * 1e3:.0f} mm to the "
               f"+x side (dx {dx * 1e3:g} mm, implicit integrator) the arch stands until the field at it reaches a "
               f"level, then its feet slide together, it closes into a loop and tips over: {speeds_text} (its net "
               f"moment's vertical part from {FLIP_START:g} to -{FLIP_OVER:g} of its start; paper: flips in "
               f"{PAPER_FLIP_S:g} s). At {1e3 * v[-1]:g} mm/s it ends lying on the plate with its moment along "
               f"the field, its centroid {shift:+.1f} mm along x, and the magnet rises {1e3 * v[-1] * dur[-1]:.1f} mm "
               f"during the flip"
               + (f"; at dx {fine['dx'] * 1e3:g} mm it flips from {1e3 * fine['level']:.2f} mT in "
                  f"{fine['duration']:.3f} s" if fine is not None else "")
               + ". The explicit engine on the same grid, with the magnet rising at "
               + " / ".join(f"{x:g}" for x in EXPLICIT["magnet_speed_mm_s"]) + " mm/s, flips from "
               + " / ".join(f"{x:.2f}" for x in EXPLICIT["flip_level_mT"]) + " mT in "
               + " / ".join(f"{x:.3f}" for x in EXPLICIT["flip_time_s"])
               + " s. The level grows with the magnet's speed as a fold passed at a finite rate predicts, "
               + f"L0 + c v^(2/3) (Haberman 1979): through the explicit rises at 50-200 mm/s L0 = {law0:.2f} mT, "
               + f"c = {law_c:.4f} mT (mm/s)^(-2/3), {explicit_level_at(1e3 * v[0]):.2f} mT at {1e3 * v[0]:g} mm/s; "
               + "the flip is faster the faster the field rises through it.")
    info = {"particles": fast["particles"], "dx_m": dx, "solver": "implicit (generalized_alpha, rho_inf 0.5)",
            "run_wall_s": round(float(sum(r["wall_s"] for r in runs)), 1), "offset_m": OFFSET,
            "magnet_centre_m": {"start": Z_START, "top": Z_TOP},
            "levels_mT": {"start": round(1e3 * float(runs[0]["B"][0]), 3), "top": round(1e3 * float(runs[0]["B"][-1]), 3)
                          if runs[0]["t"][-1] >= runs[0]["t_up"] else None},
            "integrators": [r["integrator"] for r in runs],
            "explicit": {k: list(v) for k, v in EXPLICIT.items()},
            "passage_law": {"L0_mT": law0, "c_mT_per_mm_s_2_3": law_c, "exponent": PASSAGE_EXPONENT,
                            "fitted_to_mm_s": list(LAW_SPEEDS_MM_S)}}
    if fine is not None:
        info.update(fine_dx_m=fine["dx"], fine_particles=fine["particles"], fine_level_mT=1e3 * fine["level"],
                    fine_flip_time_s=fine["duration"], fine_wall_s=round(fine["wall_s"], 1),
                    fine_integrator=fine["integrator"])
    figures = [{"csv": course_csv, "png": course_png,
                "caption": "the vertical part of the arch's net moment through the flip, per magnet speed and "
                           "grid"},
               {"csv": csv, "png": views,
                "caption": f"the arch flipping at {1e3 * v[-1]:g} mm/s: the start, the snap and the end"}]
    return ReproduceResult(NAME, csv, png, None, summary, rows, info, figures)


ROBOT = Robot(
    name=NAME,
    title="Arch-shaped robot (flipping at a hand's speed)",
    source="seed 002 sec 5.5",
    quantity="field level at which the arch flips and the flip's time, under the actuator rising at 5-20 mm/s",
    sentence="The arch of seed 002 under the paper's actuator turned over and rising at a hand's speed beside it: "
             "the field at which it snaps over and how long the snap takes, by the implicit integrator.",
    reproduce=reproduce,
)
