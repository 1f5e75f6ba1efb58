"""Any Magpylib source or collection as a field source: sampled once on a lattice, interpolated on the device.

Magpylib (>= 5, SI units: metres, tesla, amperes) computes B of arbitrary magnet and coil assemblies on the
host. Calling it per particle per step would be far too slow, so :class:`MagpylibSource` samples B once on a
regular lattice covering the region the robot moves in and interpolates there with tricubic Catmull-Rom
splines (the tensor product of 1D cubic Hermite interpolation with central-difference slopes). The
interpolant is C1, so the gradient taken from it (the derivative of the spline, not a finite difference) is
continuous and the magnetic force has no jumps between cells. Value error is O(h^3) and gradient error
O(h^2) in the lattice spacing h; a spacing of a fifth of the distance to the nearest magnet gives better
than 1% (see docs/fields.md).

Lattice layout: the nodes span ``bounds`` exactly, plus one ghost layer outside each face so that every
point inside ``bounds`` has its full 4x4x4 stencil. Keep the lattice (ghost layer included) out of the
magnets and away from wires, where B is not smooth.
"""

import numpy as np
import warp as wp

from magsoro.fields.base import FieldSource, as_points

HEADER = 15
"""Device parameter header: origin (3, the first ghost node), spacing (3), node counts (3), bounds lo (3), hi (3)."""


def _catmull_rom(t):
    """Weights (..., 4) and their t-derivatives for nodes -1, 0, 1, 2 at fraction t in [0, 1]."""
    t2 = t * t
    t3 = t2 * t
    w = np.stack([(-t3 + 2 * t2 - t) / 2, (3 * t3 - 5 * t2 + 2) / 2, (-3 * t3 + 4 * t2 + t) / 2, (t3 - t2) / 2], -1)
    dw = np.stack([(-3 * t2 + 4 * t - 1) / 2, (9 * t2 - 10 * t) / 2, (-9 * t2 + 8 * t + 1) / 2, (3 * t2 - 2 * t) / 2], -1)
    return w, dw


def _import_magpylib():
    try:
        import magpylib
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "MagpylibSource needs Magpylib (>= 5): pip install magpylib, or install magsoro with its test extra"
        ) from exc
    return magpylib


