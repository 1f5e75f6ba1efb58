"""Linear solvers for the Newton tangents of the static solver and the implicit integrator.

A Newton step solves J du = -R with J = dR/du, the tangent on the unknowns (node displacements, ``dim`` per node,
node after node: unknown k's components are rows k dim .. k dim + dim - 1). J is the negative of a stiffness: -J
is symmetric positive definite at a stable equilibrium without colliders; friction colliders make it unsymmetric.

Two kinds, one interface (:class:`LinearSolver`: ``solve(b)``, ``kind``, ``iterations``, ``setup_time``):

- ``"direct"``: sparse LU (:func:`factor`: SuperLU in its symmetric mode, checked). Exact to rounding, and the only
  one that gives the determinant's sign the stability check reads (:attr:`DirectSolver.lu`). Its cost grows
  faster than the unknowns (fill), and its memory too.
- ``"iterative"``: a Krylov method on A = -J preconditioned by one V-cycle of smoothed-aggregation algebraic
  multigrid (PyAMG; Vanek, Mandel and Brezina 1996). CG when J is symmetric, restarted flexible GMRES otherwise
  (the hierarchy is built on J itself then: Galerkin coarse levels R A P with R = P^T). What makes it work on these tangents:

  * the near-null space: the rigid-body modes of the unknowns (translations and infinitesimal rotations about
    the nodes' positions; 3 in 2D, 6 in 3D, :func:`rigid_body_modes`), smoothed by a few block Gauss-Seidel
    sweeps of A v = 0 (so that they vanish at the clamps) before the hierarchy is built;
  * geometric aggregation on the node lattice (``grid``: each aggregate the nodes of a 2^dim block of cells,
    each coarser level again): the quadratic B-spline couples every node with the 5^dim around it, and PyAMG's
    standard aggregation on that graph makes aggregates of ~100 nodes (27 for the whole 3D cantilever), whose
    coarse space cannot follow a bending beam (400 iterations without converging);
  * nodal block Gauss-Seidel as the smoother, run as point Gauss-Seidel on D^-1 A (D the dim x dim diagonal
    blocks): the same sweep as PyAMG's block smoother, 5 to 10 times faster than it on these matrices;
  * an exact coarsest solve (sparse LU): PyAMG's default pseudo-inverse cuts the small singular values of the
    badly conditioned coarse matrices, and the preconditioner stops being definite (CG's residual grew again
    after 40 iterations).

  The relative tolerance of each solve is the caller's (the Newton loop chooses it: Eisenstat and Walker's
  forcing terms, :func:`forcing_term`). A Krylov solve that misses it is done again by the direct solver, and the
  solver says so (:attr:`LinearSolver.fallbacks`). :meth:`IterativeSolver.update` keeps the hierarchy for the
  next tangent of a Newton solve (the tangent changes little from one iteration to the next; the Krylov method
  runs on the new one), rebuilt when its iterations grow.

``"auto"`` is direct up to :data:`DIRECT_MAX_UNKNOWNS` unknowns and iterative above (measured: the crossover of
one Newton iteration's solve on this project's 2-core CPU, benchmarks/linear_scaling.py, benchmarks/README.md).
"""

from __future__ import annotations

import time

import numpy as np

#: the static solver's "auto" chooses the direct solver up to this many unknowns, the iterative one above: one Newton
#: iteration's solve on the 3D cantilever took 0.36 s direct and 0.44 s iterative at 6,960 unknowns, 2.0 s and 1.1 s
#: at 16,167 (benchmarks/linear_scaling.py; benchmarks/README.md, "Linear solvers"). The implicit integrator,
#: which keeps a factorisation for many solves, has its own (magsoro.mpm.newton.implicit.DIRECT_MAX_UNKNOWNS)
DIRECT_MAX_UNKNOWNS = 8_000
#: the relative tolerance |A x - b| / |b| of an iterative solve when the caller gives none
ITERATIVE_RTOL = 1.0e-8
#: the tightest relative tolerance an iterative solve is asked for: about what a backward-stable direct solve
#: leaves on these tangents (the cantilevers' at their field: 8e-10 in 2D, 2.5e-10 in 3D; condition numbers near
#: 1e8), below which CG's true residual stagnates (1e-9 and 1e-10 missed in 300 iterations in 2D)
RTOL_FLOOR = 1.0e-9
#: J counts as symmetric (CG) when two random probes find |x^T J y - y^T J x| <= SYMMETRY_RTOL |J x| |y|
#: (is_symmetric; the elastic tangent's central differences leave ~1e-16 of J unsymmetric, friction tens of %)
SYMMETRY_RTOL = 1.0e-10
#: Krylov iterations of one solve before it falls back to the direct solver
MAX_KRYLOV = 300
#: flexible GMRES's restart length
GMRES_RESTART = 60
#: lattice aggregation: nodes per aggregate along each axis (lattice_aggregates), and whether the tentative
#: prolongator is smoothed (one damped Jacobi step: "smoothed" aggregation)
AGGREGATE_BLOCK = 3
SMOOTH_PROLONGATOR = True
#: Gauss-Seidel sweeps of the V-cycle before and after each coarse correction (forward before, backward after)
CYCLE_SWEEPS = 1
#: the coarsest level has at most this many unknowns (solved by sparse LU)
COARSE_UNKNOWNS = 600
#: block Gauss-Seidel sweeps (symmetric) that smooth the rigid-body modes before the hierarchy is built
CANDIDATE_SWEEPS = 1
#: the hierarchy is kept for the next tangent (IterativeSolver.update) while a solve takes at most this many times
#: the iterations per digit of residual reduction of the first solve after it was built (and at least REBUILD_MIN
#: more: IterativeSolver.stale)
REBUILD_GROWTH = 1.5
REBUILD_MIN = 10
#: Eisenstat and Walker's forcing terms (choice 2): eta_k = GAMMA (|r_k| / |r_k-1|)^ALPHA, at most ETA_MAX,
#: safeguarded by GAMMA eta_k-1^ALPHA where that is above ETA_SAFEGUARD
EW_GAMMA = 0.9
EW_ALPHA = 2.0
ETA_MAX = 1.0e-2
ETA_SAFEGUARD = 0.1

