"""Design the block magnetisations of scenes/tentacle.toml with the Kirchhoff rod model (magsoro.rod).

Seed 000 sec 4.5 (Pittiglio et al.): "an optimization technique was used to estimate each block's magnetization
vector so that, in a given magnetic field, the desired shape could be obtained". Here: eight 4 mm blocks, each
magnetised in the x-z plane at an angle a_k (|Br| of the material), a 20 mT field along +x, weight included,
and a target S shape (the first half of the tentacle turns 60 degrees towards +x at constant curvature, the
second half turns back). Least squares on the eight angles; the residual is the distance of 33 centreline
points from the target, in units of the length.

    python scenes/tentacle/design.py         # prints the vectors for [robot.parts.magnetization] (about 30 s)
"""

from __future__ import annotations

import numpy as np

LENGTH = 0.032  # free length, m
DIAMETER = 0.002  # m
BLOCKS = 8
FIELD = (0.02, 0.0, 0.0)  # design field, T
TURN = np.pi / 3  # each half of the S turns this much, rad


def rod_for(angles, shear_modulus, bulk_modulus, density, remanence):
    """The tentacle as a magsoro.rod.Rod hanging from the origin along -z; block k magnetised along
    (cos a_k, 0, sin a_k) in the reference frame."""
    from magsoro.rod import CrossSection, MagnetSegment, Rod

    # material frame at the clamp: d1 = +y, d2 = +x, d3 = -z (the tangent)
    base = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    seg = LENGTH / len(angles)
    mags = [MagnetSegment(k * seg, (k + 1) * seg, tuple(base.T @ (remanence * np.array([np.cos(a), 0.0, np.sin(a)]))))
            for k, a in enumerate(angles)]
    youngs = 9.0 * bulk_modulus * shear_modulus / (3.0 * bulk_modulus + shear_modulus)
    return Rod(LENGTH, CrossSection.circle(DIAMETER), youngs_modulus=youngs, magnetisation=mags, density=density,
               base_rotation=base, n_nodes=33)


def target_shape(n=33):
    s = np.linspace(0.0, LENGTH, n)
    phi = np.where(s < LENGTH / 2, TURN * s / (LENGTH / 2), TURN * (LENGTH - s) / (LENGTH / 2))
    tx, tz = np.sin(phi), -np.cos(phi)
    ds = s[1] - s[0]
    x = np.concatenate([[0.0], np.cumsum(0.5 * (tx[1:] + tx[:-1]) * ds)])
    z = np.concatenate([[0.0], np.cumsum(0.5 * (tz[1:] + tz[:-1]) * ds)])
    return s, np.stack([x, z], axis=1)


def design(shear_modulus=120.03e3, bulk_modulus=20 * 120.03e3, density=1876.2, remanence=0.112):
    from scipy.optimize import least_squares

    s, target = target_shape()

    def residual(angles):
        sol = rod_for(angles, shear_modulus, bulk_modulus, density, remanence).solve(FIELD)
        x = np.interp(s, sol.s, sol.positions[:, 0])
        z = np.interp(s, sol.s, sol.positions[:, 2])
        return np.concatenate([x - target[:, 0], z - target[:, 1]]) / LENGTH

    # start: first half magnetised down the axis (turns towards +x in a +x field), second half up the axis
    a0 = np.where(np.arange(BLOCKS) < BLOCKS // 2, -np.pi / 2, np.pi / 2)
    res = least_squares(residual, a0, diff_step=1e-3, max_nfev=60)
    return res.x, float(np.sqrt(np.mean(res.fun**2)))


if __name__ == "__main__":
    angles, rms = design()
    print(f"rms distance from the target: {rms:.2e} L")
    print("vectors = [")
    for a in angles:
        print(f"  [{np.cos(a):.4f}, 0.0, {np.sin(a):.4f}],")
    print("]")
