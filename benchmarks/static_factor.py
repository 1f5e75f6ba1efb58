"""The static solver's factorisation (magsoro.mpm.newton.static.factor: SuperLU in its symmetric mode) against scipy's
default sparse LU, on the triangle robot's tangent, timed in one run.

    python benchmarks/static_factor.py [--preview] [--repeats N]

The tangent is the triangle's (scenes/triangle.toml, float64, full grid unless --preview) at its equilibrium under
gravity on the plate with the magnet at its 15 mT distance (Simulation.solve_static along the reproduction's path
0, 5, 10, 15 mT with 1-4 mT on the way). Each factorisation is made ``--repeats`` times (the fastest is kept);
records the unknowns, the entries, the fill (entries of L and U) and the relative residual |J x - b| / |b| of a
solve of a random right-hand side. Writes benchmarks/results/<date>-cpu-<commit>-static-factor[-preview].json with
the machine and the commit.
"""

import argparse
import datetime
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance  # date, commit (MAGSORO_COMMIT without git history), machine

ROOT = Path(__file__).resolve().parents[1]


def tangent(preview: bool):
    """The triangle's tangent at its 15 mT equilibrium (the reproduction's static sweep up to 15 mT)."""
    from magsoro.mpm.newton.static import StaticSolver
    from magsoro.robots import triangle as T
    from magsoro.robots.base import Context

    with tempfile.TemporaryDirectory() as tmp:
        ctx = Context(out=Path(tmp), preview=preview, device="cpu", log=lambda msg: print(msg, flush=True))
        sim, *_ = T.static_sweep(ctx, [0, 5, 10, 15], T.BETWEEN_MT)
    solver = StaticSolver(sim, sim.time)  # a solver at the state reached (the loads at the last time)
    return solver.tangent(solver.u_nodes, 1.0, 1.0)


def timed(make, J, repeats: int):
    best, lu = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        lu = make(J)
        best = min(best, time.perf_counter() - t0)
    b = np.random.default_rng(1).standard_normal(J.shape[0])
    residual = float(np.linalg.norm(J @ lu.solve(b) - b) / np.linalg.norm(b))
    return {"seconds": round(best, 4), "fill": int(lu.L.nnz + lu.U.nnz), "relative_residual": residual}


def main(argv=None) -> int:
    from scipy.sparse.linalg import splu

    from magsoro.mpm.newton.static import factor

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preview", action="store_true", help="the preview grid")
    ap.add_argument("--repeats", type=int, default=3, help="factorisations of each kind (the fastest is kept)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        raise SystemExit(f"static_factor: --repeats must be >= 1, got {args.repeats}")
    J = tangent(args.preview).tocsc()
    out = {"benchmark": "static_factor", "preview": args.preview, **provenance(), "unknowns": int(J.shape[0]),
           "entries": int(J.nnz), "repeats": args.repeats,
           "symmetric_mode": timed(factor, J, args.repeats), "default": timed(lambda A: splu(A), J, args.repeats)}
    out["default_over_symmetric_mode_seconds"] = round(out["default"]["seconds"] / out["symmetric_mode"]["seconds"], 3)
    name = f"{datetime.date.today().isoformat()}-cpu-{out['commit']}-static-factor{'-preview' if args.preview else ''}.json"
    path = ROOT / "benchmarks" / "results" / name
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps({k: out[k] for k in ("unknowns", "entries", "symmetric_mode", "default")}), f"; {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
