import os

import numpy as np
import pytest
import warp as wp

wp.config.quiet = True
os.environ.setdefault("MPLBACKEND", "Agg")


def lattice_block(lo, hi, h):
    """Points at cell centres of spacing h filling the box [lo, hi]."""
    axes = [np.arange(l + 0.5 * h, u, h) for l, u in zip(lo, hi)]
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def make_block_model(lo, hi, dx, ppc=2, *, density=1000.0, G=1e5, K=None, Br=(0, 0, 0), precision="float64", domain=None, clamped=None):
    """A single-material block model for engine tests."""
    from magsoro.mpm.model import Model

    dim = len(lo)
    h = dx / ppc
    X = lattice_block(lo, hi, h)
    dlo, dhi = domain if domain is not None else (np.array(lo) - 10 * dx, np.array(hi) + 10 * dx)
    return Model(
        X, h**dim, density, G, 20 * G if K is None else K, np.asarray(Br, dtype=float), 0,
        np.zeros(len(X), bool) if clamped is None else clamped(X),
        dx=dx, domain_lo=dlo, domain_hi=dhi, precision=precision, device="cpu",
    )


def run_solver(model, control, settings, dt, steps):
    """Step a one-thread Solver ``steps`` times by ``dt`` from the reference state; returns the final State."""
    from magsoro.mpm.solver import Solver

    settings.threads = 1
    solver = Solver(model, settings)
    a, b = solver.new_state(), solver.new_state()
    for _ in range(steps):
        solver.step(a, b, control, dt)
        a, b = b, a
    return a


@pytest.fixture
def block_model():
    return make_block_model
