"""Speeds of seed 002's robots under the paper's actuator moving under the plate (issue "Robot library II").

Seed 002 reports speeds for its robots (triangle: warping 9 mm/s, locomotion 1.5 mm/s; cross: arching 4.8 and
grabbing 3.5 mm/s; secs 4.3, 4.4, 5.1) but not the speed of the magnet that drives them. These runs move the
paper's actuator at a stated constant speed and read how fast the robot answers:

- rising magnet (triangle warping, cross arching and grabbing): the magnet, centred under the point that moves
  (the triangle's top vertex, the cross's centre), waits ``SETTLE`` s at ``Z_START`` while the robot settles on the
  plate, then rises at constant speed until its top face is 1 mm under the plate top; the heights of marked
  material are sampled every ``SAMPLE`` s and the speed is the largest rate over two samples (10 ms);
- passing magnet (triangle locomotion): the magnet moves along -y from beyond the top vertex to beyond the
  opposite side at constant speed, under the plate; the speed is the centroid's mean speed along the pass.

The actuator (seed 002 sec 4.1): an N35 disc, 100 mm across and 10 mm thick, remanence set to ``ACTUATOR_BR``
so that the field at the centre of its face is 50 mT as the paper states (the same magnet as
scenes/pentagram.toml, which moves it along the plate).
"""

from __future__ import annotations

import copy
import math
import time

import numpy as np

from magsoro.errors import SimulationError
from magsoro.robots.base import _save, plot_curve, simulation, write_csv

ACTUATOR_BR = 0.5099   # T: 50 mT at the face centre of the 100 mm x 10 mm disc (scenes/pentagram.toml)
Z_TOP = -0.006         # m: magnet centre with its top face 1 mm below the plate top (z = 0 is the plate top)
Z_START = -0.08        # m: magnet centre at the start of a rising run (|B| at the robot ~2 mT)
SETTLE = 0.04          # s: the robot settles on the plate before the magnet moves
SAMPLE = 0.005         # s between height samples; rates are taken over two samples
AFTER = 0.06           # s the run goes on after the magnet stops
PASS_FROM, PASS_TO = 0.09, -0.08   # m: y of the magnet's centre at the start and end of a pass (triangle)
IMPLICIT_ROOM = 0.01   # m: room added below the domain for the implicit integrator's passes (passing_run)
PASS_AFTER = 0.05      # s after a pass
PROGRESS = 0.005       # m of magnet travel between the progress lines of an implicit run (_centroid_run)
#: m of magnet travel before a slow run's rates count: its first step switches the field on and the robot answers
#: within it (the triangle's vertex lifts about 1 mm in a step of 25-100 ms, where the explicit engine's 40 ms of
#: settling hold it)
START_TRAVEL = 0.005


def actuator(data: dict, remanence_sign: float) -> dict:
    """The scene's ``magnet`` field table made the paper's actuator (50 mT at its face), north face up for +1."""
    m = next(f for f in data["fields"] if f.get("name") == "magnet")
    m.update(diameter=0.1, length=0.01, axis=[0.0, 0.0, 1.0], remanence=float(remanence_sign) * ACTUATOR_BR)
    return m


def largest_rate(t: np.ndarray, z: np.ndarray, t_from: float = SETTLE) -> tuple[float, float]:
    """Largest rate dz/dt (m/s) of samples ``z`` at times ``t`` over centred two-sample differences from
    ``t_from`` on, and the time it happens."""
    t, z = np.asarray(t, float), np.asarray(z, float)
    if len(t) < 3:
        return float("nan"), float("nan")
    rate = (z[2:] - z[:-2]) / (t[2:] - t[:-2])
    tm = t[1:-1]
    ok = tm >= t_from
    if not ok.any():
        return float("nan"), float("nan")
    k = int(np.argmax(rate[ok]))
    return float(rate[ok][k]), float(tm[ok][k])


def moving_rate(t: np.ndarray, z: np.ndarray, speed: float) -> float:
    """:func:`largest_rate` of samples ``z`` at times ``t`` once the magnet, moving at ``speed`` (m/s) from SETTLE on,
    has travelled START_TRAVEL."""
    return largest_rate(t, z, SETTLE + START_TRAVEL / speed)[0]


