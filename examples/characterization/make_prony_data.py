"""Make the synthetic viscoelastic example data of docs/characterization.md from a known Prony series plus noise.

    python examples/characterization/make_prony_data.py [--out DIR]

SYNTHETIC data, not measurements. Writes, next to this script by default:

- ``relaxation_prony3.csv``: a stress-relaxation test in uniaxial tension held at 20 % engineering strain,
  columns ``time`` (s), ``stress`` (nominal, Pa) and ``strain``; 201 log-spaced times 0.01 .. 1000 s.
- ``sweep_prony3.csv``: a shear frequency sweep, columns ``frequency`` (Hz), ``storage_modulus`` and
  ``loss_modulus`` (Pa); 26 log-spaced frequencies 0.001 .. 100 Hz.
- ``prony_truth.json``: the series the data were made from.

Material: G(t) = G0 (g_inf + sum_i g_i exp(-t / tau_i)) with G0 = 24 kPa (the instantaneous shear modulus of the
Yeoh example, tensile_yeoh.csv), g = 0.18, 0.12, 0.08 and tau = 0.05, 2, 80 s. The held tension follows the
incompressible Neo-Hookean form P(t) = G(t) (lam - lam^-2), lam = 1 + strain (the form read_relaxation_csv
inverts). Noise: 1 % of the reading (Gaussian) on stress, G' and G'' separately.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from magsoro.characterization.viscoelastic import prony_relaxation, prony_storage_loss

G0 = 24.0e3  # Pa
G = (0.18, 0.12, 0.08)
TAU = (0.05, 2.0, 80.0)  # s
STRAIN = 0.2
NOISE = 0.01


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).parent), help="output folder (default: next to this script)")
    out = Path(parser.parse_args(argv).out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2024)

    time = np.geomspace(0.01, 1000.0, 201)
    lam = 1.0 + STRAIN
    stress = prony_relaxation(time, G0, G, TAU) * (lam - lam**-2) * (1.0 + NOISE * rng.standard_normal(time.size))
    path = out / "relaxation_prony3.csv"
    with open(path, "w") as f:
        f.write(f"# SYNTHETIC stress relaxation at {STRAIN:.0%} tensile strain, {NOISE:.0%} noise "
                "(make_prony_data.py)\n")
        f.write("time,stress,strain\n")
        for t, p in zip(time, stress):
            f.write(f"{t:.6g},{p:.6g},{STRAIN}\n")
    print(f"wrote {path}")

    freq = np.geomspace(1e-3, 100.0, 26)
    storage, loss = prony_storage_loss(freq, G0, G, TAU)
    storage = storage * (1.0 + NOISE * rng.standard_normal(freq.size))
    loss = loss * (1.0 + NOISE * rng.standard_normal(freq.size))
    path = out / "sweep_prony3.csv"
    with open(path, "w") as f:
        f.write(f"# SYNTHETIC shear frequency sweep, {NOISE:.0%} noise (make_prony_data.py)\n")
        f.write("frequency,storage_modulus,loss_modulus\n")
        for row in zip(freq, storage, loss):
            f.write(",".join(f"{v:.6g}" for v in row) + "\n")
    print(f"wrote {path}")

    truth = {"synthetic": True, "shear_modulus": G0, "g": list(G), "tau": list(TAU), "g_inf": 1.0 - sum(G),
             "prony": [[g, t] for g, t in zip(G, TAU)], "held_strain": STRAIN, "noise": NOISE}
    path = out / "prony_truth.json"
    path.write_text(json.dumps(truth, indent=2) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
