"""The explicit engine's answer to the rise of robot arch_flip: seed 002's arch (scenes/arch_flip.toml, dx 0.5 mm,
no mass damping, self-contact) under the paper's actuator turned over, 10 mm to the side, rising from the depth that
gives 4 mT at the arch to the one that gives 45 mT at stated speeds (magsoro.robots.arch_flip.flip_run with
``explicit``). Records the level at the arch when the flip starts and the flip's time: the references of
arch_flip's comparison rows (magsoro.robots.arch_flip.EXPLICIT).

    python benchmarks/arch_flip_explicit.py [--speeds 50,100,200]

Writes benchmarks/results/<date>-cpu-<commit>-arch-flip-explicit.json with the machine and the commit.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    from magsoro.robots.arch_flip import NAME, flip_run
    from magsoro.robots.base import Context, scene_data

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speeds", default="50,100,200", help="magnet speeds, mm/s")
    args = ap.parse_args(argv)
    base = scene_data(NAME)
    ctx = Context(out=ROOT / "runs" / "arch_flip_explicit", log=print)
    runs = []
    for v in [float(s) * 1e-3 for s in args.speeds.split(",")]:
        r = flip_run(ctx, base, v, label=" (explicit)", explicit=True)
        runs.append({"magnet_speed_mm_s": v * 1e3, "flip_level_mT": 1e3 * r["level"], "flip_time_s": r["duration"],
                     "flip_start_s": r["t_start"], "final_moment_up": r["final_up"],
                     "centroid_shift_mm": 1e3 * float(r["cx"][-1] - r["cx"][0]), "wall_s": round(r["wall_s"], 1),
                     "steps": r["steps"], "dx_m": r["dx"], "particles": r["particles"]})
        print(runs[-1], flush=True)
    result = {"benchmark": "arch_flip_explicit", **provenance(), "scene": "scenes/arch_flip.toml",
              "integrator": "explicit", "runs": runs}
    out = ROOT / "benchmarks" / "results" / f"{result['date'][:10]}-cpu-{result['commit']}-arch-flip-explicit.json"
    out.write_text(json.dumps(result, indent=1))
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
