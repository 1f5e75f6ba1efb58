"""Linear solvers of the Newton tangents (magsoro.mpm.newton.linear): the multigrid-preconditioned Krylov solver against
sparse LU on elasticity stiffnesses and on the static solver's own tangents, its fallbacks, the forcing terms, the
scene key static.linear_solver, and (slow) the triangle robot's static sweep solved both ways."""

import itertools
import tempfile
from pathlib import Path

import numpy as np
import pytest
from scipy import sparse
from scipy.sparse.linalg import spsolve

from magsoro.mpm.newton import linear
from magsoro.mpm.newton.linear import (DirectSolver, IterativeSolver, forcing_term, lattice_aggregates, make_linear_solver,
                                rigid_body_modes)

ROOT = Path(__file__).resolve().parents[1]


def _mesh(shape):
    """A structured P1 mesh of the box of ``shape`` cells (2D: two triangles a square; 3D: Kuhn's six tetrahedra a
    cube, conforming): vertices (integer lattice coordinates, as floats) and elements."""
    dim = len(shape)
    cells = np.stack(np.meshgrid(*[np.arange(n + 1) for n in shape], indexing="ij"), axis=-1).reshape(-1, dim)
    index = {tuple(c): i for i, c in enumerate(cells.tolist())}
    elements = []
    for base in itertools.product(*[range(n) for n in shape]):
        for order in itertools.permutations(range(dim)):
            corner = list(base)
            element = [index[tuple(corner)]]
            for axis in order:
                corner[axis] += 1
                element.append(index[tuple(corner)])
            elements.append(element)
    elements = np.asarray(elements)
    # positive orientation (PyAMG's P1 element stiffness takes the signed volume): swap two vertices where negative
    edges = cells[elements[:, 1:]] - cells[elements[:, :1]]
    flip = np.linalg.det(edges.astype(float)) < 0.0
    elements[flip, 0], elements[flip, 1] = elements[flip, 1], elements[flip, 0].copy()
    return cells, elements


def _elasticity(shape, nu=0.3):
    """The tangent convention of the static solver for a linear-elastic box clamped on its x = 0 face: J = -K (K
    the P1 stiffness, SPD once clamped), with the free nodes' lattice coordinates and positions."""
    from pyamg.gallery import linear_elasticity_p1

    cells, elements = _mesh(shape)
    K, _ = linear_elasticity_p1(cells.astype(float), elements, E=1.0e5, nu=nu, format="csr")
    dim = len(shape)
    free_nodes = np.flatnonzero(cells[:, 0] > 0)
    dofs = (free_nodes[:, None] * dim + np.arange(dim)).ravel()
    K = K.tocsr()[dofs][:, dofs].tocsc()
    return -K, cells[free_nodes], cells[free_nodes].astype(float)


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_body_modes_span_a_free_bodys_null_space(dim):
    """K B = 0 for the unclamped stiffness, and B has full rank (3 columns in 2D, 6 in 3D)."""
    from pyamg.gallery import linear_elasticity_p1

    cells, elements = _mesh((3,) * dim)
    K, _ = linear_elasticity_p1(cells.astype(float) * 1e-3, elements, E=1.0e5, format="csr")
    B = rigid_body_modes(cells * 1e-3)
    assert B.shape == (len(cells) * dim, 3 if dim == 2 else 6)
    assert np.linalg.matrix_rank(B) == B.shape[1]
    assert np.abs(K @ B).max() < 1e-9 * np.abs(K).max()


def test_lattice_aggregates_partition_the_nodes_and_merge_small_blocks():
    """Every node in one aggregate per level; a first-level block of fewer than min_nodes nodes joins a neighbour;
    the levels end at one aggregate."""
    rng = np.random.default_rng(0)
    cells = np.unique(rng.integers(0, 12, size=(400, 3)), axis=0)
    aggs = lattice_aggregates(cells, coarsest=1, min_nodes=3, block=3)
    assert aggs[-1].shape[1] == 1
    n = len(cells)
    for agg in aggs:
        assert agg.shape[0] == n and np.all(np.asarray(agg.sum(axis=1)).ravel() == 1)
        n = agg.shape[1]
    first = np.asarray(aggs[0].sum(axis=0)).ravel()
    assert first.min() >= 3


@pytest.mark.parametrize("shape", [(40, 12), (16, 6, 5)])
def test_multigrid_cg_matches_sparse_lu(shape):
    """CG preconditioned by the smoothed-aggregation V-cycle (rigid-body modes, lattice aggregates) solves a 2D
    and a 3D clamped elasticity stiffness to the sparse direct solution within 1e-8, in few iterations."""
    J, cells, positions = _elasticity(shape)
    b = np.random.default_rng(1).standard_normal(J.shape[0])
    lin = make_linear_solver(J, "iterative", near_null=rigid_body_modes(positions), grid=cells)
    assert lin.kind == "iterative" and lin.symmetric and lin.dim == len(shape)
    x = lin.solve(b, rtol=1e-12)
    exact = spsolve(J.tocsc(), b)
    assert np.linalg.norm(x - exact) <= 1e-8 * np.linalg.norm(exact)
    assert lin.fallbacks == 0 and 0 < lin.iterations <= 60
    assert len(lin.levels) >= 2  # a hierarchy, not one smoother


