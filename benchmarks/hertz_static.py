"""An elastic sphere pressed on a much stiffer elastic block by the static solver with contact between bodies,
against Hertz's law F = 4/3 E* R^(1/2) d^(3/2): the validation case ``hertz_bodies`` at a resolution of choice.

    python benchmarks/hertz_static.py [--cells 10] [--depths 0.025,0.05,0.075,0.1]

The set-up, the finite-body term and the offset fit are those of magsoro.validation.hertz_bodies. ``--cells``:
cells through R; ``--depths``: the clamp's displacements, in units of R (at most 0.1).

Writes benchmarks/results/<date>-cpu-<commit>-hertz-static.json with the machine and the commit: per level the
force, the local indentation, Hertz's force there and the error; the fitted offset and constant.
"""

import argparse
import json
import sys
from pathlib import Path

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cells", type=float, default=10.0, help="cells through the sphere's radius")
    p.add_argument("--depths", default="0.025,0.05,0.075,0.1", help="the clamp's displacements, units of R")
    args = p.parse_args(argv)
    from magsoro.validation.hertz_bodies import SphereOnBlock, compare, measure

    setup = SphereOnBlock(cells=args.cells, levels=tuple(float(v) for v in args.depths.split(",")))
    levels, particles = measure(setup, log=print)
    comp = compare(setup, levels)
    R = setup.radius
    rows = [{"clamp_displacement_over_R": lv.approach / R, "force_n": lv.force, "local_indentation_over_R": float(d / R),
             "hertz_n": float(ref), "error": float(err), "force_over_hertz_at_clamp_displacement": float(bare),
             "newton_iterations": lv.iterations, "wall_s": round(lv.wall_s, 1)}
            for lv, d, ref, err, bare in zip(levels, comp.indentation, comp.hertz, comp.error, comp.bare)]
    result = {"benchmark": "hertz_static", **provenance(), "cells_through_radius": args.cells, "particles": particles,
              "e_star_pa": setup.e_star, "fitted_offset_cells": comp.offset / setup.dx,
              "constant_over_hertz": comp.constant / comp.hertz_constant, "levels": rows}
    out = ROOT / "benchmarks" / "results" / f"{result['date'][:10]}-cpu-{result['commit']}-hertz-static.json"
    out.write_text(json.dumps(result, indent=1))
    print(json.dumps(rows, indent=1))
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
