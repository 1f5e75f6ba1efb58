"""An external permanent magnet following a keyframed pose: position AND moment over time.

:class:`KeyframedDipole` is a :class:`~magsoro.fields.base.FieldSource` (host B / grad B and the device form the
MPM engine evaluates) whose position is interpolated linearly and whose moment turns along the great circle
between keyframes (spherical linear interpolation at constant |m|), the way a robot arm carries a magnet
between two poses. It reuses the point-dipole device function of :mod:`magsoro.fields.dipole`, so the engine's
field code is the one already verified there.

Pose tables are CSV files with columns t (s), x, y, z (m), mx, my, mz (A m^2): :meth:`KeyframedDipole.from_csv`
and :meth:`KeyframedDipole.to_csv`. When the moment never turns, :meth:`KeyframedDipole.scene_field` gives the
``[[fields]]`` table of a scene (a dipole with a position path), which ``magsoro run`` loads as is.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from magsoro.fields.base import FieldSource
from magsoro.fields.dipole import Dipole, dipole_field
from magsoro.fields.profiles import Keyframes

COLUMNS = ["t", "x", "y", "z", "mx", "my", "mz"]


def slerp(u0, u1, s: float) -> np.ndarray:
    """Vector between ``u0`` and ``u1`` (same length) turned by the fraction ``s`` of the angle between them,
    its length interpolated linearly; opposite vectors turn about an axis perpendicular to ``u0``."""
    u0, u1 = np.asarray(u0, dtype=float), np.asarray(u1, dtype=float)
    n0, n1 = np.linalg.norm(u0), np.linalg.norm(u1)
    if n0 == 0 or n1 == 0:
        return (1 - s) * u0 + s * u1
    a, b = u0 / n0, u1 / n1
    c = float(np.clip(a @ b, -1.0, 1.0))
    if c > 1.0 - 1e-12:
        d = (1 - s) * a + s * b
        d /= np.linalg.norm(d)
    else:
        if c < -1.0 + 1e-12:
            helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
            perp = np.cross(a, helper)
            perp /= np.linalg.norm(perp)
        else:
            perp = b - c * a
            perp /= np.linalg.norm(perp)
        ang = np.arccos(c) * s
        d = np.cos(ang) * a + np.sin(ang) * perp
    return ((1 - s) * n0 + s * n1) * d


class KeyframedDipole(FieldSource):
    """Point dipole (seed 004 eq 14) with keyframed position (m) and moment (A m^2).

    times : (K,) increasing, s. positions : (K, 3) m. moments : (K, 3) A m^2. Held constant outside the table.
    """

    def __init__(self, times, positions, moments):
        self.path = Keyframes(times, positions)
        m = np.asarray(moments, dtype=np.float64)
        if m.shape != (len(self.path.times), 3) or self.path.values.shape[1] != 3:
            raise ValueError("a keyframed dipole needs (K, 3) positions and (K, 3) moments, one row per time")
        if np.any(np.linalg.norm(m, axis=1) == 0) or not np.all(np.isfinite(m)):
            raise ValueError("keyframed dipole moments must be finite and non-zero")
        self.moments = m

    @property
    def times(self) -> np.ndarray:
        return self.path.times

    @property
    def positions(self) -> np.ndarray:
        return self.path.values

    def position_at(self, t: float) -> np.ndarray:
        """Magnet position (m) at time t (s)."""
        return self.path.value(t)

    def moment_at(self, t: float) -> np.ndarray:
        """Magnet moment (A m^2) at time t (s)."""
        times = self.path.times
        if t <= times[0]:
            return self.moments[0].copy()
        if t >= times[-1]:
            return self.moments[-1].copy()
        k = int(np.searchsorted(times, t, side="right")) - 1
        s = (t - times[k]) / (times[k + 1] - times[k])
        return slerp(self.moments[k], self.moments[k + 1], s)

    def dipole_at(self, t: float) -> Dipole:
        """The fixed :class:`~magsoro.fields.Dipole` at time t."""
        return Dipole(self.moment_at(t), self.position_at(t))

    def B(self, points, t=0.0):
        return self.dipole_at(t).B(points)

    def grad_B(self, points, t=0.0):
        return self.dipole_at(t).grad_B(points)

    def device_func(self):
        return dipole_field

    def device_params(self, t):
        return np.concatenate([self.position_at(t), self.moment_at(t)])

    @property
    def moment_is_constant(self) -> bool:
        return bool(np.allclose(self.moments, self.moments[0], rtol=1e-12, atol=0.0))

    def scene_field(self) -> dict:
        """The scene ``[[fields]]`` table (a ``dipole`` with a position ``path``) of this source; only for a
        constant moment, which is what the scene schema supports."""
        if not self.moment_is_constant:
            raise ValueError("the moment turns between keyframes; a scene dipole has a constant moment "
                             "(use KeyframedDipole in Python, e.g. appended to Simulation.control.sources)")
        return {
            "type": "dipole",
            "moment": [float(v) for v in self.moments[0]],
            "position": [float(v) for v in self.positions[0]],
            "path": {"times": [float(v) for v in self.times], "positions": [[float(v) for v in p] for p in self.positions]},
        }

    def to_csv(self, path) -> None:
        """Write the keyframes as CSV (t, x, y, z, mx, my, mz)."""
        with Path(path).open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(COLUMNS)
            for t, p, m in zip(self.times, self.positions, self.moments):
                w.writerow([f"{t:.12g}", *[f"{v:.12e}" for v in p], *[f"{v:.12e}" for v in m]])

    @classmethod
    def from_csv(cls, path) -> "KeyframedDipole":
        """Read keyframes written by :meth:`to_csv` (header t, x, y, z, mx, my, mz)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such file")
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
        if not rows or any(c not in rows[0] for c in COLUMNS):
            raise ValueError(f"{path}: needs a header with {COLUMNS} and at least one row")
        data = np.array([[float(r[c]) for c in COLUMNS] for r in rows])
        return cls(data[:, 0], data[:, 1:4], data[:, 4:7])

    def __repr__(self):
        return f"KeyframedDipole({len(self.times)} keyframes, t = {self.times[0]:g} .. {self.times[-1]:g} s)"
