"""Geometry: shapes filled with particles on a lattice aligned with the MPM grid."""

from magsoro.geometry.primitives import Box, Cylinder, Polygon, Rectangle, Shape, Sphere, fill_lattice

__all__ = ["Shape", "Box", "Cylinder", "Sphere", "Rectangle", "Polygon", "fill_lattice"]