def test_unsymmetric_tangent_is_solved_by_gmres():
    """A friction-like unsymmetric part (1 % of the entries, on the same pattern): GMRES on J with the hierarchy
    of its symmetric part, to the direct solution within 1e-8."""
    J, cells, positions = _elasticity((10, 5, 4))
    A = J.tocoo()
    skew = sparse.csc_matrix((0.01 * np.random.default_rng(2).standard_normal(A.nnz) * A.data, (A.row, A.col)),
                             shape=J.shape)
    J = (J + skew).tocsc()
    lin = make_linear_solver(J, "iterative", near_null=rigid_body_modes(positions), grid=cells)
    assert not lin.symmetric
    b = np.random.default_rng(3).standard_normal(J.shape[0])
    x = lin.solve(b, rtol=1e-11)
    exact = spsolve(J, b)
    assert lin.fallbacks == 0 and np.linalg.norm(x - exact) <= 1e-8 * np.linalg.norm(exact)


def test_missed_tolerance_falls_back_to_the_direct_solver(monkeypatch):
    """A Krylov solve that misses its tolerance within MAX_KRYLOV iterations is done again by sparse LU, counted
    and explained; the answer is the direct one."""
    J, cells, positions = _elasticity((12, 4, 4))
    lin = IterativeSolver(J, near_null=rigid_body_modes(positions), grid=cells)
    monkeypatch.setattr(linear, "MAX_KRYLOV", 2)
    b = np.random.default_rng(4).standard_normal(J.shape[0])
    x = lin.solve(b, rtol=1e-10)
    assert lin.fallbacks == 1 and lin.failed and lin.stale() and "solved directly" in lin.message
    assert np.linalg.norm(J @ x - b) <= 1e-10 * np.linalg.norm(b)


def test_indefinite_tangent_is_still_solved():
    """A tangent with negative stiffness directions (Newton's iterates far from equilibrium): CG meets negative
    curvature, and the solve still returns the answer (GMRES, or the direct solver)."""
    J, cells, positions = _elasticity((12, 4, 4))
    from scipy.sparse.linalg import eigsh

    lowest = eigsh((-J).tocsc(), k=4, sigma=0.0, which="LM", return_eigenvectors=False)
    lowest = np.sort(lowest)
    shift = 0.5 * float(lowest[1] + lowest[2])  # -J' = -J - shift I: two eigenvalues below zero
    Jshift = (J + shift * sparse.identity(J.shape[0])).tocsc()
    lin = IterativeSolver(Jshift, near_null=rigid_body_modes(positions), grid=cells)
    b = np.random.default_rng(5).standard_normal(J.shape[0])
    x = lin.solve(b, rtol=1e-9)
    assert np.linalg.norm(Jshift @ x - b) <= 1.01e-9 * np.linalg.norm(b)


def test_forcing_terms():
    """Eisenstat-Walker: ETA_MAX at the first step, the square of the residual's fall after it, safeguarded, never
    below the caller's floor nor RTOL_FLOOR."""
    assert forcing_term(1.0, None, None) == linear.ETA_MAX
    assert forcing_term(1e-3, 1.0, 1e-2) == pytest.approx(linear.EW_GAMMA * 1e-6)
    assert forcing_term(1e-15, 1.0, 1e-4) == linear.RTOL_FLOOR
    assert forcing_term(1e-12, 1.0, 1e-4, floor=1e-5) == 1e-5
    # a slow fall (0.9) after a loose step: the safeguard keeps eta from jumping down
    assert forcing_term(0.5, 1.0, 0.5) == pytest.approx(min(linear.ETA_MAX, max(0.9 * 0.25, 0.9 * 0.25)))


def test_auto_picks_the_direct_solver_below_the_threshold():
    J, cells, positions = _elasticity((6, 3, 3))
    assert make_linear_solver(J).kind == "direct"
    lin = make_linear_solver(J, "auto", near_null=rigid_body_modes(positions), grid=cells, direct_max=10)
    assert lin.kind == "iterative"
    assert isinstance(make_linear_solver(J, "direct"), DirectSolver)
    with pytest.raises(ValueError, match="'auto', 'direct', 'iterative'"):
        make_linear_solver(J, "cg")


# -- the static solver's own tangents ---------------------------------------------------------------------------