KINDS = ("auto", "direct", "iterative")

#: the factorisation's check (factor): the largest relative residual |J x - b| / |b| of a solve accepted from the
#: symmetric-mode LU before the default one is made instead
FACTOR_CHECK = 1.0e-9
#: an Ordering serves matrices whose number of entries differs from the pattern it was found for by at most this
#: fraction
PATTERN_DRIFT = 0.05
#: a kept order is forgotten when a factorisation in it fills more than this many times what it was kept for
#: (Ordering.check_fill)
FILL_GROWTH = 1.5


def factor(J, ordering: "Ordering | None" = None):
    """Sparse LU of a tangent ``J`` (CSC), as scipy's ``splu`` object (``solve``, ``L``, ``U``, ``perm_r``,
    ``perm_c``) or a :class:`PermutedLU` with the same. The tangents here have a symmetric pattern and a diagonal
    that carries them (stiffness, springs), so SuperLU runs in its symmetric mode: fill-reducing minimum-degree
    ordering of J + J^T, pivots on the diagonal. On the triangle robot's tangent at 15 mT (7629 unknowns, 1.7 M
    entries, 3D) that leaves 20 % less fill and factorises in 0.27 s against 0.41 s for the default (column ordering
    of J^T J, partial pivoting); the relative residuals of a solve were 1.7e-13 and 4.2e-13 (`python
    benchmarks/static_factor.py`, file benchmarks/results/2026-11-28-cpu-909c75f-static-factor.json).

    ``ordering``: an :class:`Ordering` that keeps the symmetric permutation found for J's sparsity pattern; a later
    J of the same pattern is factorised in that order with no ordering step of its own.

    A factorisation whose solve of a random right-hand side leaves a relative residual above FACTOR_CHECK (a pivot
    too small on the diagonal: an indefinite or strongly unsymmetric tangent), or that fails, is made again the
    default way. Raises RuntimeError when that fails too (a singular tangent)."""
    from scipy.sparse.linalg import splu

    J = J.tocsc()
    symmetric = {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
    try:
        perm = ordering.permutation(J) if ordering is not None else None
        if perm is not None:
            lu = PermutedLU(splu(J[perm][:, perm].tocsc(), permc_spec="NATURAL", **symmetric), perm)
            ordering.check_fill(int(lu.L.nnz + lu.U.nnz))
        else:
            lu = splu(J, permc_spec="MMD_AT_PLUS_A", **symmetric)
            if ordering is not None:
                ordering.learn(J, lu)
        b = np.random.default_rng(0).standard_normal(J.shape[0])
        x = lu.solve(b)
        size = float(np.linalg.norm(b))
        if np.all(np.isfinite(x)) and float(np.linalg.norm(J @ x - b)) <= FACTOR_CHECK * size:
            return lu
    except RuntimeError:
        pass
    return splu(J)


class PermutedLU:
    """SuperLU's factorisation of P J P^T (P the symmetric permutation ``perm``: row k of P J P^T is row perm[k] of
    J) with J's solve. ``L``, ``U``, ``perm_r`` and ``perm_c`` are the permuted matrix's: det(P J P^T) = det J, so
    they give J's determinant sign as the unpermuted factors would."""

    def __init__(self, lu, perm: np.ndarray):
        self.lu, self.perm = lu, perm
        self.L, self.U, self.perm_r, self.perm_c = lu.L, lu.U, lu.perm_r, lu.perm_c

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b)
        x = np.empty_like(b, dtype=np.float64)
        x[self.perm] = self.lu.solve(b[self.perm])
        return x


