"""Bare MLS-MPM reference step for benchmarks: the same particle data as the engine, Neo-Hookean stress with one
(G, K), gravity, and nothing else (no magnetics, no contact, no clamps, no checks, a fixed dense grid block).

``magsoro bench`` times it in the same run as each scene, so every figure can be given as a ratio to it: the cost
of the engine's features and safety checks.
"""

import functools
import time

import numpy as np
import warp as wp

wp.set_module_options({"max_unroll": 32, "enable_backward": False})  # never under wp.Tape


@functools.cache
def reference_kernels(dim: int):
    vec = wp.types.vector(length=dim, dtype=wp.float32)
    mat = wp.types.matrix(shape=(dim, dim), dtype=wp.float32)
    ivec = wp.types.vector(length=dim, dtype=wp.int32)
    KN = 3 if dim == 3 else 1

    @wp.func
    def weights(fx: vec):
        w0 = vec()
        w1 = vec()
        w2 = vec()
        for a in range(dim):
            w0[a] = 0.5 * (1.5 - fx[a]) * (1.5 - fx[a])
            w1[a] = 0.75 - (fx[a] - 1.0) * (fx[a] - 1.0)
            w2[a] = 0.5 * (fx[a] - 0.5) * (fx[a] - 0.5)
        return w0, w1, w2

    @wp.func
    def sel(w0: vec, w1: vec, w2: vec, o: int, a: int):
        if o == 0:
            return w0[a]
        if o == 1:
            return w1[a]
        return w2[a]

    @wp.func
    def node(i: int, j: int, k: int, base: ivec, fx: vec, w0: vec, w1: vec, w2: vec, dx: float, shape: ivec):
        """Weight, offset x_i - x_p and flat index of stencil node (i, j[, k])."""
        o = ivec()
        o[0] = i
        o[1] = j
        if wp.static(dim == 3):
            o[2] = k
        wgt = float(1.0)
        d = vec()
        for a in range(dim):
            wgt = wgt * sel(w0, w1, w2, o[a], a)
            d[a] = (float(o[a]) - fx[a]) * dx
        n = base + o
        idx = n[0] * shape[1] + n[1]
        if wp.static(dim == 3):
            idx = idx * shape[2] + n[2]
        return wgt, d, idx

    @wp.kernel
    def p2g(x: wp.array(dtype=vec), v: wp.array(dtype=vec), C: wp.array(dtype=mat), F: wp.array(dtype=mat),
            vol: wp.array(dtype=float), mass: wp.array(dtype=float), G: float, K: float, lo: vec, shape: ivec,
            dx: float, dt: float, gp: wp.array(dtype=vec), gm: wp.array(dtype=float)):
        p = wp.tid()
        xg = (x[p] - lo) / dx
        base = ivec()
        fx = vec()
        for a in range(dim):
            base[a] = int(wp.floor(xg[a] - 0.5))
            fx[a] = xg[a] - float(base[a])
            if base[a] < 0 or base[a] + 2 >= shape[a]:
                return  # left the fixed block (not expected in a short benchmark); never write out of bounds
        w0, w1, w2 = weights(fx)
        Fp = F[p]
        J = wp.determinant(Fp)
        FinvT = wp.transpose(wp.inverse(Fp))
        I1 = wp.trace(wp.transpose(Fp) * Fp)
        if wp.static(dim == 2):
            I1 = I1 + 1.0
        P = G * wp.pow(J, -0.6666667) * (Fp - I1 / 3.0 * FinvT) + K * J * (J - 1.0) * FinvT
        affine = (-dt * vol[p] * 4.0 / (dx * dx)) * (P * wp.transpose(Fp)) + mass[p] * C[p]
        mv = mass[p] * v[p]
        for i in range(3):
            for j in range(3):
                for k in range(KN):
                    wgt, d, idx = node(i, j, k, base, fx, w0, w1, w2, dx, shape)
                    wp.atomic_add(gp, idx, wgt * (mv + affine * d))
                    wp.atomic_add(gm, idx, wgt * mass[p])

    @wp.kernel
    def grid(gp: wp.array(dtype=vec), gm: wp.array(dtype=float), g: vec, dt: float, gv: wp.array(dtype=vec)):
        i = wp.tid()
        m = gm[i]
        if m > 0.0:
            gv[i] = gp[i] / m + dt * g
        else:
            gv[i] = vec()

    @wp.kernel
    def g2p(gv: wp.array(dtype=vec), lo: vec, shape: ivec, dx: float, dt: float, x: wp.array(dtype=vec),
            v: wp.array(dtype=vec), C: wp.array(dtype=mat), F: wp.array(dtype=mat)):
        p = wp.tid()
        xg = (x[p] - lo) / dx
        base = ivec()
        fx = vec()
        for a in range(dim):
            base[a] = int(wp.floor(xg[a] - 0.5))
            fx[a] = xg[a] - float(base[a])
            if base[a] < 0 or base[a] + 2 >= shape[a]:
                return
        w0, w1, w2 = weights(fx)
        nv = vec()
        nC = mat()
        for i in range(3):
            for j in range(3):
                for k in range(KN):
                    wgt, d, idx = node(i, j, k, base, fx, w0, w1, w2, dx, shape)
                    gvi = gv[idx]
                    nv = nv + wgt * gvi
                    nC = nC + (wgt * 4.0 / (dx * dx)) * wp.outer(gvi, d)
        v[p] = nv
        C[p] = nC
        F[p] = (wp.identity(n=dim, dtype=float) + dt * nC) * F[p]
        x[p] = x[p] + dt * nv

    return dict(p2g=p2g, grid=grid, g2p=g2p, vec=vec, mat=mat, ivec=ivec)