def _static(scene_name: str, kind: str):
    from magsoro.mpm.newton.static import StaticSolver
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    scene = load_scene(ROOT / "scenes" / scene_name)
    scene.simulation.precision = "float64"
    sim = Simulation(scene)
    return sim, StaticSolver(sim, scene.simulation.duration, linear_solver=kind)


@pytest.mark.parametrize("scene_name", ["cantilever_2d.toml", "cantilever_3d.toml"])
def test_static_tangent_solved_iteratively_matches_direct(scene_name):
    """The Newton step of a clamped cantilever's tangent (2D plane strain and 3D, the scene's field): the
    iterative solver (the StaticSolver's: rigid-body modes of the unknowns' nodes, lattice aggregates) to the
    direct step within 1e-7 (measured 1.5e-10 and 8e-11)."""
    _, st = _static(scene_name, "iterative")
    J = st.tangent(st.u_nodes, 1.0, 1.0)
    r = st.residual(st.u_nodes, 1.0, 1.0)
    lin = st._linear_solver(J)
    assert lin.kind == "iterative" and lin.symmetric and lin.near_null_dim == (3 if st.dim == 2 else 6)
    du = lin.solve(-r, rtol=1e-8)  # about what the direct solve leaves (2e-10 to 8e-10): CG stagnates below 1e-9
    exact = DirectSolver(J).solve(-r)
    assert lin.fallbacks == 0
    assert np.linalg.norm(du - exact) <= 1e-7 * np.linalg.norm(exact)


def test_static_level_iterative_matches_direct():
    """The 2D cantilever at field level 0.25 from straight: Newton with the iterative solver (Eisenstat-Walker
    tolerances) reaches the direct solver's equilibrium within 1e-6 of the displacement, both converged to the
    scene's tolerance; the level reports its Krylov iterations, and the stability check without a factorisation
    (LOBPCG) finds the direct one's lowest stiffness."""
    results = {}
    for kind in ("direct", "iterative"):
        sim, st = _static("cantilever_2d.toml", kind)
        res = st.solve_level(0.25)
        assert res.converged and res.residual_relative <= 1e-8
        results[kind] = (st.u_nodes.copy(), res)
    (ud, rd), (ui, ri) = results["direct"], results["iterative"]
    assert np.abs(ui - ud).max() <= 1e-6 * np.abs(ud).max()
    assert rd.linear_solver == "direct" and rd.linear_iterations == 0 and rd.linear_solves == rd.iterations
    assert ri.linear_solver == "iterative" and ri.linear_iterations > 0 and ri.linear_solves == ri.iterations
    assert ri.linear_setups <= ri.iterations
    assert ri.lowest_eigenvalue == pytest.approx(rd.lowest_eigenvalue, rel=1e-4)


def test_scene_key_and_default():
    """[static] linear_solver: 'auto' by default, read by the StaticSolver; other values are refused by name."""
    from magsoro.errors import SceneError
    from magsoro.mpm.newton.static import StaticSolver
    from magsoro.scene import load_scene, parse_scene

    scene = load_scene(ROOT / "scenes" / "cantilever_2d.toml")
    assert scene.static.linear_solver == "auto"
    scene.static.linear_solver = "iterative"
    from magsoro.simulation import Simulation

    sim = Simulation(scene)
    assert StaticSolver(sim, scene.simulation.duration).linear_solver == "iterative"
    import tomllib

    data = tomllib.loads((ROOT / "scenes" / "cantilever_2d.toml").read_text())
    data["static"] = {"linear_solver": "cg"}
    with pytest.raises(SceneError, match="linear_solver"):
        parse_scene(data, base_dir=ROOT / "scenes")


def _triangle_sweeps(monkeypatch):
    """The triangle robot on its friction plate (seed 002; scenes/triangle.toml's preview grid) along the magnet's
    path to 15 mT by the static solver, once with the direct solver everywhere and once with the iterative one
    everywhere (friction: GMRES, and the stability check by shift-invert on iterative solves): the final particle
    positions of each, and the reference positions."""
    from magsoro.robots import triangle as T
    from magsoro.robots.base import Context

    positions = {}
    for kind, threshold in (("direct", 10**9), ("iterative", 0)):
        monkeypatch.setattr(linear, "DIRECT_MAX_UNKNOWNS", threshold)  # 'auto' picks the kind everywhere
        with tempfile.TemporaryDirectory() as tmp:
            ctx = Context(out=Path(tmp), preview=True, device="cpu", log=lambda msg: None)
            sim, X0, *_ , sweep, _ = T.static_sweep(ctx, [0, 5, 10, 15], [b for b in T.BETWEEN_MT if b < 15])
        assert all(lev.converged for lev in sweep.levels)
        used = {lev.linear_solver for lev in sweep.levels}
        assert used == {kind}, used
        positions[kind] = (sim.state.x.numpy().astype(np.float64), X0)
    return positions