class Ordering:
    """The fill-reducing symmetric ordering of one sparsity pattern, found once and reused by :func:`factor` for
    every matrix of that pattern (a Newton solve's tangents all share theirs). The first factorisation orders by
    SuperLU's minimum degree on J + J^T and is kept as the inverse of its column permutation; when a second matrix
    of the pattern comes, reverse Cuthill-McKee is weighed against it and kept where its fill (its envelope) is
    smaller. A slender body's tangent is nearly banded: on the 3D strip of benchmarks/implicit_vs_explicit.py (8937
    unknowns) RCM left 6.6 M entries in L and U against minimum degree's 7.9 M and factorised in 0.37 s against
    0.54 s. (Weighing takes about 0.2 s there, spent only by runs that factorise more than once.)"""

    def __init__(self):
        self.perm = None
        self.kind = ""
        self.fill = self.nnz = 0
        self.weighed = False  # whether reverse Cuthill-McKee was weighed against minimum degree
        self.relearnt = 0  # orders forgotten because they filled too much (check_fill)

    def permutation(self, J) -> "np.ndarray | None":
        """The ordering kept for J's pattern, or None when it has none for it. Any symmetric ordering gives the
        same solution, so a pattern that differs from the learnt one by a few entries (exact zeros that sparse
        arithmetic dropped, a contact spring's block) keeps it; one of another size, or more than PATTERN_DRIFT
        more or fewer entries, is learnt anew."""
        if self.perm is None or J.shape[0] != len(self.perm) or abs(J.nnz - self.nnz) > PATTERN_DRIFT * self.nnz:
            return None
        if not self.weighed:
            self._weigh(J)
        return self.perm

    def check_fill(self, fill: int) -> None:
        """After a factorisation in the kept order: forget the order when it filled more than FILL_GROWTH times what
        it was kept for, so that the next tangent learns one for its own pattern. Springs between the layers of a
        fold (self-contact) couple nodes far apart in the reference lattice, a few entries that the kept order
        (learnt without them) turns into fill: on the everting tube (scenes/everting_tube.toml) that made the
        factorisations 84 % of a step."""
        if self.fill and fill > FILL_GROWTH * self.fill:
            self.perm, self.kind, self.fill, self.nnz = None, "", 0, 0
            self.relearnt += 1

    def learn(self, J, lu) -> None:
        """Keep the minimum-degree ordering of J's pattern from ``lu``, J's factorisation in that order."""
        self.nnz = J.nnz
        self.perm, self.kind, self.fill = np.argsort(lu.perm_c), "minimum degree", int(lu.L.nnz + lu.U.nnz)
        self.weighed = False

    def _weigh(self, J) -> None:
        """Keep reverse Cuthill-McKee for J's pattern instead where its envelope holds less fill."""
        from scipy.sparse.csgraph import reverse_cuthill_mckee

        self.weighed = True
        n = J.shape[0]
        if n == 0:
            return
        pattern = J.copy()
        pattern.data = np.ones_like(pattern.data)
        rcm = reverse_cuthill_mckee((pattern + pattern.T).tocsr(), symmetric_mode=True)
        P = pattern[rcm][:, rcm].tocsc()
        P.sort_indices()
        counts = np.diff(P.indptr)
        top = P.indices[np.minimum(P.indptr[:-1], max(P.nnz - 1, 0))] if P.nnz else np.arange(n)
        first = np.where(counts > 0, np.minimum(top, np.arange(n)), np.arange(n))  # each column's first row
        envelope = int(np.sum(np.arange(n) - first))
        fill = 2 * (envelope + n)  # L and U within the envelope, diagonals counted in both as SuperLU stores them
        if fill < self.fill:
            self.perm, self.kind, self.fill = np.asarray(rcm, dtype=np.int64), "reverse Cuthill-McKee", fill


def rigid_body_modes(positions) -> np.ndarray:
    """The rigid-body modes of ``n`` nodes at ``positions`` (n, dim), m: an (n dim, 3) array in 2D (two
    translations, the rotation about z), (n dim, 6) in 3D (three translations, the rotations about x, y, z), the
    components of node k in rows k dim .. k dim + dim - 1. Rotations are taken about the nodes' centroid and
    every column is scaled to unit length (the multigrid setup orthonormalises them per aggregate; this keeps
    the arithmetic well scaled)."""
    X = np.asarray(positions, dtype=np.float64)
    n, dim = X.shape
    if dim not in (2, 3):
        raise ValueError(f"rigid_body_modes: positions must be (n, 2) or (n, 3), not {X.shape}")
    X = X - X.mean(axis=0)
    if dim == 2:
        B = np.zeros((n * 2, 3))
        B[0::2, 0] = 1.0
        B[1::2, 1] = 1.0
        B[0::2, 2], B[1::2, 2] = -X[:, 1], X[:, 0]
    else:
        B = np.zeros((n * 3, 6))
        for a in range(3):
            B[a::3, a] = 1.0
        x, y, z = X[:, 0], X[:, 1], X[:, 2]
        B[1::3, 3], B[2::3, 3] = -z, y  # about x
        B[0::3, 4], B[2::3, 4] = z, -x  # about y
        B[0::3, 5], B[1::3, 5] = -y, x  # about z
    norms = np.linalg.norm(B, axis=0)
    return B / np.where(norms > 0.0, norms, 1.0)


