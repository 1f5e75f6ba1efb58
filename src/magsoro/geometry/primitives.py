"""Primitive shapes and the lattice fill that turns them into particles.

Particles sit on a regular lattice aligned with the grid: along each axis, ``particles_per_cell`` points per
cell at offsets (k + 1/2) / n of the cell. Each particle stands for exactly (dx / n)^dim of material, so a
filled body's volume is count x (dx / n)^dim and the same scene always gives the same particles.
"""

from __future__ import annotations

import numpy as np

from magsoro.geometry.transforms import rotation_to_axis


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
        # a vertex repeated (the outline closed by the first vertex again) is an edge of zero length: drop it
        keep = np.any(self.vertices != np.roll(self.vertices, -1, axis=0), axis=1)
        if keep.sum() >= 3:
            self.vertices = self.vertices[keep]
        crossing = self._crossing_edges()
        if crossing is not None:
            i, j = crossing
            raise ValueError(f"vertices: the polygon's edges {i} and {j} (from vertex {i} and from vertex {j}) cross: "
                             f"the outline intersects itself; list the vertices in order around it")
        if abs(self._signed_area()) == 0:
            raise ValueError("vertices: the polygon has zero area (its vertices lie on one line)")

    def _crossing_edges(self) -> tuple[int, int] | None:
        """The first pair of edges (i, j), i < j, that are not neighbours and cross or touch, or None (a simple
        polygon). Edge i runs from vertex i to vertex i + 1."""
        a = self.vertices
        b = np.roll(a, -1, axis=0)
        k = len(a)

        def orient(p, q, r):
            return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

        for i in range(k - 2):
            j = np.arange(i + 2, k if i > 0 else k - 1)  # the last edge neighbours edge 0
            if not len(j):
                continue
            p, q, r, s = a[i], b[i], a[j], b[j]
            o1, o2, o3, o4 = orient(p, q, r), orient(p, q, s), orient(r, s, p), orient(r, s, q)
            hit = (o1 != o2) & (o3 != o4) & (o1 * o2 <= 0) & (o3 * o4 <= 0)
            if hit.any():
                return i, int(j[np.argmax(hit)])
        return None

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


def euler_rotation(degrees) -> np.ndarray:
    """Rotation matrix (local -> world) from angles [rx, ry, rz] in degrees, applied about the fixed x, then y,
    then z axes (R = Rz Ry Rx). A 2D scene's shapes use rz only."""
    rx, ry, rz = np.deg2rad(np.asarray(degrees, dtype=np.float64).reshape(3))
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


class Transformed(Shape):
    """A shape defined in its own frame, placed by a rotation ``rotation`` (local -> world, 3x3 or 2x2) and a
    translation ``position`` (m): world = R local + position."""

    def __init__(self, local: Shape, position, rotation=None):
        self.local = local
        self.dim = local.dim
        d = self.dim
        self.position = np.asarray(position, dtype=np.float64).reshape(d)
        R = np.eye(d) if rotation is None else np.asarray(rotation, dtype=np.float64)
        self.R = R[:d, :d]

    def contains(self, points):
        return self.local.contains((np.asarray(points, dtype=np.float64)[:, : self.dim] - self.position) @ self.R)

    def bounds(self):
        lo, hi = (np.asarray(b, dtype=np.float64)[: self.dim] for b in self.local.bounds())
        corners = np.array(np.meshgrid(*[[l, h] for l, h in zip(lo, hi)], indexing="ij")).reshape(self.dim, -1).T
        world = corners @ self.R.T + self.position
        return world.min(axis=0), world.max(axis=0)

    def volume(self):
        return self.local.volume()


class Tube(Shape):
    """Hollow cylinder: ``inner_radius`` <= r <= ``outer_radius``, length ``length`` (m), centred at ``center``
    along ``axis``."""

    def __init__(self, center, outer_radius, inner_radius, length, axis=(0, 0, 1)):
        self.center = np.asarray(center, dtype=np.float64).reshape(3)
        self.outer, self.inner, self.length = float(outer_radius), float(inner_radius), float(length)
        if not (0 <= self.inner < self.outer) or self.length <= 0:
            raise ValueError("a tube needs 0 <= inner_radius < outer_radius and length > 0")
        self.R = rotation_to_axis(axis)
        self._hull = Cylinder(center, outer_radius, length, axis)

    def contains(self, points):
        q = (np.asarray(points) - self.center) @ self.R
        r = np.hypot(q[:, 0], q[:, 1])
        return (r <= self.outer) & (r >= self.inner) & (np.abs(q[:, 2]) <= 0.5 * self.length)

    def bounds(self):
        return self._hull.bounds()

    def volume(self):
        return np.pi * (self.outer**2 - self.inner**2) * self.length


class Slab(Shape):
    """A 2D region (polygon, annular sector) extruded symmetrically along local z over ``thickness`` (m)."""

    def __init__(self, profile: Shape, thickness: float):
        if profile.dim != 2:
            raise ValueError("the extruded profile must be two-dimensional")
        self.profile, self.thickness = profile, float(thickness)
        if self.thickness <= 0:
            raise ValueError("extrusion thickness must be > 0")

    def contains(self, points):
        p = np.asarray(points)
        return self.profile.contains(p[:, :2]) & (np.abs(p[:, 2]) <= 0.5 * self.thickness)

    def bounds(self):
        lo, hi = self.profile.bounds()
        t = 0.5 * self.thickness
        return np.array([lo[0], lo[1], -t]), np.array([hi[0], hi[1], t])

    def volume(self):
        return self.profile.volume() * self.thickness


class AnnularSector(Shape):
    """2D annular sector about the origin: ``radius`` - width/2 <= r <= ``radius`` + width/2 and polar angle in
    [start, end] (radians, end > start, span <= 2 pi). Used for arc/arch strips."""

    dim = 2

    def __init__(self, radius: float, width: float, start: float, end: float):
        self.inner, self.outer = float(radius) - 0.5 * float(width), float(radius) + 0.5 * float(width)
        self.start, self.end = float(start), float(end)
        if not (0 <= self.inner < self.outer):
            raise ValueError("an arc needs 0 < width <= 2 radius")
        if not (0 < self.end - self.start <= 2 * np.pi + 1e-12):
            raise ValueError("an arc needs 0 < end_angle - start_angle <= 360 degrees")

    def contains(self, points):
        p = np.asarray(points)
        r = np.hypot(p[:, 0], p[:, 1])
        # angle measured from start in [0, 2 pi): robust to sectors crossing the +x axis
        a = np.mod(np.arctan2(p[:, 1], p[:, 0]) - self.start, 2 * np.pi)
        return (r >= self.inner) & (r <= self.outer) & (a <= self.end - self.start + 1e-12)

    def bounds(self):
        # the extreme points are the corner points and the axis crossings inside the span
        angles = [self.start, self.end] + [k * 0.5 * np.pi for k in range(-8, 9) if self.start < k * 0.5 * np.pi < self.end]
        a = np.asarray(angles)
        pts = np.concatenate([np.stack([r * np.cos(a), r * np.sin(a)], axis=1) for r in (self.inner, self.outer)])
        return pts.min(axis=0), pts.max(axis=0)

    def volume(self):
        return 0.5 * (self.end - self.start) * (self.outer**2 - self.inner**2)
