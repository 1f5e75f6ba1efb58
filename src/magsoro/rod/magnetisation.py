"""Magnetisation profiles along a rod: the remanence Br(s) (tesla) in the rod's material frame (d1, d2, d3)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from magsoro.errors import SceneError


def _vec3(value, name: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise SceneError(f"{name}: must be 3 numbers, got {value!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise SceneError(f"{name}: must be 3 finite numbers, got {value!r}")
    return a


@dataclass(frozen=True)
class MagnetSegment:
    """A stretch ``start <= s < end`` (m, arc length from the clamp) with uniform remanence ``remanence`` (T),
    given in the material frame: component 3 is along the rod axis, 1 along the width, 2 along the thickness."""

    start: float
    end: float
    remanence: tuple[float, float, float]


class Magnetisation:
    """Remanence profile Br(s) in tesla, material frame.

    Build it from a list of :class:`MagnetSegment` (or ``(start, end, (Br1, Br2, Br3))`` tuples; arc lengths in m),
    from a callable ``s -> Br`` (s in m, Br a 3-vector in T), or from one 3-vector (uniform over the whole rod).
    Points covered by no segment are unmagnetised. Segment ends become integration nodes so the
    jump in Br is resolved exactly.
    """

    def __init__(self, profile=None, length: float | None = None):
        self._callable: Callable | None = None
        self.segments: list[MagnetSegment] = []
        if profile is None:
            return
        if callable(profile):
            self._callable = profile
            return
        arr = None
        try:
            arr = np.asarray(profile, dtype=np.float64)
        except (TypeError, ValueError):
            arr = None
        if arr is not None and arr.shape == (3,):
            if length is None:
                raise SceneError("magnetisation: a uniform remanence needs the rod length")
            self.segments = [MagnetSegment(0.0, float(length), tuple(_vec3(arr, "magnetisation")))]
            return
        if not isinstance(profile, Sequence):
            raise SceneError(f"magnetisation: expected segments, a callable or a 3-vector (T), got {profile!r}")
        for i, seg in enumerate(profile):
            name = f"magnetisation[{i}]"
            if isinstance(seg, MagnetSegment):
                start, end, br = seg.start, seg.end, seg.remanence
            else:
                try:
                    start, end, br = seg
                except (TypeError, ValueError):
                    raise SceneError(f"{name}: expected (start m, end m, remanence T 3-vector), got {seg!r}") from None
            start, end = float(start), float(end)
            if not (np.isfinite(start) and np.isfinite(end)) or not (0.0 <= start < end):
                raise SceneError(f"{name}: need 0 <= start < end (m), got start={start}, end={end}")
            if length is not None and end > length * (1 + 1e-12):
                raise SceneError(f"{name}: end = {end} m lies beyond the rod length {length} m")
            self.segments.append(MagnetSegment(start, end, tuple(_vec3(br, f"{name}.remanence"))))
        ordered = sorted(self.segments, key=lambda g: g.start)
        for a, b in zip(ordered, ordered[1:]):
            if b.start < a.end - 1e-15:
                raise SceneError(f"magnetisation: segments [{a.start}, {a.end}] and [{b.start}, {b.end}] m overlap")

    def breakpoints(self) -> list[float]:
        """Arc lengths (m) where Br may jump."""
        pts = set()
        for g in self.segments:
            pts.update((g.start, g.end))
        return sorted(pts)

    def __call__(self, s) -> np.ndarray:
        """Br at arc lengths ``s`` (m, scalar or array of shape (N,)); returns (3,) or (N, 3) in tesla."""
        s_arr = np.asarray(s, dtype=np.float64)
        flat = np.atleast_1d(s_arr).ravel()
        if self._callable is not None:
            out = np.array([_vec3(self._callable(float(x)), f"magnetisation({x})") for x in flat]).reshape(-1, 3)
        else:
            out = np.zeros((flat.size, 3))
            for g in self.segments:
                inside = (flat >= g.start) & (flat < g.end)
                out[inside] = g.remanence
        return out[0] if s_arr.ndim == 0 else out
