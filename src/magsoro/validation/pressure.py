"""Pressure loads: a thick ring under internal pressure (2D plane strain) against an independent radial model.

The ring (inner radius a = 4 mm, outer b = 6 mm, G = 100 kPa, K = 20 G, so Poisson's ratio 0.475) carries a
gauge pressure p on its inner surface (a ``[bodies.pressure]`` table whose cavity is the disc r < a). References:

- Lame's small-strain solution, plane strain: u(r) = (1 + nu) p a^2 / (E (b^2 - a^2)) ((1 - 2 nu) r + b^2 / r);
- :func:`radial_displacement`: the same material law as the engine's Neo-Hookean (W = G/2 (J^-2/3 I1 - 3) +
  K/2 (J - 1)^2, plane strain) at finite strain, the ring discretised along the radius in linear elements, its
  total energy (strain energy minus p times the cavity's area change: a pressure on a closed cavity is a
  conservative load) minimised by Newton's method. At p = G/10 the ring's bore widens by about 10 %, where the
  follower load (on the current, stretched surface) and a dead load (on the reference surface) give displacements
  about 10 % apart: the comparison sees which the engine applies (tests/test_pressure.py).
"""

from __future__ import annotations

import numpy as np

RING_A, RING_B, RING_G = 4e-3, 6e-3, 1e5  # m, m, Pa


def ring_scene(pressure: float, dx: float = 5e-4, precision: str = "float64", ramp: float = 0.0) -> dict:
    """Scene dict of the ring with ``pressure`` (Pa) in its bore (material K = 20 G, the engine's default)."""
    a, b = RING_A, RING_B
    return {
        "simulation": {"dim": 2, "dx": dx, "domain_lo": [-0.01, -0.01], "domain_hi": [0.01, 0.01], "duration": 1e-3,
                       "precision": precision},
        "bodies": [{
            "name": "ring",
            "shape": {"type": "arc", "center": [0.0, 0.0], "radius": (a + b) / 2, "width": b - a, "start_angle": 0.0,
                      "end_angle": 360.0},
            "material": {"density": 1000.0, "shear_modulus": RING_G},
            "pressure": {"cavity": {"type": "arc", "center": [0.0, 0.0], "radius": a / 2, "width": a,
                                    "start_angle": 0.0, "end_angle": 360.0},
                         "value": pressure, "ramp": ramp},
        }],
        "output": {"particles": False},
    }


def lame_displacement(r, pressure: float, shear: float, bulk: float, a: float = RING_A, b: float = RING_B):
    """Radial displacement (m) at radius ``r`` of a plane-strain thick ring under internal ``pressure``, small
    strain (Lame)."""
    nu = (3 * bulk - 2 * shear) / (2 * (3 * bulk + shear))
    E = 2 * shear * (1 + nu)
    r = np.asarray(r, dtype=np.float64)
    return (1 + nu) * pressure * a**2 / (E * (b**2 - a**2)) * ((1 - 2 * nu) * r + b**2 / r)


def law_stretch_derivatives(l1, l2, l3, k: float):
    """(dW/dl1, dW/dl2) per unit G of the engine's Neo-Hookean W = 1/2 (J^-2/3 I1 - 3) + k/2 (J - 1)^2 (k = K/G)
    at principal stretches l1, l2 and a held l3 (arrays); raises ArithmeticError on J <= 0."""
    J = l1 * l2 * l3
    if np.any(J <= 0.0):
        raise ArithmeticError("the radial model inverted an element")
    I1 = l1**2 + l2**2 + l3 * l3
    Jm = J ** (-2.0 / 3.0)
    dW_dJ = -Jm / (3.0 * J) * I1 + k * (J - 1.0)
    return Jm * l1 + dW_dJ * l2 * l3, Jm * l2 + dW_dJ * l1 * l3


def newton_minimise(gradient, u: np.ndarray, free: int | None = None, iterations: int = 50) -> np.ndarray:
    """Minimise an energy from its analytic ``gradient`` by Newton's method, the Hessian by central differences
    (step 1e-7) and symmetrised, over the first ``free`` unknowns of ``u`` (all by default; the rest held);
    returns u once a step is below 1e-13, raises ArithmeticError after ``iterations``."""
    u = np.array(u, dtype=np.float64)
    m = len(u) if free is None else free
    eps = 1e-7
    for _ in range(iterations):
        g = gradient(u)[:m]
        H = np.empty((m, m))
        for j in range(m):
            du = np.zeros_like(u)
            du[j] = eps
            H[:, j] = ((gradient(u + du) - gradient(u - du)) / (2 * eps))[:m]
        step = np.linalg.solve(0.5 * (H + H.T), -g)
        u[:m] += step
        if np.max(np.abs(step)) < 1e-13:
            return u
    raise ArithmeticError(f"the radial model did not converge in {iterations} Newton iterations")


def radial_displacement(pressure: float, shear: float, bulk: float, a: float = RING_A, b: float = RING_B,
                        n: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Finite-strain radial displacement of the plane-strain ring (module docstring): node radii R (m) and their
    displacements u (m), from ``n`` linear elements. Newton's method on the energy, in units of a and G, with the
    Hessian by central differences of the analytic gradient."""
    R = np.linspace(1.0, b / a, n + 1)
    Rm, dR = 0.5 * (R[1:] + R[:-1]), np.diff(R)
    k, q = bulk / shear, pressure / shear
    w = 2 * np.pi * Rm * dR  # element areas (reference)

    def gradient(u):
        r = R + u
        l1 = np.diff(r) / dR  # radial stretch
        l2 = 0.5 * (r[1:] + r[:-1]) / Rm  # hoop stretch
        dW_dl1, dW_dl2 = law_stretch_derivatives(l1, l2, 1.0, k)
        g = np.zeros_like(r)
        c1 = dW_dl1 * w / dR
        g[1:] += c1
        g[:-1] -= c1
        c2 = dW_dl2 * w * 0.5 / Rm
        g[1:] += c2
        g[:-1] += c2
        g[0] -= q * 2.0 * np.pi * r[0]  # d/dr_a of -q pi (r_a^2 - 1)
        return g

    u = newton_minimise(gradient, np.zeros_like(R))
    return R * a, u * a