def lattice_aggregates(cells, coarsest: int = 1, min_nodes: int = 1, block: int = 2) -> list:
    """Geometric aggregation of nodes on a lattice: the nodes whose integer coordinates ``cells`` (n, dim) fall in
    one 2^dim block form an aggregate; each coarser level groups the blocks the same way, until at most
    ``coarsest`` aggregates are left. On the first level an aggregate of fewer than ``min_nodes`` nodes joins the
    largest neighbouring block's (the rigid-body modes of one or two nodes are linearly dependent: 3D needs three
    nodes not on a line, which a 2^3 block's three nodes never are). Returns, per level, the aggregation operator
    (CSR, nodes x aggregates, ones) as PyAMG's ``aggregate=('predefined', {'AggOp': ...})`` wants it."""
    from itertools import product

    from scipy import sparse

    key = np.asarray(cells, dtype=np.int64)
    dim = key.shape[1]
    out = []
    first = True
    while True:
        key = key // block
        uniq, agg = np.unique(key, axis=0, return_inverse=True)
        agg = np.asarray(agg).ravel()
        if first and min_nodes > 1:
            size = np.bincount(agg, minlength=len(uniq))
            index = {tuple(k): i for i, k in enumerate(uniq.tolist())}
            target = np.arange(len(uniq))
            for i in np.flatnonzero(size < min_nodes):
                around = [index.get(tuple(uniq[i] + np.array(o))) for o in product((-1, 0, 1), repeat=dim) if any(o)]
                around = [j for j in around if j is not None and size[j] >= min_nodes]
                if around:
                    target[i] = max(around, key=lambda j: size[j])
            kept, agg = np.unique(target[agg], return_inverse=True)
            agg = np.asarray(agg).ravel()
            uniq = uniq[kept]
        first = False
        n = len(agg)
        out.append(sparse.csr_matrix((np.ones(n), (np.arange(n), agg)), shape=(n, len(uniq))))
        if len(uniq) <= coarsest or len(uniq) == n:
            return out
        key = uniq


def forcing_term(norm: float, last_norm: float | None, last_eta: float | None, floor: float = 0.0) -> float:
    """Eisenstat and Walker's forcing term (their choice 2, 1996) for the Newton step at residual norm ``norm``
    after one at ``last_norm`` solved to ``last_eta``: the relative tolerance of the linear solve, loose far from
    the solution and tight near it so that Newton keeps its quadratic convergence. EW_GAMMA (norm /
    last_norm)^EW_ALPHA, at most ETA_MAX (ETA_MAX at the first step), safeguarded against dropping faster than the
    convergence does, and never below ``floor`` (the tolerance that is enough for the Newton solve to converge
    this step) nor RTOL_FLOOR."""
    if last_norm is None or last_eta is None or last_norm <= 0.0:
        eta = ETA_MAX
    else:
        eta = EW_GAMMA * (norm / last_norm) ** EW_ALPHA
        guard = EW_GAMMA * last_eta ** EW_ALPHA
        if guard > ETA_SAFEGUARD:
            eta = max(eta, guard)
        eta = min(eta, ETA_MAX)
    return float(max(eta, floor, RTOL_FLOOR))


def is_symmetric(J, rtol: float = SYMMETRY_RTOL) -> bool:
    """Whether J is symmetric to ``rtol``, by two random probes: |x^T J y - y^T J x| <= rtol |J x| |y| (two
    products, where forming J - J^T cost a fifth of a Newton iteration's linear solve on the hexahedron's tangent;
    an unsymmetric part of relative size s shows as about s / sqrt(n) of the scale, so friction's, 36 % of J on
    the pentahedron, stands out by orders of magnitude, and the central differences' 1e-16 does not)."""
    n = J.shape[0]
    if n == 0:
        return True
    rng = np.random.default_rng(12345)
    x, y = rng.standard_normal(n), rng.standard_normal(n)
    Jx = J @ x
    scale = float(np.linalg.norm(Jx)) * float(np.linalg.norm(y))
    return abs(float(y @ Jx) - float(x @ (J @ y))) <= rtol * scale