def _sampled(sim, t_end: float, take, sample: float = SAMPLE) -> float:
    """Advance ``sim`` to ``t_end`` calling ``take`` every ``sample`` s (and at the start); returns the wall time."""
    w0 = time.perf_counter()
    take()
    while sim.time < t_end - 1e-9:
        sim.advance_to(min(t_end, sim.time + sample))
        take()
    return time.perf_counter() - w0


def slow_settings(data: dict, speed: float, implicit_step: float | None, implicit_max_step: float | None = None) -> float:
    """Make ``data`` a run of the implicit integrator when ``implicit_step`` (m of magnet travel per step) is given:
    backward Euler, steps of implicit_step / ``speed`` (the largest; halved where Newton needs it) and no mass damping
    (the scene's damping settles the explicit engine; at the magnet's speed it would drag the robot with a force
    of c m v). The linear solver is the integrator's 'auto': the robot's contacts with its plate change the
    tangent at nearly every Newton iteration, which turns it iterative on the full grid (10,200 unknowns) and
    leaves the preview's 3,108 to the direct one (benchmarks/README.md, "Contact rounds and kept tangents in
    implicit steps"). ``implicit_max_step`` (m of magnet travel, at least ``implicit_step``): steps grow after easy
    ones (the integrator's implicit.grow and easy_iterations) up to it, and the samples are that far apart.
    Returns the sampling interval: SAMPLE for the explicit engine, the largest step for the implicit one."""
    if implicit_step is None:
        return SAMPLE
    dt = float(implicit_step) / float(speed)
    dt_max = max(dt, float(implicit_max_step) / float(speed)) if implicit_max_step is not None else dt
    data["simulation"].update(integrator="implicit", damping=0.0)
    data["implicit"] = {"scheme": "backward_euler", "dt": dt, "dt_max": dt_max}
    return dt_max


def rising_run(name: str, base: dict, xy, speed: float, remanence_sign: float, markers, ctx, label: str,
               implicit_step: float | None = None) -> dict:
    """The magnet rises under ``xy`` at ``speed`` (m/s). ``markers(X0) -> {key: mask}`` picks the material whose
    mean height is sampled. ``implicit_step``: run by the implicit integrator (:func:`slow_settings`). Returns
    times, magnet heights, marker heights (m) and run facts."""
    data = copy.deepcopy(base)
    sample = slow_settings(data, speed, implicit_step)
    m = actuator(data, remanence_sign)
    t_move = SETTLE + (Z_TOP - Z_START) / speed
    start, top = [float(xy[0]), float(xy[1]), Z_START], [float(xy[0]), float(xy[1]), Z_TOP]
    m["position"] = start
    m["path"] = {"times": [0.0, SETTLE, t_move], "positions": [start, start, top]}
    t_end = t_move + AFTER
    data["simulation"]["duration"] = t_end
    sim = simulation(name, data, preview=ctx.preview, device=ctx.device)
    X0 = sim.model.host["positions"].astype(np.float64)
    masks = markers(X0)
    rec = {"t": [], "magnet_z": [], **{k: [] for k in masks}}

    def take():
        x = sim.state.x.numpy().astype(np.float64)
        if not np.isfinite(x).all():
            raise FloatingPointError(f"{label}: non-finite positions at t = {sim.time:.4f} s")
        rec["t"].append(sim.time)
        rec["magnet_z"].append(float(np.interp(sim.time, [0.0, SETTLE, t_move], [Z_START, Z_START, Z_TOP])))
        for k, mask in masks.items():
            rec[k].append(float(x[mask, 2].mean()))

    wall = _sampled(sim, t_end, take, sample)
    out = {k: np.asarray(v) for k, v in rec.items()}
    out.update(speed=speed, t_move=t_move, wall_s=wall, dx=sim.model.dx, particles=int(len(X0)),
               integrator=sim.integrator_info(), sample_s=sample)
    ctx.log(f"  {label} at {speed * 1e3:.0f} mm/s: {wall:.0f} s wall")
    return out


