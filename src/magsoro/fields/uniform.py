"""Spatially uniform fields (coil systems far from their windings), constant or following a time profile."""

from __future__ import annotations

import numpy as np
import warp as wp

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
        """Largest |B(t)| over time, tesla."""
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
        """An upper bound of |B(t)| over time, tesla: |B| (|offset| + 1)."""
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
        """Largest |B(t)| over time, tesla."""
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
        """Largest |B| of the keyframes, tesla (linear interpolation never exceeds it)."""
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


class Regional(FieldSource):
    """A different uniform field in each of several axis-aligned boxes, zero outside them; grad B is zero.

    ``Regional([(lo, hi, source), ...])``: ``lo``, ``hi`` are box corners (3-vectors, metres) and ``source`` a
    :class:`Uniform` (constant or with a time profile). Made for batched runs of independent copies of a scene
    in one simulation (the ``sweep`` benchmark scene): each copy sits in its own box and gets its own drive.
    Boxes must not overlap. A point on a box face counts as inside. The engine evaluates it per particle at
    the current positions, so a copy that leaves its box stops feeling its field.
    """

    def __init__(self, regions):
        self.regions = []
        for i, item in enumerate(regions):
            try:
                lo, hi, src = item
            except (TypeError, ValueError):
                raise ValueError(f"Regional: region {i} must be (lo, hi, Uniform), got {item!r}") from None
            lo, hi = _vec3(lo, f"region {i} lo"), _vec3(hi, f"region {i} hi")
            if not np.all(hi > lo):
                raise ValueError(f"Regional: region {i} needs hi > lo on every axis, got lo {lo}, hi {hi}")
            if not isinstance(src, Uniform):
                raise ValueError(f"Regional: region {i} takes a Uniform source, got {type(src).__name__}")
            self.regions.append((lo, hi, src))
        if not self.regions:
            raise ValueError("Regional: needs at least one region")
        for i in range(len(self.regions)):
            for j in range(i):
                (a0, a1, _), (b0, b1, _) = self.regions[i], self.regions[j]
                if np.all(a0 < b1) and np.all(b0 < a1):
                    raise ValueError(f"Regional: regions {j} and {i} overlap")

    def _region_of(self, p: np.ndarray) -> np.ndarray:
        idx = np.full(len(p), -1)
        for k, (lo, hi, _) in enumerate(self.regions):
            inside = np.all((p >= lo) & (p <= hi), axis=1)
            idx[inside & (idx < 0)] = k
        return idx

    def B(self, points, t=0.0):
        p = as_points(points)
        out = np.zeros((len(p), 3))
        idx = self._region_of(p)
        for k, (_, _, src) in enumerate(self.regions):
            out[idx == k] = src.uniform_value(t)
        return out

    def grad_B(self, points, t=0.0):
        return np.zeros((len(as_points(points)), 3, 3))

    def max_magnitude(self, points, t=0.0):
        return max(src.peak() for _, _, src in self.regions)

    def device_params(self, t):
        rows = [np.concatenate([lo, hi, src.uniform_value(t)]) for lo, hi, src in self.regions]
        return np.concatenate([[float(len(rows))], *rows])

    def device_func(self):
        return _regional_func

    def __repr__(self):
        return f"Regional({len(self.regions)} regions)"


@wp.func
def _regional_func(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
    n = int(prm[0])
    b = wp.vec3d()
    found = int(0)
    for k in range(n):
        o = 1 + 9 * k
        if found == 0:
            if p[0] >= prm[o] and p[1] >= prm[o + 1] and p[2] >= prm[o + 2]:
                if p[0] <= prm[o + 3] and p[1] <= prm[o + 4] and p[2] <= prm[o + 5]:
                    b = wp.vec3d(prm[o + 6], prm[o + 7], prm[o + 8])
                    found = 1
    return b, wp.mat33d()
