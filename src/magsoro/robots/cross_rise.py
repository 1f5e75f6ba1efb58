"""Cross-shaped robot of seed 002 (sec 5.1) arching and grabbing under the paper's actuator rising at a hand's
speed, by the implicit integrator (scenes/cross_rise.toml).

Seed 002 reports an arching speed of 4.8 mm/s (field at the robot pointing down) and a grabbing speed of 3.5 mm/s
(field reversed) but not how fast the magnet moved. ``magsoro reproduce cross`` answers that with the explicit
engine for a magnet rising at 50 to 200 mm/s, compressed in time; this reproduction runs the same rise at 5, 10 and
20 mm/s (the preview: 20 mm/s on the coarse grid) and reads, for both directions of the magnet,

- the largest rate of the strips' deflection (the centre above the tips for arching, the tips above the centre for
  grabbing) while the magnet rises, and the deflection reached at the top;
- the magnet speed at which the deflection rate is the paper's (the rate grows in proportion to the magnet's speed
  where the robot follows it quasi-statically), for arching and for grabbing.

The full run also rises at 20 mm/s on a grid twice as fine (dx 0.5 mm, 4 cells through the 2 mm strips) for the
convergence row, and on the preview grid (dx 2 mm, one cell through them) for the record, and compares with the
explicit engine's answers at dx 1 mm (the deflection at the top: benchmarks/cross_rise_explicit.py; the rates:
docs/robots/cross/cross_speeds.csv).
"""

from __future__ import annotations

import copy
import math

import numpy as np

from magsoro.robots.base import Context, ReproduceResult, Robot, plot_courses, scene_data, write_csv

NAME = "cross_rise"
SPEEDS = [0.005, 0.01, 0.02]   # m/s (preview: the last)
#: magnet travel per implicit step (m): the first step and the largest the steps grow to after easy ones (as
#: magsoro.robots.triangle_stroke)
STEPS = (0.25e-3, 1.0e-3)
PREVIEW_STEPS = (0.5e-3, 2.0e-3)
#: the convergence row's finer grid (m): 4 cells through the 2 mm strips (issue "The seeds' slow experiments": at
#: least 3 through every plate); ``magsoro converge`` found dx 1 and 0.5 mm within 1.6 % on the arching rise
FINE_DX = 0.5e-3
#: (mode, the magnet's remanence sign): south face up arches the cross, north face up makes it grab
MODES = (("arching", -1.0), ("grabbing", +1.0))
PAPER = {"arching": 4.8, "grabbing": 3.5}   # mm/s, seed 002 sec 5.1
#: the explicit engine's answers to the same rise (scenes/cross.toml, dx 1 mm, grid damping 120 1/s): the deflection
#: from the flat start with the magnet at its top (mm; ``python benchmarks/cross_rise_explicit.py``, 200 mm/s), and
#: the largest deflection rate per magnet speed at 50, 100 and 200 mm/s (``magsoro reproduce cross``,
#: docs/robots/cross/cross_speeds.csv: 0.0878-0.0888 and 0.0795-0.0796). The deflection is compared from the flat
#: start: when the magnet appears at t = 0 (7 mT at the robot) the explicit engine's strips answer dynamically and
#: stand 1.31 mm apart at the start of the rise when grabbing, where the quasi-static answer is 1.0 mm
EXPLICIT_TOP_MM = {"arching": 5.67, "grabbing": 5.65}
EXPLICIT_RATE_RATIO = {"arching": 0.0883, "grabbing": 0.0795}
#: the deflection at the top within this fraction of the explicit engine's: both integrators follow the same
#: quasi-static response (the explicit one with grid damping and particle contact, this one without damping and
#: with the Newton solvers' collider contact)
EXPLICIT_TOL = 0.05
#: the deflection rate per magnet speed at 5 and 20 mm/s within this fraction of each other (quasi-static)
QUASI_STATIC_TOL = 0.10
#: the deflection at the top on the two grids within this fraction (issue "The seeds' slow experiments")
CONVERGENCE_TOL = 0.10
#: the magnet speeds that give the paper's arching and grabbing speeds within this factor of each other: one hand
#: moved the magnet in both experiments
ONE_HAND_FACTOR = 1.5


def deflection(run: dict, mode: str) -> np.ndarray:
    """The strips' deflection (m) of a rise's samples: the centre above the tips (arching) or the tips above the
    centre (grabbing)."""
    return run["centre"] - run["tips"] if mode == "arching" else run["tips"] - run["centre"]


