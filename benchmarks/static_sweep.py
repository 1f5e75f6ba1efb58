"""The static solver against dynamic relaxation, timed in one run on the same machine.

    python benchmarks/static_sweep.py [--levels 8] [--rounds 2]

1. A field sweep of the validation beam (magsoro.validation.beam: Zhao's beam, 2D plane strain, t/dx = 4, float64,
   perpendicular field, bn from 0.004 / levels to 0.004): ``Simulation.solve_static`` over all levels in one
   solve, against one ``settle_beam(method="relax")`` (the ``--equilibrium`` path: dynamic relaxation with kinetic
   damping) per level; the solver's wall time and the tips of both against the Kirchhoff rod.
2. Whole processes: ``magsoro run scenes/cantilever_2d.toml --static`` against ``--equilibrium``, alternating, each
   ``--rounds`` times (medians).

Writes benchmarks/results/<date>-cpu-<commit>-static.json with the machine and the commit.
"""

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import _commit  # the checkout's commit (MAGSORO_COMMIT without git history)

ROOT = Path(__file__).resolve().parents[1]


def sweep(n_levels: int) -> dict:
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation
    from magsoro.validation.beam import BeamSetup, beam_scene, rod_reference, settle_beam, sweep_schedule

    setup = BeamSetup(floor=False)
    bns = [0.004 * (k + 1) / n_levels for k in range(n_levels)]
    L, tip_s = setup.length, setup.length - 0.25 * setup.dx
    t0 = time.perf_counter()
    sim = Simulation(parse_scene(beam_scene(setup, sweep_schedule(setup, [bns[-1]], 90.0))))
    build_s = time.perf_counter() - t0
    tips = []
    res = sim.solve_static(levels=[b / bns[-1] for b in bns], on_level=lambda s, r: tips.append(s.probe_values()))
    static_dy = [v["tip_y"] / L for v in tips]
    static_dx = [(v["tip_x"] - tip_s) / L for v in tips]
    relax_s, relax_dy, relax_dx = [], [], []
    for bn in bns:
        t = time.perf_counter()
        r = settle_beam(setup, bn, 90.0, method="relax")
        relax_s.append(time.perf_counter() - t)
        relax_dy.append(r.tip_dy)
        relax_dx.append(r.tip_dx)
    ref_dx, ref_dy = rod_reference(setup, bns, 90.0, tip_s, L)
    mape = lambda dy: float(np.mean(np.abs(np.asarray(dy) - ref_dy) / np.abs(ref_dy)))  # noqa: E731
    return {
        "bn": bns,
        "static_converged": res.converged,
        "static_solver_s": res.wall_time,
        "static_build_s": build_s,
        "static_residual_evaluations": res.residual_evaluations,
        "relax_s_per_level": relax_s,
        "relax_total_s": float(sum(relax_s)),
        "speedup_solver": float(sum(relax_s)) / res.wall_time,
        "static_tip_dy_over_L": static_dy,
        "static_tip_dx_over_L": static_dx,
        "relax_tip_dy_over_L": relax_dy,
        "relax_tip_dx_over_L": relax_dx,
        "rod_tip_dy_over_L": ref_dy.tolist(),
        "static_mape_vs_rod": mape(static_dy),
        "relax_mape_vs_rod": mape(relax_dy),
    }


def processes(rounds: int) -> dict:
    scene = ROOT / "scenes" / "cantilever_2d.toml"
    times = {"static": [], "equilibrium": []}
    tips = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for mode in ("static", "equilibrium"):
                out = Path(tmp) / f"{mode}{r}"
                t = time.perf_counter()
                subprocess.run([sys.executable, "-m", "magsoro", "run", str(scene), f"--{mode}", "--out", str(out), "--quiet"],
                               check=True, capture_output=True)
                times[mode].append(time.perf_counter() - t)
                lines = (out / "metrics.csv").read_text().splitlines()
                head, last = lines[0], lines[-1]
                row = dict(zip(head.split(","), (float(v) for v in last.split(","))))
                tips[mode] = [row["tip_x"], row["tip_y"]]
    med = {k: float(np.median(v)) for k, v in times.items()}
    free_length = 0.0178  # from the clamp's face (x = 2.2 mm) to the beam's end
    gap = float(np.hypot(*np.subtract(tips["static"], tips["equilibrium"]))) / free_length
    return {"scene": "scenes/cantilever_2d.toml", "rounds_s": times, "median_s": med,
            "speedup_process": med["equilibrium"] / med["static"], "tips_m": tips, "tip_gap_over_free_length": gap}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    result = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": _commit(),
        "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(), "cpu_count": os.cpu_count()},
        "sweep": sweep(args.levels),
        "processes": processes(args.rounds),
    }
    out = ROOT / "benchmarks" / "results" / f"{datetime.date.today().isoformat()}-cpu-{result['commit']}-static.json"
    out.write_text(json.dumps(result, indent=1))
    s, p = result["sweep"], result["processes"]
    print(f"sweep of {args.levels} levels: static solver {s['static_solver_s']:.2f} s against {s['relax_total_s']:.1f} s of "
          f"relaxation ({s['speedup_solver']:.1f}x); MAPE vs rod static {100 * s['static_mape_vs_rod']:.2f} %, relaxation "
          f"{100 * s['relax_mape_vs_rod']:.2f} %")
    print(f"cantilever_2d as processes: --static {p['median_s']['static']:.2f} s, --equilibrium {p['median_s']['equilibrium']:.2f} s "
          f"({p['speedup_process']:.1f}x); tips {p['tips_m']['static']} and {p['tips_m']['equilibrium']} m, "
          f"{100 * p['tip_gap_over_free_length']:.3f} % of the free length apart")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