@pytest.mark.slow
def test_triangle_static_sweep_direct_and_tight_iterative_agree(monkeypatch):
    """The triangle's sweep (_triangle_sweeps) with every Krylov solve to 1e-6 (linear.ETA_MAX): the iterative
    path takes the direct one's Newton iterations level by level and ends at the same equilibrium within 1e-6 of
    the largest displacement. Passed in 1 of 2 runs on 2026-11-28 (the other failed next to the xfail test below;
    not diagnosed: the threaded scatter's summation order is one suspect)."""
    monkeypatch.setattr(linear, "ETA_MAX", 1e-6)
    positions = _triangle_sweeps(monkeypatch)
    (xd, X0), (xi, _) = positions["direct"], positions["iterative"]
    assert np.abs(xi - xd).max() <= 1e-6 * np.abs(xd - X0).max()


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="a known failure: with Eisenstat-Walker tolerances (eta up to 1e-2; 1e-3 and "
                   "1e-4 fail as well) Newton stalls on the triangle's friction contact at the gravity level, where "
                   "solves to 1e-6 follow the direct path")
def test_triangle_static_sweep_direct_and_iterative_agree(monkeypatch):
    """The same with the default forcing terms."""
    positions = _triangle_sweeps(monkeypatch)
    (xd, X0), (xi, _) = positions["direct"], positions["iterative"]
    assert np.abs(xi - xd).max() <= 1e-6 * np.abs(xd - X0).max()


def _strip_lattice(nx, ny, nz):
    """An SPD matrix on an nx x ny x nz node lattice that couples each node with the 5 x 5 x 5 around it, as the
    quadratic B-spline tangents do: the tensor product of three diagonally dominant pentadiagonal matrices (CSC)."""
    from scipy import sparse

    def line(n):
        return sparse.diags([-0.5 * np.ones(n - 2), -np.ones(n - 1), 4.0 * np.ones(n), -np.ones(n - 1),
                             -0.5 * np.ones(n - 2)], [-2, -1, 0, 1, 2])

    return sparse.kron(sparse.kron(line(nx), line(ny)), line(nz)).tocsc()


def test_ordering_keeps_the_smaller_fill_and_serves_the_pattern_again():
    """linear.Ordering keeps whichever of minimum degree (SuperLU's own) and reverse Cuthill-McKee (whose fill is
    its envelope) leaves the smaller fill, checked here against both factorisations made by hand (on the 3D
    strip's implicit tangent, 8937 unknowns, RCM's 6.6 M entries won over 7.9 M). A later matrix of the same
    pattern is factorised in the kept order with no ordering step and solves to rounding; a matrix of another
    size is learnt anew."""
    from scipy import sparse
    from scipy.sparse.csgraph import reverse_cuthill_mckee
    from scipy.sparse.linalg import splu

    from magsoro.mpm.newton.linear import Ordering, PermutedLU, factor

    B = sparse.csr_matrix(np.ones((3, 3)) + 3.0 * np.eye(3))  # three unknowns per node, as in 3D
    J = sparse.kron(_strip_lattice(60, 4, 3), B).tocsc()
    J.eliminate_zeros()
    order = Ordering()
    first = factor(J, order)
    assert not isinstance(first, PermutedLU)  # the first factorisation learns the ordering
    assert order.kind == "minimum degree" and not order.weighed  # RCM is weighed when the pattern comes again
    mmd = first.L.nnz + first.U.nnz
    assert order.permutation(J) is not None and order.weighed
    p = reverse_cuthill_mckee(J.tocsr(), symmetric_mode=True)
    by_hand = splu(J[p][:, p].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    rcm = by_hand.L.nnz + by_hand.U.nnz
    assert order.kind == ("reverse Cuthill-McKee" if order.fill < mmd else "minimum degree")
    assert order.fill <= mmd and order.fill >= min(mmd, rcm)  # the envelope bounds RCM's fill from above
    J2 = (J + sparse.diags(np.linspace(0.0, 1.0, J.shape[0]))).tocsc()
    again = factor(J2, order)
    assert isinstance(again, PermutedLU)
    fresh = factor(J2)  # its own minimum-degree ordering (the fill depends on the values a little: exact zeros)
    assert again.L.nnz + again.U.nnz <= 1.01 * (fresh.L.nnz + fresh.U.nnz)
    b = np.random.default_rng(1).standard_normal(J.shape[0])
    assert np.linalg.norm(J2 @ again.solve(b) - b) <= 1e-12 * np.linalg.norm(b)
    cube = sparse.kron(_strip_lattice(6, 6, 6), B).tocsc()
    assert order.permutation(cube) is None  # another size: learnt anew
    factor(cube, order)
    assert len(order.perm) == cube.shape[0]