def pass_path(speed: float, approach: float = 0.0) -> tuple[dict, float, float]:
    """The magnet's path of a pass at ``speed`` (m/s) with ``approach`` (m) beyond PASS_FROM (:func:`passing_run`):
    (its path table, when it is at PASS_FROM, when at PASS_TO). It waits SETTLE s at its start, then moves along
    -y at ``speed`` all the way."""
    t_start = SETTLE + float(approach) / speed
    t_pass = t_start + (PASS_FROM - PASS_TO) / speed
    pa, p0, p1 = [0.0, PASS_FROM + float(approach), Z_TOP], [0.0, PASS_FROM, Z_TOP], [0.0, PASS_TO, Z_TOP]
    if approach > 0.0:
        return {"times": [0.0, SETTLE, t_start, t_pass], "positions": [pa, pa, p0, p1]}, t_start, t_pass
    return {"times": [0.0, SETTLE, t_pass], "positions": [p0, p0, p1]}, t_start, t_pass


def _centroid_run(name: str, base: dict, path: dict, t_end: float, speed: float, remanence_sign: float, domain,
                  ctx, label: str, implicit_step: float | None, keep_failed: bool,
                  implicit_max_step: float | None = None, markers=None, snapshots=()) -> dict:
    """Scene ``name`` (table ``base``) with the actuator following ``path`` (keyframes: times, positions) until
    ``t_end`` in a domain widened to ``domain`` (lo, hi), the mass centre sampled (the shared part of
    :func:`passing_run` and :func:`stroke_run`; their arguments). Returns times, the magnet's position (from the
    path's keyframes, linear between), the centroid and the mean height of each of ``markers(X0) -> {key: mask}``
    (m) with run facts; ``frames``: the particles' positions (m) at the first samples at or after the times
    ``snapshots`` (s), as (time, positions) pairs. A run the engine stops raises, or with ``keep_failed`` returns
    what it sampled with ``failed`` (the engine's message)."""
    data = copy.deepcopy(base)
    sample = slow_settings(data, speed, implicit_step, implicit_max_step)
    m = actuator(data, remanence_sign)
    m["path"] = path
    m["position"] = list(path["positions"][0])
    key_t, key_p = np.asarray(path["times"], float), np.asarray(path["positions"], float)
    S = data["simulation"]
    S["duration"], S["domain_lo"], S["domain_hi"] = t_end, list(domain[0]), list(domain[1])
    if implicit_step is not None:
        # the Newton solvers model a domain wall a body starts within reach of as a frictionless collider at the
        # nodes; on the preview grid (dx 2 mm) the domain's floor, two cells under the plate, would carry the robot
        # instead of its friction plate
        S["domain_lo"][2] -= IMPLICIT_ROOM
    sim = simulation(name, data, preview=ctx.preview, device=ctx.device)
    mass = sim.model.host["mass"].astype(np.float64)
    masks = {} if markers is None else markers(sim.model.host["positions"].astype(np.float64))
    rec = {"t": [], "mx": [], "my": [], "mz": [], "cx": [], "cy": [], "cz": [], **{k: [] for k in masks}}
    w0, logged = time.perf_counter(), [None]
    pending, frames = sorted(float(t) for t in snapshots), []

    def take():
        x = sim.state.x.numpy().astype(np.float64)
        if not np.isfinite(x).all():
            raise FloatingPointError(f"{label}: non-finite positions at t = {sim.time:.4f} s")
        if pending and sim.time >= pending[0] - 1e-9:
            frames.append((sim.time, x.copy()))
            while pending and sim.time >= pending[0] - 1e-9:
                pending.pop(0)
        c = (mass[:, None] * x).sum(0) / mass.sum()
        at = [float(np.interp(sim.time, key_t, key_p[:, k])) for k in range(3)]
        rec["t"].append(sim.time)
        for k, v in zip(("mx", "my", "mz", "cx", "cy", "cz"), (*at, *c)):
            rec[k].append(float(v))
        for k, mask in masks.items():
            rec[k].append(float(x[mask, 2].mean()))
        if implicit_step is not None and (logged[0] is None or np.linalg.norm(np.subtract(at, logged[0])) >= PROGRESS - 1e-12):
            # a long run's course, line by line, so that a run stopped on the way still says where the robot went
            logged[0] = at
            ctx.log(f"    t {sim.time:.3f} s: magnet y {1e3 * at[1]:+.1f} z {1e3 * at[2]:+.1f} mm, centroid y "
                    f"{1e3 * c[1]:+.2f} z {1e3 * c[2]:+.2f} mm ({time.perf_counter() - w0:.0f} s wall)")

    failed = None
    try:
        _sampled(sim, t_end, take, sample)
    except SimulationError as exc:
        if not keep_failed:
            raise
        failed = str(exc)
        ctx.log(f"  {label} at {speed * 1e3:.0f} mm/s stopped at t = {sim.time:.3f} s: {exc}")
    out = {k: np.asarray(v) for k, v in rec.items()}
    out.update(speed=speed, wall_s=time.perf_counter() - w0, dx=sim.model.dx, particles=int(len(mass)),
               integrator=sim.integrator_info(), sample_s=sample, failed=failed, frames=frames)
    return out


