"""How thick a body is where it is thinnest, in grid cells: the resolution check behind ``magsoro run``'s note on
bodies with fewer than three cells through a plate, a hinge or a wall.

A body's particles sit on the lattice of spacing ``h`` (``dx / particles_per_cell``), each standing for an
``h``-sized square or cube, so the body is the union of those squares. The check rasterises that union at ``h / 2``
and takes the Euclidean distance transform ``d`` (distance from each sub-cell centre to the nearest empty one):
on a plate of ``n`` rows, ``2 n`` sub-rows, the largest ``d`` is ``n`` sub-cells, so ``2 max d`` is the plate's
thickness ``n h`` exactly for axis-aligned plates, with any parity of ``n``. A particle's local thickness is twice
the largest ``d`` within a box around it that reaches the middle of a part up to ``limit`` thick (the
"ridge" of the distance map): on a thin part that is the part's thickness; on a thick one it exceeds the limit.
Parts are measured across their narrowest direction, so a long thin hinge is thin however long it is, and a
plate's corners (where the ridge is still the plate's) are not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: sub-cells per particle spacing in the rasterised body: 2 makes the thickness exact for whole rows of either parity
SUBDIVISION = 2
#: bodies whose rasterised box would exceed this many sub-cells are measured at the particle spacing instead
#: (a thickness over by at most one spacing, for an odd number of rows)
MAX_SUBCELLS = 40_000_000


@dataclass
class Thickness:
    """Thin parts of one body: the thickness of its thinnest part (m; exact below the limit asked for, and at least
    about the limit when no part is thinner), and how many of its particles lie in parts thinner than the limit."""

    thinnest: float
    thin: np.ndarray  # (N,) bool: the particles in parts thinner than the limit
    particles: int

    @property
    def thin_particles(self) -> int:
        return int(self.thin.sum())


def thin_parts(positions: np.ndarray, spacing: float, limit: float, origin=None) -> Thickness | None:
    """Measure one body's particles ``positions`` (N, dim) on a lattice of ``spacing`` (m) whose sites lie at
    ``origin + (j + 1/2) spacing``: the thickness of its thinnest part, when under ``limit`` (m), and how many
    particles lie in parts thinner than ``limit``. None when the particles do not sit on that lattice (a particle
    file of another spacing): the measure would see holes."""
    x = np.asarray(positions, dtype=np.float64)
    n, dim = x.shape
    if n == 0:
        return None
    origin = np.zeros(dim) if origin is None else np.asarray(origin, dtype=np.float64)[:dim]
    f = (x - origin) / spacing - 0.5
    j = np.rint(f).astype(np.int64)
    if np.abs(f - j).max() > 0.05:
        return None
    j -= j.min(axis=0)
    extent = j.max(axis=0) + 1
    sub = SUBDIVISION if np.prod(extent * SUBDIVISION + 2, dtype=np.float64) <= MAX_SUBCELLS else 1
    occupied = np.zeros(tuple(extent * sub + 2), dtype=bool)  # a ring of empty sub-cells round the body
    for offset in np.ndindex(*(sub,) * dim):
        occupied[tuple((j * sub + 1 + np.array(offset)).T)] = True
    from scipy import ndimage

    d = ndimage.distance_transform_edt(occupied)
    # the ridge of a part thinner than ``limit`` is within limit / 2 of every point of it
    reach = int(np.ceil(0.5 * limit / spacing * sub)) + 1
    ridge = ndimage.maximum_filter(d, size=2 * reach + 1, mode="constant", cval=0.0)
    # a particle's thickness: the thinnest over its sub-cells (its sub-cells see the same ridge but for the edges)
    local = np.full(n, np.inf)
    for offset in np.ndindex(*(sub,) * dim):
        local = np.minimum(local, ridge[tuple((j * sub + 1 + np.array(offset)).T)])
    thickness = 2.0 * local * spacing / sub
    thin = thickness < limit * (1.0 - 1e-9)
    return Thickness(float(thickness.min()), thin, n)
