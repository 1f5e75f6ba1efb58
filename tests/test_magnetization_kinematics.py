"""Magnetisation kinematics per material (issue 25): the moment carried by F (Zhao's law, default) or by the
rotation R of F = R U (material.magnetization_follows = "R"); docs/engine.md, "Magnetisation kinematics"."""

import functools

import numpy as np
import pytest
import warp as wp

from magsoro.constants import MU0
from magsoro.mpm.interaction import polar_rotation_np
from magsoro.mpm.kernels.stencil import make_magnetization, make_types
from magsoro.mpm.laws.viscous import viscous_struct

wp.config.quiet = True


@functools.cache
def _kernels(dim: int, scalar=wp.float64):
    t = make_types(dim, scalar)
    mat, v3 = t.mat, t.v3
    g = make_magnetization(dim, scalar)
    rotation_stress, magnetic_energy, moment_map = g.rotation_stress, g.magnetic_energy, g.moment_map

    @wp.kernel
    def evaluate(F: wp.array(dtype=mat), follows: int, B: v3, Br: v3, P: wp.array(dtype=mat), W: wp.array(dtype=scalar),
                 M: wp.array(dtype=mat)):
        i = wp.tid()
        W[i] = magnetic_energy(F[i], follows, B, Br)
        M[i] = moment_map(F[i], follows)
        if follows != 0:
            P[i] = rotation_stress(F[i], B, Br)

    return evaluate, mat, v3


def _evaluate(F, follows, B, Br, scalar=wp.float64):
    """P (R law only), W and the moment map of each of ``F`` (n, dim, dim)."""
    F = np.asarray(F, dtype=np.float64)
    n, dim = F.shape[0], F.shape[1]
    k, mat, v3 = _kernels(dim, scalar)
    npd = np.float64 if scalar is wp.float64 else np.float32
    Fw = wp.array(F.astype(npd), dtype=mat, device="cpu")
    P = wp.zeros(n, dtype=mat, device="cpu")
    W = wp.zeros(n, dtype=scalar, device="cpu")
    M = wp.zeros(n, dtype=mat, device="cpu")
    wp.launch(k, dim=n, inputs=[Fw, int(follows), v3(*B), v3(*Br), P, W, M], device="cpu")
    return P.numpy().astype(np.float64), W.numpy().astype(np.float64), M.numpy().astype(np.float64)


def _rotation(dim, rng):
    if dim == 2:
        a = rng.uniform(-np.pi, np.pi)
        return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _samples(dim, rng):
    """Random F, near-identity F, F with repeated singular values (and the identity)."""
    out = [np.eye(dim)]
    for _ in range(6):
        out.append(np.eye(dim) + 0.35 * rng.standard_normal((dim, dim)))
    for _ in range(3):
        out.append(np.eye(dim) + 1e-4 * rng.standard_normal((dim, dim)))
    for _ in range(3):
        s = np.full(dim, rng.uniform(0.7, 1.4))
        if dim == 3:
            s[2] = rng.uniform(0.7, 1.4)  # two equal singular values
        out.append(_rotation(dim, rng) @ np.diag(s) @ _rotation(dim, rng).T)
    out.append(_rotation(dim, rng) @ np.diag(np.full(dim, 1.2)))  # all equal: a scaled rotation
    return [f for f in out if np.linalg.det(f) > 0.2]


