"""Creep of loaded slender beams with the two F-update choices of the engine (docs/engine.md, "Why the remap").

Runs the 2D Zhao beam (t/dx = 2, float64, CFL 0.4) under a perpendicular field Br B/(mu0 G) = 0.0005, and the
same beam sagging under its own weight by 0.25 L (linear estimate), with ``velocity_gradient`` = "grid" and
"remap", and prints the tip deflection against the Kirchhoff rod. About 2 CPU-minutes.

    python benchmarks/creep_check.py [--json]
"""

from __future__ import annotations

import argparse
import json

from magsoro.validation.beam import BeamSetup, rod_reference, run_gravity, run_sweep


def magnetic(mode: str) -> dict:
    s = BeamSetup(t_over_dx=2, velocity_gradient=mode)
    r = run_sweep(s, (0.0005,), 90.0)
    ref = float(rod_reference(s, (0.0005,), 90.0, r.tip_s, r.free_length)[1][0])
    return {"case": "field bn=0.0005, hold 6/omega_1", "mode": mode, "engine": float(r.tip_dy[0]), "rod": ref,
            "error": float(r.tip_dy[0]) / ref - 1.0}


def gravity(mode: str) -> dict:
    s = BeamSetup(t_over_dx=2, velocity_gradient=mode)
    value, ref, _ = run_gravity(s, sag=0.25, duration=10.0)
    return {"case": "own weight, sag 0.25 L, 10/omega_1", "mode": mode, "engine": value, "rod": ref,
            "error": value / ref - 1.0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = [f(m) for f in (magnetic, gravity) for m in ("grid", "remap")]
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    for r in rows:
        print(f"{r['case']:<38} {r['mode']:<6} engine {r['engine']:+.5f}  rod {r['rod']:+.5f}  "
              f"error {100 * r['error']:+.2f} %")


if __name__ == "__main__":
    main()
