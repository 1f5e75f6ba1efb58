"""The grid block's refit when it is oversized (``Solver._oversized``, ``GRID_SHRINK``), on the pentagram's crawl:

    python benchmarks/grid_shrink.py [--until 0.6]

Runs scenes/pentagram.toml's crawl at its preview resolution from t = 0 to ``--until`` s twice in one process,
with the refit (GRID_SHRINK = 2, as shipped) and with the block kept while the particles stay inside it
(GRID_SHRINK = inf, the behaviour before), and reports wall time, steps and the block's nodes at the end. Writes
benchmarks/results/<date>-cpu-<commit>-grid-shrink.json with the machine and the commit.
"""

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

from magsoro.bench.runner import _commit  # the checkout's commit (MAGSORO_COMMIT without git history)

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--until", type=float, default=0.6, help="simulated time of each run (s)")
    args = ap.parse_args()
    import magsoro.mpm.solver as solver_module
    from magsoro.robots.base import scene_data, simulation
    from magsoro.robots.pentagram import _with_dx

    runs = {}
    for label, shrink in (("refit", 2.0), ("kept", float("inf"))):
        solver_module.GRID_SHRINK = shrink
        sim = simulation("pentagram", _with_dx(scene_data("pentagram")), preview=False, device="cpu")
        t0 = time.perf_counter()
        sim.advance_to(args.until)
        runs[label] = {"wall_s": time.perf_counter() - t0, "steps": sim.steps, "grid": sim.solver.grid_info()}
    result = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"), "commit": _commit(),
        "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(), "cpu_count": os.cpu_count()},
        "scene": "scenes/pentagram.toml crawl at its preview dx and particles per cell", "until_s": args.until,
        "runs": runs, "speedup": runs["kept"]["wall_s"] / runs["refit"]["wall_s"],
    }
    out = ROOT / "benchmarks" / "results" / f"{datetime.date.today().isoformat()}-cpu-{result['commit']}-grid-shrink.json"
    out.write_text(json.dumps(result, indent=1))
    for label, r in runs.items():
        print(f"{label}: {r['wall_s']:.1f} s, {r['steps']} steps, block at the end {r['grid']['nodes']} nodes")
    print(f"speed-up {result['speedup']:.2f}x; wrote {out}")


if __name__ == "__main__":
    main()
