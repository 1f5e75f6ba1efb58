"""The triangle robot's field sweep (seed 002 Figs. 6 and 9) by the static solver along the magnet's path, against
the reproduction's dynamic sweep, timed in one run.

    python benchmarks/triangle_sweep.py [--preview] [--static-only] [--between 1,2,3,4]

`magsoro reproduce triangle` raises the N35 magnet under the plate level by level (B_z at the robot's centre 0 to
45 mT) and reads the vertex warp height W_t and the centroid height at the end of each hold, by the dynamics.
Here the same levels are solved as equilibria: the magnet's positions become a path in (pseudo-)time, the static
solver (float64) settles the robot under gravity with the magnet far, then moves along the path level by level
(:meth:`magsoro.mpm.static.StaticSolver.move_to`: the field moves with the load increments, each level from the
last equilibrium, the plate's friction anchors carried along). ``--between`` adds levels (mT) that the static
sweep passes through but the curve does not read (the robot lifts off the plate between about 3 and 6 mT, and
the load increments along the magnet's path are in its position, not its field). The dynamic sweep is the reproduction's (its
stepped path, holds and damping; without the animation). Records per level W_t, the centroid height, Newton
iterations and wall time, and both wall times. Writes
benchmarks/results/<date>-cpu-<commit>-triangle-sweep[-preview].json with the machine and the commit.
"""

import argparse
import copy
import datetime
import json
import sys
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance  # date, commit (MAGSORO_COMMIT without git history), machine

ROOT = Path(__file__).resolve().parents[1]


def _robot(data: dict, preview: bool):
    """The triangle's Simulation from scene ``data`` and its reference for T.measure: (sim, X0, mass, corners,
    the measure at rest)."""
    from magsoro.robots import triangle as T
    from magsoro.robots.base import simulation

    sim = simulation("triangle", data, preview=preview, device="cpu")
    X0 = sim.model.host["positions"].astype(np.float64)
    mass = sim.model.host["mass"].astype(np.float64)
    corners = T._corners(data)
    return sim, X0, mass, corners, T.measure(sim, X0, mass, corners)


def static_sweep(levels, preview: bool, between=()) -> dict:
    from magsoro.mpm.static import StaticSolver
    from magsoro.robots import triangle as T
    from magsoro.robots.base import scene_data

    d = copy.deepcopy(scene_data("triangle"))
    magnet = next(f for f in d["fields"] if f.get("name") == "magnet")
    read = set(levels)
    levels = sorted(set(levels) | set(between))
    offsets = T.magnet_offsets(magnet, levels)
    far = [0.0, 0.0, float(offsets[0][2]) - 10 * abs(float(offsets[0][2]))]  # where the robot settles first
    times = [float(k) for k in range(len(offsets) + 1)]
    magnet["path"] = {"times": times, "positions": [far] + [list(map(float, o)) for o in offsets]}
    d["simulation"]["precision"] = "float64"
    d["simulation"]["duration"] = times[-1]
    d.setdefault("output", {})["particles"] = False
    sim, X0, mass, corners, rest = _robot(d, preview)
    t0 = time.perf_counter()
    sc = sim.scene.static
    solver = StaticSolver(sim, 0.0, tolerance=sc.tolerance, max_iterations=sc.max_iterations)
    first = [solver.solve_level(0.0), solver.solve_level(1.0)]  # gravity, then the far magnet's field
    rows = []
    for k, lv in enumerate(levels):
        tk = time.perf_counter()
        solver.move_to(float(k + 1))
        res = solver.solve_level(1.0)
        solver.write_state()
        m = T.measure(sim, X0, mass, corners)
        rows.append({"B_mT": lv, "read": lv in read, "converged": res.converged, "Wt_mm": 1e3 * float(np.mean(m["vertex"]) - np.mean(rest["vertex"])),
                     "centroid_height_mm": 1e3 * float(m["centroid"]), "iterations": res.iterations,
                     "load_increments": res.increments, "wall_s": round(time.perf_counter() - tk, 1),
                     "message": res.message})
        print(f"static {lv:g} mT: W_t {rows[-1]['Wt_mm']:.3f} mm, centroid {rows[-1]['centroid_height_mm']:.3f} mm, "
              f"{res.iterations} iterations, {rows[-1]['wall_s']} s", flush=True)
        if not res.converged:
            break
    return {"wall_s": round(time.perf_counter() - t0, 1), "particles": int(sim.model.n_particles),
            "settle_iterations": [r.iterations for r in first], "levels": rows}


def dynamic_sweep(levels, preview: bool) -> dict:
    from magsoro.robots import triangle as T
    from magsoro.robots.base import scene_data

    data = scene_data("triangle")
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    offsets = T.magnet_offsets(magnet, levels)
    times, positions, reads = T.stepped_path(offsets, T.SETTLE, T.HOLD, T.MOVE)
    magnet["path"] = {"times": times, "positions": positions}
    data.setdefault("output", {})["particles"] = False
    sim, X0, mass, corners, rest = _robot(data, preview)
    t0 = time.perf_counter()
    rows = []
    for lv, t_read in zip(levels, reads):
        T.advance(sim, t_read, None, T.FRAME_EVERY)
        m = T.measure(sim, X0, mass, corners)
        rows.append({"B_mT": lv, "Wt_mm": 1e3 * float(np.mean(m["vertex"]) - np.mean(rest["vertex"])),
                     "centroid_height_mm": 1e3 * float(m["centroid"])})
        print(f"dynamic {lv:g} mT: W_t {rows[-1]['Wt_mm']:.3f} mm, centroid {rows[-1]['centroid_height_mm']:.3f} mm",
              flush=True)
    return {"wall_s": round(time.perf_counter() - t0, 1), "particles": int(sim.model.n_particles), "levels": rows}


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
    if not args.static_only:
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
    print(f"static {out['static']['wall_s']} s" + (f", dynamic {out['dynamic']['wall_s']} s" if "dynamic" in out else "")
          + f"; {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