def passing_run(name: str, base: dict, speed: float, remanence_sign: float, domain, ctx, label: str,
                implicit_step: float | None = None, approach: float = 0.0, keep_failed: bool = False,
                implicit_max_step: float | None = None) -> dict:
    """The magnet passes along y from PASS_FROM to PASS_TO under the plate at ``speed`` (m/s) in a domain widened
    to ``domain`` (lo, hi); the mass centre is sampled. ``implicit_step``: run by the implicit integrator
    (:func:`slow_settings`). ``approach`` (m): the magnet starts this much farther along +y and comes in at the same
    speed, so the robot meets its field growing instead of switched on at PASS_FROM (the implicit integrator
    could not start there at hand speeds: benchmarks/README.md); the displacement is still read from PASS_FROM
    to PASS_TO. Returns times, magnet y, centroid (m) and run facts (``t_start``, ``t_pass``: when the magnet is at
    PASS_FROM and PASS_TO). ``implicit_max_step``: :func:`slow_settings`. ``keep_failed``: a run the engine stops (SimulationError) returns what it sampled up to
    there with ``failed`` (the engine's message) and no displacement, instead of raising (benchmarks)."""
    path, t_start, t_pass = pass_path(speed, approach)
    out = _centroid_run(name, base, path, t_pass + PASS_AFTER, speed, remanence_sign, domain, ctx, label,
                        implicit_step, keep_failed, implicit_max_step)
    out.update(magnet_y=out["my"], t_start=t_start, t_pass=t_pass, approach=float(approach))
    if out["failed"] is not None:
        out.update(dy=float("nan"), mean_speed=float("nan"))
        return out
    i0, i1 = np.searchsorted(out["t"], t_start), np.searchsorted(out["t"], t_pass)
    out.update(dy=float(out["cy"][i1] - out["cy"][i0]),
               mean_speed=float((out["cy"][i1] - out["cy"][i0]) / (t_pass - t_start)))
    ctx.log(f"  {label} at {speed * 1e3:.0f} mm/s: centroid moved {out['dy'] * 1e3:+.1f} mm along y in the pass "
            f"({out['wall_s']:.0f} s wall)")
    return out


def rise_path(xy, speed: float) -> tuple[dict, float]:
    """The magnet's path of a rise at ``speed`` (m/s; :func:`rise_run`): it waits SETTLE s at Z_START under ``xy``
    and rises to Z_TOP. Returns its path table and the time it reaches the top."""
    x, y = map(float, xy)
    t_up = SETTLE + (Z_TOP - Z_START) / speed
    return {"times": [0.0, SETTLE, t_up], "positions": [[x, y, Z_START], [x, y, Z_START], [x, y, Z_TOP]]}, t_up


