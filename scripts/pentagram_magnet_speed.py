"""The pentagram's crawl (scenes/pentagram.toml, preview resolution) with the magnet passing under the plate at a
given speed, to see how the robot's speed depends on the magnet's (seed 002 gives none):

    python scripts/pentagram_magnet_speed.py SPEED_MM_S [--out FILE.json]

The magnet waits 0.05 s at x = -100 mm, passes at constant speed to x = +100 mm and rests 0.1 s, as in the scene
(which passes at 200 mm/s); the robot's mass centre is sampled every 50 ms. Prints (and writes with --out) the
centroid's displacement along the pass, its mean speed over the pass, its final height and the peak height.
Measured on 2026-11-26 (one core each): 50 mm/s: +53.6 mm, 13.4 mm/s, 681 s wall; 25 mm/s: +55.9 mm, 7.0 mm/s,
1324 s wall (the reproduction's 200 mm/s: +54.5 mm, 54 mm/s).
"""

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from magsoro.robots.base import scene_data, simulation  # noqa: E402
from magsoro.robots.pentagram import _with_dx  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("speed", type=float, help="magnet speed (mm/s)")
    ap.add_argument("--out", type=Path, help="write the result as JSON here")
    args = ap.parse_args()
    if not (args.speed > 0 and math.isfinite(args.speed)):
        raise SystemExit(f"pentagram_magnet_speed: SPEED_MM_S must be a finite number > 0, got {args.speed}")
    v = args.speed * 1e-3
    data = _with_dx(scene_data("pentagram"))
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    x0, x1, z = -0.1, 0.1, magnet["position"][2]
    wait, rest = 0.05, 0.1
    t_pass = wait + (x1 - x0) / v
    magnet["path"] = {"times": [0.0, wait, t_pass, t_pass + rest],
                      "positions": [[x0, 0.0, z], [x0, 0.0, z], [x1, 0.0, z], [x1, 0.0, z]]}
    data["simulation"]["duration"] = t_pass + rest
    sim = simulation("pentagram", data, preview=False, device=None)
    mass = sim.model.host["mass"].astype(np.float64)
    track, w0 = [], time.perf_counter()
    while sim.time < t_pass + rest - 1e-9:
        sim.advance_to(min(t_pass + rest, sim.time + 0.05))
        x = sim.state.x.numpy().astype(np.float64)
        c = (mass[:, None] * x).sum(0) / mass.sum()
        track.append((sim.time, c[0], c[2], float(x[:, 2].max())))
    tr = np.array(track)
    i0, i1 = np.searchsorted(tr[:, 0], wait), np.searchsorted(tr[:, 0], t_pass)
    moved = float(tr[i1, 1] - tr[i0, 1])
    res = {"magnet_speed_mm_s": args.speed, "dx_mm": sim.model.dx * 1e3, "displacement_in_pass_mm": moved * 1e3,
           "mean_speed_mm_s": moved * 1e3 / (t_pass - wait), "end_centroid_z_mm": float(tr[-1, 2]) * 1e3,
           "peak_height_mm": float(tr[:, 3].max()) * 1e3, "wall_s": round(time.perf_counter() - w0, 1),
           "steps": sim.steps}
    print(json.dumps(res, indent=1))
    if args.out:
        args.out.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
