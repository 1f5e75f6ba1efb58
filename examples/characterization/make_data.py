"""Make the example data sets of docs/characterization.md from known parameters plus noise.

    python examples/characterization/make_data.py [--out DIR]

Writes, next to this script by default:

- ``tensile_ogden3.csv``: uniaxial tension of an Ogden-3 material, 5 specimens x 500 points, strain 0..6.
- ``tensile_yeoh.csv``: uniaxial tension of a Yeoh material, 5 specimens x 500 points, strain 0..5.
  Stress noise: 2 % of the reading (Gaussian), i.e. a load cell with a percent-of-reading error.
- ``cube_force_torque.csv``: force and torque on a 6.35 mm N52 cube (Br 1.40 T) at 16 positions 16..31 cm
  (1 cm apart, centre to centre) from an N52 cylinder of 101.6 mm x 101.6 mm, Br 1.48 T, with two sample
  orientations (the second 90 deg about the sample's y axis) and three repetitions: the rig of seed 001 sec IV.
- ``truth.json``: the parameters the data were made from.

Force/torque details. The cylinder sits at the origin with its axis along x; the sample moves along z (seed 001:
"the PM and the motorized stage were placed orthogonally with their centres aligned"). The cube's magnetisation
is tilted 3 deg from its z axis towards x so that every moment component is exercised. The field is the exact
closed form (``CylinderMagnet(model="exact")``), and force and torque are integrated over the cube volume
(3x3x3 Gauss-Legendre points, torque about the cube centre including the lever arm of the distributed force),
so the data carry the small errors of the point-dipole and multipole assumptions that the fit makes.
Noise: Gaussian with a standard deviation of one count of an ATI Nano17 (1/320 N, 1/64 N mm). Seed 001 names
the sensor but not its resolution; these figures are ATI's for the Nano17 SI-12-0.12 calibration and are an
assumption here.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from magsoro import MU0
from magsoro.characterization import (
    NANO17_FORCE_RESOLUTION,
    NANO17_TORQUE_RESOLUTION,
    force_torque_matrices,
    rotation_matrix,
    uniaxial_stress,
)
from magsoro.fields.cylinder import CylinderMagnet

HERE = Path(__file__).resolve().parent

# tensile truths (Pa; Ogden exponents dimensionless). Same sets as tests/test_characterization.py: chosen so
# that all parameters are identifiable from uniaxial data.
OGDEN3 = dict(mu1=-7.0e3, alpha1=-6.2, mu2=17.0e3, alpha2=0.9, mu3=75.0, alpha3=6.7)
YEOH = dict(C10=12.0e3, C20=-500.0, C30=25.0)
STRESS_NOISE = 0.02  # relative

# magnetic rig (seed 001 sec IV-A-2 and IV-B)
REF_MAGNET = dict(diameter=0.1016, length=0.1016, remanence=1.48)  # m, m, T
CUBE_SIDE = 6.35e-3  # m
CUBE_REMANENCE = 1.40  # T
CUBE_TILT_DEG = 3.0
DISTANCES = np.arange(16, 32) * 0.01  # m, centre to centre
REPETITIONS = 3
ORIENTATIONS = {0: rotation_matrix("y", 0.0), 1: rotation_matrix("y", 90.0)}


def write_tensile(path: Path, model: str, params: dict, max_strain: float, rng, specimens=5, points=500):
    strain = np.linspace(0.0, max_strain, points)
    clean = uniaxial_stress(model, params, strain)
    with open(path, "w") as f:
        f.write(f"# synthetic {model} tensile data: {specimens} specimens, {STRESS_NOISE:.0%} stress noise\n")
        f.write("specimen,strain,stress\n")
        for s in range(specimens):
            noisy = clean * (1.0 + STRESS_NOISE * rng.standard_normal(points))
            for e, p in zip(strain, noisy):
                f.write(f"S{s + 1},{e:.6f},{p:.6g}\n")


def cube_force_torque(magnet, centre, moment_global):
    """Force (N) and torque about the centre (N m) on a uniformly magnetised cube, by 3x3x3 Gauss quadrature."""
    nodes, weights = np.polynomial.legendre.leggauss(3)
    g = 0.5 * CUBE_SIDE * np.array(np.meshgrid(nodes, nodes, nodes, indexing="ij")).reshape(3, -1).T
    w = (0.5 * np.array(np.meshgrid(weights, weights, weights, indexing="ij")).reshape(3, -1).T).prod(axis=1)
    pts = centre + g
    eye = np.broadcast_to(np.eye(3), (len(pts), 3, 3))
    AF, AT = force_torque_matrices(magnet, pts, eye)
    f_pts = w[:, None] * (AF @ moment_global)  # each Gauss point carries its share of the moment
    t_pts = w[:, None] * (AT @ moment_global) + np.cross(g, f_pts)
    return f_pts.sum(axis=0), t_pts.sum(axis=0)


def write_force_torque(path: Path, rng) -> dict:
    magnet = CylinderMagnet(**REF_MAGNET, position=(0, 0, 0), axis=(1, 0, 0), model="exact")
    volume = CUBE_SIDE**3
    direction = rotation_matrix("y", CUBE_TILT_DEG) @ np.array([0.0, 0.0, 1.0])
    moment = CUBE_REMANENCE * volume / MU0 * direction  # sample frame, A m^2 (seed 001 eq 9)
    with open(path, "w") as f:
        f.write("# synthetic force/torque on a 6.35 mm N52 cube near a 101.6 x 101.6 mm N52 cylinder (axis x)\n")
        f.write("# units: x,y,z m; fx,fy,fz N; tx,ty,tz N m\n")
        f.write("x,y,z,fx,fy,fz,tx,ty,tz,orientation,repetition\n")
        for o, R in ORIENTATIONS.items():
            for rep in range(REPETITIONS):
                for zc in DISTANCES:
                    centre = np.array([0.0, 0.0, zc])
                    F, T = cube_force_torque(magnet, centre, R @ moment)
                    F = F + NANO17_FORCE_RESOLUTION * rng.standard_normal(3)
                    T = T + NANO17_TORQUE_RESOLUTION * rng.standard_normal(3)
                    f.write(
                        ",".join(f"{v:.6g}" for v in (*centre, *F, *T)) + f",{o},{rep}\n"
                    )
    return {
        "reference_magnet": {**REF_MAGNET, "position": [0, 0, 0], "axis": [1, 0, 0]},
        "cube_side": CUBE_SIDE,
        "volume": volume,
        "remanence": CUBE_REMANENCE,
        "moment": moment.tolist(),
        "moment_norm": float(np.linalg.norm(moment)),
        "direction": direction.tolist(),
        "orientations": {"1": "y:90"},
        "force_noise": NANO17_FORCE_RESOLUTION,
        "torque_noise": NANO17_TORQUE_RESOLUTION,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(HERE), help="output folder (default: next to this script)")
    ap.add_argument("--seed", type=int, default=2021, help="random seed")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    write_tensile(out / "tensile_ogden3.csv", "ogden3", OGDEN3, 6.0, rng)
    write_tensile(out / "tensile_yeoh.csv", "yeoh", YEOH, 5.0, rng)
    magnetic = write_force_torque(out / "cube_force_torque.csv", rng)
    truth = {
        "tensile_ogden3.csv": {
            "model": "ogden3",
            "params": OGDEN3,
            "initial_shear_modulus": OGDEN3["mu1"] + OGDEN3["mu2"] + OGDEN3["mu3"],
        },
        "tensile_yeoh.csv": {"model": "yeoh", "params": YEOH, "initial_shear_modulus": 2 * YEOH["C10"]},
        "cube_force_torque.csv": magnetic,
    }
    (out / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")
    for name in ("tensile_ogden3.csv", "tensile_yeoh.csv", "cube_force_torque.csv", "truth.json"):
        print(f"wrote {out / name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
