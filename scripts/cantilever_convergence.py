"""Record how the 2D magnetic cantilever's tip deflection converges with grid refinement (core issue).

Runs the scene of tests/test_cantilever.py at several thickness-to-dx ratios and compares the settled tip
deflection with the Kirchhoff-rod solution (magsoro.rod). Writes docs/results/cantilever_convergence.csv.

    python scripts/cantilever_convergence.py [RATIO ...]
"""

import csv
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.test_cantilever import BN, L, T, rod_tip_deflection, run_tip_history  # noqa: E402


def main(ratios):
    ref = rod_tip_deflection()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    rows = []
    for r in ratios:
        t0 = time.perf_counter()
        hist, sim = run_tip_history(r)
        wall = time.perf_counter() - t0
        tip = hist[-1, 1]
        drift = abs(hist[-1, 1] - hist[-3, 1]) / abs(tip)
        rows.append(dict(thickness_over_dx=r, dx_m=T / r, particles=sim.model.n_particles, steps=sim.steps, wall_s=round(wall, 1),
                         tip_y_m=tip, rod_tip_y_m=ref, rel_error=(tip - ref) / ref, last_quarter_drift=drift))
        print(rows[-1], flush=True)
    out = ROOT / "docs" / "results" / "cantilever_convergence.csv"
    with out.open("w", newline="") as fh:
        fh.write(f"# L={L} m, t={T} m, Br*B/(mu0*G)={BN}, 2D plane strain, float32, CPU {platform.processor() or platform.machine()}, commit {commit}\n")
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {out}")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [3, 4, 6, 8])
