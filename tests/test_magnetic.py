"""Magnetic coupling of the engine against closed forms (seed 000 eqs 11-16).

- A uniform field exerts no net force on a free magnetised body; the total angular momentum grows at the rate
  m x B, and the body spins up with angular acceleration (m x B) / I.
- In a dipole field, the net force on a small magnetised cube equals (m . grad) B at its centre.
"""

import numpy as np
import pytest

from magsoro import MU0
from magsoro.fields import Dipole, Uniform
from magsoro.mpm.model import Control, SolverSettings
from magsoro.mpm.solver import Solver
from tests.conftest import make_block_model


def _angular_momentum(model, state, dx, origin):
    """APIC angular momentum about ``origin``: sum m (x - o) x v + m (dx^2/4) eps : C (see tests docstring)."""
    m = model.host["mass"]
    s = state.numpy()
    r = s["x"] - origin
    L = np.cross(r, s["v"]) * m[:, None]
    C = s["C"]
    spin = np.stack([C[:, 2, 1] - C[:, 1, 2], C[:, 0, 2] - C[:, 2, 0], C[:, 1, 0] - C[:, 0, 1]], axis=1)
    return (L + m[:, None] * (dx**2 / 4) * spin).sum(axis=0)


def _run(model, control, dt, n, settings=None):
    solver = Solver(model, settings or SolverSettings())
    a, b = solver.new_state(), solver.new_state()
    for _ in range(n):
        solver.step(a, b, control, dt)
        a, b = b, a
    return solver, a


def test_uniform_field_no_net_force_and_torque_m_cross_B():
    a, dx = 3e-3, 2e-4
    Br = np.array([0.1, 0.0, 0.0])
    B = np.array([0.0, 0.008, 0.0])
    model = make_block_model([0, 0, 0], [a, a, a], dx, ppc=1, density=1000.0, G=1e6, Br=Br)
    control = Control([Uniform(B)])
    solver = Solver(model)
    dt = 0.5 * solver.stable_dt(control)
    n = 1500
    _, state = _run(model, control, dt, n)
    t = n * dt
    mass = model.host["mass"]
    M = mass.sum()
    V = model.host["volumes"].sum()
    # net force: total momentum / t against the body's weight scale M g
    P = (mass[:, None] * state.numpy()["v"]).sum(axis=0)
    assert np.linalg.norm(P / t) < 1e-6 * M * 9.81
    # torque: dL/dt = m x B with m = V Br / mu0 (the body has rotated by < 1 mrad, so m is still along x)
    centre = np.full(3, a / 2)
    L = _angular_momentum(model, state, dx, centre)
    torque = np.cross(V * Br / MU0, B)
    assert L[2] / t == pytest.approx(torque[2], rel=5e-3)
    assert abs(L[0]) + abs(L[1]) < 1e-6 * abs(L[2])
    # angular acceleration: rigid-rotation fit of particle velocities about the centroid, omega = alpha t
    x = state.numpy()["x"]
    v = state.numpy()["v"]
    r = x - (mass[:, None] * x).sum(0) / M
    # v_x = -w r_y, v_y = w r_x for rotation about z
    omega = np.sum(mass * (r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0])) / np.sum(mass * (r[:, 0] ** 2 + r[:, 1] ** 2))
    inertia = M * a**2 / 6.0  # cube about its axis
    assert omega / t == pytest.approx(torque[2] / inertia, rel=0.02)


def test_dipole_net_force_matches_m_dot_grad_B():
    a, dx, d = 1e-3, 1.25e-4, 1.0e-2  # cube side 1/10 of its distance to the dipole
    Br = np.array([0.0, 0.0, 0.2])
    centre = np.array([0.0, 0.0, d])
    lo, hi = centre - a / 2, centre + a / 2
    model = make_block_model(lo, hi, dx, ppc=2, density=1000.0, G=2e5, Br=Br)
    dipole = Dipole(moment=[0.0, 0.3, 0.5], position=[0.0, 0.0, 0.0])
    control = Control([dipole])
    solver = Solver(model)
    dt = 0.5 * solver.stable_dt(control)
    n = 20
    _, state = _run(model, control, dt, n)
    mass = model.host["mass"]
    force = (mass[:, None] * state.numpy()["v"]).sum(axis=0) / (n * dt)
    m = model.host["volumes"].sum() * Br / MU0
    expected = dipole.grad_B(centre[None])[0] @ m  # (m . grad) B_i = G_ij m_j, equal to (grad B)^T m as curl B = 0
    assert np.linalg.norm(force - expected) < 0.02 * np.linalg.norm(expected)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_2d_uniform_torque(precision):
    """Plane strain: dL_z/dt = (m x B)_z with m = A depth Br / mu0."""
    a, dx = 3e-3, 2e-4
    Br = np.array([0.1, 0.0, 0.0])
    B = np.array([0.0, 0.01, 0.0])
    model = make_block_model([0, 0], [a, a], dx, ppc=2, density=1000.0, G=1e6, Br=Br, precision=precision)
    control = Control([Uniform(B)])
    dt = 0.5 * Solver(model).stable_dt(control)
    n = 400
    _, state = _run(model, control, dt, n)
    s = state.numpy()
    mass = model.host["mass"]
    r = s["x"] - a / 2
    Lz = np.sum(mass * (r[:, 0] * s["v"][:, 1] - r[:, 1] * s["v"][:, 0])) + np.sum(mass * dx**2 / 4 * (s["C"][:, 1, 0] - s["C"][:, 0, 1]))
    torque = model.host["volumes"].sum() * Br[0] * B[1] / MU0
    assert Lz / (n * dt) == pytest.approx(torque, rel=5e-3 if precision == "float64" else 2e-2)
