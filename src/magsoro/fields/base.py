"""The field-source interface shared by every source and by the MPM engine.

A source gives the applied flux density B (tesla) and its gradient grad_B[n, i, j] = dB_i/dx_j (tesla per metre)
at points in metres, on the host (numpy) and on the device (a Warp function the engine calls per particle).

Device contract (what a new source implements to plug into the engine):

- ``device_func()`` returns a ``@wp.func`` with signature ``(p: wp.vec3d, prm: wp.array(dtype=wp.float64))`` that
  returns ``(wp.vec3d, wp.mat33d)``: B and grad B at the point p (metres). It is evaluated in float64 whatever the
  simulation precision, because magnet fields involve differences of nearly equal terms.
- ``device_params(t)`` returns a 1D float64 numpy array with everything the function needs at time t (pose,
  moment, lattice values ...). Its length must not change between calls.

A spatially uniform source sets ``uniform = True`` and implements ``uniform_value(t)`` instead: the engine adds
the sum of all uniform sources as a single vector, and they cost nothing per particle.
"""

from __future__ import annotations

import numpy as np


def as_points(points) -> np.ndarray:
    """Return points as a float64 (N, 3) array; a single point (3,) becomes (1, 3)."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 1:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3) in metres, got {np.shape(points)}")
    return p


class FieldSource:
    """Base class of all field sources. Sources add with ``+`` into a :class:`FieldSum`."""

    uniform: bool = False

    def B(self, points, t: float = 0.0) -> np.ndarray:
        """Flux density at ``points`` ((N, 3) metres) and time ``t`` (s), as (N, 3) tesla."""
        raise NotImplementedError

    def grad_B(self, points, t: float = 0.0) -> np.ndarray:
        """Gradient ``grad_B[n, i, j] = dB_i/dx_j`` at ``points`` ((N, 3) metres), as (N, 3, 3) tesla per metre."""
        raise NotImplementedError

    # uniform sources
    def uniform_value(self, t: float) -> np.ndarray:
        """For uniform sources: the field vector (tesla) at time ``t``."""
        raise NotImplementedError

    # device form
    def device_func(self):
        """The ``@wp.func`` evaluating (B, grad B) of this source on the device; see the module docstring."""
        raise NotImplementedError(f"{type(self).__name__} has no device form")

    def device_params(self, t: float) -> np.ndarray:
        """Float64 parameter vector passed to :meth:`device_func` at time ``t``."""
        raise NotImplementedError(f"{type(self).__name__} has no device form")

    def max_magnitude(self, points, t: float = 0.0) -> float:
        """Largest |B| (tesla) over ``points`` at time ``t``; used for time-step estimates."""
        b = self.B(points, t)
        return float(np.max(np.linalg.norm(b, axis=1))) if len(b) else 0.0

    def sources(self) -> list["FieldSource"]:
        """The elementary sources this one is made of (itself for an elementary source)."""
        return [self]

    def __add__(self, other: "FieldSource") -> "FieldSum":
        return FieldSum([*self.sources(), *other.sources()])


def unit_vector(v, name: str) -> np.ndarray:
    """``v`` as a unit 3-vector; ValueError naming ``name`` when it is not 3 finite numbers or is zero."""
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers, got {v!r}")
    n = np.linalg.norm(a)
    if n == 0:
        raise ValueError(f"{name} must be non-zero")
    return a / n


class MovingSource(FieldSource):
    """A source with a ``position`` (m) that may follow keyframes ``path``, and, where it has an ``axis``, an
    ``axis_path`` of keyframed directions."""

    path = None
    axis_path = None

    def position_at(self, t: float) -> np.ndarray:
        """Centre (metres) at time ``t`` (s)."""
        return self.path.value(t) if self.path is not None else self.position

    def axis_at(self, t: float) -> np.ndarray:
        """Unit axis at time ``t`` (s)."""
        return unit_vector(self.axis_path.value(t), "axis") if self.axis_path is not None else self.axis


class FieldSum(FieldSource):
    """Superposition of sources: B and grad B add."""

    def __init__(self, sources):
        self._sources = []
        for s in sources:
            self._sources.extend(s.sources())

    @property
    def uniform(self) -> bool:  # type: ignore[override]
        """True when every source of the sum is uniform (the same B at every point)."""
        return all(s.uniform for s in self._sources)

    def sources(self):
        return list(self._sources)

    def B(self, points, t=0.0):
        p = as_points(points)
        out = np.zeros((len(p), 3))
        for s in self._sources:
            out += s.B(p, t)
        return out

    def grad_B(self, points, t=0.0):
        p = as_points(points)
        out = np.zeros((len(p), 3, 3))
        for s in self._sources:
            out += s.grad_B(p, t)
        return out

    def uniform_value(self, t):
        return sum((s.uniform_value(t) for s in self._sources if s.uniform), np.zeros(3))

    def __repr__(self):
        return f"FieldSum({self._sources!r})"
