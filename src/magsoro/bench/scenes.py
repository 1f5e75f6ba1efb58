"""Fixed benchmark scenes, part of the package so `magsoro bench` measures the same work everywhere.

- walker: a Hu et al.-style millimetre sheet walker (3D, dx 0.1 mm, about 9k particles, 25 mm domain), sinusoidal
  magnetisation profile along its length, rotating 8 mT field, friction floor.
- walker_1m: the same walker in a 1 m domain (the grid block must make it cost the same).
- walker_dipole: the walker with magnetic interaction between its own parts (simulation.magnetic_interaction =
  "dipole"), refreshed every 10 steps; timed against the same walker without it in the same rounds.
- walker_total: the walker in the total-Lagrangian form, which a one-body scene runs by default
  (``formulation = "auto"``); the others run the updated form.
- beam2d: Zhao et al.'s cantilever (seed 000 sec 4.2), 2D plane strain at the validation resolution t/dx = 4.
- block1m: an elastic block of about 10^6 particles falling on a floor (3D).
- sweep: 8 copies of the walker side by side in one simulation (a 4 x 2 tile on the same floor, 1 mm apart), each
  driven by its own rotating field (8 mT at 5, 6, ... 12 Hz) through a :class:`magsoro.fields.Regional` source:
  a batched parameter sweep. Its figures are compared with running the walker 8 times one after another.
"""

import numpy as np

from magsoro.geometry.primitives import Box, Rectangle, fill_lattice
from magsoro.mpm.colliders import Collider
from magsoro.fields import Regional, Rotating, Uniform
from magsoro.mpm.model import Control, Model, SolverSettings


#: Walker sheet size (m) and the sweep's tile: copies 4 along x and 2 along y, 1 mm apart (10 cells: no grid
#: node is shared by two copies).
WALKER_SIZE = (4.0e-3, 1.5e-3, 0.2e-3)
SWEEP_TILE = (4, 2)
SWEEP_GAP = 1.0e-3
SWEEP_FREQUENCIES_HZ = tuple(5.0 + k for k in range(8))


def _walker_particles(center, dx, lo):
    # Sheet 4.0 x 1.5 x 0.2 mm (Hu et al. 2018 walker scale), Ecoflex-NdFeB: E about 85 kPa, 1860 kg/m^3;
    # magnetisation magnitude 62 kA/m (Br = mu0 M = 0.078 T) rotating once along the length in the x-z plane.
    X, v_each = fill_lattice(Box(center, list(WALKER_SIZE)), dx, 2, lo, 3)
    n = len(X)
    s = (X[:, 0] - (center[0] - 0.5 * WALKER_SIZE[0])) / WALKER_SIZE[0]
    Br = 0.078 * np.stack([np.cos(2 * np.pi * s), np.zeros(n), np.sin(2 * np.pi * s)], axis=1)
    return X, v_each, Br


def _walker(domain: float, formulation: str = "updated", interaction_every: int | None = None):
    dx = 1e-4
    c = domain / 2
    floor_z = c - 0.005
    lo = np.full(3, c - 0.0125) if domain <= 0.025 else np.zeros(3)
    hi = lo + (0.025 if domain <= 0.025 else domain)
    X, v_each, Br = _walker_particles([c, c, floor_z + 0.1e-3 + 0.5 * dx], dx, lo)
    n = len(X)
    model_kw = dict(dx=dx, domain_lo=lo, domain_hi=hi)
    floor = Collider.half_space([c, c, floor_z], [0, 0, 1], mode="friction", friction=0.3)
    control = Control([Uniform(Rotating(0.008, 5.0, u=(1, 0, 0), v=(0, 0, 1)))], [floor])
    settings = SolverSettings(damping=10.0, gravity=(0.0, 0.0, -9.81), formulation=formulation)
    if interaction_every is not None:
        settings.magnetic_interaction, settings.interaction_every = "dipole", interaction_every
    return (X, np.full(n, v_each), 1860.0, 2.8e4, Br, model_kw), control, settings


