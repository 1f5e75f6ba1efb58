"""Magnetic interaction between magnetised material: the field the bodies' own magnetisation makes.

Method (docs/engine.md, "Magnetic interaction"): each particle's current moment m_p = F_p Br_p V_p / mu0 (2D:
per unit depth, the in-plane part) is spread onto the nodes of a grid of spacing dx over the magnetised particles
with the engine's quadratic B-spline weights, so the nodes carry point dipoles with the particles' total moment
and centroid. The field of that lattice of dipoles at every node, H = sum_j T(x_i - x_j) m_j, and its gradient,
grad H = sum_j grad T(x_i - x_j) m_j, are discrete convolutions with the sampled dipole tensors

    3D: T(r) = (3 r r^T / r^2 - I) / (4 pi r^3),    2D (line dipoles): T(r) = (2 r r^T / r^2 - I) / (2 pi r^2),

computed by FFT on a zero-padded grid (free space, Hockney and Eastwood): O(G log G) for G nodes. The self
term T(0) = -I / (3 dx^3) (2D: -I / (2 dx^2)) is the field at the centre of a uniformly magnetised cube (square)
cell, so a uniform region gives the macroscopic H (inside a sphere -M/3) and B = mu0 (H + M) (2/3 mu0 M). The
particles take H and grad H back with the same weights, as B_int = mu0 H and grad B_int = mu0 grad H, which the
engine adds to the applied field: the magnetic stress takes B_int, the gradient force (grad B_int)^T m.

Momentum: the force on the particles sums to mu0 sum_i m_i . (grad T * m)_i, a quadratic form of an odd
convolution, which vanishes: a body's own field exerts no net force on it, to round-off, at every refresh.
"""

import functools
import math

import numpy as np
import warp as wp

from magsoro.constants import MU0
from magsoro.mpm.settings import INTERACTION_MODES
from magsoro.mpm.kernels.stencil import host_bspline, make_stencil

# No kernel here runs under wp.Tape (only magsoro.diff's rollout does): Warp need not build their adjoints.
wp.set_module_options({"enable_backward": False})

MODES = INTERACTION_MODES
MARGIN = 2  # nodes kept between the magnetised particles' box and the grid's edge (the stencil's reach)


def polar_rotation_np(F: np.ndarray) -> np.ndarray:
    """The rotation R of the polar decomposition F = R U of each of ``F`` (..., dim, dim), float64, as the engine's
    ``polar_rotation`` (:func:`magsoro.mpm.kernels.stencil.make_magnetization`) takes it: from the SVD F = W S V^T,
    R = W V^T with the last column of W flipped where det(W V^T) < 0."""
    W, _, Vt = np.linalg.svd(np.asarray(F, dtype=np.float64))
    flip = np.linalg.det(W @ Vt) < 0.0
    W[flip, :, -1] *= -1.0
    return W @ Vt


def sym_pairs(dim: int) -> list[tuple[int, int]]:
    """The (a, b), a <= b, components of a symmetric dim x dim tensor in the order the grids store them."""
    return [(a, b) for a in range(dim) for b in range(a, dim)]


def sym_triples(dim: int) -> list[tuple[int, int, int]]:
    """The a <= b <= c components of a fully symmetric three-index tensor (the dipole tensor's gradient)."""
    return [(a, b, c) for a in range(dim) for b in range(a, dim) for c in range(b, dim)]


