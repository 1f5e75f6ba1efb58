"""Files of ``magsoro plan``: the plan (JSON), the magnet keyframes (CSV, and a scene table when the moment is
constant), the PRB shapes (CSV), pictures, and the MPM replay's tip paths."""

from __future__ import annotations

import csv
import json
import math
import time
from pathlib import Path

import numpy as np


def plan_summary(plan, planner, wall_time: float) -> dict:
    """JSON-ready summary of a :class:`~magsoro.actuation.planning.Plan` (SI units, angles in rad and deg)."""
    robot = plan.robot
    steps = []
    for k, s in enumerate(plan.steps):
        steps.append({
            "step": k,
            "links": s.links,
            "magnet_position_m": [float(v) for v in s.position],
            "magnet_moment_Am2": [float(v) for v in s.moment],
            "tip_angle_rad": float(robot.angles(s.theta)[-1]),
            "target_tip_angle_rad": float(s.target[-1]),
            "tip_angle_error_deg": math.degrees(s.tip_angle_error),
            "shape_rms_error_deg": math.degrees(s.shape_rms_error),
            "tip_position_m": [float(v) for v in robot.tip(s.theta)],
            "max_out_of_plane_field_T": s.max_out_of_plane_field,
            "magnet_clearance_m": s.min_distance,
            "stiffness_margin": s.stiffness_margin,
            "path_jump": s.path_jump,
            "evaluations": s.evaluations,
        })
    return {
        "links": robot.n_links,
        "link_length_m": robot.link_length,
        "bending_stiffness_Nm2": robot.bending_stiffness,
        "magnetisation_angles_rad": [float(a) for a in plan.magnetisation_angles],
        "magnet_moment_Am2": planner.moment,
        "fixed_direction": None if planner.fixed is None else [float(v) for v in planner.fixed],
        "max_tip_angle_error_deg": float(np.degrees(plan.tip_angle_errors.max())),
        "max_shape_rms_error_deg": float(max(math.degrees(s.shape_rms_error) for s in plan.steps)),
        "max_out_of_plane_field_T": float(max(s.max_out_of_plane_field for s in plan.steps)),
        "planning_wall_time_s": wall_time,
        "steps": steps,
    }


def write_shapes(path, plan) -> None:
    """PRB and target link ends of every step: CSV step, joint, x, y, target_x, target_y (m)."""
    robot = plan.robot
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["step", "joint", "x", "y", "target_x", "target_y"])
        for k, s in enumerate(plan.steps):
            J = robot.joints(s.theta)
            T = robot.joints(robot.configuration(s.target))
            for j in range(len(J)):
                w.writerow([k, j, f"{J[j, 0]:.9e}", f"{J[j, 1]:.9e}", f"{T[j, 0]:.9e}", f"{T[j, 1]:.9e}"])