class MagpylibSource(FieldSource):
    """B of a Magpylib source or collection, sampled on a regular lattice and interpolated (tricubic).

    Parameters
    ----------
    source : a Magpylib source (magnet, current, dipole ...), a ``magpylib.Collection``, or a list of them
        (their fields add). Magpylib 5+ works in SI: positions in metres, polarisation in tesla, currents in A.
    bounds : ((xmin, ymin, zmin), (xmax, ymax, zmax)), metres. The region where the field is wanted.
    spacing : float or 3-vector, metres. Largest lattice spacing; each axis is divided into
        ceil(extent / spacing) equal cells so the lattice ends exactly on ``bounds``. Give this or ``shape``.
    shape : 3 ints >= 2. Number of lattice nodes along x, y, z inside ``bounds``. Give this or ``spacing``.
    times : optional sequence of K increasing times (s) for a source whose Magpylib ``path`` has K poses: one
        lattice is sampled per pose and B(t) is interpolated linearly between them (held at the ends).
        Without ``times`` the source must have a single pose.

    Notes
    -----
    Host ``B`` / ``grad_B`` raise ``ValueError`` for points outside ``bounds`` (see :meth:`contains`). The device
    form cannot raise: there positions outside ``bounds`` are clamped to the nearest point of ``bounds``,
    i.e. the field is continued as constant along the outward normal. Keep the robot inside the lattice.
    """

    def __init__(self, source, bounds, spacing=None, shape=None, times=None):
        mp = _import_magpylib()
        lo, hi = (np.asarray(b, dtype=np.float64).reshape(3) for b in bounds)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
            raise ValueError(f"bounds must be ((xmin, ymin, zmin), (xmax, ymax, zmax)) with max > min, got {bounds!r}")
        if (spacing is None) == (shape is None):
            raise ValueError("give exactly one of spacing (metres) or shape (nodes per axis)")
        extent = hi - lo
        if spacing is not None:
            sp = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (3,))
            if not np.all(sp > 0):
                raise ValueError(f"spacing must be > 0 m, got {spacing!r}")
            cells = np.maximum(1, np.ceil(extent / sp - 1e-9)).astype(int)
        else:
            sh = np.broadcast_to(np.asarray(shape), (3,))
            if np.any(sh.astype(int) != sh) or np.any(sh < 2):
                raise ValueError(f"shape must be 3 integers >= 2, got {shape!r}")
            cells = sh.astype(int) - 1
        self.lo, self.hi = lo, hi
        self.cells = cells
        self.spacing = extent / cells
        self.nodes = cells + 3  # one ghost node outside each face
        self.origin = lo - self.spacing
        axes = [self.origin[d] + self.spacing[d] * np.arange(self.nodes[d]) for d in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        try:
            raw = mp.getB(source, grid, squeeze=False, sumup=True)
        except Exception as exc:
            raise TypeError(
                f"MagpylibSource needs a Magpylib source, Collection or list of sources; Magpylib said: {exc}"
            ) from exc
        raw = np.asarray(raw, dtype=np.float64)
        K = raw.shape[1]
        lattices = raw.reshape(K, *self.nodes, 3)
        if not np.all(np.isfinite(lattices)):
            raise ValueError("Magpylib returned non-finite B on the lattice: move the lattice off wires and magnet edges")
        if times is None:
            if K != 1:
                raise ValueError(f"the source has a path of {K} poses: give times=... ({K} values in s) to follow it")
            self.times = None
        else:
            tt = np.asarray(times, dtype=np.float64).ravel()
            if len(tt) != K or np.any(np.diff(tt) <= 0):
                raise ValueError(f"times must be {K} strictly increasing values (one per path pose), got {len(tt)}")
            self.times = tt
        self.lattices = lattices
        self.source = source
        self._packed = None

    # lattice ----------------------------------------------------------------------------------------------------
    def contains(self, points) -> np.ndarray:
        """Boolean (N,): which points (metres) lie inside ``bounds`` (faces included, 1e-9 relative slack)."""
        p = as_points(points)
        tol = 1e-9 * (self.hi - self.lo)
        return np.all((p >= self.lo - tol) & (p <= self.hi + tol), axis=1)

    def _lattice_at(self, t) -> np.ndarray:
        if self.times is None:
            return self.lattices[0]
        tt = self.times
        if t <= tt[0]:
            return self.lattices[0]
        if t >= tt[-1]:
            return self.lattices[-1]
        k = int(np.searchsorted(tt, t, side="right")) - 1
        f = (t - tt[k]) / (tt[k + 1] - tt[k])
        return (1.0 - f) * self.lattices[k] + f * self.lattices[k + 1]

    def _interpolate(self, p, lattice):
        s = (np.clip(p, self.lo, self.hi) - self.lo) / self.spacing
        cell = np.clip(np.floor(s).astype(int), 0, self.cells - 1)
        w, dw = _catmull_rom(s - cell)  # (N, 3, 4)
        dw = dw / self.spacing[None, :, None]
        B = np.zeros((len(p), 3))
        grad_B = np.zeros((len(p), 3, 3))
        # padded index of stencil node i (node -1 of the cell) is cell + i
        for i in range(4):
            for j in range(4):
                for k in range(4):
                    v = lattice[cell[:, 0] + i, cell[:, 1] + j, cell[:, 2] + k]
                    wx, wy, wz = w[:, 0, i], w[:, 1, j], w[:, 2, k]
                    B += (wx * wy * wz)[:, None] * v
                    grad_B[:, :, 0] += (dw[:, 0, i] * wy * wz)[:, None] * v
                    grad_B[:, :, 1] += (wx * dw[:, 1, j] * wz)[:, None] * v
                    grad_B[:, :, 2] += (wx * wy * dw[:, 2, k])[:, None] * v
        return B, grad_B

    def _checked(self, points):
        p = as_points(points)
        inside = self.contains(p)
        if not np.all(inside):
            bad = p[~inside][0]
            raise ValueError(
                f"{int(np.sum(~inside))} point(s) lie outside the MagpylibSource lattice bounds "
                f"{self.lo.tolist()} .. {self.hi.tolist()} m, e.g. {bad.tolist()}; enlarge bounds"
            )
        return p

    # host forms -------------------------------------------------------------------------------------------------
    def field_and_gradient(self, points, t=0.0):
        """(B (N, 3) tesla, grad B (N, 3, 3) tesla/metre) from the interpolant; ValueError outside ``bounds``."""
        return self._interpolate(self._checked(points), self._lattice_at(t))

    def B(self, points, t=0.0):
        return self.field_and_gradient(points, t)[0]

    def grad_B(self, points, t=0.0):
        return self.field_and_gradient(points, t)[1]

    def max_magnitude(self, points, t=0.0):
        # the lattice covers the whole region: its largest node value bounds the interpolant closely enough
        return float(np.max(np.linalg.norm(self._lattice_at(t), axis=-1)))

    # device form ------------------------------------------------------------------------------------------------
    def device_func(self):
        return lattice_field

    def device_params(self, t):
        # the engine asks every step; a static lattice (no times) is packed once
        if self.times is None and self._packed is not None:
            return self._packed
        header = np.concatenate([self.origin, self.spacing, self.nodes.astype(np.float64), self.lo, self.hi])
        packed = np.concatenate([header, self._lattice_at(t).reshape(-1)])
        if self.times is None:
            self._packed = packed
        return packed

    def __repr__(self):
        return f"MagpylibSource({self.source!r}, bounds=({self.lo.tolist()}, {self.hi.tolist()}), shape={(self.cells + 1).tolist()})"


@wp.func
def _cr_weights(t: wp.float64):
    half = wp.float64(0.5)
    t2 = t * t
    t3 = t2 * t
    w = wp.vec4d(
        half * (-t3 + wp.float64(2.0) * t2 - t),
        half * (wp.float64(3.0) * t3 - wp.float64(5.0) * t2 + wp.float64(2.0)),
        half * (wp.float64(-3.0) * t3 + wp.float64(4.0) * t2 + t),
        half * (t3 - t2),
    )
    dw = wp.vec4d(
        half * (wp.float64(-3.0) * t2 + wp.float64(4.0) * t - wp.float64(1.0)),
        half * (wp.float64(9.0) * t2 - wp.float64(10.0) * t),
        half * (wp.float64(-9.0) * t2 + wp.float64(8.0) * t + wp.float64(1.0)),
        half * (wp.float64(3.0) * t2 - wp.float64(2.0) * t),
    )
    return w, dw


@wp.func
def lattice_field(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
    """Tricubic Catmull-Rom B and its gradient from a lattice in ``prm`` (layout: see MagpylibSource).

    Points outside the bounds are clamped onto them.
    """
    zero = wp.float64(0.0)
    ny = int(prm[7])
    nz = int(prm[8])
    B = wp.vec3d(zero, zero, zero)
    grad_B = wp.mat33d(zero, zero, zero, zero, zero, zero, zero, zero, zero)
    cell = wp.vec3i(0, 0, 0)
    frac = wp.vec3d(zero, zero, zero)
    for d in range(3):
        lo = prm[9 + d]
        hi = prm[12 + d]
        h = prm[3 + d]
        ncell = int(prm[6 + d]) - 3
        x = wp.clamp(p[d], lo, hi)
        s = (x - lo) / h
        c = wp.clamp(int(wp.floor(s)), 0, ncell - 1)
        cell[d] = c
        frac[d] = s - wp.float64(c)
    wx, dwx = _cr_weights(frac[0])
    wy, dwy = _cr_weights(frac[1])
    wz, dwz = _cr_weights(frac[2])
    dwx = dwx / prm[3]
    dwy = dwy / prm[4]
    dwz = dwz / prm[5]
    # a run-time trip count keeps these loops rolled: unrolled, the 64-node stencil takes ~15 s to compile
    four = int(prm[6]) * 0 + 4
    for i in range(four):
        for j in range(four):
            for k in range(four):
                idx = HEADER + 3 * (((cell[0] + i) * ny + (cell[1] + j)) * nz + (cell[2] + k))
                v = wp.vec3d(prm[idx], prm[idx + 1], prm[idx + 2])
                B = B + (wx[i] * wy[j] * wz[k]) * v
                col = wp.vec3d(dwx[i] * wy[j] * wz[k], wx[i] * dwy[j] * wz[k], wx[i] * wy[j] * dwz[k])
                grad_B = grad_B + wp.outer(v, col)
    return B, grad_B
