"""An elastic sphere pressed on a much stiffer elastic block by the static solver with contact between bodies,
against Hertz's law F = 4/3 E* R^(1/2) d^(3/2).

    python benchmarks/hertz_static.py [--cells 6] [--depths 0.25,0.5,1.0]

The sphere (R = 4 mm, G = 100 kPa, K = 1 MPa) has its upper half clamped and moved down by d (a clamp path); the
block below it (G 100 times the sphere's, bottom clamped) stands for a half-space of negligible compliance. The
force is the contact force the block exerts on the sphere (a collider_force probe between bodies); d runs to R/10
in the fractions given. ``--cells``: cells through R.

Writes benchmarks/results/<date>-cpu-<commit>-hertz-static.json with the machine and the commit.
"""

import argparse
import json
import math
import sys
import time
from pathlib import Path

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]
RADIUS = 4e-3
SPHERE = (1e5, 1e6)  # shear and bulk modulus, Pa
BLOCK = (1e7, 1e8)


def youngs(G: float, K: float) -> float:
    return 9.0 * K * G / (3.0 * K + G)


def poisson(G: float, K: float) -> float:
    return (3.0 * K - 2.0 * G) / (6.0 * K + 2.0 * G)


def scene(cells: float, fractions: list) -> dict:
    dx = RADIUS / cells
    thickness, width, d_max = 3 * dx, 2.6 * RADIUS, RADIUS / 10
    material = lambda G, K: {"density": 1000.0, "shear_modulus": G, "bulk_modulus": K}  # noqa: E731
    return {"simulation": {"dim": 3, "dx": dx, "domain_lo": [-8e-3, -8e-3, -6e-3], "domain_hi": [8e-3, 8e-3, 1.2e-2],
                           "duration": 1.0, "precision": "float64", "formulation": "total"},
            "bodies": [{"name": "sphere", "shape": {"type": "sphere", "center": [0, 0, RADIUS], "radius": RADIUS},
                        "material": material(*SPHERE)},
                       {"name": "block", "shape": {"type": "box", "center": [0, 0, -thickness / 2], "size": [width, width, thickness]},
                        "material": material(*BLOCK)}],
            "clamps": [{"region": {"type": "box", "center": [0, 0, 1.5 * RADIUS], "size": [2.2 * RADIUS, 2.2 * RADIUS, RADIUS]},
                        "body": "sphere", "path": {"times": [0.0, 1.0], "positions": [[0, 0, 0], [0, 0, -d_max]]}},
                       {"region": {"type": "box", "center": [0, 0, -thickness], "size": [1.1 * width, 1.1 * width, 1.5 * dx]},
                        "body": "block"}],
            "contact": {"friction": 0.0},
            "probes": [{"type": "collider_force", "name": "F", "bodies": ["block", "sphere"]}],
            "static": {"times": fractions},
            "output": {"particles": False}}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cells", type=float, default=6.0, help="cells through the sphere's radius")
    p.add_argument("--depths", default="0.25,0.5,1.0", help="the indentations, as fractions of R/10")
    args = p.parse_args(argv)
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    fractions = [float(v) for v in args.depths.split(",")]
    sim = Simulation(parse_scene(scene(args.cells, fractions), source="hertz_static"))
    e_star = 1.0 / ((1 - poisson(*SPHERE) ** 2) / youngs(*SPHERE) + (1 - poisson(*BLOCK) ** 2) / youngs(*BLOCK))
    rows = []
    t0 = time.perf_counter()

    def level(s, r):
        d = RADIUS / 10 * r.time
        force = s.probe_values()["F_Fz"]
        hertz = 4.0 / 3.0 * e_star * math.sqrt(RADIUS) * d ** 1.5
        rows.append({"d_over_R": d / RADIUS, "force_n": force, "hertz_n": hertz, "ratio": force / hertz,
                     "newton_iterations": r.iterations, "wall_s": round(time.perf_counter() - t0, 1)})
        print(rows[-1], flush=True)

    run = sim.solve_static(on_level=level)
    result = {"benchmark": "hertz_static", **provenance(), "cells_through_radius": args.cells,
              "particles": int(sim.model.n_particles), "e_star_pa": e_star, "converged": bool(run.converged),
              "levels": rows}
    out = ROOT / "benchmarks" / "results" / f"{result['date'][:10]}-cpu-{result['commit']}-hertz-static.json"
    out.write_text(json.dumps(result, indent=1))
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