def plot_plan(path, plan, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    robot = plan.robot
    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    cmap = plt.get_cmap("viridis")
    K = len(plan.steps)
    for k, s in enumerate(plan.steps):
        c = cmap(k / max(1, K - 1))
        J = 1e3 * robot.joints(s.theta)
        T = 1e3 * robot.joints(robot.configuration(s.target))
        axes[0].plot(T[:, 0], T[:, 1], "--", color=c, lw=1)
        axes[0].plot(J[:, 0], J[:, 1], "-o", color=c, ms=2, label=f"step {k}")
        axes[1].plot(1e3 * s.position[0], 1e3 * s.position[1], "o", color=c)
        m = s.moment / np.linalg.norm(s.moment)
        axes[1].arrow(1e3 * s.position[0], 1e3 * s.position[1], 20 * m[0], 20 * m[1], color=c, width=0.8)
        axes[1].annotate(f"z={1e3 * s.position[2]:.0f}", (1e3 * s.position[0], 1e3 * s.position[1]), fontsize=6,
                         xytext=(3, -8), textcoords="offset points")
    axes[0].set_aspect("equal")
    axes[0].set_title("PRB (solid) and target (dashed)")
    axes[0].legend(fontsize=7)
    axes[1].plot([0], [0], "k+")
    axes[1].set_aspect("equal")
    axes[1].set_title("magnet positions (x-y, z in mm) and moment directions")
    for ax in axes:
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_replay(path, result, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if result.dim == 3:  # the plane, and the tip's height out of it
        fig, (ax, az) = plt.subplots(1, 2, figsize=(10, 5), gridspec_kw={"width_ratios": [3, 2]})
    else:
        fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(1e3 * result.tip_prb[:, 0], 1e3 * result.tip_prb[:, 1], "-", color="C0", label="PRB (quasi-static)")
    ax.plot(1e3 * result.tip_mpm[:, 0], 1e3 * result.tip_mpm[:, 1], "-", color="C1", label=f"MPM replay ({result.dim}D)")
    ax.plot(1e3 * result.step_end_prb[:, 0], 1e3 * result.step_end_prb[:, 1], "o", color="C0")
    ax.plot(1e3 * result.step_end_mpm[:, 0], 1e3 * result.step_end_mpm[:, 1], "s", color="C1", mfc="none")
    for J in result.step_end_joints_mpm:
        ax.plot(1e3 * J[:, 0], 1e3 * J[:, 1], "-", color="C1", lw=0.6, alpha=0.6)
    for J in result.step_end_joints_prb:
        ax.plot(1e3 * J[:, 0], 1e3 * J[:, 1], "--", color="C0", lw=0.6, alpha=0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.legend(fontsize=8)
    ax.set_title(title or "tip path: MPM replay vs PRB")
    if result.dim == 3:
        az.plot(result.times, 1e3 * result.out_of_plane, "-", color="C1")
        az.axhline(0.0, color="C0", lw=0.8, ls="--", label="PRB (in the plane)")
        az.set_xlabel("t [s]")
        az.set_ylabel("tip z - plane z [mm]")
        az.legend(fontsize=8)
        az.set_title("out of the plane")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_plan(config, out, replay: bool = False, progress=None) -> dict:
    """Plan (and optionally replay) a :class:`~magsoro.actuation.config.PlanConfig`; write the files into
    ``out``; return the summary (also written as plan.json)."""
    from magsoro.actuation.replay import replay as run_replay

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    robot, target, planner, strip = config.build()
    t0 = time.perf_counter()
    plan = planner.plan(target, progress=progress)
    summary = plan_summary(plan, planner, time.perf_counter() - t0)
    summary["name"] = config.name
    rc = config.replay
    step_duration = (rc.step_duration if rc is not None and rc.step_duration is not None
                     else strip.first_period(robot.n_links * robot.link_length))
    move_fraction = rc.move_fraction if rc is not None else 0.5
    source = plan.keyframes(step_duration, move_fraction)
    source.to_csv(out / "epm_path.csv")
    files = ["plan.json", "epm_path.csv", "prb_shapes.csv", "plan.png"]
    summary["keyframes"] = {"step_duration_s": step_duration, "move_fraction": move_fraction, "file": "epm_path.csv"}
    if source.moment_is_constant:
        # a constant moment: the keyframes load as a plain scene dipole with a path
        table = source.scene_field()
        lines = ["# magnet keyframes of the plan; paste into a scene (magsoro run)", "[[fields]]",
                 'type = "dipole"', f"moment = {table['moment']}", f"position = {table['position']}",
                 f"path = {{ times = {table['path']['times']}, positions = {table['path']['positions']} }}", ""]
        (out / "epm_field.toml").write_text("\n".join(lines))
        files.append("epm_field.toml")
    write_shapes(out / "prb_shapes.csv", plan)
    plot_plan(out / "plan.png", plan, config.name or "magnet-path plan")
    if replay:
        if rc is None:
            from magsoro.actuation.config import ActuationInputError

            raise ActuationInputError("the plan has no [replay] table (needs at least replay.dx)")
        result = run_replay(plan, strip, rc.dx, step_duration, move_fraction, rc.damping_ratio, dim=rc.dim,
                            floor=rc.floor)
        with (out / "replay.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            z = ["tip_mpm_z"] if result.dim == 3 else []
            w.writerow(["t", "tip_mpm_x", "tip_mpm_y"] + z + ["tip_prb_x", "tip_prb_y", "error"])
            for t, a, b, e in zip(result.times, result.tip_mpm, result.tip_prb, result.path_errors):
                w.writerow([f"{t:.9g}"] + [f"{v:.9e}" for v in a] + [f"{b[0]:.9e}", f"{b[1]:.9e}", f"{e:.9e}"])
        plot_replay(out / "replay.png", result, (config.name or "plan") + ": MPM replay")
        errs = result.step_end_errors
        summary["replay"] = {
            "dx_m": rc.dx,
            "step_duration_s": result.step_duration,
            "dt_s": result.dt,
            "mpm_steps": result.steps,
            "particles": result.particles,
            "wall_time_s": result.wall_time,
            "step_end_tip_errors_m": [float(e) for e in errs],
            "max_step_end_tip_error_m": float(errs.max()),
            "max_step_end_tip_error_over_length": float(errs.max() / (robot.n_links * robot.link_length)),
            "max_path_tip_error_m": float(result.path_errors.max()),
            "dim": result.dim,
        }
        if result.dim == 3:
            inplane = result.step_end_in_plane_errors
            summary["replay"].update({
                "floor": rc.floor,
                "step_end_in_plane_tip_errors_m": [float(e) for e in inplane],
                "max_step_end_in_plane_tip_error_m": float(inplane.max()),
                "step_end_tip_z_m": [float(v) for v in result.step_end_mpm[:, 2] - result.plane_z],
                "max_abs_tip_z_m": float(np.abs(result.out_of_plane).max()),
            })
        files += ["replay.csv", "replay.png"]
    summary["files"] = files
    (out / "plan.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary
