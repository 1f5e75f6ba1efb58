"""The static solver's 3D tangent: Warp-kernel assembly against the numpy assembly it replaced, in one run.

    python benchmarks/static_assembly.py [--rounds 3]

On scenes/continuum_soft.toml at its preview grid (3D, 6448 particles, float64, uniform field along +x), at the
equilibrium of a 1 mT level (a bent state, so every particle's F differs from I):

- ``StaticSolver.tangent`` as shipped (kernels ``material_tangent`` and ``assemble_tangent``, magsoro.mpm.newton.static);
- the numpy assembly the solver used before (dP/dF by 2 dim^2 launches of the stress kernel, then an einsum over
  particles and a bincount into the CSC pattern; written out again below as the reference);
- one sparse LU factorisation of the tangent (SuperLU), for scale;
- the stability check on that tangent: ``StaticSolver.lowest_mode`` as shipped (one LU shared by the shift-invert
  eigensolver and the determinant's sign) against the check before (eigsh factorising K itself, then a second LU
  for the sign), written out again below; both must give the same eigenvalue.

Both tangents are compared entry by entry (largest difference over the largest entry). Writes
benchmarks/results/<date>-cpu-<commit>-static-assembly.json with the machine and the commit.
"""

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import _commit  # the checkout's commit (MAGSORO_COMMIT without git history)

ROOT = Path(__file__).resolve().parents[1]