def rise_run(name: str, base: dict, xy, speed: float, remanence_sign: float, domain, ctx, label: str, markers,
             implicit_step: float | None = None, implicit_max_step: float | None = None) -> dict:
    """The rise of :func:`rising_run` (the magnet under ``xy`` from Z_START to Z_TOP at ``speed``, AFTER s more) in
    a domain widened to ``domain`` (lo, hi), sampled as :func:`stroke_run` samples (at the implicit integrator's
    largest step, with progress lines); ``markers(X0) -> {key: mask}`` picks the material whose mean height is
    sampled. Returns the sampled series (times ``t``, the magnet's position ``mx``, ``my``, ``mz``, the centroid
    ``cx``, ``cy``, ``cz`` and one per marker, m) with run facts and ``t_up``."""
    path, t_up = rise_path(xy, speed)
    out = _centroid_run(name, base, path, t_up + AFTER, speed, remanence_sign, domain, ctx, label, implicit_step,
                        False, implicit_max_step, markers)
    out["t_up"] = t_up
    ctx.log(f"  {label} at {speed * 1e3:.0f} mm/s: {out['wall_s']:.0f} s wall")
    return out


def stroke_path(start_xy, end_xy, speed: float) -> tuple[dict, tuple[float, float, float]]:
    """The magnet's path of a stroke at ``speed`` (m/s; :func:`stroke_run`): it waits SETTLE s at Z_START under
    ``start_xy``, rises to Z_TOP, moves level to under ``end_xy`` and goes down to Z_START again. Returns its path
    table and the times (t_up, t_moved, t_down) at which it reaches the top, ends its level move and is down."""
    x0, y0 = map(float, start_xy)
    x1, y1 = map(float, end_xy)
    rise = (Z_TOP - Z_START) / speed
    t_up = SETTLE + rise
    t_moved = t_up + math.hypot(x1 - x0, y1 - y0) / speed
    t_down = t_moved + rise
    positions = [[x0, y0, Z_START], [x0, y0, Z_START], [x0, y0, Z_TOP], [x1, y1, Z_TOP], [x1, y1, Z_START]]
    return {"times": [0.0, SETTLE, t_up, t_moved, t_down], "positions": positions}, (t_up, t_moved, t_down)


def stroke_run(name: str, base: dict, start_xy, end_xy, speed: float, remanence_sign: float, domain, ctx,
               label: str, implicit_step: float | None = None, keep_failed: bool = False,
               implicit_max_step: float | None = None, markers=None, snapshots: int = 0) -> dict:
    """A stroke of the magnet (:func:`stroke_path`): it rises under ``start_xy`` (the triangle's vertex: seed 002
    Fig. 4c moves the actuator "from one of the vertex to its opposite side"), moves level under the plate to
    ``end_xy`` and goes down, all at ``speed`` (m/s), in a domain widened to ``domain``; the mass centre is
    sampled. Unlike :func:`passing_run` the magnet's rim never sweeps across the robot. Returns times, the magnet's
    position, the centroid (m) and run facts: ``along`` the centroid's displacement along the level move while the
    magnet moves level and over the whole stroke (``along_stroke``, the magnet down again and AFTER s more),
    ``move_speed`` the first over the move's time, ``lift`` the centroid's largest rise, ``course`` the centroid
    along the stroke from its start at each sample. ``implicit_step``,
    ``implicit_max_step`` (:func:`slow_settings`) and ``keep_failed`` as in :func:`passing_run`; ``markers(X0) ->
    {key: mask}`` picks material whose mean height is sampled too (the rise under the start is a warping run);
    ``snapshots``: the particles' positions kept at that many times in each leg (``frames``), for pictures."""
    path, (t_up, t_moved, t_down) = stroke_path(start_xy, end_xy, speed)
    keys = path["times"][1:]  # the robot's shape at the stroke's turns and between them (``snapshots`` per leg)
    when = [keys[0]] + [a + (b - a) * (k + 1) / max(snapshots, 1) for a, b in zip(keys[:-1], keys[1:])
                        for k in range(max(snapshots, 1))] if snapshots else []
    out = _centroid_run(name, base, path, t_down + AFTER, speed, remanence_sign, domain, ctx, label, implicit_step,
                        keep_failed, implicit_max_step, markers, when)
    d = np.subtract(end_xy, start_xy).astype(float)
    d /= max(float(np.linalg.norm(d)), 1e-300)
    out.update(t_up=t_up, t_moved=t_moved, t_down=t_down, direction=d.tolist())
    if out["failed"] is not None:
        out.update(along=float("nan"), along_stroke=float("nan"), move_speed=float("nan"), lift=float("nan"))
        return out
    c = np.stack([out["cx"], out["cy"]], axis=1) @ d
    out["course"] = c - c[0]  # the centroid along the stroke from where it started (m), per sample
    i0, i1 = np.searchsorted(out["t"], t_up), np.searchsorted(out["t"], t_moved)
    out.update(along=float(c[i1] - c[i0]), along_stroke=float(c[-1] - c[0]),
               move_speed=float((c[i1] - c[i0]) / (t_moved - t_up)), lift=float(out["cz"].max() - out["cz"][0]))
    ctx.log(f"  {label} at {speed * 1e3:.0f} mm/s: centroid moved {out['along'] * 1e3:+.2f} mm along the stroke while "
            f"the magnet moved level, {out['along_stroke'] * 1e3:+.2f} mm in all ({out['wall_s']:.0f} s wall)")
    return out


