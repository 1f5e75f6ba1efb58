"""The triangle robot's field sweep (seed 002 Figs. 6 and 9) by the static solver along the magnet's path, against
the same sweep by the dynamics, timed in one run.

    python benchmarks/triangle_sweep.py [--preview] [--static-only] [--between 1,2,3,4]

The static sweep is the full reproduction's (`magsoro reproduce triangle`: magsoro.robots.triangle.static_sweep):
the magnet's positions for the levels (B_z at the robot's centre 0 to 45 mT) become a path in pseudo-time, and
the static solver (float64) settles the robot under gravity at level 0 (the magnet 1 m away), then moves along the
path level by level (Simulation.solve_static(times=...): the field moves with the load increments, each level
from the last equilibrium, the plate's friction anchors carried along). ``--between`` adds levels (mT) that the
static sweep passes through but the curve does not read (the reproduction's are 1, 2, 3 and 4: the robot lifts
off the plate there, and the load increments along the magnet's path are in its position, not its field). The
dynamic sweep is the scene file's (its stepped path, holds and damping; the preview reproduction's, without the
animation). Records per level W_t, the centroid height, Newton iterations and wall time, and both wall times.
Writes benchmarks/results/<date>-cpu-<commit>-triangle-sweep[-preview][-between][-static].json with the machine
and the commit.
"""

import argparse
import datetime
import json
import sys
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance  # date, commit (MAGSORO_COMMIT without git history), machine

ROOT = Path(__file__).resolve().parents[1]


def static_sweep(levels, preview: bool, between=()) -> dict:
    """The reproduction's static sweep through ``levels`` (read) and ``between`` (mT, solved on the way)."""
    import tempfile

    from magsoro.robots import triangle as T
    from magsoro.robots.base import Context, RobotError

    with tempfile.TemporaryDirectory() as tmp:
        ctx = Context(out=Path(tmp), preview=preview, device="cpu", log=lambda msg: print(msg, flush=True))
        try:
            sim, _, _, _, rest, read, sweep, _ = T.static_sweep(ctx, levels, between)
        except RobotError as exc:
            return {"converged": False, "message": str(exc)}
    measured = dict(read)
    rows = []
    for lv, res in zip(sorted(set(levels) | set(between)), sweep.levels):
        row = {"B_mT": lv, "read": lv in measured, "converged": res.converged, "iterations": res.iterations,
               "load_increments": res.increments, "wall_s": round(res.wall_time, 1), "message": res.message}
        if lv in measured:
            m = measured[lv]
            row.update({"Wt_mm": 1e3 * float(np.mean(m["vertex"]) - np.mean(rest["vertex"])),
                        "centroid_height_mm": 1e3 * float(m["centroid"])})
        rows.append(row)
    return {"converged": True, "wall_s": round(sweep.wall_s, 1), "particles": int(sim.model.n_particles), "levels": rows}


def dynamic_sweep(levels, preview: bool) -> dict:
    """The sweep by the dynamics (magsoro.robots.triangle.dynamic_sweep: the scene file's stepped magnet path)."""
    import tempfile

    from magsoro.robots import triangle as T
    from magsoro.robots.base import Context

    with tempfile.TemporaryDirectory() as tmp:
        ctx = Context(out=Path(tmp), preview=preview, device="cpu", log=lambda msg: print(msg, flush=True))
        sim, _, _, _, rest, read, wall, _ = T.dynamic_sweep(ctx, levels)
    rows = [{"B_mT": lv, "Wt_mm": 1e3 * float(np.mean(m["vertex"]) - np.mean(rest["vertex"])),
             "centroid_height_mm": 1e3 * float(m["centroid"])} for lv, m in read]
    return {"wall_s": round(wall, 1), "particles": int(sim.model.n_particles), "levels": rows}


def main(argv=None) -> int:
    from magsoro.robots import triangle as T

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preview", action="store_true", help="the preview grid and levels")
    ap.add_argument("--static-only", action="store_true", help="skip the dynamic sweep")
    ap.add_argument("--between", default="", help="comma-separated levels (mT) the static sweep passes through unread")
    args = ap.parse_args(argv)
    levels = T.PREVIEW_LEVELS_MT if args.preview else T.LEVELS_MT
    between = [float(v) for v in args.between.split(",") if v.strip()]
    out = {
        "benchmark": "triangle_sweep",
        "preview": args.preview,
        "levels_mT": levels,
        **provenance(),
        "between_mT": between,
        "static": static_sweep(levels, args.preview, between),
    }
    if not args.static_only and out["static"]["converged"]:
        out["dynamic"] = dynamic_sweep(levels, args.preview)
        out["dynamic_over_static_wall"] = round(out["dynamic"]["wall_s"] / out["static"]["wall_s"], 3)
        read = [s for s in out["static"]["levels"] if s["read"]]
        pairs = [(s, d) for s, d in zip(read, out["dynamic"]["levels"]) if s["converged"]]
        out["Wt_static_minus_dynamic_mm"] = [round(s["Wt_mm"] - d["Wt_mm"], 4) for s, d in pairs]
    stamp = datetime.date.today().isoformat()
    name = (f"{stamp}-cpu-{out['commit']}-triangle-sweep{'-preview' if args.preview else ''}"
            f"{'-between' if between else ''}{'-static' if args.static_only else ''}.json")
    path = ROOT / "benchmarks" / "results" / name
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"static {out['static'].get('wall_s', 'failed')} s" + (f", dynamic {out['dynamic']['wall_s']} s" if "dynamic" in out else "")
          + f"; {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