class LinearSolver:
    """A solver of J x = b for one tangent J. ``kind``: "direct" or "iterative"; ``iterations``: Krylov iterations
    of the last :meth:`solve` (0 for direct); ``total_iterations`` and ``solves`` over its life; ``setup_time``:
    seconds to build it (factorisation, or multigrid hierarchy); ``fallbacks``: solves the iterative method missed
    and the direct solver did instead; ``message``: why, for the last one."""

    kind = "direct"

    def __init__(self):
        self.iterations = 0
        self.total_iterations = 0
        self.solves = 0
        self.setup_time = 0.0
        self.solve_time = 0.0
        self.fallbacks = 0
        self.message = ""

    @property
    def shape(self):
        return self.J.shape

    def solve(self, b: np.ndarray, rtol: float | None = None, x0: np.ndarray | None = None) -> np.ndarray:
        raise NotImplementedError

    def operator(self):
        """``solve`` as a scipy LinearOperator (a preconditioner for a Krylov method on a larger Jacobian)."""
        from scipy.sparse.linalg import LinearOperator

        return LinearOperator(self.J.shape, matvec=lambda v: self.solve(np.asarray(v).ravel()), dtype=np.float64)


class DirectSolver(LinearSolver):
    """:func:`factor` of J (in the order ``ordering`` keeps for its pattern); ``lu`` the factorisation (its U's
    diagonal and permutations give the determinant's sign)."""

    kind = "direct"

    def __init__(self, J, ordering: "Ordering | None" = None):
        super().__init__()
        t0 = time.perf_counter()
        self.J = J.tocsc()
        self.lu = factor(self.J, ordering)
        self.setup_time = time.perf_counter() - t0

    def solve(self, b, rtol=None, x0=None):
        t0 = time.perf_counter()
        x = self.lu.solve(np.asarray(b, dtype=np.float64))
        self.iterations = 0
        self.solves += 1
        self.solve_time += time.perf_counter() - t0
        return x


class _BlockGaussSeidel:
    """Nodal block Gauss-Seidel sweeps on A x = b as point Gauss-Seidel on D^-1 A x = D^-1 b (D: A's dim x dim
    diagonal blocks): within a node the scaled diagonal block is the identity, so a point sweep is the block
    sweep. ``sweep``: 'forward', 'backward' or 'symmetric'. Called as PyAMG calls a smoother, (A, x, b), x in
    place."""

    def __init__(self, A, blocksize: int, sweep: str = "symmetric", iterations: int = 1):
        from scipy import sparse

        A = A.tocsr()
        n = A.shape[0] // blocksize
        Ab = A.tobsr(blocksize=(blocksize, blocksize))
        rows = np.repeat(np.arange(n), np.diff(Ab.indptr))
        on = rows == Ab.indices
        D = np.zeros((n, blocksize, blocksize))
        D[rows[on]] = Ab.data[on]
        # an empty node (no diagonal block) keeps its value: identity there
        empty = np.abs(D).reshape(n, -1).max(axis=1) == 0.0
        D[empty] = np.eye(blocksize)
        try:
            Dinv = np.linalg.inv(D)
        except np.linalg.LinAlgError:  # a coarse node with dependent candidates: its zero rows stay unchanged
            Dinv = np.linalg.pinv(D, rcond=1e-12, hermitian=True)
        self.Dinv = sparse.bsr_matrix((Dinv, np.arange(n), np.arange(n + 1)), shape=A.shape).tocsr()
        self.S = (self.Dinv @ A).tocsr()
        self.S.sort_indices()
        self.n, self.sweep, self.iterations = A.shape[0], sweep, iterations

    def __call__(self, A, x, b, sweep: str | None = None):
        from pyamg import amg_core

        S, n = self.S, self.n
        sweep = self.sweep if sweep is None else sweep
        bb = self.Dinv @ np.asarray(b).ravel()
        for _ in range(self.iterations):
            if sweep in ("forward", "symmetric"):
                amg_core.gauss_seidel(S.indptr, S.indices, S.data, x, bb, 0, n, 1)
            if sweep in ("backward", "symmetric"):
                amg_core.gauss_seidel(S.indptr, S.indices, S.data, x, bb, n - 1, -1, -1)