def rise(ctx: Context, data: dict, mode: str, speed: float, steps, dx: float | None = None) -> dict:
    """One rise of ``mode`` (MODES) at ``speed`` (m/s) on ``ctx``'s grid, or at spacing ``dx`` (m; the scene's
    particles per cell) when given; ``steps`` (first, largest) in m of magnet travel. The result gains
    ``deflection`` (its samples, m), ``rate`` (the largest deflection rate once the magnet has moved
    _seed002_speeds.START_TRAVEL, m/s), ``top`` (the deflection at the end, the magnet at its top, from the flat
    start, m) and ``growth`` (the same less the deflection when the magnet starts to rise, m)."""
    from magsoro.robots import _seed002_speeds as sp
    from magsoro.robots.cross import markers

    if dx is not None:
        data = copy.deepcopy(data)
        data["simulation"]["dx"] = float(dx)
    grid = " (preview grid)" if ctx.preview else (f" (dx {dx * 1e3:g} mm)" if dx is not None else "")
    S = data["simulation"]
    domain = (list(S["domain_lo"]), list(S["domain_hi"]))
    r = sp.rise_run(NAME, data, (0.0, 0.0), speed, dict(MODES)[mode], domain, ctx, mode + grid, markers,
                    implicit_step=steps[0], implicit_max_step=steps[1])
    d = deflection(r, mode)
    i0 = int(np.searchsorted(r["t"], sp.SETTLE))
    r.update(deflection=d, rate=sp.moving_rate(r["t"], d, speed), top=float(d[-1] - d[0]), growth=float(d[-1] - d[i0]))
    return r


