"""The static solver's linear solvers against the size of the problem: the direct sparse LU against multigrid-
preconditioned Krylov (magsoro.mpm.newton.linear), on one 3D scene refined step by step, timed in one run.

    python benchmarks/linear_scaling.py [--dx 4.2e-4 3e-4 2.4e-4 2.1e-4 1.8e-4] [--level 0.05]
                                        [--direct-limit 300] [--kinds direct iterative]

The scene is Zhao et al.'s clamped magnetic cantilever in 3D (scenes/cantilever_3d.toml: 17.2 x 5 x 0.84 mm,
Br 0.258 T along it, 5.9 mT across it), float64, at each grid spacing ``--dx`` (particles grow as dx^-3). At each
size and for each linear solver, a fresh StaticSolver solves field level ``--level`` (a small deflection: a few
Newton iterations) from the straight beam, and the run records: Newton iterations, the time spent assembling
tangents and solving the linear systems (setup: factorisations or multigrid hierarchies, and solves), their sum per
Newton iteration ("assembly + solve"), the Krylov iterations, the stability check's time (shift-invert
eigensolver on the LU, or LOBPCG on the hierarchy), the level's wall time, and the largest difference of the two
solvers' displacements over the largest displacement. The direct solver is skipped at the sizes after one where
its level took more than ``--direct-limit`` seconds, and above ``--direct-max-unknowns`` unknowns (its memory: the
file records both). Writes
benchmarks/results/linear_scaling.json with the machine and the commit.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance  # date, commit (MAGSORO_COMMIT without git history), machine

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "cantilever_3d.toml"


def one(dx: float, kind: str, level: float, direct_max_unknowns: int) -> tuple[dict, np.ndarray | None]:
    from magsoro.mpm.newton.static import StaticSolver
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    scene = load_scene(SCENE)
    scene.simulation.precision = "float64"
    scene.simulation.dx = dx
    sim = Simulation(scene, source=str(SCENE))
    st = StaticSolver(sim, scene.simulation.duration, linear_solver=kind)
    unknowns = int(len(st.unknown_nodes) * st.dim)
    if kind == "direct" and unknowns > direct_max_unknowns:
        return {"dx_m": dx, "particles": int(sim.model.n_particles), "unknowns": unknowns, "linear_solver": kind,
                "skipped": f"more than --direct-max-unknowns {direct_max_unknowns} unknowns"}, None
    clocks = {"tangent": 0.0, "linear": 0.0, "stability": 0.0}

    def timed(name, fn):
        def wrapper(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                clocks[name] += time.perf_counter() - t0
        return wrapper

    st.tangent = timed("tangent", st.tangent)
    check = st.lowest_mode

    def lowest_mode(*args, **kwargs):  # the check's own tangent and solves count as the check's, not Newton's
        before = (clocks["tangent"], clocks["linear"])
        t0 = time.perf_counter()
        try:
            return check(*args, **kwargs)
        finally:
            clocks["stability"] += time.perf_counter() - t0
            clocks["tangent"], clocks["linear"] = before

    st.lowest_mode = lowest_mode
    make = st._linear_solver

    def linear_solver(J, *args, **kwargs):
        t0 = time.perf_counter()
        lin = make(J, *args, **kwargs)
        clocks["linear"] += time.perf_counter() - t0
        if not getattr(lin, "_timed", False):
            lin.solve = timed("linear", lin.solve)
            lin._timed = True
        return lin

    st._linear_solver = linear_solver
    t0 = time.perf_counter()
    res = st.solve_level(level)
    wall = time.perf_counter() - t0
    newton = max(res.iterations, 1)
    out = {
        "dx_m": dx, "particles": int(sim.model.n_particles), "unknowns": unknowns,
        "linear_solver": kind, "converged": bool(res.converged), "newton_iterations": int(res.iterations),
        "load_increments": int(res.increments), "linear_iterations": int(res.linear_iterations),
        "linear_iterations_per_newton": round(res.linear_iterations / newton, 1),
        "linear_setups": int(res.linear_setups), "linear_fallbacks": int(res.linear_fallbacks),
        "tangent_s": round(clocks["tangent"], 3), "linear_s": round(clocks["linear"], 3),
        "ms_per_newton_iteration": round(1e3 * (clocks["tangent"] + clocks["linear"]) / newton, 1),
        "linear_ms_per_newton_iteration": round(1e3 * clocks["linear"] / newton, 1),
        "stability_check_s": round(clocks["stability"], 3), "lowest_eigenvalue": res.lowest_eigenvalue,
        "level_wall_s": round(wall, 2),
    }
    return out, st.u_nodes.copy()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx", type=float, nargs="+", default=[4.2e-4, 3.0e-4, 2.4e-4, 2.1e-4, 1.8e-4],
                    help="grid spacings, m (coarse to fine)")
    ap.add_argument("--level", type=float, default=0.05, help="the field level solved from the straight beam")
    ap.add_argument("--kinds", nargs="+", default=["direct", "iterative"], choices=["direct", "iterative"])
    ap.add_argument("--direct-limit", type=float, default=300.0,
                    help="skip the direct solver at the sizes after one where its level took longer (s)")
    ap.add_argument("--direct-max-unknowns", type=int, default=50_000,
                    help="skip the direct solver above this many unknowns: at dx 1.8e-4 (about 70,000 unknowns) "
                         "SuperLU's factorisation was killed for memory on this 23 GB machine (24 GB resident)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "linear_scaling.json")
    args = ap.parse_args(argv)
    rows, skipped = [], []
    direct_ok = True
    for dx in args.dx:
        answers = {}
        for kind in args.kinds:
            if kind == "direct" and not direct_ok:
                skipped.append({"dx_m": dx, "linear_solver": "direct",
                                "why": f"the direct level took more than {args.direct_limit:g} s at a coarser dx"})
                print(f"dx {dx:g}: direct skipped", flush=True)
                continue
            row, u = one(dx, kind, args.level, args.direct_max_unknowns)
            print(json.dumps(row), flush=True)
            if u is None:
                skipped.append({"dx_m": dx, "unknowns": row["unknowns"], "linear_solver": kind, "why": row["skipped"]})
                continue
            answers[kind] = u
            rows.append(row)
            if kind == "direct" and row["level_wall_s"] > args.direct_limit:
                direct_ok = False
        if len(answers) == 2:
            a, b = answers["direct"], answers["iterative"]
            diff = float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-300))
            for row in rows[-2:]:
                row["displacement_difference"] = diff
    out = {"benchmark": "linear_scaling", **provenance(), "scene": "scenes/cantilever_3d.toml (float64, dx varied)",
           "level": args.level, "direct_limit_s": args.direct_limit, "direct_max_unknowns": args.direct_max_unknowns,
           "rows": rows, "skipped": skipped}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