def numpy_tangent(st, u_nodes, field_level: float):
    """dR/du on the free DOFs (CSC) by the numpy method the solver used before the kernels (uniform fields:
    the elastic part only), without the slaving and the null-mode shift."""
    import warp as wp
    from scipy import sparse

    from magsoro.mpm.newton.static import F_STEP

    st.node_forces(u_nodes, field_level, 1.0)
    dim, n = st.dim, st.model.n_particles
    nodes, _, g = st.particle_stencil()
    V0 = st.model.host["volumes"]
    F0 = st.F.numpy().astype(np.float64)
    Fw = wp.zeros(n, dtype=st.model.kernels["mat"], device=st.dev)
    Pw = wp.zeros(n, dtype=st.model.kernels["mat"], device=st.dev)
    A = np.zeros((n, dim, dim, dim, dim))
    for b in range(dim):
        for d in range(dim):
            P = []
            for sign in (1.0, -1.0):
                Fp = F0.copy()
                Fp[:, b, d] += sign * F_STEP
                Fw.assign(Fp)
                wp.launch(st.kk["particle_stress"], dim=n, device=st.dev, inputs=[Fw, st.bodies, Pw])
                P.append(Pw.numpy().astype(np.float64))
            A[:, :, :, b, d] = (P[0] - P[1]) / (2.0 * F_STEP)
    A[st.model.host["clamped"]] = 0.0
    S = nodes.shape[1]
    n_dof = len(st.free) * dim
    rows = st.dof_of_node[nodes]
    r_idx, c_idx, vals = [], [], []
    chunk = max(1, 2_000_000 // (S * S * dim * dim))
    for lo in range(0, n, chunk):
        sl = slice(lo, lo + chunk)
        blk = -np.einsum("p,pacbd,psc,ptd->psatb", V0[sl], A[sl], g[sl], g[sl], optimize=True)
        rr = rows[sl][:, :, None, None, None] * dim + np.arange(dim)[None, None, :, None, None]
        cc = rows[sl][:, None, None, :, None] * dim + np.arange(dim)[None, None, None, None, :]
        rr, cc = np.broadcast_to(rr, blk.shape), np.broadcast_to(cc, blk.shape)
        ok = (rr >= 0) & (cc >= 0)
        r_idx.append(rr[ok])
        c_idx.append(cc[ok])
        vals.append(blk[ok])
    return sparse.csc_matrix((np.concatenate(vals), (np.concatenate(r_idx), np.concatenate(c_idx))), shape=(n_dof, n_dof))


def stability_before(st, J):
    """The lowest-mode check as it was before the shared factorisation: eigsh's own LU, a second one for the sign."""
    from scipy.sparse.linalg import eigsh

    from magsoro.mpm.newton.static import _odd_negative_count

    K = (0.5 * (-J + -J.T)).tocsc()
    vals, _ = eigsh(K, k=1, sigma=0.0, which="LM", v0=np.ones(K.shape[0]))
    if vals[0] > 0.0 and st.contact is None and _odd_negative_count(K):
        vals, _ = eigsh(K, k=1, sigma=0.0, which="SA", v0=np.ones(K.shape[0]))
    return float(vals[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    from scipy.sparse.linalg import splu

    from magsoro.mpm.newton.static import StaticSolver
    from magsoro.robots.base import scene_data, simulation

    data = scene_data("continuum_soft")
    data["fields"] = [{"name": "drive", "type": "uniform", "B": [0.001, 0.0, 0.0]}]
    data["simulation"]["duration"] = 0.1
    data.setdefault("output", {})["particles"] = False
    sim = simulation("continuum_soft", data, preview=True, device=None)
    st = StaticSolver(sim, 0.1)
    level = st.solve_level(1.0)
    u = st.u_nodes.copy()
    kernel_s, numpy_s, lu_s, check_s, before_s = [], [], [], [], []
    lams = []
    st.tangent(u, 1.0, 1.0)  # compiles and builds the pattern once
    for _ in range(args.rounds):
        t = time.perf_counter()
        J = st.tangent(u, 1.0, 1.0)
        kernel_s.append(time.perf_counter() - t)
        t = time.perf_counter()
        J_np = numpy_tangent(st, u, 1.0)
        numpy_s.append(time.perf_counter() - t)
        t = time.perf_counter()
        splu(J)
        lu_s.append(time.perf_counter() - t)
        t = time.perf_counter()
        lam_now, _ = st.lowest_mode(J)
        check_s.append(time.perf_counter() - t)
        t = time.perf_counter()
        lam_before = stability_before(st, J)
        before_s.append(time.perf_counter() - t)
        lams.append((lam_now, lam_before))
    # the shipped tangent is on the unknowns (E^T J E, the slaving of light nodes) less a null-mode shift of 1e-12
    # of its median diagonal: compare it with the numpy tangent taken the same way
    J_np_red = (st.E.T @ J_np @ st.E).tocsc()
    n = J.shape[0]
    rel = float(np.abs((J - J_np_red).data).max()) / float(np.abs(J_np_red.data).max())
    med = {k: float(np.median(v)) for k, v in (("kernel", kernel_s), ("numpy", numpy_s), ("lu", lu_s),
                                                ("stability_check", check_s), ("stability_check_before", before_s))}
    result = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": _commit(),
        "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(), "cpu_count": os.cpu_count()},
        "scene": "scenes/continuum_soft.toml --preview, uniform 1 mT along +x, at its equilibrium",
        "particles": int(sim.model.n_particles), "unknowns": int(n), "nonzeros": int(J.nnz),
        "level_converged": bool(level.converged), "level_iterations": int(level.iterations),
        "rounds_s": {"kernel": kernel_s, "numpy": numpy_s, "lu": lu_s, "stability_check": check_s,
                     "stability_check_before": before_s}, "median_s": med,
        "speedup_stability_check": med["stability_check_before"] / med["stability_check"],
        "lowest_eigenvalue_now_before": lams,
        "speedup_assembly": med["numpy"] / med["kernel"],
        "largest_difference_over_largest_entry": rel,
    }
    out = ROOT / "benchmarks" / "results" / f"{datetime.date.today().isoformat()}-cpu-{result['commit']}-static-assembly.json"
    out.write_text(json.dumps(result, indent=1))
    print(f"{result['particles']} particles, {n} unknowns: tangent {med['kernel']:.3f} s (kernels) against {med['numpy']:.3f} s "
          f"(numpy), {result['speedup_assembly']:.1f}x; one LU {med['lu']:.3f} s; largest difference {rel:.2e} of the largest entry")
    print(f"stability check {med['stability_check']:.3f} s (one LU) against {med['stability_check_before']:.3f} s (two), "
          f"{result['speedup_stability_check']:.2f}x; lowest eigenvalue (now, before) {lams[-1]}")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