def rises(ctx: Context, data: dict, groups: list[tuple]) -> list[dict]:
    """The rises of every mode and speed of each group (``ctx``, speeds in m/s, ``steps`` as in :func:`rise`,
    ``dx`` or None), as jobs that run at once where the first ``ctx.workers`` allows (:func:`run_jobs`, the groups'
    jobs in the order given: the longest first). Returns, per group, {mode: [result per speed]}."""
    from magsoro.robots.base import Job, run_jobs

    keys, jobs = [], []
    for g, (c, speeds, steps, dx) in enumerate(groups):
        grid = " preview grid" if c.preview else (f" dx {dx * 1e3:g} mm" if dx is not None else "")
        for mode, _ in MODES:
            for v in reversed(speeds):  # the fastest first
                keys.append((g, mode, v))
                jobs.append(Job(rise, c, (data, mode, v, steps, dx), label=f"{mode} {v * 1e3:g} mm/s{grid}"))
    done = dict(zip(keys, run_jobs(ctx, jobs)))
    return [{mode: [done[(g, mode, v)] for v in speeds] for mode, _ in MODES}
            for g, (_, speeds, _, _) in enumerate(groups)]


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.robots import _seed002_speeds as sp
    from magsoro.robots.base import Context as Ctx
    from magsoro.validation.registry import Row

    data = scene_data(NAME)
    speeds = SPEEDS[-1:] if ctx.preview else SPEEDS
    coarse = fine = None
    if ctx.preview:
        runs, = rises(ctx, data, [(ctx, speeds, PREVIEW_STEPS, None)])
    else:  # the fastest rise twice as fine (convergence row; the longest runs, first) and on the preview grid
        fine, runs, coarse = rises(ctx, data, [
            (ctx, SPEEDS[-1:], STEPS, FINE_DX), (ctx, speeds, STEPS, None),
            (Ctx(out=ctx.out, preview=True, device=ctx.device, log=ctx.log, workers=1), SPEEDS[-1:], STEPS, None)])
    v = np.array(speeds)
    rate = {m: np.array([r["rate"] for r in runs[m]]) for m, _ in MODES}
    growth = {m: np.array([r["growth"] for r in runs[m]]) for m, _ in MODES}
    top = {m: np.array([r["top"] for r in runs[m]]) for m, _ in MODES}
    # the deflection rate in proportion to the magnet's speed: least squares through the origin
    ratio = {m: float(np.sum(rate[m] * v) / np.sum(v * v)) for m, _ in MODES}
    v_paper = {m: PAPER[m] * 1e-3 / ratio[m] if ratio[m] > 0 else float("nan") for m, _ in MODES}
    table = {"magnet_speed_mm_s": 1e3 * v,
             "arching_deflection_rate_mm_s": 1e3 * rate["arching"],
             "grabbing_deflection_rate_mm_s": 1e3 * rate["grabbing"],
             "arching_deflection_at_top_mm": 1e3 * top["arching"],
             "grabbing_deflection_at_top_mm": 1e3 * top["grabbing"],
             "arching_deflection_growth_mm": 1e3 * growth["arching"],
             "grabbing_deflection_growth_mm": 1e3 * growth["grabbing"],
             "arching_wall_s": np.array([r["wall_s"] for r in runs["arching"]]),
             "grabbing_wall_s": np.array([r["wall_s"] for r in runs["grabbing"]])}
    dx = runs["arching"][0]["dx"]
    csv, png = sp.write_speeds(ctx.out, NAME, table, {"arching 4.8 mm/s (sec 5.1)": PAPER["arching"],
                                                      "grabbing 3.5 mm/s (sec 5.1)": PAPER["grabbing"]},
                               note=f"dx = {dx * 1e3:.1f} mm; implicit integrator; the paper gives no magnet speed")
    # the deflection against the magnet's height, per mode and speed (one curve per mode if quasi-static)
    course = {f"{m} {r['speed'] * 1e3:g} mm/s": (1e3 * r["mz"], 1e3 * r["deflection"]) for m, _ in MODES for r in runs[m]}
    course_png = plot_courses(ctx.out / f"{NAME}_course.png", course, "magnet centre height (mm; plate top at 0)",
                              "deflection (mm)", "Cross-shaped robot: deflection as the magnet rises",
                              note=f"dx = {dx * 1e3:.1f} mm", dashed=lambda label: label.startswith("grabbing"))
    course_csv = write_csv(ctx.out / f"{NAME}_course.csv", {
        f"{k.replace(' mm/s', 'mms').replace(' ', '_')}_{q}": arr for k, (a, b) in course.items()
        for q, arr in (("magnet_z_mm", a), ("deflection_mm", b))})

    case = f"robot-{NAME}"
    inputs = {"dx_mm": dx * 1e3, "magnet_speeds_mm_s": list(map(float, 1e3 * v))}
    rows = []
    for m, _ in MODES:  # each deflects the right way by at least a strip's half thickness
        g = 1e3 * top[m][-1]
        rows.append(Row(case, f"{m}: deflection with the magnet at the top at {1e3 * v[-1]:g} mm/s (mm, from the flat "
                              f"start), at least 1 mm (half the strips' thickness) the right way",
                        inputs | {"magnet_speed_mm_s": 1e3 * v[-1]}, 1.0, g, float(max(0.0, 1.0 - g)), 0.0))
    if not ctx.preview:
        for m, _ in MODES:
            g = 1e3 * top[m][-1]
            err = abs(g - EXPLICIT_TOP_MM[m]) / EXPLICIT_TOP_MM[m]
            rows.append(Row(case, f"{m}: deflection at the top at 20 mm/s against the explicit engine's at 200 mm/s "
                                  f"(mm from the flat start, dx 1 mm, benchmarks/cross_rise_explicit.py)", inputs,
                            EXPLICIT_TOP_MM[m], g, err, EXPLICIT_TOL))
            per = rate[m] / v
            spread = float(abs(per[0] - per[-1]) / max(abs(per[-1]), 1e-12))
            rows.append(Row(case, f"{m}: deflection rate per magnet speed at 5 against 20 mm/s, |difference| / at "
                                  f"20 mm/s: the robot follows the magnet quasi-statically",
                            inputs | {"explicit_ratio": EXPLICIT_RATE_RATIO[m], "ratios": list(map(float, per))},
                            0.0, spread, spread, QUASI_STATIC_TOL))
            f = fine[m][0]
            gap = float(abs(top[m][-1] - f["top"]) / max(abs(f["top"]), 1e-12))
            rows.append(Row(case, f"{m}: deflection at the top at 20 mm/s, dx {dx * 1e3:g} mm against "
                                  f"{f['dx'] * 1e3:g} mm (4 cells through the strips), |difference| / the finer",
                            inputs | {"fine_mm": 1e3 * f["top"], "coarse_dx_2mm_mm": 1e3 * coarse[m][0]["top"]},
                            0.0, gap, gap, CONVERGENCE_TOL))
        a, b = v_paper["arching"], v_paper["grabbing"]
        off = abs(math.log(a / b) / math.log(ONE_HAND_FACTOR)) if a > 0 and b > 0 else float("inf")
        rows.append(Row(case, f"magnet speeds (mm/s) that give the paper's arching (4.8 mm/s) and grabbing (3.5 mm/s) "
                              f"speeds, within a factor {ONE_HAND_FACTOR:g} of each other (one hand moved the magnet); "
                              f"error: log base {ONE_HAND_FACTOR:g} of their ratio",
                        inputs | {"grabbing_mm_s": 1e3 * b}, 1e3 * b, 1e3 * a, off, 1.0))
    rates_text = "; ".join(f"{1e3 * s:g} mm/s: arching {1e3 * ra:.2f}, grabbing {1e3 * rg:.2f} mm/s"
                           for s, ra, rg in zip(v, rate["arching"], rate["grabbing"]))
    summary = (f"Under the paper's actuator rising at a hand's speed (dx {dx * 1e3:g} mm, implicit integrator) the "
               f"strips deflect at {rates_text}; at the top the cross has arched {1e3 * top['arching'][-1]:.2f} mm "
               f"and grabbed {1e3 * top['grabbing'][-1]:.2f} mm (the explicit engine at 200 mm/s: "
               f"{EXPLICIT_TOP_MM['arching']:.2f} and {EXPLICIT_TOP_MM['grabbing']:.2f} mm). The rates are {ratio['arching']:.3f} and "
               f"{ratio['grabbing']:.3f} times the magnet's speed, so the paper's 4.8 and 3.5 mm/s need a magnet "
               f"rising at {1e3 * v_paper['arching']:.0f} and {1e3 * v_paper['grabbing']:.0f} mm/s"
               + (f"; at 20 mm/s on the grid twice as fine (dx {fine['arching'][0]['dx'] * 1e3:g} mm) it arches "
                  f"{1e3 * fine['arching'][0]['top']:.2f} mm and grabs {1e3 * fine['grabbing'][0]['top']:.2f} mm, "
                  f"on the coarse one (dx {coarse['arching'][0]['dx'] * 1e3:g} mm, one cell through the strips) "
                  f"{1e3 * coarse['arching'][0]['top']:.2f} and {1e3 * coarse['grabbing'][0]['top']:.2f} mm"
                  if fine is not None else "") + ".")
    every = [r for m, _ in MODES for r in runs[m]]
    info = {"particles": every[0]["particles"], "dx_m": dx, "solver": "implicit (backward Euler)",
            "run_wall_s": round(float(sum(r["wall_s"] for r in every)), 1),
            "steps_m_of_travel": list(PREVIEW_STEPS if ctx.preview else STEPS),
            "integrators": {m: [r["integrator"] for r in runs[m]] for m, _ in MODES},
            "rate_per_magnet_speed": ratio, "magnet_speed_for_paper_mm_s": {m: 1e3 * x for m, x in v_paper.items()}}
    if coarse is not None:
        info.update(coarse_dx_m=coarse["arching"][0]["dx"],
                    coarse_top_mm={m: 1e3 * coarse[m][0]["top"] for m, _ in MODES},
                    coarse_wall_s=round(sum(coarse[m][0]["wall_s"] for m, _ in MODES), 1))
    if fine is not None:
        info.update(fine_dx_m=fine["arching"][0]["dx"], fine_particles=fine["arching"][0]["particles"],
                    fine_top_mm={m: 1e3 * fine[m][0]["top"] for m, _ in MODES},
                    fine_wall_s=round(sum(fine[m][0]["wall_s"] for m, _ in MODES), 1),
                    fine_integrators={m: fine[m][0]["integrator"] for m, _ in MODES})
    figures = [{"csv": course_csv, "png": course_png,
                "caption": "the strips' deflection against the magnet's height, per mode and magnet speed"}]
    return ReproduceResult(NAME, csv, png, None, summary, rows, info, figures)


ROBOT = Robot(
    name=NAME,
    title="Cross-shaped robot (arching and grabbing at a hand's speed)",
    source="seed 002 sec 5.1",
    quantity="deflection rate of the strips under the actuator rising at 5-20 mm/s, arching and grabbing",
    sentence="The cross of seed 002 under the paper's actuator rising at a hand's speed, south face up (it arches) "
             "and north face up (it grabs): how fast its strips deflect, by the implicit integrator, beside the "
             "explicit engine's answers at 50-200 mm/s.",
    reproduce=reproduce,
)
