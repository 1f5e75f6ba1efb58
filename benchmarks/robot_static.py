"""A robot reproduction by the static solver against the same reproduction by the dynamics, timed in one run.

    python benchmarks/robot_static.py [--full] [--robot strip_magnet]

`magsoro reproduce strip_magnet` solves one equilibrium per magnet gap with the static solver and falls back to
the dynamic sweep (the magnet rising gap by gap, each hold settled) where the static solver refuses the scene.
This script runs both paths of the same reproduction back to back in one process (the dynamic one by making the
static solver refuse), at the preview grid or with ``--full`` at the full one, and records their wall times, the
ratio, and how far the two curves are apart.

Writes benchmarks/results/<date>-cpu-<commit>-robot-static.json with the machine and the commit.
"""

import argparse
import datetime
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import _commit  # the checkout's commit (MAGSORO_COMMIT without git history)

ROOT = Path(__file__).resolve().parents[1]
CURVES = {"strip_magnet": ("gap_mm", "strain_percent")}


def run(robot: str, preview: bool, dynamic: bool) -> dict:
    """One reproduction; ``dynamic`` makes the static solver refuse the scene, so the reproduction takes its
    dynamic path. Returns its wall time, solver, curve and check results."""
    import magsoro.mpm.newton.static as static
    from magsoro.errors import SimulationError
    from magsoro.robots import reproduce
    from magsoro.robots.base import read_csv

    original = static.check_supported

    def refuse(sim):
        raise SimulationError("refused by benchmarks/robot_static.py to time the dynamic path")

    if dynamic:
        static.check_supported = refuse
    try:
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            res = reproduce(robot, out=Path(out), preview=preview)
            wall = time.perf_counter() - t0
            csv = read_csv(res.csv)
    finally:
        static.check_supported = original
    x, y = CURVES[robot]
    return {"wall_s": round(wall, 2), "solver": res.info.get("solver"), x: [float(v) for v in csv[x]],
            y: [float(v) for v in csv[y]], "checks_passed": int(sum(r.passed for r in res.rows)),
            "checks": len(res.rows)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="strip_magnet", choices=sorted(CURVES))
    ap.add_argument("--full", action="store_true", help="the full grid (default: the preview)")
    args = ap.parse_args(argv)
    preview = not args.full
    static_run = run(args.robot, preview, dynamic=False)
    dynamic_run = run(args.robot, preview, dynamic=True)
    _, y = CURVES[args.robot]
    a, b = np.array(static_run[y]), np.array(dynamic_run[y])
    out = {
        "benchmark": "robot_static",
        "robot": args.robot,
        "resolution": "preview" if preview else "full",
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "commit": _commit(),
        "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(), "cpu_count": os.cpu_count()},
        "static": static_run,
        "dynamic": dynamic_run,
        "dynamic_over_static_wall": round(dynamic_run["wall_s"] / static_run["wall_s"], 2),
        "curve_difference_relative": [round(float(v), 5) for v in (a / b - 1.0)],
    }
    stamp = datetime.date.today().isoformat()
    path = ROOT / "benchmarks" / "results" / f"{stamp}-cpu-{out['commit']}-robot-static.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"{args.robot} ({out['resolution']}): static {static_run['wall_s']:.1f} s, dynamic {dynamic_run['wall_s']:.1f} s "
          f"({out['dynamic_over_static_wall']:.2f}x); {y} static / dynamic - 1: "
          f"{', '.join(f'{v:+.2%}' for v in out['curve_difference_relative'])}; {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
