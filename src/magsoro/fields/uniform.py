"""Spatially uniform fields (coil systems far from their windings), constant or following a time profile."""

from __future__ import annotations

import numpy as np

from magsoro.fields.base import FieldSource, as_points
from magsoro.fields.profiles import Keyframes


def _vec3(v, name):
    a = np.asarray(v, dtype=np.float64).ravel()
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers, got {v!r}")
    return a


class Ramp:
    """B(t) = B * clip((t - start) / duration, 0, 1): a linear ramp from zero to ``B`` (tesla) over ``duration`` s."""

    def __init__(self, B, duration: float, start: float = 0.0):
        self.B = _vec3(B, "B")
        if not duration > 0:
            raise ValueError(f"ramp duration must be > 0 s, got {duration}")
        self.duration = float(duration)
        self.start = float(start)

    def __call__(self, t):
        return self.B * float(np.clip((t - self.start) / self.duration, 0.0, 1.0))

    def peak(self):
        return float(np.linalg.norm(self.B))


class Sine:
    """B(t) = B * (offset + sin(2 pi frequency t + phase)); ``frequency`` in Hz, ``phase`` in radians."""

    def __init__(self, B, frequency: float, phase: float = 0.0, offset: float = 0.0):
        self.B = _vec3(B, "B")
        self.frequency = float(frequency)
        self.phase = float(phase)
        self.offset = float(offset)

    def __call__(self, t):
        return self.B * (self.offset + np.sin(2 * np.pi * self.frequency * t + self.phase))

    def peak(self):
        return float(np.linalg.norm(self.B)) * (abs(self.offset) + 1.0)


class Rotating:
    """A field of constant ``magnitude`` (tesla) rotating at ``frequency`` (Hz) in the plane spanned by ``u`` and ``v``.

    B(t) = magnitude * (cos(w t + phase) u + sin(w t + phase) v) with w = 2 pi frequency; u and v are
    orthonormalised (v is made perpendicular to u), so the rotation sense is from u towards v.
    An optional ``ramp`` (s) grows the magnitude linearly from zero to avoid an impulsive start.
    """

    def __init__(self, magnitude: float, frequency: float, u=(1, 0, 0), v=(0, 1, 0), phase: float = 0.0, ramp: float = 0.0):
        u = _vec3(u, "u")
        v = _vec3(v, "v")
        nu = np.linalg.norm(u)
        if nu == 0:
            raise ValueError("rotation axis u must be non-zero")
        u = u / nu
        v = v - np.dot(v, u) * u
        nv = np.linalg.norm(v)
        if nv < 1e-12:
            raise ValueError("rotation vectors u and v must not be parallel")
        self.u, self.v = u, v / nv
        self.magnitude = float(magnitude)
        self.frequency = float(frequency)
        self.phase = float(phase)
        self.ramp = float(ramp)

    def __call__(self, t):
        a = 2 * np.pi * self.frequency * t + self.phase
        s = 1.0 if self.ramp <= 0 else float(np.clip(t / self.ramp, 0.0, 1.0))
        return s * self.magnitude * (np.cos(a) * self.u + np.sin(a) * self.v)

    def peak(self):
        return abs(self.magnitude)


class KeyframedVector:
    """Field vector interpolated linearly between keyframes (``times`` in s, ``vectors`` (K, 3) in tesla)."""

    def __init__(self, times, vectors):
        self.table = Keyframes(times, vectors)
        if self.table.values.shape[1] != 3:
            raise ValueError("keyframed field vectors need 3 components (Bx, By, Bz)")

    @classmethod
    def from_csv(cls, path):
        """CSV with header ``t,Bx,By,Bz`` (s, tesla)."""
        k = Keyframes.from_csv(path, ["Bx", "By", "Bz"])
        return cls(k.times, k.values)

    def __call__(self, t):
        return self.table.value(t)

    def peak(self):
        return float(np.max(np.linalg.norm(self.table.values, axis=1)))


class Uniform(FieldSource):
    """Spatially uniform field.

    ``Uniform(B)`` with ``B`` a 3-vector in tesla is constant; ``Uniform(profile)`` with ``profile`` one of
    :class:`Ramp`, :class:`Sine`, :class:`Rotating`, :class:`KeyframedVector` (or any callable t -> 3-vector
    tesla) varies in time. grad B is zero.
    """

    uniform = True

    def __init__(self, B=(0.0, 0.0, 0.0)):
        if callable(B):
            self.profile = B
        else:
            const = _vec3(B, "B")
            self.profile = lambda t, c=const: c
        self._peak = getattr(B, "peak", None)

    def uniform_value(self, t):
        return np.asarray(self.profile(t), dtype=np.float64)

    def B(self, points, t=0.0):
        p = as_points(points)
        return np.tile(self.uniform_value(t), (len(p), 1))

    def grad_B(self, points, t=0.0):
        return np.zeros((len(as_points(points)), 3, 3))

    def peak(self) -> float:
        """Largest |B| over time (tesla), used for time-step estimates."""
        if self._peak is not None:
            return self._peak()
        return float(np.linalg.norm(self.uniform_value(0.0)))

    def max_magnitude(self, points, t=0.0):
        return self.peak()

    def __repr__(self):
        return f"Uniform({self.profile!r})"