def dipole_tensors(offsets: np.ndarray, h: float, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Dipole tensor T_ab and its gradient S_abc = dT_ab/dx_c at the points ``offsets`` (..., dim) m, for lattice
    spacing ``h``: returned as (len(sym_pairs), ...) and (len(sym_triples), ...) arrays in 1/m^3 and 1/m^4 (2D:
    1/m^2, 1/m^3). At r = 0: T = -I/(3 h^3) (2D: -I/(2 h^2)), S = 0."""
    x = np.moveaxis(np.asarray(offsets, dtype=np.float64), -1, 0)
    r2 = np.sum(x * x, axis=0)
    zero = r2 == 0.0
    r2s = np.where(zero, 1.0, r2)
    if dim == 3:
        c, k1, k2, k3 = 1.0 / (4.0 * math.pi), 3.0, 15.0, 3.0
        inv_r3 = r2s ** -1.5
        t_xx, t_i = k1 * inv_r3 / r2s, inv_r3  # 3 x x / r^5, 1 / r^3
        s_xxx, s_x = k2 * inv_r3 / (r2s * r2s), k3 * inv_r3 / r2s  # 15 / r^7, 3 / r^5
        self_term = -1.0 / (3.0 * h**3)
    else:
        c = 1.0 / (2.0 * math.pi)
        inv_r2 = 1.0 / r2s
        t_xx, t_i = 2.0 * inv_r2 * inv_r2, inv_r2  # 2 x x / r^4, 1 / r^2
        s_xxx, s_x = 8.0 * inv_r2**3, 2.0 * inv_r2 * inv_r2  # 8 / r^6, 2 / r^4
        self_term = -1.0 / (2.0 * h**2)
    T = []
    for a, b in sym_pairs(dim):
        t = c * (t_xx * x[a] * x[b] - (t_i if a == b else 0.0))
        T.append(np.where(zero, self_term if a == b else 0.0, t))
    S = []
    for a, b, d in sym_triples(dim):
        delta = (x[d] if a == b else 0.0) + (x[b] if a == d else 0.0) + (x[a] if b == d else 0.0)
        S.append(np.where(zero, 0.0, c * (-s_xxx * x[a] * x[b] * x[d] + s_x * delta)))
    return np.array(T), np.array(S)


@functools.cache
def make_interaction_kernels(dim: int, scalar) -> dict:
    """The deposit and gather kernels of the interaction grid for ``dim`` and ``scalar`` (grids in ``scalar``)."""
    s = make_stencil(dim, scalar)
    t = s.types
    vec, mat, ivec, v3, m3 = t.vec, t.mat, t.ivec, t.v3, t.m3
    NS = s.NS
    inplane, bspline_weights, local_coords = s.inplane, s.bspline_weights, s.local_coords
    moment_map = s.moment_map
    outside_block, flat_index, stencil_node = s.outside_block, s.flat_index, s.stencil_node
    n_sym = dim * (dim + 1) // 2
    vsym = wp.types.vector(length=n_sym, dtype=scalar)

    @wp.kernel
    def deposit_moments(
        x: wp.array(dtype=vec),
        F: wp.array(dtype=mat),
        Br: wp.array(dtype=v3),
        follows: wp.array(dtype=wp.int32),
        vol0: wp.array(dtype=scalar),
        lo: vec,
        inv_h: scalar,
        shape: ivec,
        n_total: int,
        scale: scalar,
        body: wp.array(dtype=wp.int32),
        select: int,
        M: wp.array(dtype=scalar),
    ):
        """Spread particle ``p``'s moment F Br V0 ``scale`` (A m^2; 2D: A m, in-plane; R Br V0 ``scale`` when it
        follows R, :func:`magsoro.mpm.kernels.stencil.make_magnetization`) onto its stencil's nodes:
        M[a n_total + node] holds component a. ``select`` >= 0: only the particles of that body."""
        p = wp.tid()
        if select >= 0 and body[p] != select:
            return
        Fbr = moment_map(F[p], follows[p]) * inplane(Br[p])
        if wp.length_sq(Fbr) == scalar(0.0):
            return
        base, fx = local_coords(x[p], lo, inv_h)
        if outside_block(base, shape):
            return
        w0, w1, w2 = bspline_weights(fx)
        first = flat_index(base, shape)
        moment = Fbr * (vol0[p] * scale)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
            for a in range(dim):
                wp.atomic_add(M, a * n_total + idx, weight * moment[a])

    @wp.kernel
    def gather_field(
        x: wp.array(dtype=vec),
        lo: vec,
        inv_h: scalar,
        shape: ivec,
        n_total: int,
        fields: wp.array(dtype=scalar),
        mu0: scalar,
        B: wp.array(dtype=v3),
        grad_B: wp.array(dtype=m3),
    ):
        """B = mu0 H and grad B = mu0 grad H at particle ``p`` from the node fields (H: components 0 .. dim-1,
        then the symmetric grad H in :func:`sym_pairs` order); zero outside the grid."""
        p = wp.tid()
        base, fx = local_coords(x[p], lo, inv_h)
        b = v3()
        g = m3()
        if not outside_block(base, shape):
            w0, w1, w2 = bspline_weights(fx)
            first = flat_index(base, shape)
            hv = vec()
            gs = vsym()
            for q in range(NS):
                weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
                for a in range(dim):
                    hv[a] = hv[a] + weight * fields[a * n_total + idx]
                for c in range(n_sym):
                    gs[c] = gs[c] + weight * fields[(dim + c) * n_total + idx]
            for a in range(dim):
                b[a] = mu0 * hv[a]
            c = int(0)
            for a in range(dim):
                for e in range(a, dim):
                    value = mu0 * gs[c]
                    g[a, e] = value
                    g[e, a] = value
                    c += 1
        B[p] = b
        grad_B[p] = g

    @wp.kernel
    def add_field(B_int: wp.array(dtype=v3), grad_B_int: wp.array(dtype=m3), keep: int, B: wp.array(dtype=v3),
                  grad_B: wp.array(dtype=m3)):
        """B += B_int, grad_B += grad_B_int (``keep`` = 0: B = B_int, grad_B = grad_B_int)."""
        p = wp.tid()
        if keep != 0:
            B[p] = B[p] + B_int[p]
            grad_B[p] = grad_B[p] + grad_B_int[p]
        else:
            B[p] = B_int[p]
            grad_B[p] = grad_B_int[p]

    return {"deposit_moments": deposit_moments, "gather_field": gather_field, "add_field": add_field}


# -- launchers: the one place each kernel's argument order is written (as in :mod:`magsoro.mpm.kernels.p2g`); ``kernels``
# is :func:`make_interaction_kernels`' table -------------------------------------------------------------------

def launch_deposit_moments(kernels, n, *, x, F, Br, follows, vol0, lo, inv_h, shape, n_total, scale, body, select, M,
                           device, record=False):
    """``deposit_moments`` over ``n`` particles: their moments onto the field grid (origin ``lo``, 1/spacing
    ``inv_h``, ``shape`` nodes, ``n_total`` of them) into ``M``; ``select`` >= 0: that body only."""
    return wp.launch(kernels["deposit_moments"], dim=n, device=device, record_cmd=record,
                     inputs=[x, F, Br, follows, vol0, lo, inv_h, shape, n_total, scale, body, select, M])


def launch_gather_field(kernels, n, *, x, lo, inv_h, shape, n_total, fields, mu0, B, grad_B, device, record=False):
    """``gather_field`` over ``n`` particles: B and grad B at ``x`` from the node ``fields``."""
    return wp.launch(kernels["gather_field"], dim=n, device=device, record_cmd=record,
                     inputs=[x, lo, inv_h, shape, n_total, fields, mu0, B, grad_B])


def launch_add_field(kernels, n, *, B_int, grad_B_int, keep, B, grad_B, device, record=False):
    """``add_field`` over ``n`` particles: the bodies' own field added into (``keep`` 1) or written over (0) ``B``
    and ``grad_B``."""
    return wp.launch(kernels["add_field"], dim=n, device=device, record_cmd=record,
                     inputs=[B_int, grad_B_int, keep, B, grad_B])


@functools.lru_cache(maxsize=8)
def _kernel_spectra(padded: tuple, h: float, dim: int, real: str = "float64") -> np.ndarray:
    """The convolution's spectra as one (dim + len(sym_pairs), dim, ...) array: output c (H_a, then grad H in
    :func:`sym_pairs` order) from moment component b, the rFFT of T_ab or of dT_ae/dx_b sampled at every signed
    circular offset of a grid of ``padded`` nodes, in the precision ``real``."""
    from scipy import fft as sfft  # imported here: scipy.fft costs 0.6 s of every run's start-up
    axes = [np.fft.fftfreq(n, 1.0 / n) * h for n in padded]  # 0, 1, ..., -2, -1 times h
    offsets = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    T, S = dipole_tensors(offsets, h, dim)
    spatial = tuple(range(1, dim + 1))
    Tk, Sk = sfft.rfftn(T, axes=spatial), sfft.rfftn(S, axes=spatial)
    pair = {p: i for i, p in enumerate(sym_pairs(dim))}
    tri = {}
    for c, (a, b, d) in enumerate(sym_triples(dim)):
        for perm in ((a, b, d), (a, d, b), (b, a, d), (b, d, a), (d, a, b), (d, b, a)):
            tri[perm] = c
    rows = [[Tk[pair[tuple(sorted((a, b)))]] for b in range(dim)] for a in range(dim)]
    rows += [[Sk[tri[(a, e, b)]] for b in range(dim)] for a, e in sym_pairs(dim)]
    complex_type = np.complex64 if real == "float32" else np.complex128
    return np.array(rows, dtype=complex_type)


class MagneticInteraction:
    """The bodies' own field at the particles of a :class:`~magsoro.mpm.model.Model`, refreshed on demand.

    ``depth`` (2D): the out-of-plane thickness the particle volumes include; the 2D field is that of line dipoles
    of moment m / depth per unit length. After :meth:`refresh`, ``B`` and ``grad_B`` (device arrays, the model's
    scalar) hold mu0 H and mu0 grad H at the particles, ``grad_B`` with the self-torque correction folded in
    (:meth:`refresh`); :meth:`field_at` gives the total B of the bodies at any points (a magnetometer's reading).
    """

    def __init__(self, model, depth: float = 1.0):
        self.model = model
        self.dim, self.h = model.dim, float(model.dx)
        self.depth = float(depth) if model.dim == 2 else 1.0
        self.k = make_interaction_kernels(model.dim, model.scalar)
        self.magnetised = np.linalg.norm(model.host["remanence"][:, : model.dim], axis=1) > 0
        self.body = np.asarray(model.host["body"])
        self.bodies = tuple(int(b) for b in np.unique(self.body[self.magnetised]))  # the magnetised bodies
        n = model.n_particles
        self.B = wp.zeros(n, dtype=model.kernels["v3"], device=model.device)
        self.grad_B = wp.zeros(n, dtype=model.kernels["m3"], device=model.device)
        self.refreshes = 0
        self.host_reads = 0
        self.correct_self_torque = True
        self.self_torque = {}  # body -> the lattice's net self-torque removed at the last refresh (N m; 2D: z)
        self._padded = {}  # grid key ("all" or a body) -> its padded FFT size, kept while the box fits it
        self._key = self._lo_node = self._n = None  # the box of the last solve
        self._M = self._fields = None
        self._on_cpu = wp.get_device(model.device).is_cpu
        if len(self.bodies) > 1:  # each body's own field alone, for its self-torque
            self._B_own = wp.zeros(n, dtype=model.kernels["v3"], device=model.device)
            self._grad_B_own = wp.zeros(n, dtype=model.kernels["m3"], device=model.device)

    @property
    def active(self) -> bool:
        return bool(self.magnetised.any())

    # -- the grid ------------------------------------------------------------------------------------------
    def _fit(self, x_np: np.ndarray, key="all") -> None:
        """Place the grid over the magnetised particles (of body ``key``, or all), aligned with the model's
        grid; a new padded size (and kernel spectra) only when the box outgrows the current one."""
        from scipy import fft as sfft
        m, h = self.model, self.h
        mask = self.magnetised if key == "all" else self.magnetised & (self.body == key)
        pts = x_np[mask].astype(np.float64)
        lo = np.floor((pts.min(axis=0) - m.domain_lo) / h).astype(np.int64) - MARGIN
        hi = np.ceil((pts.max(axis=0) - m.domain_lo) / h).astype(np.int64) + MARGIN
        n = hi - lo + 1
        padded = self._padded.get(key)
        if padded is None or np.any(2 * n - 1 > np.asarray(padded)):
            # two nodes of room per axis before the next resize; the spectra depend on the size only, so a body
            # that moves without growing keeps them
            padded = self._padded[key] = tuple(int(sfft.next_fast_len(int(2 * (g + 2) - 1), real=True)) for g in n)
        # the grids hold the box only (the transforms pad it); reallocated only when a box outgrows them
        total = int(np.prod(n))
        n_out = self.dim + len(sym_pairs(self.dim))
        if self._M is None or self._M.shape[0] < self.dim * total:
            dev, sc = m.device, m.scalar
            cap = int(np.prod(np.asarray(padded) // 2 + 1))
            self._M = wp.zeros(self.dim * cap, dtype=sc, device=dev)
            self._fields = wp.zeros(n_out * cap, dtype=sc, device=dev)
        self._key, self._lo_node, self._n = key, lo, n

    def _grid_args(self):
        k = self.model.kernels
        sc = self.model.scalar
        lo = k["vec"](*[sc(self.model.domain_lo[a] + self._lo_node[a] * self.h) for a in range(self.dim)])
        return lo, sc(1.0 / self.h), k["ivec"](*[int(v) for v in self._n]), int(np.prod(self._n))

    def _solve(self, x: wp.array, F: wp.array) -> None:
        """Deposit the moments (of the box's body, or all) at positions ``x`` with deformation gradients ``F``
        and convolve."""
        from scipy import fft as sfft
        m = self.model
        lo, inv_h, shape, total = self._grid_args()
        self._M.zero_()
        scale = 1.0 / (MU0 * self.depth)
        select = -1 if self._key == "all" else int(self._key)
        launch_deposit_moments(self.k, m.n_particles, x=x, F=F, Br=m.Br, follows=m.follows, vol0=m.vol0, lo=lo,
                               inv_h=inv_h, shape=shape, n_total=total, scale=m.scalar(scale), body=m.body, select=select,
                               M=self._M, device=m.device)
        dim, padded, n = self.dim, self._padded[self._key], tuple(int(v) for v in self._n)
        if not self._on_cpu:
            self.host_reads += 1
        M = self._M.numpy()[: dim * total].reshape((dim,) + n)
        # grids and transforms in the model's precision (float32 halves their cost). The box is a corner of the
        # padded grid: the forward transforms pad one axis at a time and the inverse ones keep the box's rows of
        # each axis before the next, which skips the zero rows and the rows not read back (about half the work).
        Mk = sfft.rfft(M, n=padded[-1], axis=dim, workers=-1)
        for axis in range(dim - 1, 0, -1):
            Mk = sfft.fft(Mk, n=padded[axis - 1], axis=axis, workers=-1)
        K = _kernel_spectra(padded, self.h, dim, np.dtype(self.model.np_scalar).name)  # (outputs, dim, ...)
        out = np.empty((K.shape[0],) + Mk.shape[1:], dtype=Mk.dtype)
        for c in range(K.shape[0]):
            np.multiply(K[c, 0], Mk[0], out=out[c])
            for b in range(1, dim):
                out[c] += K[c, b] * Mk[b]
        for axis in range(1, dim):
            out = sfft.ifft(out, axis=axis, workers=-1)[(slice(None),) * axis + (slice(0, n[axis - 1]),)]
        fields = sfft.irfft(out, n=padded[-1], axis=dim, workers=-1)[..., : n[-1]]
        size = fields.size
        if self._on_cpu:
            self._fields.numpy()[:size] = fields.ravel()
        else:
            self._fields[:size].assign(fields.ravel())
        self._M_host = M

    def _gather(self, x: wp.array, B: wp.array, grad_B: wp.array) -> None:
        m = self.model
        lo, inv_h, shape, total = self._grid_args()
        launch_gather_field(self.k, m.n_particles, x=x, lo=lo, inv_h=inv_h, shape=shape, n_total=total,
                            fields=self._fields, mu0=m.scalar(MU0), B=B, grad_B=grad_B, device=m.device)

    # -- the self-torque -------------------------------------------------------------------------------------
    def moments(self, F_np: np.ndarray) -> np.ndarray:
        """Each particle's current moment m = F Br V0 / mu0 (A m^2), (N, 3); 2D: the in-plane part carried by F
        and the out-of-plane part Br_z V0 / mu0, as the engine's gradient force takes it. Particles whose moment
        follows R (magnetization_follows 1) carry Br with the rotation R of F = R U instead."""
        h, dim = self.model.host, self.dim
        m = np.array(h["remanence"], dtype=np.float64)
        Fm = F_np.astype(np.float64)
        rot = h["magnetization_follows"] != 0
        if rot.any():
            Fm = Fm.copy()
            Fm[rot] = polar_rotation_np(Fm[rot])
        m[:, :dim] = np.einsum("pij,pj->pi", Fm, m[:, :dim])
        return m * (h["volumes"][:, None] / MU0)

    def _remove_self_torque(self, x: wp.array, F: wp.array, x_np: np.ndarray) -> None:
        """Fold into ``grad_B`` the force field that cancels, body by body, the net torque the body's own lattice
        field exerts on it (docs/engine.md, "Self-torque").

        A body's own field exerts no net torque on it in physics; the lattice of node dipoles is not invariant
        under rotation and leaves one (first order in dx; up to ~2 % of mu0 M^2 V for a tilted 4:1 bar at four
        cells' width). It is measured from the body's field alone (the field of all bodies when there is one
        magnetised body, otherwise one more solve on the body's own box): tau = sum_p (x_p - c) x f_p + m_p x B_p
        over its particles, f_p = (grad B_p)^T m_p. It is cancelled by the forces f_p = w_p alpha x (x_p - c),
        w_p = |m_p| and c the w-weighted centroid, which sum to zero and whose torque I alpha = -tau
        (I = sum_p w_p (|r_p|^2 1 - r_p r_p^T)), so magnetised material bears the correction and the net force
        stays zero. The engine's gradient force is (grad B)^T m at the particle's current moment, so the force
        enters ``grad_B`` as the rank-one term m f^T / |m|^2, exact at the refresh. Torques between bodies are not
        touched. ``x_np``: the positions ``x`` on the host (the refresh read them already)."""
        dim = self.dim
        x_np = x_np.astype(np.float64)
        F_np = F.numpy()
        if not self._on_cpu:
            self.host_reads += 1
        m = self.moments(F_np)
        w = np.linalg.norm(m, axis=1)
        grad_B_all = self.grad_B.numpy()  # on the CPU a view: the correction is written in place
        B_all = None if len(self.bodies) > 1 else self.B.numpy()
        own = B_all is None
        for b in self.bodies:
            sel = np.nonzero((self.body == b) & (w > 0.0))[0]
            if own:
                self._fit(x_np, b)
                self._solve(x, F)
                self._gather(x, self._B_own, self._grad_B_own)
                Bb, grad_Bb = self._B_own.numpy()[sel], self._grad_B_own.numpy()[sel]
            else:
                Bb, grad_Bb = B_all[sel], grad_B_all[sel]
            Bb, grad_Bb = Bb.astype(np.float64), grad_Bb.astype(np.float64)
            ms, ws = m[sel], w[sel]
            c = (ws[:, None] * x_np[sel]).sum(axis=0) / ws.sum()
            r = np.zeros((len(sel), 3))
            r[:, :dim] = x_np[sel] - c
            f = np.einsum("pij,pi->pj", grad_Bb, ms)
            tau = np.cross(r, f).sum(axis=0) + np.cross(ms, Bb).sum(axis=0)
            if dim == 2:
                inertia = np.sum(ws * np.sum(r * r, axis=1))
                alpha = np.array([0.0, 0.0, -tau[2] / inertia]) if inertia > 0.0 else np.zeros(3)
                self.self_torque[b] = float(tau[2])
            else:
                inertia = np.einsum("p,pij->ij", ws, np.einsum("pk,pk->p", r, r)[:, None, None] * np.eye(3)
                                    - np.einsum("pi,pj->pij", r, r))
                alpha = -np.linalg.pinv(inertia) @ tau
                self.self_torque[b] = tau
            fc = ws[:, None] * np.cross(alpha, r)
            grad_B_all[sel] = grad_B_all[sel] + (np.einsum("pi,pj->pij", ms, fc) / (ws * ws)[:, None, None]).astype(grad_B_all.dtype)
        if not self._on_cpu:
            self.grad_B.assign(grad_B_all)

    # -- public ---------------------------------------------------------------------------------------------
    def refresh(self, x: wp.array, F: wp.array) -> None:
        """Recompute ``B`` and ``grad_B`` at the particles for positions ``x`` and deformation gradients ``F``, with
        each body's spurious self-torque removed (:meth:`_remove_self_torque`; ``correct_self_torque`` False:
        the lattice's field as it is)."""
        if not self.active:
            return
        if not self._on_cpu:
            self.host_reads += 1
        x_np = x.numpy()
        self._fit(x_np)
        self._solve(x, F)
        self._gather(x, self.B, self.grad_B)
        if self.correct_self_torque:
            self._remove_self_torque(x, F, x_np)
        self.refreshes += 1

    def add_to(self, B: wp.array, grad_B: wp.array, keep: bool) -> None:
        """Add the last refresh's field into the engine's per-particle arrays (``keep`` False: overwrite)."""
        launch_add_field(self.k, self.model.n_particles, B_int=self.B, grad_B_int=self.grad_B, keep=1 if keep else 0,
                         B=B, grad_B=grad_B, device=self.model.device)

    def field_at(self, points, x: wp.array, F: wp.array) -> np.ndarray:
        """Flux density B = mu0 (H + M) (T, (P, 3)) of the bodies' magnetisation at ``points`` (P, dim or 3) m, for
        the particle positions ``x`` and deformation gradients ``F``. Points inside the grid take the node fields
        with the particles' weights; points outside it the field of the node dipoles summed directly."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))[:, : self.dim]
        out = np.zeros((len(pts), 3))
        if not self.active:
            return out
        self._fit(x.numpy())
        self._solve(x, F)
        dim, h = self.dim, self.h
        n = tuple(int(v) for v in self._n)
        fields = self._fields.numpy()[: (dim + len(sym_pairs(dim))) * int(np.prod(n))].reshape((-1,) + n).astype(np.float64)
        M = self._M_host.astype(np.float64)
        lo = self.model.domain_lo + self._lo_node * h
        base, _, w3 = host_bspline(pts, lo, h)
        inside = np.all(base >= 0, axis=1) & np.all(base + 2 < self._n, axis=1)
        if not inside.all():  # the node dipoles, summed directly at the points outside the grid
            nodes = np.nonzero(np.any(M != 0.0, axis=0))
            moments = np.stack([M[a][nodes] for a in range(dim)], axis=-1)
            pos = lo + np.stack(nodes, axis=-1) * h
        for i, p in enumerate(pts):
            if inside[i]:
                weights = functools.reduce(np.multiply.outer, [w3[:, i, a] for a in range(dim)])
                sl = tuple(slice(b, b + 3) for b in base[i])
                H = np.array([np.sum(weights * fields[a][sl]) for a in range(dim)])
                Mp = np.array([np.sum(weights * M[a][sl]) for a in range(dim)]) / (h**dim)
                out[i, :dim] = MU0 * (H + Mp)
            else:
                T, _ = dipole_tensors(p - pos, h, dim)
                H = np.zeros(dim)
                for c, (a, b) in enumerate(sym_pairs(dim)):
                    H[a] += np.sum(T[c] * moments[:, b])
                    if a != b:
                        H[b] += np.sum(T[c] * moments[:, a])
                out[i, :dim] = MU0 * H
        return out
