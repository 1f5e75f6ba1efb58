"""Evaluate field sources on the device at particle positions (the engine's side of the field interface)."""


import functools

import numpy as np
import warp as wp

from magsoro.fields.base import FieldSource


@functools.cache
def accumulate_kernel(func, dim: int, scalar, differentiable: bool = False):
    """Kernel adding (B, grad B) of one source's ``func`` at particle positions into per-particle arrays.

    In 2D (plane strain in the x-y plane) the particle sits at (x, y, plane_z). ``differentiable``: with its
    adjoint, for the differentiable rollout's wp.Tape (:mod:`magsoro.diff`); a simulation's has none, which Warp
    would otherwise compile for every source (docs/engine.md, "Compile time").
    """
    vec = wp.types.vector(length=dim, dtype=scalar)
    v3 = wp.types.vector(length=3, dtype=scalar)
    m3 = wp.types.matrix(shape=(3, 3), dtype=scalar)

    @wp.kernel(enable_backward=differentiable)
    def accumulate(
        x: wp.array(dtype=vec),
        prm: wp.array(dtype=wp.float64),
        plane_z: wp.float64,
        overwrite: int,
        B: wp.array(dtype=v3),
        grad_B: wp.array(dtype=m3),
    ):
        i = wp.tid()
        xp = x[i]
        p = wp.vec3d(wp.float64(xp[0]), wp.float64(xp[1]), plane_z)
        if wp.static(dim == 3):
            p = wp.vec3d(wp.float64(xp[0]), wp.float64(xp[1]), wp.float64(xp[2]))
        b, g = func(p, prm)
        bs = v3(scalar(b[0]), scalar(b[1]), scalar(b[2]))
        gs = m3(g)
        if overwrite == 1:
            B[i] = bs
            grad_B[i] = gs
        else:
            B[i] = B[i] + bs
            grad_B[i] = grad_B[i] + gs

    return accumulate


def launch_accumulate(kernel, n, *, x, params, plane_z, overwrite, B, grad_B, device, record=False):
    """An :func:`accumulate_kernel` over ``n`` positions ``x``: the source's (B, grad B) with parameters ``params``
    (float64) written into (``overwrite`` 1) or added to (0) ``B`` and ``grad_B``; ``plane_z`` a wp.float64. The one
    place its argument order is written; ``record=True`` returns Warp's recorded launch."""
    return wp.launch(kernel, dim=n, device=device, record_cmd=record,
                     inputs=[x, params, plane_z, overwrite, B, grad_B])


class FieldEvaluator:
    """Holds the sources of a run and fills per-particle B / grad B arrays each step.

    Uniform sources are summed on the host into one vector (:meth:`uniform_value`); the others run a kernel
    each. ``has_gradient`` is False when every source is uniform, and then no per-particle arrays are used.
    """

    def __init__(self, sources: list[FieldSource], dim: int, scalar, device, plane_z: float = 0.0):
        flat = []
        for s in sources:
            flat.extend(s.sources())
        self.uniform_sources = [s for s in flat if s.uniform]
        self.point_sources = [s for s in flat if not s.uniform]
        self.dim, self.scalar, self.device = dim, scalar, device
        self.plane_z = float(plane_z)
        self._kernels = [accumulate_kernel(s.device_func(), dim, scalar) for s in self.point_sources]
        self._params = [
            wp.array(np.asarray(s.device_params(0.0), dtype=np.float64), dtype=wp.float64, device=device)
            for s in self.point_sources
        ]

    @property
    def has_gradient(self) -> bool:
        return bool(self.point_sources)

    def uniform_value(self, t: float) -> np.ndarray:
        out = np.zeros(3)
        for s in self.uniform_sources:
            out += s.uniform_value(t)
        return out

    @property
    def param_arrays(self) -> list:
        """The device arrays (float64) the non-uniform sources' kernels read their parameters from, in order."""
        return list(self._params)

    def params_at(self, t: float) -> np.ndarray:
        """The non-uniform sources' parameters at time ``t``, one after the other (the layout of
        :attr:`param_arrays`)."""
        out = []
        for src, prm in zip(self.point_sources, self._params):
            values = np.asarray(src.device_params(t), dtype=np.float64)
            if values.shape != tuple(prm.shape):
                raise ValueError(f"{type(src).__name__}.device_params changed length during the run")
            out.append(values)
        return np.concatenate(out) if out else np.zeros(0)

    def record_launches(self, x: wp.array, B: wp.array, grad_B: wp.array) -> list:
        """The launches of :meth:`evaluate` for positions ``x``, recorded (``wp.Launch``) for a check window: they
        read the parameters the arrays of :attr:`param_arrays` hold when they run (the window's drive table
        fills them), not those of a time given here."""
        return [launch_accumulate(kern, x.shape[0], x=x, params=prm, plane_z=wp.float64(self.plane_z),
                                  overwrite=1 if k == 0 else 0, B=B, grad_B=grad_B, device=self.device, record=True)
                for k, (kern, prm) in enumerate(zip(self._kernels, self._params))]

    def evaluate(self, x: wp.array, B: wp.array, grad_B: wp.array, t: float) -> None:
        """Write the non-uniform sources' B (T) and grad B (T/m) at positions ``x`` into ``B`` and ``grad_B`` (device
        arrays)."""
        n = x.shape[0]
        for k, (src, kern, prm) in enumerate(zip(self.point_sources, self._kernels, self._params)):
            values = np.asarray(src.device_params(t), dtype=np.float64)
            if values.shape != tuple(prm.shape):
                raise ValueError(f"{type(src).__name__}.device_params changed length during the run")
            prm.assign(values)
            launch_accumulate(kern, n, x=x, params=prm, plane_z=wp.float64(self.plane_z), overwrite=1 if k == 0 else 0,
                              B=B, grad_B=grad_B, device=self.device)

    def evaluate_host(self, points: np.ndarray, t: float = 0.0):
        """Device evaluation of all sources (uniform included) at (N, dim) points, returned as numpy (B, grad B).

        Used to check device forms against host forms.
        """
        vec = wp.types.vector(length=self.dim, dtype=self.scalar)
        v3 = wp.types.vector(length=3, dtype=self.scalar)
        m3 = wp.types.matrix(shape=(3, 3), dtype=self.scalar)
        pts = np.asarray(points, dtype=np.float64)
        x = wp.array(pts[:, : self.dim], dtype=vec, device=self.device)
        B = wp.zeros(len(pts), dtype=v3, device=self.device)
        grad_B = wp.zeros(len(pts), dtype=m3, device=self.device)
        if self.has_gradient:
            self.evaluate(x, B, grad_B, t)
        return B.numpy().astype(np.float64) + self.uniform_value(t), grad_B.numpy().astype(np.float64)