class ReferenceStep:
    """The bare MLS-MPM step on the given particles, set up once: :meth:`time` runs ``steps`` more steps and
    returns their wall time (s), so a benchmark can alternate it with the engine (float32, recorded launches)."""

    def __init__(self, positions, volumes, masses, shear_modulus: float, bulk_modulus: float, dx: float, dt: float,
                 device: str = "cpu", margin: int = 8):
        X = np.asarray(positions, dtype=np.float64)
        n, dim = X.shape
        k = reference_kernels(dim)
        lo_node = np.floor(X.min(axis=0) / dx - 0.5).astype(int) - margin
        hi_node = np.floor(X.max(axis=0) / dx - 0.5).astype(int) + 2 + margin
        shape = hi_node - lo_node + 1
        lo = lo_node * dx
        nn = int(np.prod(shape))
        self.n_particles, self.grid_nodes, self.device = n, nn, device
        x = wp.array(X.astype(np.float32), dtype=k["vec"], device=device)
        v = wp.zeros(n, dtype=k["vec"], device=device)
        C = wp.zeros(n, dtype=k["mat"], device=device)
        F = wp.array(np.broadcast_to(np.eye(dim, dtype=np.float32), (n, dim, dim)).copy(), dtype=k["mat"], device=device)
        vol = wp.array(np.asarray(volumes, dtype=np.float32), dtype=float, device=device)
        mass = wp.array(np.asarray(masses, dtype=np.float32), dtype=float, device=device)
        self._gp = wp.zeros(nn, dtype=k["vec"], device=device)
        self._gm = wp.zeros(nn, dtype=float, device=device)
        gv = wp.zeros(nn, dtype=k["vec"], device=device)
        g = k["vec"](*([0.0] * (dim - 1) + [-9.81]))
        lov, shp = k["vec"](*lo.astype(np.float32)), k["ivec"](*shape.astype(np.int32))
        self._launches = [
            wp.launch(k["p2g"], dim=n, inputs=[x, v, C, F, vol, mass, float(shear_modulus), float(bulk_modulus), lov, shp, dx, dt, self._gp, self._gm], device=device, record_cmd=True),
            wp.launch(k["grid"], dim=nn, inputs=[self._gp, self._gm, g, dt, gv], device=device, record_cmd=True),
            wp.launch(k["g2p"], dim=n, inputs=[gv, lov, shp, dx, dt, x, v, C, F], device=device, record_cmd=True),
        ]
        for _ in range(3):
            self._one()
        wp.synchronize_device(device)

    def _one(self):
        self._gp.zero_()
        self._gm.zero_()
        for cmd in self._launches:
            cmd.launch()

    def time(self, steps: int) -> float:
        t0 = time.perf_counter()
        for _ in range(steps):
            self._one()
        wp.synchronize_device(self.device)
        return time.perf_counter() - t0


def time_reference(positions, volumes, masses, shear_modulus: float, bulk_modulus: float, dx: float, dt: float,
                   steps: int, device: str = "cpu", margin: int = 8) -> dict:
    """Run ``steps`` bare steps from rest on the given particles and return timing."""
    ref = ReferenceStep(positions, volumes, masses, shear_modulus, bulk_modulus, dx, dt, device, margin)
    wall = ref.time(steps)
    n = ref.n_particles
    return {"n_particles": n, "steps": steps, "ms_per_step": 1e3 * wall / steps, "particle_steps_per_s": n * steps / wall, "grid_nodes": ref.grid_nodes}
