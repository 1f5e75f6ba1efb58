"""Seed 002's triangle under the paper's actuator moving at hand speeds, by the implicit integrator: warping (the
magnet rising under the top vertex, Fig. 7c) and locomotion (Fig. 4c: the magnet passing along -y under the robot,
or a stroke: rising under the top vertex, moving level to under the opposite side's middle and going down).

    python benchmarks/seed002_slow.py [--motion warp|pass|stroke|both] [--speeds 5,10,20] [--step-mm 0.5]
                                      [--preview] [--dx DX] [--approach-mm 60]

Each run is magsoro.robots._seed002_speeds's rising or passing run of magsoro reproduce triangle, with the implicit
integrator (backward Euler, no mass damping) stepping ``--step-mm`` of magnet travel per step (dt = step / speed;
halved where Newton needs it). In a pass the magnet starts ``--approach-mm`` beyond the explicit runs' start and
comes in at the same speed (at the usual start its rim is 17 mm from the robot and the field would come on at
once); the displacement is read over the usual pass. ``--speeds`` in mm/s; ``--preview``: the robot's preview grid (dx 2 mm: one cell
through the plate, where the total-Lagrangian form the integrator uses bends far softer than at the full grid; a
check that the script runs, not a result); ``--dx``: another grid spacing (m). Records per run: the top vertex's largest rise rate (once the magnet has moved 5 mm) and its rise over the run
(warping),
the centroid's displacement along the pass and its mean speed (locomotion; a stroke: along the stroke while the
magnet moves level and over the whole stroke, the speed in the level move and the centroid's largest lift), the integrator's steps, rejected steps
and Newton iterations, and the wall time. A pass the engine stops keeps its series up to there with ``failed``
(the engine's message) and no displacement. Writes
benchmarks/results/<date>-cpu-<commit>-seed002-slow-<motion>[-preview]-<speeds>mms.json with the machine and the commit.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]
#: the pass's domain (m): reproduce's (magsoro.robots.triangle.LOCO_DOMAIN) with room along +y up to the magnet's
#: start, since a slow magnet draws the robot towards it before it passes (the implicit integrator models only the
#: walls a body starts at)
PASS_DOMAIN = ((-0.036, -0.170, -0.004), (0.036, 0.110, 0.040))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--motion", choices=["warp", "pass", "stroke", "both"], default="both",
                    help="both: warp and pass")
    ap.add_argument("--speeds", default="5,10,20", help="magnet speeds, mm/s")
    ap.add_argument("--step-mm", type=float, default=0.5, help="magnet travel per implicit step, mm")
    ap.add_argument("--max-step-mm", type=float, default=None,
                    help="steps grow after easy ones up to this magnet travel, mm (samples that far apart; "
                         "default --step-mm)")
    ap.add_argument("--pictures", type=int, default=3,
                    help="stroke: side views of the robot at this many times per leg, to a PNG beside the result")
    ap.add_argument("--preview", action="store_true", help="the robot's preview grid")
    ap.add_argument("--dx", type=float, default=None, help="grid spacing, m (default the scene's)")
    ap.add_argument("--approach-mm", type=float, default=60.0,
                    help="pass: the magnet starts this much beyond its usual start and comes in at the same speed, mm")
    args = ap.parse_args(argv)
    from magsoro.robots import _seed002_speeds as sp
    from magsoro.robots import triangle
    from magsoro.robots.base import Context, scene_data

    data = scene_data(triangle.NAME)
    if args.dx is not None:
        data["simulation"]["dx"] = float(args.dx)
    ctx = Context(out=ROOT / "benchmarks" / "results", preview=args.preview, device="cpu",
                  log=lambda msg: print(msg, flush=True))
    corners = triangle.outer_vertices(data)
    i_top = int(np.argmax(corners[:, 1]))
    top = corners[i_top]

    def vertices(X0):
        return {"top": np.linalg.norm(X0[:, :2] - top, axis=1) < 0.002}

    speeds = [float(v) * 1e-3 for v in args.speeds.split(",")]
    step = args.step_mm * 1e-3
    max_step = None if args.max_step_mm is None else args.max_step_mm * 1e-3
    runs, pictures = [], []
    for v in speeds:
        if args.motion in ("warp", "both"):
            r = sp.rising_run(triangle.NAME, data, top, v, +1.0, vertices, ctx, "warping", implicit_step=step)
            i0 = int(np.searchsorted(r["t"], sp.SETTLE))
            rate = sp.moving_rate(r["t"], r["top"], v)
            runs.append({"motion": "warp", "magnet_speed_mm_s": v * 1e3, "vertex_rise_rate_mm_s": 1e3 * rate,
                         "vertex_rise_mm": 1e3 * float(r["top"][-1] - r["top"][i0]), "wall_s": round(r["wall_s"], 1),
                         "dx_m": r["dx"], "particles": r["particles"], "dt_s": r["sample_s"], "integrator": r["integrator"],
                         "t_s": r["t"].tolist(), "vertex_z_m": r["top"].tolist()})
        if args.motion in ("pass", "both"):
            r = sp.passing_run(triangle.NAME, data, v, +1.0, PASS_DOMAIN, ctx, "locomotion", implicit_step=step,
                               approach=args.approach_mm * 1e-3, keep_failed=True, implicit_max_step=max_step)
            runs.append({"motion": "pass", "magnet_speed_mm_s": v * 1e3, "approach_mm": args.approach_mm,
                         "failed": r.get("failed"),
                         "centroid_along_magnet_mm": -1e3 * r["dy"],
                         "centroid_speed_along_magnet_mm_s": -1e3 * r["mean_speed"], "wall_s": round(r["wall_s"], 1),
                         "dx_m": r["dx"], "particles": r["particles"], "dt_s": r["sample_s"], "integrator": r["integrator"],
                         "t_s": r["t"].tolist(), "magnet_y_m": r["magnet_y"].tolist(), "centroid_x_m": r["cx"].tolist(),
                         "centroid_y_m": r["cy"].tolist(), "centroid_z_m": r["cz"].tolist()})
        if args.motion == "stroke":
            side = 0.5 * (corners[(i_top + 1) % 3] + corners[(i_top + 2) % 3])
            r = sp.stroke_run(triangle.NAME, data, top, side, v, +1.0, PASS_DOMAIN, ctx, "stroke", implicit_step=step,
                              keep_failed=True, implicit_max_step=max_step, markers=vertices,
                              snapshots=args.pictures)
            pictures.append((v, r["frames"], r))
            i0 = int(np.searchsorted(r["t"], sp.SETTLE))
            i1 = int(np.searchsorted(r["t"], r["t_up"]))
            rise_rate = sp.moving_rate(r["t"][: i1 + 1], r["top"][: i1 + 1], v)
            runs.append({"motion": "stroke", "magnet_speed_mm_s": v * 1e3, "failed": r["failed"],
                         "from_mm": (1e3 * top).tolist(), "to_mm": (1e3 * side).tolist(),
                         "centroid_along_stroke_in_level_move_mm": 1e3 * r["along"],
                         "centroid_along_stroke_mm": 1e3 * r["along_stroke"],
                         "centroid_speed_in_level_move_mm_s": 1e3 * r["move_speed"], "centroid_lift_mm": 1e3 * r["lift"],
                         "vertex_rise_rate_in_rise_mm_s": 1e3 * rise_rate,
                         "vertex_rise_in_rise_mm": 1e3 * float(r["top"][i1] - r["top"][i0]),
                         "vertex_z_m": r["top"].tolist(),
                         "t_up_s": r["t_up"], "t_moved_s": r["t_moved"], "t_down_s": r["t_down"],
                         "wall_s": round(r["wall_s"], 1), "dx_m": r["dx"], "particles": r["particles"],
                         "dt_s": r["sample_s"], "integrator": r["integrator"], "t_s": r["t"].tolist(),
                         "magnet_m": np.stack([r["mx"], r["my"], r["mz"]], 1).tolist(),
                         "centroid_m": np.stack([r["cx"], r["cy"], r["cz"]], 1).tolist()})
        print({k: val for k, val in runs[-1].items() if not isinstance(val, (list, dict))}, flush=True)
    result = {"benchmark": "seed002_slow", **provenance(), "robot": triangle.NAME, "preview": args.preview,
              "step_mm": args.step_mm, "max_step_mm": args.max_step_mm, "integrator": "implicit, backward Euler, no mass damping", "runs": runs}
    tag = "-preview" if args.preview else ""
    out = ROOT / "benchmarks" / "results" / (f"{result['date'][:10]}-cpu-{result['commit']}-seed002-slow-{args.motion}{tag}"
                                              f"-{args.speeds.replace(',', '_')}mms.json")
    out.write_text(json.dumps(result, indent=1))
    print(out)
    for v, frames, r in pictures:
        if frames:
            print(sp.stroke_side_views(out.with_name(f"{out.stem}-{v * 1e3:g}mms.png"), frames, r,
                                       f"triangle stroke at {v * 1e3:g} mm/s"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
