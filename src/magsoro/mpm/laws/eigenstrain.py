"""Stimulus-driven eigenstrain: a material whose stress-free shape follows a scalar stimulus (temperature, swelling
ratio, light dose, ...) given as a time profile.

Model (multiplicative split, as thermal expansion and swelling are written at finite strain):

    F = F_e F_s,  F_s = lambda(s) I  (isotropic)  or  F_s = I + (lambda(s) - 1) a a^T  (along a unit a),

with ``a`` in the reference frame and s = s(t) the stimulus. The energy per reference volume is
W(F) = f(s) det(F_s) W_e(F F_s^-1): W_e is the material's own law (:mod:`magsoro.mpm.laws.elastic`) on the elastic part,
counted per volume of the stress-free (intermediate) configuration, and f(s) > 0 the modulus factor. Every law's
energy is linear in its moduli (G, K, Cij, Ogden mu_i; the Ogden exponents are not moduli), so scaling all moduli
by f scales W_e by f, and the stress is

    P = dW/dF = f det(F_s) P_e(F F_s^-1) F_s^-T.

A free body therefore takes F = F_s and carries no stress; lambda < 1 shrinks, > 1 swells. The magnetic stress
and the moment m = F Br V0 / mu0 are unchanged (the magnetic particles do not shrink with the matrix), and so is
the mass: a hydrogel that expels water loses some, which only the inertia would see.

Axisymmetric sections: the isotropic eigenstretch acts round the ring as well (F_s = lambda I in 3D, det F_s =
lambda^3), so a free ring shrinks by lambda in r, z and its circumference alike; a directional one lies in the
(r, z) plane.

2D (plane strain): F_zz = 1 for the body, and the eigenstretch acts in the plane only (F_s is the 2 x 2 tensor,
F_s,zz = 1), so a free 2D section shrinks by lambda along both in-plane axes, stress-free, and
det F_s = lambda^2 (isotropic) or lambda (along an in-plane direction). (A 3D-isotropic lambda held at F_zz = 1
would leave sigma_zz and shrink the section by (1 + nu) times more strain.)

The tables ``stretch`` = [[s, lambda], ...] and ``modulus_factor`` = [[s, f], ...] are interpolated linearly in s
and held constant outside their range (a single row: a constant).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from magsoro.fields.profiles import Keyframes


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def table_problem(rows, positive: str) -> str | None:
    """What is wrong with a table [[s, value], ...] (values ``positive``, their name), or None: at least one row,
    two finite numbers per row, s strictly increasing, every value > 0."""
    if isinstance(rows, (str, bytes)) or not isinstance(rows, Sequence) or len(rows) == 0:
        return f"must be a table [[s, {positive}], ...] of at least one row"
    for i, r in enumerate(rows):
        if isinstance(r, (str, bytes)) or not isinstance(r, Sequence) or len(r) != 2:
            return f"row {i} must be two numbers [s, {positive}], got {r!r}"
        if not all(_finite(x) for x in r):
            return f"row {i} must be two finite numbers [s, {positive}], got {list(r)!r}"
        if not r[1] > 0:
            return f"{positive} must be > 0 in every row, got {r[1]!r} in row {i}"
    s = [float(r[0]) for r in rows]
    if any(b <= a for a, b in zip(s, s[1:])):
        return f"the s column must be strictly increasing, got {s}"
    return None


class SineStimulus:
    """s(t) = offset + amplitude sin(2 pi frequency t + phase); ``frequency`` in Hz, ``phase`` in radians."""

    def __init__(self, frequency: float, amplitude: float = 1.0, offset: float = 0.0, phase: float = 0.0):
        self.frequency, self.amplitude, self.offset, self.phase = float(frequency), float(amplitude), float(offset), float(phase)

    def __call__(self, t: float) -> float:
        return self.offset + self.amplitude * math.sin(2.0 * math.pi * self.frequency * t + self.phase)

    def bounds(self) -> tuple[float, float]:
        return self.offset - abs(self.amplitude), self.offset + abs(self.amplitude)


class KeyframeStimulus:
    """s(t) interpolated linearly between ``values`` at increasing ``times`` (s), held outside the table. A ramp
    from ``initial`` to ``final`` over [start, start + duration] is :meth:`ramp`, a constant :meth:`constant`."""

    def __init__(self, times, values):
        self.table = Keyframes(times, values)
        if self.table.values.shape[1] != 1:
            raise ValueError("stimulus keyframes need one value per time")

    @classmethod
    def ramp(cls, duration: float, start: float = 0.0, initial: float = 0.0, final: float = 1.0) -> KeyframeStimulus:
        if not duration > 0:
            raise ValueError(f"ramp duration must be > 0 s, got {duration}")
        return cls([start, start + duration], [initial, final])

    @classmethod
    def constant(cls, value: float) -> KeyframeStimulus:
        return cls([0.0], [value])

    def __call__(self, t: float) -> float:
        return float(np.interp(float(t), self.table.times, self.table.values[:, 0]))

    def bounds(self) -> tuple[float, float]:
        v = self.table.values[:, 0]
        return float(v.min()), float(v.max())


class Stimulus:
    """One material's eigenstretch law (module docstring): the stimulus profile s(t) (a callable with
    ``bounds()`` -> (lowest, highest s), e.g. :class:`KeyframeStimulus`), the tables ``stretch`` [[s, lambda], ...]
    and ``modulus_factor`` [[s, f], ...] (None: f = 1), and ``direction`` (None: isotropic; else ``dim``
    components in the reference frame, any non-zero length). ValueError names the bad argument."""

    def __init__(self, profile, stretch, modulus_factor=None, direction=None):
        if not callable(profile):
            raise ValueError("profile must be a callable t (s) -> stimulus")
        problem = table_problem(stretch, "lambda")
        if problem is not None:
            raise ValueError(f"stretch: {problem}")
        if modulus_factor is not None:
            problem = table_problem(modulus_factor, "f")
            if problem is not None:
                raise ValueError(f"modulus_factor: {problem}")
        self.profile = profile
        self.stretch = np.asarray(stretch, dtype=np.float64).reshape(-1, 2)
        self.modulus_factor = None if modulus_factor is None else np.asarray(modulus_factor, dtype=np.float64).reshape(-1, 2)
        self.direction = None
        if direction is not None:
            a = np.asarray(direction, dtype=np.float64).ravel()
            n = float(np.linalg.norm(a))
            if a.size not in (2, 3) or not np.all(np.isfinite(a)) or not n > 0:
                raise ValueError(f"direction must be 2 or 3 finite components of non-zero length, got {direction!r}")
            self.direction = a / n

    def values(self, t: float) -> tuple[float, float]:
        """(lambda, f) at time t (s)."""
        s = float(self.profile(t))
        lam = float(np.interp(s, self.stretch[:, 0], self.stretch[:, 1]))
        f = 1.0 if self.modulus_factor is None else float(np.interp(s, self.modulus_factor[:, 0], self.modulus_factor[:, 1]))
        return lam, f

    def tensors(self, lam: float, f: float, dim: int, ring: bool = False) -> tuple[np.ndarray, float, float]:
        """F_s^-1 (dim x dim), the stress factor f det F_s and 1 / F_s,tt for the stretch ``lam`` and modulus factor
        ``f``. ``ring``: an axisymmetric section (dim 2), whose isotropic eigenstretch acts round the ring too
        (F_s,tt = lambda, det F_s = lambda^3); a directional one lies in the (r, z) plane (F_s,tt = 1)."""
        if self.direction is None:
            return np.eye(dim) / lam, f * lam ** (dim + 1 if ring else dim), 1.0 / lam if ring else 1.0
        if self.direction.size != dim:
            raise ValueError(f"direction has {self.direction.size} components, the model is {dim}D")
        a = self.direction
        return np.eye(dim) + (1.0 / lam - 1.0) * np.outer(a, a), f * lam, 1.0

    def stiffening(self, dim: int, ring: bool = False) -> float:
        """An upper bound of f det F_s over the stimulus range the profile reaches: the factor by which the
        squared elastic wave speed grows (the time step's bound). The maximum of each piecewise-linear table over
        the range lies at a breakpoint inside it or at an end; the product of the two maxima bounds the maximum of
        the product."""
        lo, hi = self.profile.bounds()

        def top(table):
            s = np.concatenate([[lo, hi], table[(table[:, 0] > lo) & (table[:, 0] < hi), 0]])
            return float(np.max(np.interp(s, table[:, 0], table[:, 1])))

        lam = top(self.stretch)
        f = 1.0 if self.modulus_factor is None else top(self.modulus_factor)
        return f * lam ** ((dim + 1 if ring else dim) if self.direction is None else 1)
