"""First Piola stress of every registered material law (magsoro.mpm.laws.elastic) against central differences of
its strain energy, through the engine's own device code; initial shear moduli against small-strain slopes."""

import numpy as np
import pytest
import warp as wp

from magsoro.mpm.kernels import make_kernels
from magsoro.mpm.laws.elastic import LAW_PARAM_COUNT, LAWS
from magsoro.validation.closed_form import central_difference_stress


def _evaluate(dim, Fs, G, K, model=0, prm=()):
    """``prm``: the law numbers, zero-padded to LAW_PARAM_COUNT."""
    k = make_kernels(dim, wp.float64)
    F = wp.array(np.asarray(Fs, dtype=np.float64), dtype=k["mat"])
    P = wp.zeros(len(Fs), dtype=k["mat"])
    psi = wp.zeros(len(Fs), dtype=wp.float64)
    wp.launch(k["stress_kernel"], dim=len(Fs), inputs=[F, model, G, K, k["vprm"](*_padded(prm)), P, psi])
    return P.numpy(), psi.numpy()


LAW_LIST = list(LAWS.values())


def _padded(prm):
    return tuple(prm) + (0.0,) * (LAW_PARAM_COUNT - len(prm))


def _example(law):
    return {p.key: p.example for p in law.parameters}


MODELS = {law.name: (law.code, law.pack(_example(law))) for law in LAW_LIST}


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", list(MODELS))
def test_stress_is_energy_derivative(dim, name):
    """First Piola stress of each engine material equals central differences of its energy (float64)."""
    model, prm = MODELS[name]
    rng = np.random.default_rng(3)
    G, K = 3.0e5, 6.0e6
    Fs = [np.eye(dim) + 0.3 * rng.standard_normal((dim, dim)) for _ in range(6)]
    Fs = [F if np.linalg.det(F) > 0.2 else np.eye(dim) for F in Fs]
    P, _ = _evaluate(dim, Fs, G, K, model, prm)
    h = 1e-6
    for n, F in enumerate(Fs):
        fd = central_difference_stress(lambda Fs_: _evaluate(dim, Fs_, G, K, model, prm)[1], F, h)
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


@pytest.mark.parametrize("name", ["mooney-rivlin", "yeoh"])
def test_small_strain_shear_modulus_of_other_models(name):
    """Simple shear at small strain: P_xy = mu0 gamma with mu0 = 2 (C10 + C01) or 2 C10."""
    model, prm = MODELS[name]
    mu0 = 2 * (prm[0] + prm[1]) if name == "mooney-rivlin" else 2 * prm[0]
    gamma = 1e-6
    F = np.eye(3)
    F[0, 1] = gamma
    P, _ = _evaluate(3, [F], 0.0, 4e6, model, prm)
    assert P[0][0, 1] == pytest.approx(mu0 * gamma, rel=1e-4)


def test_yeoh_stiffens_under_large_stretch():
    """Yeoh with C30 > 0 carries more nominal stress than Neo-Hookean of the same initial modulus at 200 % strain."""
    lam = 3.0
    F = np.diag([lam, lam**-0.5, lam**-0.5])
    Pn, _ = _evaluate(3, [F], 2.4e5, 5e6, 0, (0, 0, 0))
    Py, _ = _evaluate(3, [F], 0.0, 5e6, 2, (1.2e5, 0.0, 4.0e2))
    assert Py[0][0, 0] > Pn[0][0, 0]


def _evaluate_law(law, Fs):
    """Stress and energy of ``law`` at its example parameters, G its initial shear modulus, K = 4 G (comparable to
    G, so the isochoric part is not hidden behind the volumetric one)."""
    params = _example(law)
    G = law.initial_shear_modulus(params)
    return _evaluate(Fs[0].shape[0], Fs, G, 4.0 * G, law.code, law.pack(params))


def _near_and_stretched(dim):
    rng = np.random.default_rng(11)
    near = [np.eye(dim) + 0.05 * rng.standard_normal((dim, dim)) for _ in range(4)]
    stretched = np.diag([1.6, 0.7, 0.85][:dim]) + 0.1 * rng.standard_normal((dim, dim))
    return near + [stretched]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("law", LAW_LIST, ids=lambda law: law.name)
def test_stress_is_energy_derivative_near_rest_and_stretched(law, dim):
    Fs = _near_and_stretched(dim)
    assert all(np.linalg.det(F) > 0.3 for F in Fs)
    P, _ = _evaluate_law(law, Fs)
    for n, F in enumerate(Fs):
        fd = central_difference_stress(lambda Fs_: _evaluate_law(law, Fs_)[1], F, 1e-6)
        rel = np.abs(fd - P[n]).max() / np.abs(P[n]).max()
        assert rel < 1e-6, (law.name, n, rel)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("law", LAW_LIST, ids=lambda law: law.name)
def test_initial_shear_modulus_is_small_strain_slope(law, dim):
    P, psi = _evaluate_law(law, [np.eye(dim)])
    assert np.abs(P[0]).max() < 1e-9 * law.initial_shear_modulus(_example(law)) and abs(psi[0]) < 1e-6
    gamma = 1e-5
    F = np.eye(dim)
    F[0, 1] = gamma  # simple shear, J = 1
    P, _ = _evaluate_law(law, [F])
    assert P[0][0, 1] / gamma == pytest.approx(law.initial_shear_modulus(_example(law)), rel=1e-6)