def _sweep():
    dx = 1e-4
    lo, hi = np.zeros(3), np.full(3, 0.05)
    floor_z = 0.02
    pitch = (WALKER_SIZE[0] + SWEEP_GAP, WALKER_SIZE[1] + SWEEP_GAP)
    xs, brs, regions = [], [], []
    for k, f in enumerate(SWEEP_FREQUENCIES_HZ):
        i, j = k % SWEEP_TILE[0], k // SWEEP_TILE[0]
        center = [0.015 + i * pitch[0], 0.02 + j * pitch[1], floor_z + 0.1e-3 + 0.5 * dx]
        X, v_each, Br = _walker_particles(center, dx, lo)
        xs.append(X)
        brs.append(Br)
        box_lo = [center[0] - 0.45 * pitch[0], center[1] - 0.45 * pitch[1], lo[2]]  # 0.05 mm clear of the next
        box_hi = [center[0] + 0.45 * pitch[0], center[1] + 0.45 * pitch[1], hi[2]]
        regions.append((box_lo, box_hi, Uniform(Rotating(0.008, f, u=(1, 0, 0), v=(0, 0, 1)))))
    X = np.concatenate(xs)
    floor = Collider.half_space([0.0, 0.0, floor_z], [0, 0, 1], mode="friction", friction=0.3)
    control = Control([Regional(regions)], [floor])
    settings = SolverSettings(damping=10.0, gravity=(0.0, 0.0, -9.81))
    return (X, np.full(len(X), v_each), 1860.0, 2.8e4, np.concatenate(brs), dict(dx=dx, domain_lo=lo, domain_hi=hi)), control, settings


def _beam2d():
    # Zhao et al. beam: L = 17.2 mm free length, t = 0.84 mm, G = 303 kPa, Br = 0.258 T; dx = t / 4.
    dx = 0.84e-3 / 4
    depth = 5e-3
    shape = Rectangle([0.0094 - 0.0008, 0.0], [0.0188, 0.84e-3])
    lo, hi = np.array([-0.004, -0.02]), np.array([0.024, 0.02])
    X, a_each = fill_lattice(shape, dx, 2, lo, 2)
    n = len(X)
    Br = np.tile([0.258, 0.0, 0.0], (n, 1))
    clamped = X[:, 0] < 0.0
    from magsoro.constants import MU0

    B = 0.004 * MU0 * 303e3 / 0.258
    control = Control([Uniform([0.0, B, 0.0])])
    settings = SolverSettings(damping=150.0)
    return (X, np.full(n, a_each * depth), 1030.0, 303e3, Br, dict(dx=dx, domain_lo=lo, domain_hi=hi), clamped), control, settings


def _block1m():
    dx = 1e-3
    shape = Box([0.1, 0.1, 0.1], [0.05, 0.05, 0.05])
    lo, hi = np.zeros(3), np.full(3, 0.2)
    X, v_each = fill_lattice(shape, dx, 2, lo, 3)
    n = len(X)
    control = Control([], [Collider.half_space([0.1, 0.1, 0.07], [0, 0, 1], mode="slip")])
    settings = SolverSettings(gravity=(0.0, 0.0, -9.81))
    return (X, np.full(n, v_each), 1100.0, 1e5, np.zeros((n, 3)), dict(dx=dx, domain_lo=lo, domain_hi=hi)), control, settings


SCENES = {
    "walker": lambda: _walker(0.025),
    "walker_1m": lambda: _walker(1.0),
    "walker_total": lambda: _walker(0.025, formulation="total"),
    "walker_dipole": lambda: _walker(0.025, interaction_every=10),
    "beam2d": _beam2d,
    "block1m": _block1m,
    "sweep": _sweep,
}


def build(name: str, device: str = "cpu", precision: str = "float32"):
    """Model, Control and SolverSettings of benchmark scene ``name``."""
    spec, control, settings = SCENES[name]()
    X, vol, rho, G, Br, kw = spec[:6]
    clamped = spec[6] if len(spec) > 6 else np.zeros(len(X), bool)
    model = Model(X, vol, rho, G, 20 * G, Br, 0, clamped, precision=precision, device=device, **kw)
    return model, control, settings
