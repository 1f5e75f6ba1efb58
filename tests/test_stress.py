"""Neo-Hookean first Piola stress against central differences of its strain energy (the same device code)."""

import numpy as np
import pytest
import warp as wp

from magsoro.mpm.kernels import make_kernels


def _evaluate(dim, Fs, G, K):
    k = make_kernels(dim, wp.float64)
    F = wp.array(np.asarray(Fs, dtype=np.float64), dtype=k["mat"])
    P = wp.zeros(len(Fs), dtype=k["mat"])
    psi = wp.zeros(len(Fs), dtype=wp.float64)
    wp.launch(k["stress_kernel"], dim=len(Fs), inputs=[F, G, K, P, psi])
    return P.numpy(), psi.numpy()


@pytest.mark.parametrize("dim", [2, 3])
def test_neo_hookean_stress_is_energy_derivative(dim):
    rng = np.random.default_rng(3)
    G, K = 3.0e5, 6.0e6
    Fs = [np.eye(dim) + 0.3 * rng.standard_normal((dim, dim)) for _ in range(6)]
    Fs = [F if np.linalg.det(F) > 0.2 else np.eye(dim) for F in Fs]
    P, _ = _evaluate(dim, Fs, G, K)
    h = 1e-6
    for n, F in enumerate(Fs):
        perturbed = []
        for i in range(dim):
            for j in range(dim):
                for s in (+1, -1):
                    Fp = F.copy()
                    Fp[i, j] += s * h
                    perturbed.append(Fp)
        _, psi = _evaluate(dim, perturbed, G, K)
        fd = ((psi[0::2] - psi[1::2]) / (2 * h)).reshape(dim, dim)
        rel = np.abs(fd - P[n]).max() / np.abs(P[n]).max()
        assert rel < 1e-5, (n, rel)


def test_stress_free_at_rest_and_linear_limit():
    G, K = 2.0e5, 4.0e6
    P, psi = _evaluate(3, [np.eye(3)], G, K)
    assert np.abs(P[0]).max() < 1e-9 * G and abs(psi[0]) < 1e-12 * G
    # small simple shear gamma: P_xy -> G gamma
    gamma = 1e-5
    F = np.eye(3)
    F[0, 1] = gamma
    P, _ = _evaluate(3, [F], G, K)
    assert P[0][0, 1] == pytest.approx(G * gamma, rel=1e-4)
    # small uniaxial stretch with lateral constraint (plane strain in 2D): P_xx -> (K + 4G/3) eps
    eps = 1e-6
    P2, _ = _evaluate(2, [np.diag([1 + eps, 1.0])], G, K)
    assert P2[0][0, 0] == pytest.approx((K + 4 * G / 3) * eps, rel=1e-4)
