"""Primitive shapes and the lattice fill that turns them into particles.

Particles sit on a regular lattice aligned with the grid: along each axis, ``particles_per_cell`` points per
cell at offsets (k + 1/2) / n of the cell. Each particle stands for exactly (dx / n)^dim of material, so a
filled body's volume is count x (dx / n)^dim and the same scene always gives the same particles.
"""

from __future__ import annotations

import numpy as np

from magsoro.mpm.colliders import rotation_to_axis


class Shape:
    """A solid region. ``contains(points)`` tells membership of (N, dim) points (m); ``bounds()`` its box."""

    dim = 3

    def contains(self, points: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def volume(self) -> float:
        """Exact volume (m^3; area m^2 in 2D) of the shape."""
        raise NotImplementedError


class Box(Shape):
    """Box of full ``size`` (m) centred at ``center``; optional ``rotation`` (3x3, local->world)."""

    def __init__(self, center, size, rotation=None):
        self.center = np.asarray(center, dtype=np.float64).reshape(3)
        self.half = 0.5 * np.asarray(size, dtype=np.float64).reshape(3)
        self.R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64).reshape(3, 3)
        if np.any(self.half <= 0):
            raise ValueError("box size must be > 0 along every axis")

    def contains(self, points):
        q = (np.asarray(points) - self.center) @ self.R
        return np.all(np.abs(q) <= self.half, axis=1)

    def bounds(self):
        ext = np.abs(self.R) @ self.half
        return self.center - ext, self.center + ext

    def volume(self):
        return float(np.prod(2 * self.half))


class Sphere(Shape):
    def __init__(self, center, radius):
        self.center = np.asarray(center, dtype=np.float64).reshape(3)
        self.radius = float(radius)
        if self.radius <= 0:
            raise ValueError("sphere radius must be > 0")

    def contains(self, points):
        return np.linalg.norm(np.asarray(points) - self.center, axis=1) <= self.radius

    def bounds(self):
        return self.center - self.radius, self.center + self.radius

    def volume(self):
        return 4.0 / 3.0 * np.pi * self.radius**3


class Cylinder(Shape):
    """Solid cylinder of ``radius`` and ``length`` (m) centred at ``center`` along ``axis``."""

    def __init__(self, center, radius, length, axis=(0, 0, 1)):
        self.center = np.asarray(center, dtype=np.float64).reshape(3)
        self.radius, self.length = float(radius), float(length)
        if self.radius <= 0 or self.length <= 0:
            raise ValueError("cylinder radius and length must be > 0")
        self.R = rotation_to_axis(axis)

    def contains(self, points):
        q = (np.asarray(points) - self.center) @ self.R
        return (np.hypot(q[:, 0], q[:, 1]) <= self.radius) & (np.abs(q[:, 2]) <= 0.5 * self.length)

    def bounds(self):
        axis = self.R[:, 2]
        ext = 0.5 * self.length * np.abs(axis) + self.radius * np.sqrt(np.clip(1 - axis**2, 0, 1))
        return self.center - ext, self.center + ext

    def volume(self):
        return np.pi * self.radius**2 * self.length


class Rectangle(Shape):
    """2D rectangle of full ``size`` (m) centred at ``center``, rotated by ``angle`` (rad) about z."""

    dim = 2

    def __init__(self, center, size, angle: float = 0.0):
        self.center = np.asarray(center, dtype=np.float64).reshape(2)
        self.half = 0.5 * np.asarray(size, dtype=np.float64).reshape(2)
        if np.any(self.half <= 0):
            raise ValueError("rectangle size must be > 0 along both axes")
        c, s = np.cos(angle), np.sin(angle)
        self.R = np.array([[c, -s], [s, c]])

    def contains(self, points):
        q = (np.asarray(points) - self.center) @ self.R
        return np.all(np.abs(q) <= self.half, axis=1)

    def bounds(self):
        ext = np.abs(self.R) @ self.half
        return self.center - ext, self.center + ext

    def volume(self):
        return float(np.prod(2 * self.half))


class Polygon(Shape):
    """2D simple polygon given by its vertices (K, 2) in m, in either winding order."""

    dim = 2

    def __init__(self, vertices):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 2 or len(self.vertices) < 3:
            raise ValueError("a polygon needs at least 3 vertices of 2 coordinates")
        if abs(self._signed_area()) == 0:
            raise ValueError("polygon has zero area")

    def _signed_area(self):
        x, y = self.vertices[:, 0], self.vertices[:, 1]
        return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))

    def contains(self, points):
        p = np.asarray(points)
        inside = np.zeros(len(p), dtype=bool)
        v = self.vertices
        for i in range(len(v)):
            a, b = v[i], v[(i + 1) % len(v)]
            crosses = (a[1] > p[:, 1]) != (b[1] > p[:, 1])
            with np.errstate(divide="ignore", invalid="ignore"):
                xint = a[0] + (p[:, 1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
            inside ^= crosses & (p[:, 0] < xint)
        return inside

    def bounds(self):
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def volume(self):
        return abs(self._signed_area())


def lattice_points(lo, hi, dx: float, particles_per_cell: int, origin) -> np.ndarray:
    """Lattice sites inside the box [lo, hi], aligned with the grid whose node 0 is at ``origin``."""
    n = int(particles_per_cell)
    h = dx / n
    axes = []
    for a in range(len(lo)):
        # sites at origin + (j + 1/2) h for integer j
        j0 = int(np.floor((lo[a] - origin[a]) / h - 0.5))
        j1 = int(np.ceil((hi[a] - origin[a]) / h - 0.5))
        axes.append(origin[a] + (np.arange(j0, j1 + 1) + 0.5) * h)
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def fill_lattice(shape: Shape, dx: float, particles_per_cell: int, origin, dim: int) -> tuple[np.ndarray, float]:
    """Particles of ``shape`` on the grid-aligned lattice; returns (positions (N, dim), volume per particle).

    In 2D the returned volume is the area per particle (m^2); the caller multiplies by the depth.
    """
    if particles_per_cell < 1:
        raise ValueError("particles_per_cell must be >= 1")
    lo, hi = shape.bounds()
    lo, hi = np.asarray(lo)[:dim], np.asarray(hi)[:dim]
    pts = lattice_points(lo, hi, dx, particles_per_cell, np.asarray(origin, dtype=np.float64)[:dim])
    inside = shape.contains(pts)
    return pts[inside], (dx / particles_per_cell) ** dim