class _VCycle:
    """One V-cycle of a PyAMG hierarchy whose levels carry their smoothers (_BlockGaussSeidel): on each level a
    forward sweep before the coarse correction and a backward one after it (the cycle is then a symmetric
    operator for a symmetric A: a preconditioner for CG), CYCLE_SWEEPS of each; the coarsest level solved by sparse
    LU. Used as ``M @ r`` (a scipy LinearOperator's interface); written here rather than PyAMG's ``aspreconditioner``,
    whose every application also forms the fine residual twice and its norms (a third of the cycle's time on the
    pentahedron's tangent)."""

    def __init__(self, ml):
        from scipy.sparse.linalg import splu

        self.levels = ml.levels
        coarse = ml.levels[-1].A.tocsc()
        self.shape = ml.levels[0].A.shape
        self.dtype = np.dtype(np.float64)
        try:
            lu = splu(coarse)
            self.coarse = lu.solve
        except RuntimeError:  # a singular coarsest matrix (dependent candidates): its pseudo-inverse
            pinv = np.linalg.pinv(coarse.toarray(), rcond=1e-13, hermitian=True)
            self.coarse = lambda b: pinv @ b

    def _cycle(self, k: int, b: np.ndarray) -> np.ndarray:
        if k == len(self.levels) - 1:
            return self.coarse(b)
        level = self.levels[k]
        x = np.zeros_like(b)
        for _ in range(CYCLE_SWEEPS):
            level.presmoother(level.A, x, b, "forward")
        x += level.P @ self._cycle(k + 1, level.R @ (b - level.A @ x))
        for _ in range(CYCLE_SWEEPS):
            level.postsmoother(level.A, x, b, "backward")
        return x

    def __matmul__(self, r):
        return self._cycle(0, np.asarray(r, dtype=np.float64).ravel())

    matvec = __matmul__


def _pcg(A, b, x, M, atol: float, maxiter: int):
    """Preconditioned conjugate gradients on A x = b from ``x`` (updated in place) until |b - A x| <= ``atol`` (the
    true residual, checked when the recurrence's gets there), ``maxiter`` iterations, or negative curvature (p^T A p
    <= 0, or r^T M r <= 0: A or M indefinite), where CG's steps lose their meaning. Returns (x, status,
    iterations), status 'converged', 'indefinite' or 'maxiter'."""
    r = b - A @ x
    if float(np.linalg.norm(r)) <= atol:
        return x, "converged", 0
    z = M @ r
    rz = float(r @ z)
    if not rz > 0.0:
        return x, "indefinite", 0
    p = z.copy()
    for k in range(1, maxiter + 1):
        q = A @ p
        curvature = float(p @ q)
        if not curvature > 0.0:
            return x, "indefinite", k
        alpha = rz / curvature
        x += alpha * p
        r -= alpha * q
        if float(np.linalg.norm(r)) <= atol:
            r = b - A @ x  # the recurrence drifts from the true residual: trust only the latter
            if float(np.linalg.norm(r)) <= atol:
                return x, "converged", k
        z = M @ r
        rz_new = float(r @ z)
        if not rz_new > 0.0:
            return x, "indefinite", k
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x, "maxiter", maxiter


def _gmres(A, b, x, M, atol: float, restart: int, maxiter: int):
    """Restarted right-preconditioned (flexible) GMRES on A x = b from ``x`` until |b - A x| <= ``atol``: Arnoldi
    with modified Gram-Schmidt on A M, Givens rotations for the least-squares problem, the preconditioned vectors
    kept (x = x0 + Z y), the true residual checked at every restart. At most ``maxiter`` iterations. Returns (x,
    converged, iterations)."""
    n = len(b)
    total = 0
    while total < maxiter:
        r = b - A @ x
        beta = float(np.linalg.norm(r))
        if beta <= atol:
            return x, True, total
        m = min(restart, maxiter - total)
        V = np.zeros((m + 1, n))
        Z = np.zeros((m, n))
        H = np.zeros((m + 1, m))
        cs, sn = np.zeros(m), np.zeros(m)
        g = np.zeros(m + 1)
        g[0] = beta
        V[0] = r / beta
        k = 0
        for j in range(m):
            Z[j] = M @ V[j]
            w = A @ Z[j]
            for i in range(j + 1):
                H[i, j] = float(w @ V[i])
                w -= H[i, j] * V[i]
            H[j + 1, j] = float(np.linalg.norm(w))
            if H[j + 1, j] > 0.0:
                V[j + 1] = w / H[j + 1, j]
            for i in range(j):  # the earlier rotations on the new column
                H[i, j], H[i + 1, j] = cs[i] * H[i, j] + sn[i] * H[i + 1, j], -sn[i] * H[i, j] + cs[i] * H[i + 1, j]
            rho = float(np.hypot(H[j, j], H[j + 1, j]))
            cs[j], sn[j] = (1.0, 0.0) if rho == 0.0 else (H[j, j] / rho, H[j + 1, j] / rho)
            H[j, j], H[j + 1, j] = rho, 0.0
            g[j], g[j + 1] = cs[j] * g[j], -sn[j] * g[j]
            k = j + 1
            if abs(g[j + 1]) <= atol or H[j, j] == 0.0:
                break
        y = np.zeros(k)
        for i in range(k - 1, -1, -1):  # back substitution on the rotated (triangular) H
            if H[i, i] != 0.0:
                y[i] = (g[i] - H[i, i + 1:k] @ y[i + 1:k]) / H[i, i]
        x = x + Z[:k].T @ y
        total += k
        if k < m and not abs(g[k]) <= atol:  # breakdown without convergence
            break
    r = b - A @ x
    return x, bool(float(np.linalg.norm(r)) <= atol), total