@pytest.mark.parametrize("dim", [2, 3])
def test_rotation_law_stress_is_the_derivative_of_its_energy(dim):
    rng = np.random.default_rng(25 + dim)
    B, Br = np.array([0.013, -0.021, 0.017]), np.array([0.07, 0.11, -0.05])
    Fs = np.array(_samples(dim, rng))
    P, _, _ = _evaluate(Fs, 1, B, Br)
    h = 1e-6
    scale = np.linalg.norm(B) * np.linalg.norm(Br) / MU0
    for b in range(dim):
        for d in range(dim):
            Fp, Fm = Fs.copy(), Fs.copy()
            Fp[:, b, d] += h
            Fm[:, b, d] -= h
            dW = (_evaluate(Fp, 1, B, Br)[1] - _evaluate(Fm, 1, B, Br)[1]) / (2 * h)
            np.testing.assert_allclose(P[:, b, d] / scale, dW / scale, rtol=0, atol=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_rotation_is_the_polar_factor(dim):
    rng = np.random.default_rng(7)
    Fs = np.array(_samples(dim, rng))
    _, _, R = _evaluate(Fs, 1, np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(R, polar_rotation_np(Fs), atol=1e-12)
    U = np.transpose(R, (0, 2, 1)) @ Fs
    np.testing.assert_allclose(U, np.transpose(U, (0, 2, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    # float32 compiles and agrees to its precision (wp.svd3 in float32 gives R = I to 3e-7 at F = I)
    _, _, R32 = _evaluate(Fs, 1, np.zeros(3), np.zeros(3), scalar=wp.float32)
    np.testing.assert_allclose(R32, R, atol=2e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_rotation_F_and_R_agree(dim):
    """At F = R: the same energy, moment and torque (skew part of P F^T) to 1e-10. The stresses themselves
    differ by a symmetric part: Zhao's law has a magnetostrictive stress (W changes under a stretch along Br),
    the R law none, so P_F - P_R = -(1/mu0) sym(B (x) R Br) R."""
    rng = np.random.default_rng(11)
    B, Br = np.array([0.013, -0.021, 0.017]), np.array([0.07, 0.11, -0.05])
    Rs = np.array([_rotation(dim, rng) for _ in range(8)] + [np.eye(dim)])
    PR, WR, MR = _evaluate(Rs, 1, B, Br)
    _, WF, MF = _evaluate(Rs, 0, B, Br)
    PF = -np.einsum("a,b->ab", B[:dim], Br[:dim])[None] / MU0 * np.ones((len(Rs), 1, 1))
    scale = np.linalg.norm(B) * np.linalg.norm(Br) / MU0
    np.testing.assert_allclose(MR, MF, atol=1e-10)
    np.testing.assert_allclose(WR / scale, WF / scale, atol=1e-10)
    tF, tR = PF @ np.transpose(Rs, (0, 2, 1)), PR @ np.transpose(Rs, (0, 2, 1))
    skew = lambda a: 0.5 * (a - np.transpose(a, (0, 2, 1)))  # noqa: E731
    sym = lambda a: 0.5 * (a + np.transpose(a, (0, 2, 1)))  # noqa: E731
    np.testing.assert_allclose(skew(tR) / scale, skew(tF) / scale, atol=1e-10)
    np.testing.assert_allclose(sym(tR) / scale, 0.0, atol=1e-10)  # the R law has no magnetostriction
    assert np.abs(sym(tF)).max() / scale > 0.1


# ------------------------------------------------------------------------------------------- scenes
def _square_scene(follows, precision="float64", G=2.0e6, B=(0.0, 0.05, 0.0), Br=0.1):
    """A 2D 4 mm square magnetised along x in a uniform field along y (a torque, no gravity)."""
    from magsoro.scene import parse_scene

    return parse_scene({
        "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.02, 0.02], "duration": 0.01,
                       "damping": 0.0, "gravity": [0.0, 0.0], "precision": precision},
        "bodies": [{"name": "square", "shape": {"type": "rectangle", "center": [0.01, 0.01], "size": [0.004, 0.004]},
                    "material": {"density": 1000.0, "shear_modulus": G, "magnetization_follows": follows},
                    "magnetization": {"type": "uniform", "direction": [1.0, 0.0, 0.0], "magnitude": Br}}],
        "fields": [{"type": "uniform", "B": list(B)}],
    })


def test_scene_key_reaches_the_particles():
    from magsoro.scene.build import build

    assert np.all(build(_square_scene("R")).model.host["magnetization_follows"] == 1)
    assert np.all(build(_square_scene("F")).model.host["magnetization_follows"] == 0)


def test_bad_input_is_one_line_naming_the_key():
    from magsoro.errors import SceneError

    with pytest.raises(SceneError) as err:
        _square_scene("U")
    msg = str(err.value)
    assert "bodies[0].material.magnetization_follows" in msg and "'F'" in msg and "'R'" in msg and "\n" not in msg, msg


def test_static_solver_and_rollout_refuse_R():
    from magsoro.diff.rollout import Rollout
    from magsoro.errors import SimulationError
    from magsoro.scene.build import build
    from magsoro.simulation import Simulation

    scene = _square_scene("R")
    scene.simulation.formulation = "total"
    with pytest.raises(SimulationError, match="magnetization_follows = 'R'"):
        Simulation(scene, device="cpu").solve_static(levels=[1.0], t=0.0)
    with pytest.raises(ValueError, match="magnetization_follows = 'R'"):
        Rollout(build(_square_scene("R")), dt=1e-6, n_steps=2)


def test_rigid_rotation_same_trajectory():
    """A stiff square (G 2 MPa, Br 0.1 T, B 50 mT across it) turning in a uniform field: under the R law the
    moment, torque and energy equal the F law's at any rigid rotation; the runs differ only by Zhao's law's
    magnetostrictive strain, of order B Br / (mu0 G) = 2e-3 here, over the body's 4 mm: a few micrometres at most
    while the square turns by tens of milliradians... bounded here by 0.5 % of the displacement scale."""
    from magsoro.simulation import Simulation

    out = {}
    for follows in ("F", "R"):
        sim = Simulation(_square_scene(follows), device="cpu")
        x0 = sim.state.numpy()["x"].copy()
        for _ in range(150):
            sim.step(2e-6)
        out[follows] = sim.state.numpy()["x"] - x0
    disp = np.abs(out["F"]).max()
    assert disp > 1e-6  # it turns
    eps = 0.05 * 0.1 / (MU0 * 2.0e6)
    diff = np.abs(out["F"] - out["R"]).max()
    assert diff < 4 * eps * 0.004, (diff, disp, eps)


def _dipole(m, r):
    """B (T) and grad B (T/m, G[i, j] = dB_i/dx_j) of a point dipole ``m`` (A m^2) at the origin, at ``r``."""
    k = MU0 / (4 * np.pi)
    d = np.linalg.norm(r)
    n = r / d
    B = k * (3 * n * (m @ n) - m) / d**3
    G = k * (3 * (np.outer(m, n) + np.outer(n, m) + (m @ n) * np.eye(3)) - 15 * (m @ n) * np.outer(n, n)) / d**4
    return B, G


@pytest.mark.parametrize("follows", ["F", "R"])
def test_stretched_bar_gradient_force_in_a_dipole_field(follows):
    """A bar of 8 particles along x, magnetised along x (Br 0.1 T), stretched along it by lambda = 1.3 (F =
    diag(lambda, lambda^-1/2, lambda^-1/2)), in the field of a point dipole on its axis: the engine's p2g puts the
    net gradient force (grad B)^T m on the grid (the stress impulse sums to zero), with m = lambda Br V0 / mu0 e_x
    under F and Br V0 / mu0 e_x under R; |m_F| / |m_R| = lambda."""
    from magsoro.mpm.model import Model
    from magsoro.mpm.runtime import block_struct, bodies_array, contact_grid

    lam, Br, h = 1.3, 0.1, 1e-3
    X = np.stack([0.02 + h * np.arange(8), np.full(8, 0.02), np.full(8, 0.02)], 1)
    model = Model(X, h**3, 1000.0, 1e4, 2e4, [Br, 0, 0], 0, np.zeros(8, bool), dx=2e-3, domain_lo=[0, 0, 0],
                  domain_hi=[0.04] * 3, precision="float64", device="cpu",
                  magnetization_follows=1 if follows == "R" else 0)
    k = model.kernels
    F = np.tile(np.diag([lam, lam**-0.5, lam**-0.5]), (8, 1, 1))
    m_dip = np.array([2.0, 0.0, 0.0])
    BG = [_dipole(m_dip, x - np.array([0.0, 0.02, 0.02])) for x in X]
    applied = k["Applied"]()
    applied.B_uniform = k["v3"](0.0, 0.0, 0.0)
    applied.has_gradient = 1
    applied.B = wp.array(np.array([b for b, _ in BG]), dtype=k["v3"], device="cpu")
    applied.grad_B = wp.array(np.array([g for _, g in BG]), dtype=k["m3"], device="cpu")
    shape = (22, 22, 22)
    block = block_struct(model, (0, 0, 0), shape)
    n = int(np.prod(shape))
    grid = k["GridArrays"]()
    grid.p, grid.m = wp.zeros(n, dtype=k["vec"], device="cpu"), wp.zeros(n, dtype=wp.float64, device="cpu")
    grid.clamp = wp.zeros(n, dtype=wp.int32, device="cpu")
    zv, zC = wp.zeros(8, dtype=k["vec"], device="cpu"), wp.zeros(8, dtype=k["mat"], device="cpu")
    Fw = wp.array(F, dtype=k["mat"], device="cpu")
    err = wp.zeros(2, dtype=wp.int32, device="cpu")
    src = k["Particles"]()
    src.x, src.v, src.C, src.F = model.X0, zv, zC, Fw
    wp.launch(k["p2g"], dim=8, device="cpu", inputs=[wp.array([src], dtype=k["Particles"], device="cpu"), bodies_array(model),
                                                     applied, block, wp.float64(1.0),
                                                     wp.array([grid], dtype=k["GridArrays"], device="cpu"),
                                                     err, 1, contact_grid(model), viscous_struct(model, None),
                                                     wp.zeros(0, dtype=k["mat"], device="cpu"),
                                                     wp.zeros(0, dtype=k["vec"], device="cpu")])
    total = grid.p.numpy().sum(axis=0)
    stretch = lam if follows == "F" else 1.0
    m = np.array([stretch * Br * h**3 / MU0, 0.0, 0.0])
    expected = sum(g.T @ m for _, g in BG)
    np.testing.assert_allclose(total, expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())
    # and the bodies' own field sees the same moments (the interaction's deposit and the self-torque's moments)
    from magsoro.mpm.interaction import MagneticInteraction

    mi = MagneticInteraction(model)
    np.testing.assert_allclose(mi.moments(F), np.tile(m, (8, 1)), rtol=1e-12)
    probe = np.array([[0.005, 0.02, 0.02]])
    Bs = mi.field_at(probe, model.X0, Fw)
    R = wp.array(np.tile(np.eye(3), (8, 1, 1)), dtype=k["mat"], device="cpu")
    B1 = mi.field_at(probe, model.X0, R)
    np.testing.assert_allclose(Bs, stretch * B1, rtol=1e-9, atol=1e-9 * np.abs(B1).max())
