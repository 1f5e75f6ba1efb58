"""The first moments of seed 002's triangle pass by the implicit integrator: how hard its Newton steps are.

    python benchmarks/seed002_pass_window.py [--preview] [--duration 0.35] [--speed 20] [--step-mm 0.25]
                                             [--linear-solver auto|direct|iterative]

The triangle rests on its friction plate with the pass's magnet at its usual start (y = 90 mm under the plate,
its field on at t = 0) moving along -y at ``--speed`` mm/s after the settling hold; backward Euler, steps of
``--step-mm`` of magnet travel (halved where Newton needs it), the domain floor lowered as in the implicit passes.
Records per implicit step: time, length, whether it converged, Newton iterations and wall time, and in all: steps,
halved steps, Newton iterations, tangents and wall time. Writes
benchmarks/results/<date>-cpu-<commit>-seed002-pass-window[-preview].json with the machine and the commit.
"""

import argparse
import copy
import json
import sys
import time
from pathlib import Path

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preview", action="store_true", help="the robot's preview grid")
    ap.add_argument("--duration", type=float, default=0.35, help="simulated time, s")
    ap.add_argument("--speed", type=float, default=20.0, help="magnet speed, mm/s")
    ap.add_argument("--step-mm", type=float, default=0.25, help="magnet travel per implicit step, mm")
    ap.add_argument("--linear-solver", choices=["auto", "direct", "iterative"], default="auto")
    args = ap.parse_args(argv)
    from magsoro.mpm.newton import implicit
    from magsoro.robots import _seed002_speeds as sp
    from magsoro.robots import triangle
    from magsoro.robots.base import scene_data, simulation

    speed = args.speed * 1e-3
    data = copy.deepcopy(scene_data(triangle.NAME))
    sp.slow_settings(data, speed, args.step_mm * 1e-3)
    data["implicit"]["linear_solver"] = args.linear_solver
    magnet = sp.actuator(data, 1.0)
    start, end = [0.0, sp.PASS_FROM, sp.Z_TOP], [0.0, sp.PASS_TO, sp.Z_TOP]
    t_pass = sp.SETTLE + (sp.PASS_FROM - sp.PASS_TO) / speed
    magnet["position"] = start
    magnet["path"] = {"times": [0.0, sp.SETTLE, t_pass], "positions": [start, start, end]}
    S = data["simulation"]
    S["duration"] = max(args.duration, 0.05)
    S["domain_lo"], S["domain_hi"] = [-0.036, -0.170, -0.004 - sp.IMPLICIT_ROOM], [0.036, 0.110, 0.040]
    sim = simulation(triangle.NAME, data, preview=args.preview, device="cpu")

    steps = []
    try_step = implicit.ImplicitIntegrator.try_step

    def recorded(integ, dt):
        t0 = time.perf_counter()
        result = try_step(integ, dt)
        steps.append({"t_s": integ.t, "dt_s": dt, "converged": bool(result.converged),
                      "newton_iterations": int(result.iterations), "wall_s": round(time.perf_counter() - t0, 2)})
        print(steps[-1], flush=True)
        return result

    implicit.ImplicitIntegrator.try_step = recorded
    t0 = time.perf_counter()
    try:
        sim.advance_to(args.duration)
    finally:
        implicit.ImplicitIntegrator.try_step = try_step
    integ = sim.implicit
    result = {"benchmark": "seed002_pass_window", **provenance(), "robot": triangle.NAME, "preview": args.preview,
              "particles": int(sim.model.host["positions"].shape[0]), "dx_m": float(sim.model.dx),
              "duration_s": args.duration, "magnet_speed_mm_s": args.speed, "step_mm": args.step_mm,
              "linear_solver": args.linear_solver, "wall_s": round(time.perf_counter() - t0, 1),
              "steps": integ.steps, "halved": integ.rejected, "newton_iterations": integ.newton_iterations,
              "tangents": integ.tangents, "per_step": steps}
    tag = "-preview" if args.preview else ""
    out = ROOT / "benchmarks" / "results" / f"{result['date'][:10]}-cpu-{result['commit']}-seed002-pass-window{tag}-{args.linear_solver}.json"
    out.write_text(json.dumps(result, indent=1))
    print({k: v for k, v in result.items() if k != "per_step"})
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
