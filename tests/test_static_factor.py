"""The static solver's sparse factorisation (magsoro.mpm.newton.static.factor): SuperLU in its symmetric mode, checked,
with the default LU where the check fails; and the determinant-sign parity the stability check reads from it."""

import numpy as np
import pytest
from scipy import sparse

from magsoro.mpm.newton.static import FACTOR_CHECK, _odd_negative_count, factor


def _laplacian_3d(n: int) -> sparse.csc_matrix:
    """The 7-point Laplacian on an n^3 grid (SPD), a stand-in for a stiffness with a symmetric pattern."""
    one = sparse.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sparse.identity(n)
    return (sparse.kron(sparse.kron(one, eye), eye) + sparse.kron(sparse.kron(eye, one), eye)
            + sparse.kron(sparse.kron(eye, eye), one)).tocsc()


def _residual(J, lu, seed=1) -> float:
    b = np.random.default_rng(seed).standard_normal(J.shape[0])
    return float(np.linalg.norm(J @ lu.solve(b) - b) / np.linalg.norm(b))


def test_symmetric_pattern_unsymmetric_values_solve_accurately():
    """A stiffness with friction-like unsymmetric entries on its symmetric pattern: the symmetric-mode LU solves
    it to rounding (well below FACTOR_CHECK)."""
    K = _laplacian_3d(8)
    rng = np.random.default_rng(0)
    A = K.tocoo()
    skew = sparse.csc_matrix((0.1 * rng.standard_normal(A.nnz) * (A.row != A.col), (A.row, A.col)), shape=K.shape)
    J = (K + skew).tocsc()
    lu = factor(J)
    assert _residual(J, lu) < 1e-12


def test_small_diagonal_falls_back_to_the_default_factorisation():
    """A diagonal far below its off-diagonal partners (a block [[eps, 10], [10, eps]], eps = 1e-12, in an otherwise
    SPD matrix): diagonal pivots leave a relative residual of 8e-5 (measured), above FACTOR_CHECK, and the
    factorisation made instead (partial pivoting) solves to rounding."""
    from scipy.sparse.linalg import splu

    K = _laplacian_3d(4).tolil()
    K[0, 0] = K[1, 1] = 1e-12
    K[0, 1] = K[1, 0] = 10.0
    J = K.tocsc()
    diagonal = splu(J, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    assert _residual(J, diagonal) > FACTOR_CHECK  # the case the check is for
    assert _residual(J, factor(J)) < 1e-12


@pytest.mark.parametrize("negatives", [0, 1, 2, 3])
def test_determinant_parity_from_the_factorisation(negatives):
    """_odd_negative_count on factor's LU: the parity of the negative eigenvalues of a symmetric indefinite
    matrix (the Laplacian shifted so that exactly ``negatives`` eigenvalues fall below zero)."""
    K = _laplacian_3d(5)
    vals = np.sort(np.linalg.eigvalsh(K.toarray()))
    distinct = np.unique(np.round(vals, 9))
    # a shift between distinct eigenvalues leaves ``negatives`` or more below zero; count them exactly
    shift = 0.0 if negatives == 0 else 0.5 * (distinct[negatives - 1] + distinct[negatives])
    S = (K - shift * sparse.identity(K.shape[0])).tocsc()
    count = int(np.sum(np.linalg.eigvalsh(S.toarray()) < 0))
    assert _odd_negative_count(S, factor(S)) == (count % 2 == 1)