class IterativeSolver(LinearSolver):
    """Krylov method on A = -J preconditioned by a smoothed-aggregation V-cycle (module docstring). ``near_null``:
    the near-null space (n, k) (default: the constant per component); ``grid``: integer lattice coordinates of the
    unknowns' nodes (n / dim, dim) for geometric aggregation (default: PyAMG's standard aggregation with strength
    threshold 0.08); ``symmetric``: whether J is symmetric (default: tested, :func:`is_symmetric`); ``dim``: the
    components per node."""

    kind = "iterative"

    def __init__(self, J, near_null=None, grid=None, symmetric: bool | None = None, rtol: float = ITERATIVE_RTOL,
                 dim: int | None = None):
        super().__init__()
        t0 = time.perf_counter()
        self.J = J.tocsr()
        self.rtol = float(rtol)
        n = self.J.shape[0]
        if dim is None:  # from the lattice, or from the rigid-body modes (3 in 2D, 6 in 3D)
            if grid is not None:
                dim = np.shape(grid)[1]
            elif near_null is not None and np.shape(near_null)[1] in (3, 6):
                dim = {3: 2, 6: 3}[np.shape(near_null)[1]]
            else:
                dim = 1
        self.dim = int(dim)
        if n % self.dim:
            raise ValueError(f"IterativeSolver: {n} unknowns are not a whole number of {self.dim}-component nodes")
        self.symmetric = is_symmetric(self.J) if symmetric is None else bool(symmetric)
        self.A = (-self.J).tocsr()
        self.direct = None
        self._build(near_null, grid)
        self.first_rate = None  # iterations per digit of residual reduction of the first solve with this hierarchy
        self.last_digits = 1.0
        self.failed = False  # the last solve missed its tolerance (and was done directly)
        self.rebuilds = 0
        self.setup_time = time.perf_counter() - t0

    def _build(self, near_null, grid):
        import pyamg

        dim, A = self.dim, self.A
        # the hierarchy of A itself, also where J is unsymmetric: on the pentahedron's tangent with friction (J - J^T
        # 36 % of J), GMRES preconditioned by its symmetric part's hierarchy missed 1e-2 in 300 iterations (with
        # each contact block made positive semidefinite too); by J's own, 26 iterations
        H = A
        n = A.shape[0]
        B = np.ones((n, 1)) if near_null is None else np.array(near_null, dtype=np.float64).reshape(n, -1)
        # smooth the candidates: A v = 0 by block Gauss-Seidel, so they meet the clamps (held nodes are not unknowns:
        # a rigid mode is not near-null next to them)
        smoother = _BlockGaussSeidel(H, dim, "symmetric", 1)
        zero = np.zeros(n)
        for k in range(B.shape[1]):
            v = B[:, k].copy()
            for _ in range(CANDIDATE_SWEEPS):
                smoother(H, v, zero)
            B[:, k] = v / max(float(np.linalg.norm(v)), 1e-300)
        self.near_null_dim = B.shape[1]
        coarse_nodes = max(1, COARSE_UNKNOWNS // max(B.shape[1], 1))
        kwargs = dict(B=B, symmetry="symmetric", max_coarse=COARSE_UNKNOWNS, coarse_solver="splu",
                      smooth=("jacobi", {"omega": 4.0 / 3.0}) if SMOOTH_PROLONGATOR else None,
                      presmoother=None, postsmoother=None, improve_candidates=None, keep=False)
        if grid is not None:
            aggs = lattice_aggregates(grid, coarsest=coarse_nodes, min_nodes=dim, block=AGGREGATE_BLOCK)
            kwargs.update(strength=None, aggregate=[("predefined", {"AggOp": a}) for a in aggs],
                          max_levels=len(aggs) + 1)
        else:
            kwargs.update(strength=("symmetric", {"theta": 0.08}), aggregate="standard")
        ml = pyamg.smoothed_aggregation_solver(H.tobsr(blocksize=(dim, dim)), **kwargs)
        for i, level in enumerate(ml.levels[:-1]):
            # a coarse level's nodes (aggregates) carry one unknown per near-null vector; the finest level's
            # smoother is the candidates' (the same matrix H)
            level.A = H if i == 0 else level.A.tocsr()
            level.presmoother = level.postsmoother = smoother if i == 0 else _BlockGaussSeidel(level.A, self.near_null_dim)
        self.levels = [int(level.A.shape[0]) for level in ml.levels]
        self.operator_complexity = float(ml.operator_complexity())
        self.M = _VCycle(ml)

    def preconditioner(self):
        """The V-cycle (an approximate inverse of A = -J) as a scipy LinearOperator (for LOBPCG, GMRES...)."""
        from scipy.sparse.linalg import LinearOperator

        return LinearOperator(self.A.shape, matvec=self.M.matvec, dtype=np.float64)

    def update(self, J, symmetric: bool | None = None) -> "IterativeSolver":
        """The solver for the next tangent ``J`` of the same unknowns: the Krylov method runs on J (CG or GMRES as
        ``symmetric`` says, default tested) with this hierarchy as its preconditioner (built from an earlier
        tangent); returns self."""
        self.J = J.tocsr()
        self.A = (-self.J).tocsr()
        self.symmetric = is_symmetric(self.J) if symmetric is None else bool(symmetric)
        self.direct = None
        return self

    def stale(self) -> bool:
        """Whether a new hierarchy is due: the last solve missed its tolerance, or needed REBUILD_GROWTH times the
        iterations per digit of residual reduction that the first solve with this hierarchy needed (and at least
        REBUILD_MIN iterations more than that rate gives: the tolerances differ from solve to solve)."""
        if self.first_rate is None or self.solves == 0:
            return False
        if self.failed:
            return True
        expected = self.first_rate * self.last_digits
        return self.iterations > max(REBUILD_GROWTH * expected, expected + REBUILD_MIN)

    def solve(self, b, rtol=None, x0=None, fallback: bool = True):
        """x with |J x - b| <= rtol |b| (default the solver's rtol): preconditioned CG where J is symmetric, GMRES
        where it is not or where CG meets negative curvature (an indefinite tangent: Newton's iterates far from
        the equilibrium, a compressed beam; measured on the 3D cantilever's third iterate, three negative
        eigenvalues), and the direct solver where the Krylov method misses the tolerance within MAX_KRYLOV
        iterations (counted in ``fallbacks``, the reason in ``message``); without ``fallback`` the Krylov method's
        answer is returned as it is, ``failed`` set."""
        t0 = time.perf_counter()
        rtol = self.rtol if rtol is None else max(float(rtol), RTOL_FLOOR)
        b = np.asarray(b, dtype=np.float64).ravel()
        rhs = -b  # A x = -b with A = -J
        size = float(np.linalg.norm(rhs))
        self.solves += 1
        self.iterations = 0
        if size == 0.0:
            return np.zeros_like(b)
        x = np.zeros_like(rhs) if x0 is None else np.array(x0, dtype=np.float64).ravel()  # J x = b: A x = rhs
        method, status = "CG", "unsymmetric"
        if self.symmetric:
            x, status, its = _pcg(self.A, rhs, x, self.M, rtol * size, MAX_KRYLOV)
            self.iterations += its
        if status in ("unsymmetric", "indefinite"):
            method = "GMRES" if status == "unsymmetric" else "CG, then GMRES,"
            # after CG met negative curvature: one GMRES cycle (an indefinite tangent's hierarchy is a poor
            # preconditioner: the cantilever's third iterate, GMRES at 0.45 of the residual after 100 iterations)
            budget = GMRES_RESTART if self.symmetric else MAX_KRYLOV
            x, done, its = _gmres(self.A, rhs, x, self.M, rtol * size, GMRES_RESTART, budget)
            self.iterations += its
        self.total_iterations += self.iterations
        self.last_digits = max(-np.log10(rtol), 1.0)  # the residual reduction asked for, in digits
        if self.first_rate is None:
            self.first_rate = self.iterations / self.last_digits
        achieved = float(np.linalg.norm(rhs - self.A @ x)) / size if np.all(np.isfinite(x)) else float("inf")
        self.failed = not achieved <= 1.01 * rtol
        if self.failed and fallback:
            self.message = (f"{method} with the multigrid preconditioner reached a relative residual of {achieved:.2e} "
                            f"in {self.iterations} iterations against {rtol:.1e}; solved directly instead")
            self.fallbacks += 1
            if self.direct is None:
                self.direct = DirectSolver(self.J)
            x = self.direct.solve(b)
            self.solve_time += time.perf_counter() - t0
            return x
        self.solve_time += time.perf_counter() - t0
        return x


def make_linear_solver(J, kind: str = "auto", near_null=None, grid=None, symmetric: bool | None = None,
                       rtol: float = ITERATIVE_RTOL, dim: int | None = None,
                       direct_max: int = DIRECT_MAX_UNKNOWNS) -> LinearSolver:
    """A solver of J x = b for the tangent ``J`` (sparse, square): ``kind`` "direct" (:class:`DirectSolver`),
    "iterative" (:class:`IterativeSolver`, with ``near_null``, ``grid``, ``symmetric``, ``rtol``, ``dim``) or "auto"
    (direct up to ``direct_max`` unknowns, iterative above)."""
    if kind not in KINDS:
        raise ValueError(f"linear solver kind must be one of {', '.join(map(repr, KINDS))}, not {kind!r}")
    if kind == "auto":
        kind = "direct" if J.shape[0] <= direct_max else "iterative"
    if kind == "direct":
        return DirectSolver(J)
    return IterativeSolver(J, near_null=near_null, grid=grid, symmetric=symmetric, rtol=rtol, dim=dim)
