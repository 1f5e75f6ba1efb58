"""Seed 004's magnetic-tip growing robot steered into a retroflexion by its external magnet (sec II-C), in 3D.

The magnet's poses are planned on the planar pseudo-rigid-body (PRB) model (`magsoro plan`,
examples/actuation/plan_retroflexion_tip.toml: a 60 x 6 x 6 mm strip, only the distal link magnetised, grown
straight 4 -> 7 -> 10 links, then curled to 60, 120 and 180 degrees) and replayed by the MPM engine in 3D
(:func:`magsoro.actuation.replay.replay` with ``dim = 3``), the robot growing link by link:

- on a frictionless floor with gravity (the planar plan's support);
- free in space (no floor, no gravity);
- free in the field the planar PRB sees (``planar_field``: the magnet and its mirror image in the plane, half the
  moment each, so the magnet's in-plane field on the plane and no B_z): the 3D body against its PRB.

The 3D body feels the magnet's whole field; the planar PRB sees its in-plane part. The MPM tips are compared with
the plan and with the PRB of the same links carrying Young's modulus (``beam_robot``; the plan's strip carries the
plane-strain modulus), quasi-static under the same keyframed magnet: the planar-field run is checked against that
PRB, and the floor run's distance from it is what the out-of-plane field adds. scenes/growing_retroflexion.toml is the fully
everted robot on the floor under the last pose's magnet (what `magsoro run` can show of it without the plan's
growth).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from magsoro.bundled import data_folder
from magsoro.robots.base import Context, FrameRecorder, ReproduceResult, Robot, RobotError, write_csv
from magsoro.robots.continuum_soft import Row

NAME = "growing_retroflexion"
#: the actuation plan the robot replays, in examples/ (installed with the package or in the checkout)
PLAN = Path("examples") / "actuation" / "plan_retroflexion_tip.toml"
DX, PREVIEW_DX = 1.5e-3, 3.0e-3          # m: four and two cells across the 6 mm section
#: the checks' tolerances, as a fraction of the robot's 60 mm: growth steps 0.1 mm; bends 10 %; height 5 %
GROWTH_TOL, BEND_TOL, HEIGHT_TOL = 1e-4, 0.10, 0.05


def _plan():
    from magsoro.actuation.config import PlanConfig, load

    try:
        plan = data_folder("examples").parent / PLAN
    except FileNotFoundError as exc:
        raise RobotError(f"{NAME}: {exc}") from None
    if not plan.is_file():
        raise RobotError(f"{NAME}: the plan {plan} is missing (it ships in examples/)")
    cfg = load(PlanConfig, plan)
    robot, target, planner, strip = cfg.build()
    return cfg, robot, strip, planner.plan(target)


def _recorder() -> FrameRecorder:
    """Frames of the growing robot (x-y), coloured by body. The particle count grows with the links, so the frames
    are padded to the last count with NaN (not drawn) by :func:`_pad` before the GIF is written."""
    rec = FrameRecorder(axes=(0, 1), label=lambda sim: f"t = {sim.time:.2f} s, {sim.model.n_particles} particles")

    def record(sim):
        x = sim.state.x.numpy().astype(np.float64)
        rec.frames.append((x[:, :2].copy(), rec.label(sim)))
        rec.color = np.asarray(sim.model.host["body"]).copy()  # the last step's bodies: every particle so far

    rec.record = record
    return rec


def _pad(rec: FrameRecorder) -> FrameRecorder:
    n = max(len(f[0]) for f in rec.frames)
    for k, (pts, caption) in enumerate(rec.frames):
        full = np.full((n, 2), np.nan)
        full[: len(pts)] = pts
        rec.frames[k] = (full, caption)
    return rec


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.actuation.replay import beam_robot, replay

    cfg, robot, strip, plan = _plan()
    rc = cfg.replay
    T, frac = rc.step_duration, rc.move_fraction
    dx = PREVIEW_DX if ctx.preview else DX
    L = robot.n_links * robot.link_length
    planned = np.array([robot.tip(s.theta) for s in plan.steps])

    frames = _recorder()
    runs = {}
    for name, floor, planar, what in (("floor", True, False, "on the floor"), ("free", False, False, "free"),
                                      ("planar", False, True, "free, in the PRB's (planar) field")):
        ctx.log(f"{NAME}: 3D replay {what} (dx {dx * 1e3:g} mm)")
        # the planar run is compared with the beam PRB (its tip_prb and step ends); the others with the plan's PRB
        runs[name] = replay(plan, strip, dx, T, frac, rc.damping_ratio, dim=3, floor=floor, planar_field=planar,
                            record=frames.record if floor else None,
                            check_robot=beam_robot(robot, strip) if planar else None)
    fl, fr, pl = runs["floor"], runs["free"], runs["planar"]
    beam_tips, beam_ends = pl.tip_prb, pl.step_end_prb  # the beam PRB, quasi-static under the same magnet
    z0 = fl.plane_z

    out = ctx.out
    csv = write_csv(out / f"{NAME}.csv", {
        "t_s": fl.times,
        "floor_tip_x_mm": 1e3 * fl.tip_mpm[:, 0], "floor_tip_y_mm": 1e3 * fl.tip_mpm[:, 1],
        "floor_tip_z_mm": 1e3 * (fl.tip_mpm[:, 2] - z0),
        "free_tip_x_mm": 1e3 * fr.tip_mpm[:, 0], "free_tip_y_mm": 1e3 * fr.tip_mpm[:, 1],
        "free_tip_z_mm": 1e3 * (fr.tip_mpm[:, 2] - z0),
        "planar_field_tip_x_mm": 1e3 * pl.tip_mpm[:, 0], "planar_field_tip_y_mm": 1e3 * pl.tip_mpm[:, 1],
        "beam_prb_tip_x_mm": 1e3 * beam_tips[:, 0], "beam_prb_tip_y_mm": 1e3 * beam_tips[:, 1],
        "plan_prb_tip_x_mm": 1e3 * fl.tip_prb[:, 0], "plan_prb_tip_y_mm": 1e3 * fl.tip_prb[:, 1],
    })
    png = _plot(out / f"{NAME}.png", fl, fr, pl, beam_tips, beam_ends, planned, dx)
    allx = 1e3 * np.concatenate([f[0] for f in frames.frames])
    lo, hi = allx.min(axis=0) - 8.0, allx.max(axis=0) + 8.0
    anim = _pad(frames).write_gif(out / f"{NAME}.gif", title="growing robot, 3D replay on the floor (x-y)",
                                  lims=((lo[0], hi[0]), (lo[1], hi[1])))

    to_beam = np.linalg.norm(fl.step_end_mpm[:, :2] - beam_ends, axis=1)
    planar_to_beam = pl.step_end_in_plane_errors
    inputs = {"dx_mm": dx * 1e3, "length_mm": L * 1e3, "plan": "examples/actuation/plan_retroflexion_tip.toml"}
    rows = []
    for k in range(3):
        rows.append(Row(NAME, f"floor: tip at the end of growth step {k} ({plan.steps[k].links} links) - plan, m",
                        dict(inputs, step=k), 0.0, float(fl.step_end_errors[k]), float(fl.step_end_errors[k]), GROWTH_TOL))
    for k, angle in zip(range(3, 6), (60, 120, 180)):
        rows.append(Row(NAME, f"planar field: tip at the end of bend step {k} ({angle} deg) - beam PRB / length",
                        dict(inputs, step=k), 0.0, float(planar_to_beam[k] / L), float(planar_to_beam[k] / L),
                        BEND_TOL))
    height = float(np.abs(fl.out_of_plane).max())
    rows.append(Row(NAME, "floor: largest tip height above the floor's plane / length", inputs, 0.0, height / L,
                    height / L, HEIGHT_TOL))

    zf = fr.step_end_mpm[:, 2] - z0
    summary = (f"Seed 004's magnetic-tip robot grown and curled to 180 degrees by the planned magnet, replayed in 3D "
               f"MPM (dx {dx * 1e3:g} mm). In the field the planar PRB sees (no B_z) the bends lie "
               f"{', '.join(f'{1e3 * e:.1f}' for e in planar_to_beam[3:])} mm from the beam PRB at 60, 120 and 180 "
               f"degrees; in the magnet's whole field, on a frictionless floor, {', '.join(f'{1e3 * e:.1f}' for e in to_beam[3:])} mm "
               f"(tip at most {1e3 * height:.1f} mm off the floor, growth as planned to "
               f"{1e3 * fl.step_end_errors[:3].max():.2g} mm); free "
               f"in space the magnet, 11 cm below the plane, lifts the tip {1e3 * zf[3]:.1f} mm at the first bend and "
               f"then pulls it {-1e3 * zf[4]:.0f} mm under the plane: the planar plan needs the robot supported.")
    info = {
        "dx_m": dx, "particles": fl.particles, "mpm_steps": {"floor": fl.steps, "free": fr.steps, "planar": pl.steps},
        "wall_s": {"floor": round(fl.wall_time, 1), "free": round(fr.wall_time, 1), "planar": round(pl.wall_time, 1)},
        "step_duration_s": T,
        "planned_tips_mm": np.round(1e3 * planned, 3).tolist(),
        "beam_prb_tips_mm": np.round(1e3 * beam_ends, 3).tolist(),
        "floor_tips_mm": np.round(1e3 * fl.step_end_mpm, 3).tolist(),
        "free_tips_mm": np.round(1e3 * fr.step_end_mpm, 3).tolist(),
        "planar_field_tips_mm": np.round(1e3 * pl.step_end_mpm, 3).tolist(),
        "planar_field_in_plane_error_to_beam_prb_mm": np.round(1e3 * planar_to_beam, 3).tolist(),
        "floor_in_plane_error_to_plan_mm": np.round(1e3 * fl.step_end_in_plane_errors, 3).tolist(),
        "floor_in_plane_error_to_beam_prb_mm": np.round(1e3 * to_beam, 3).tolist(),
        "magnet_positions_mm": np.round(1e3 * np.array([s.position for s in plan.steps]), 2).tolist(),
    }
    return ReproduceResult(NAME, csv, png, anim, summary, rows, info)


def _plot(path, fl, fr, pl, beam_tips, beam_ends, planned, dx):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from magsoro.robots.base import _save

    fig, (ax, az) = plt.subplots(1, 2, figsize=(9.5, 4.2), dpi=120, gridspec_kw={"width_ratios": [3, 2]})
    ax.plot(1e3 * beam_tips[:, 0], 1e3 * beam_tips[:, 1], "-", color="C0", label="beam PRB (quasi-static)")
    ax.plot(1e3 * planned[:, 0], 1e3 * planned[:, 1], "o", mfc="none", color="0.3", label="plan (step ends)")
    ax.plot(1e3 * fl.tip_mpm[:, 0], 1e3 * fl.tip_mpm[:, 1], "-", color="C1", label="magsoro 3D, on the floor")
    ax.plot(1e3 * pl.tip_mpm[:, 0], 1e3 * pl.tip_mpm[:, 1], "-", color="C2", label="magsoro 3D, PRB's field (no B_z)")
    ax.plot(1e3 * pl.step_end_mpm[:, 0], 1e3 * pl.step_end_mpm[:, 1], "^", mfc="none", color="C2")
    ax.plot(1e3 * fr.tip_mpm[:, 0], 1e3 * fr.tip_mpm[:, 1], "-", color="C3", lw=0.9, label="magsoro 3D, free")
    ax.plot(1e3 * fl.step_end_mpm[:, 0], 1e3 * fl.step_end_mpm[:, 1], "s", mfc="none", color="C1")
    ax.plot(1e3 * beam_ends[:, 0], 1e3 * beam_ends[:, 1], "D", mfc="none", color="C0")
    for J in fl.step_end_joints_mpm[3:]:
        ax.plot(1e3 * J[:, 0], 1e3 * J[:, 1], "-", color="C1", lw=0.6, alpha=0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"tip path in the plan's plane (dx {dx * 1e3:g} mm)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    az.plot(fl.times, 1e3 * fl.out_of_plane, "-", color="C1", label="on the floor")
    az.plot(fr.times, 1e3 * fr.out_of_plane, "-", color="C3", label="free")
    az.axhline(0.0, color="C0", ls="--", lw=0.8, label="PRB (in the plane)")
    az.set_xlabel("t (s)")
    az.set_ylabel("tip height above the plane (mm)")
    az.set_title("out of the plane", fontsize=9)
    az.grid(alpha=0.3)
    az.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return Path(path)


ROBOT = Robot(
    name=NAME,
    title="Magnetic-tip growing robot steered into a retroflexion, 3D",
    source="seed 004 sec II-C",
    quantity="tip path in 3D under the planned magnet poses, against the planar PRB",
    sentence=("The growing robot with a magnetic tip everts straight and is curled to 180 degrees by the external "
              "magnet whose poses the planar planner chose; the 3D MPM replay grows it link by link, on a floor and "
              "free in space in the magnet's whole field, and in the field the planar model sees."),
    reproduce=reproduce,
    in_ci=True,
)
