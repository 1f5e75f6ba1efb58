"""The triangle robot's field level by the static solver, against the gallery's dynamic sweep.

    python benchmarks/triangle_static.py [--level 15] [--max-iterations 400] [--together] [--preview]
                                         [--floor-clear-of-walls] [--fractions 0.2,0.4,0.6,0.8,1]

Seed 002's robots lie free on a friction plate and lift off it as the field rises; their reproductions run the
dynamics (docs/engine.md, "Which reproductions use it"). This script measures what the static solver does with
one of them: scenes/triangle.toml, float64, the N35 magnet held centred under the robot at the distance where B_z
at the robot's centre is ``--level`` mT (as `magsoro reproduce triangle` places it), solved from the flat robot

- by default with gravity first (level 0: gravity alone) and then the field (level 1);
- with ``--together``: field and gravity ramped together in one level;
- with ``--fractions``: gravity first, then the field in levels at those fractions of it, each solved from the
  last (a field sweep's continuation: does it spread the contact's release over the levels?).

``--preview`` takes the preview grid (dx 2 mm, one cell through the 2 mm robot); ``--floor-clear-of-walls`` moves
the domain's lower edge 6 mm further down, so that the plate lies clear of the bottom wall's band (at the preview
grid the plate's floor lies on its edge). It records whether each level converged, its Newton iterations and
wall time, the robot's vertex warp height W_t and centroid height, the particles touching the plate at rest and at
the end, and the gallery's dynamic values at the same level (docs/robots/triangle/triangle.csv, `magsoro
reproduce triangle`). Writes benchmarks/results/<date>-cpu-<commit>-triangle-static-<variant>.json with the
machine and the commit.
"""

import argparse
import copy
import csv
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import _commit  # the checkout's commit (MAGSORO_COMMIT without git history)

ROOT = Path(__file__).resolve().parents[1]
GALLERY = ROOT / "docs" / "robots" / "triangle" / "triangle.csv"


def touching(sim, floor_z: float = 0.0) -> int:
    """Particles whose ball (radius half their spacing, as the static solver's surface law has them) reaches the
    plate: centre within half a spacing of it, to 1e-6 cells."""
    sc = sim.scene.simulation
    h = sc.dx / sc.particles_per_cell
    z = sim.state.x.numpy()[:, 2]
    return int(np.count_nonzero(z - floor_z <= 0.5 * h + 1e-6 * sc.dx))


def main(argv=None) -> int:
    from magsoro.robots import triangle as T
    from magsoro.robots.base import scene_data, simulation

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=float, default=15.0, help="B_z at the robot's centre, mT (default 15)")
    ap.add_argument("--max-iterations", type=int, default=400, help="static.max_iterations (default 400; the scene default is 40)")
    ap.add_argument("--together", action="store_true", help="field and gravity ramped together in one level")
    ap.add_argument("--preview", action="store_true", help="the preview grid (dx 2 mm)")
    ap.add_argument("--floor-clear-of-walls", action="store_true", help="domain_lo z 6 mm lower")
    ap.add_argument("--fractions", default=None, help="gravity first, then the field at these comma-separated fractions")
    args = ap.parse_args(argv)

    data = scene_data("triangle")
    d = copy.deepcopy(data)
    magnet = next(f for f in d["fields"] if f.get("name") == "magnet")
    magnet.pop("path", None)
    magnet["position"] = T.magnet_offsets(magnet, [args.level])[0]
    d["simulation"]["precision"] = "float64"
    d["static"] = {"max_iterations": args.max_iterations}
    d.setdefault("output", {})["particles"] = False
    if args.floor_clear_of_walls:
        d["simulation"]["domain_lo"][2] -= 0.006
    sim = simulation("triangle", d, preview=args.preview, device="cpu")
    X0 = sim.model.host["positions"].astype(np.float64)
    mass = sim.model.host["mass"].astype(np.float64)
    corners = T.outer_vertices(d)
    rest = T.measure(sim, X0, mass, corners)
    touching_rest = touching(sim)
    fractions = None if args.fractions is None else [float(v) for v in args.fractions.split(",")]
    levels = [1.0] if args.together else [0.0] + (fractions or [1.0])
    t0 = time.perf_counter()
    res = sim.solve_static(levels=levels)
    wall = time.perf_counter() - t0
    end = T.measure(sim, X0, mass, corners)
    result = {
        "converged": res.converged,
        "message": res.message,
        "levels": [{"level": lv.level, "converged": lv.converged, "iterations": lv.iterations,
                    "load_increments": lv.increments, "wall_s": round(lv.wall_time, 1)} for lv in res.levels],
        "wall_s": round(wall, 1),
        "Wt_mm": 1e3 * float(np.mean(end["vertex"]) - np.mean(rest["vertex"])),
        "centroid_height_mm": 1e3 * float(end["centroid"]),
        "touching_particles_rest": touching_rest,
        "touching_particles_end": touching(sim),
        "particles": int(sim.model.n_particles),
        "dx_m": float(sim.scene.simulation.dx),
        "domain_lo": list(sim.scene.simulation.domain_lo),
    }
    gallery = None
    with open(GALLERY) as fh:
        for row in csv.DictReader(fh):
            if abs(float(row["B_mT"]) - args.level) < 1e-9:
                gallery = {"Wt_mm": float(row["warp_height_Wt_mm"]), "centroid_height_mm": float(row["centroid_height_abs_mm"])}
    if gallery is not None and res.converged and not args.preview:
        gallery["Wt_static_over_dynamic"] = round(result["Wt_mm"] / gallery["Wt_mm"], 5)
        gallery["centroid_static_over_dynamic"] = round(result["centroid_height_mm"] / gallery["centroid_height_mm"], 5)
    variant = ("together" if args.together else "gravity-first") + ("-steps" if fractions else "") + (
        "-preview" if args.preview else "") + ("-floor-clear" if args.floor_clear_of_walls else "")
    out = {
        "benchmark": "triangle_static",
        "variant": variant,
        "level_mT": args.level,
        "max_iterations": args.max_iterations,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "commit": _commit(),
        "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(), "cpu_count": os.cpu_count()},
        "static": result,
        "gallery_dynamic_full_grid": gallery,
    }
    stamp = datetime.date.today().isoformat()
    path = ROOT / "benchmarks" / "results" / f"{stamp}-cpu-{out['commit']}-triangle-static-{variant}.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"triangle {args.level:g} mT ({variant}): converged {res.converged}, "
          f"{', '.join(str(lv['iterations']) for lv in result['levels'])} iterations, {wall:.1f} s; W_t "
          f"{result['Wt_mm']:.3f} mm, centroid {result['centroid_height_mm']:.3f} mm (gallery: {gallery}); touching "
          f"{touching_rest} -> {result['touching_particles_end']}; {path}")
    if not res.converged:
        print(res.message)
    return 0


if __name__ == "__main__":
    sys.exit(main())
