"""The explicit engine's answer to the rise of robot cross_rise: seed 002's cross (scenes/cross.toml, dx 1 mm, grid
damping 120 1/s) under the paper's actuator rising from 80 mm below the plate to its top at a stated speed, as
``magsoro reproduce cross`` runs it (magsoro.robots._seed002_speeds.rising_run). Records the strips' deflection
(the centre above the tips for arching, the tips above the centre for grabbing) from the flat start at the time
the magnet starts to rise and at the end of the run, the magnet at its top: the references of cross_rise's
comparison rows (magsoro.robots.cross_rise.EXPLICIT_TOP_MM).

    python benchmarks/cross_rise_explicit.py [--speeds 200]

Writes benchmarks/results/<date>-cpu-<commit>-cross-rise-explicit.json with the machine and the commit.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    from magsoro.robots import _seed002_speeds as sp
    from magsoro.robots.base import Context, scene_data
    from magsoro.robots.cross import NAME, markers
    from magsoro.robots.cross_rise import MODES, deflection

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speeds", default="200", help="magnet speeds, mm/s")
    args = ap.parse_args(argv)
    base = scene_data(NAME)
    ctx = Context(out=ROOT / "runs" / "cross_rise_explicit")
    runs = []
    for v in [float(s) * 1e-3 for s in args.speeds.split(",")]:
        for mode, sign in MODES:
            r = sp.rising_run(NAME, base, (0.0, 0.0), v, sign, markers, ctx, mode)
            d = deflection(r, mode)
            i0 = int(np.searchsorted(r["t"], sp.SETTLE))
            runs.append({"mode": mode, "magnet_speed_mm_s": v * 1e3, "deflection_at_rise_start_mm": 1e3 * float(d[i0]),
                         "deflection_at_top_mm": 1e3 * float(d[-1] - d[0]),
                         "growth_mm": 1e3 * float(d[-1] - d[i0]), "wall_s": round(r["wall_s"], 1), "dx_m": r["dx"],
                         "particles": r["particles"]})
            print(runs[-1], flush=True)
    result = {"benchmark": "cross_rise_explicit", **provenance(), "scene": "scenes/cross.toml", "runs": runs}
    out = ROOT / "benchmarks" / "results" / f"{result['date'][:10]}-cpu-{result['commit']}-cross-rise-explicit.json"
    out.write_text(json.dumps(result, indent=1))
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
