"""Time profiles: scalar or vector functions of time used by field sources and moving colliders."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np


def _is_number(text) -> bool:
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return True


class Keyframes:
    """Piecewise-linear interpolation of values given at increasing times; held constant outside the table.

    ``times`` (K,) in seconds, ``values`` (K, D). ``value(t)`` returns (D,), ``rate(t)`` the slope (D,) per second
    (zero outside the table), which moving colliders use as their velocity.
    """

    def __init__(self, times, values):
        t = np.asarray(times, dtype=np.float64).ravel()
        v = np.asarray(values, dtype=np.float64)
        if v.ndim == 1:
            v = v[:, None]
        if len(t) == 0 or len(t) != len(v):
            raise ValueError(f"keyframes need as many times as values and at least one row, got {len(t)} times and {len(v)} values")
        if np.any(np.diff(t) <= 0):
            raise ValueError("keyframe times must be strictly increasing")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ValueError("keyframe times and values must be finite")
        self.times = t
        self.values = v

    @classmethod
    def from_csv(cls, path, columns: list[str]):
        """Read a CSV with a header holding ``t`` and the given value ``columns``."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"keyframe table {path} does not exist")
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
        if not rows:
            raise ValueError(f"keyframe table {path} has no rows")
        missing = [c for c in ["t", *columns] if c not in rows[0]]
        if missing:
            raise ValueError(f"keyframe table {path} lacks column(s) {missing}; it needs 't' and {columns}")
        t, v = [], []
        for k, r in enumerate(rows):
            line = k + 2  # the header is line 1
            try:
                row = [float(r[c]) for c in ["t", *columns]]
            except (TypeError, ValueError):
                bad = next(c for c in ["t", *columns] if not _is_number(r[c]))
                raise ValueError(f"keyframe table {path}: line {line}, column {bad}: {r[bad]!r} is not a number") from None
            bad = next((c for c, x in zip(["t", *columns], row) if not np.isfinite(x)), None)
            if bad is not None:
                raise ValueError(f"keyframe table {path}: line {line}, column {bad}: {r[bad]!r} is not finite")
            t.append(row[0])
            v.append(row[1:])
        return cls(t, v)

    def value(self, t: float) -> np.ndarray:
        """The interpolated value (D,) at time ``t`` (s), in the units of ``values``."""
        t = float(t)
        return np.array([np.interp(t, self.times, self.values[:, d]) for d in range(self.values.shape[1])])

    def rate(self, t: float) -> np.ndarray:
        """The slope (D,) at time ``t`` (s), units of ``values`` per second; zero outside the table."""
        if len(self.times) < 2 or t < self.times[0] or t >= self.times[-1]:
            return np.zeros(self.values.shape[1])
        k = int(np.searchsorted(self.times, t, side="right")) - 1
        return (self.values[k + 1] - self.values[k]) / (self.times[k + 1] - self.times[k])
