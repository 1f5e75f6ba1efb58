"""The magnetic-tip retroflexion plan replayed by the MPM engine in 2D and in 3D, against the PRB.

    python benchmarks/replay_3d.py [--dx 0.0015] [--variants 2d,3d-floor,3d-free,3d-planar-field]

Seed 004 steers its magnetic growing robot with an external magnet; `magsoro plan` plans the magnet's poses on a
planar pseudo-rigid-body (PRB) model and replays them in MPM (docs/actuation.md, "MPM replay"). The plan,
examples/actuation/plan_retroflexion_tip.toml (a 60 x 6 x 6 mm strip, the distal link magnetised, grown straight
4 -> 7 -> 10 links and then curled to 60, 120 and 180 degrees), is replayed here

- ``2d``: plane strain in the plan's plane (the field's in-plane part), against the plan;
- ``3d-floor``: the strip as a 3D beam in the magnet's whole field, on a frictionless floor with gravity;
- ``3d-free``: the same beam free in space, no gravity;
- ``3d-planar-field``: the free beam in the field the planar PRB sees (the magnet and its mirror image in the
  plane, half the moment each: the magnet's in-plane field on the plane, no B_z), so the out-of-plane field's
  share of the difference to the PRB is separated from the 3D body's own.

The 3D beams are compared with the plan and with the PRB of the same links carrying Young's modulus
(:func:`magsoro.actuation.replay.beam_robot`; the plan's strip carries the plane-strain modulus, 1 / (1 - nu^2) =
1.14 times stiffer), quasi-static under the same keyframed magnet. Records the tips at the end of each plan step
(the settled states), the tip's height out of the plane, wall times, particles and MPM steps. Writes
benchmarks/results/<date>-cpu-<commit>-replay-3d.json with the machine and the commit.
"""

import argparse
import datetime
import json
import sys
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance  # date, commit (MAGSORO_COMMIT without git history), machine

ROOT = Path(__file__).resolve().parents[1]
PLAN = ROOT / "examples" / "actuation" / "plan_retroflexion_tip.toml"
VARIANTS = {"2d": (2, False, False), "3d-floor": (3, True, False), "3d-free": (3, False, False),
            "3d-planar-field": (3, False, True)}


def mm(a) -> list:
    return np.round(1e3 * np.asarray(a, dtype=float), 3).tolist()


def main(argv=None) -> int:
    from magsoro.actuation.config import PlanConfig, load
    from magsoro.actuation.replay import beam_robot, prb_path, replay

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx", type=float, default=0.0015, help="grid spacing, m (default 1.5 mm: 4 cells across)")
    ap.add_argument("--variants", default=",".join(VARIANTS), help="comma-separated: " + ", ".join(VARIANTS))
    args = ap.parse_args(argv)
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        ap.error(f"unknown variant(s) {unknown}; known: {', '.join(VARIANTS)}")

    cfg = load(PlanConfig, PLAN)
    robot, target, planner, strip = cfg.build()
    plan = planner.plan(target)
    T = cfg.replay.step_duration
    beam = beam_robot(robot, strip)
    planned = np.array([robot.tip(s.theta) for s in plan.steps])
    out = {
        "benchmark": "replay_3d",
        "plan": str(PLAN.relative_to(ROOT)),
        "dx_m": args.dx,
        "step_duration_s": T,
        **provenance(),
        "planned_tips_mm": mm(planned),
        "magnet_positions_mm": mm([s.position for s in plan.steps]),
        "variants": {},
    }
    for name in variants:
        dim, floor, planar = VARIANTS[name]
        r = replay(plan, strip, args.dx, T, cfg.replay.move_fraction, cfg.replay.damping_ratio, dim=dim, floor=floor,
                   planar_field=planar)
        entry = {
            "dim": dim, "floor": floor, "planar_field": planar, "particles": r.particles, "mpm_steps": r.steps, "wall_s": round(r.wall_time, 1),
            "step_end_tips_mm": mm(r.step_end_mpm),
            "step_end_error_to_plan_mm": mm(r.step_end_errors),
        }
        if dim == 3:
            entry["step_end_in_plane_error_to_plan_mm"] = mm(r.step_end_in_plane_errors)
            entry["step_end_tip_height_mm"] = mm(r.step_end_mpm[:, 2] - r.plane_z)
            entry["max_abs_tip_height_mm"] = round(1e3 * float(np.abs(r.out_of_plane).max()), 3)
        out["variants"][name] = entry
        print(f"{name}: step-end tips {entry['step_end_tips_mm']} mm, {entry['wall_s']} s", flush=True)
    # the beam PRB's quasi-static step ends under the same keyframes (PRB only: no MPM)
    _, _, thetas = prb_path(plan, beam, T, cfg.replay.move_fraction)
    ends = np.array([beam.tip(q) for q in thetas])
    out["beam_prb_tips_mm"] = mm(ends)
    for name, entry in out["variants"].items():
        if entry["dim"] == 3:
            tips = np.array(entry["step_end_tips_mm"])[:, :2] / 1e3
            entry["step_end_in_plane_error_to_beam_prb_mm"] = mm(np.linalg.norm(tips - ends, axis=1))
    stamp = datetime.date.today().isoformat()
    path = ROOT / "benchmarks" / "results" / f"{stamp}-cpu-{out['commit']}-replay-3d-dx{1e3 * args.dx:g}mm.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