def stroke_side_views(png, frames, run: dict, title: str):
    """PNG of the robot seen from the side (y-z; colour x) at each of ``frames`` ((t, positions) pairs) of a
    :func:`stroke_run` result ``run``, the magnet's top face drawn where it is in view, the centroid's displacement
    along the stroke in each panel's title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(frames)
    cols = min(n, 5)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.4 * rows), squeeze=False)
    for ax, (t, x) in zip(axes.ravel(), frames):
        mx, my, mz = (float(np.interp(t, run["t"], run[k])) for k in ("mx", "my", "mz"))
        ax.scatter(1e3 * x[:, 1], 1e3 * x[:, 2], s=1, c=1e3 * x[:, 0], cmap="coolwarm", vmin=-25, vmax=25)
        ax.axhline(0.0, color="0.5", lw=0.8)  # the plate's top
        top = 1e3 * (mz + 0.005)
        if top > -12:
            ax.add_patch(plt.Rectangle((1e3 * my - 50.0, top - 10.0), 100.0, 10.0, color="0.8", zorder=0))
        along = 1e3 * run["course"][min(int(np.searchsorted(run["t"], t)), len(run["t"]) - 1)]
        ax.set_title(f"t {t:.2f} s, magnet y {1e3 * my:+.0f} z {1e3 * mz:+.0f}\nrobot {along:+.2f} mm along", fontsize=8)
        ax.set_xlim(-40, 40), ax.set_ylim(-12, 25), ax.set_aspect("equal"), ax.tick_params(labelsize=7)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    fig.suptitle(f"{title}, side view (y, z in mm; colour: x); dx = {1e3 * run['dx']:.1f} mm", fontsize=9)
    fig.set_dpi(110)
    fig.tight_layout()
    _save(fig, png)
    plt.close(fig)
    return png


def magnet_speed_for(paper: float, magnet_speeds, speeds) -> float | None:
    """The magnet speed at which the measured speed equals the paper's (linear in between the measured magnet
    speeds; None outside them or when the speeds do not grow with the magnet's)."""
    v, s = np.asarray(magnet_speeds, float), np.asarray(speeds, float)
    if len(v) < 2 or not np.all(np.diff(s) > 0) or not (s[0] <= paper <= s[-1]):
        return None
    return float(np.interp(paper, s, v))


def write_speeds(out_dir, name: str, table: dict, paper: dict, note: str):
    """``name``_speeds.csv (one row per magnet speed) and .png (robot speed against magnet speed, the paper's
    value as a line: it gives no magnet speed)."""
    csv = write_csv(out_dir / f"{name}_speeds.csv", table)
    v = np.asarray(table["magnet_speed_mm_s"], float)
    series = {k.removesuffix("_mm_s").replace("_", " "): np.asarray(table[k], float)
              for k in table if k.endswith("_mm_s") and k != "magnet_speed_mm_s"}
    png = plot_curve(out_dir / f"{name}_speeds.png", v, series, "magnet speed (mm/s)", "robot speed (mm/s)",
                     f"{name}: speed under the moving magnet", hlines=paper, note=note, legend_loc="center right")
    return csv, png
