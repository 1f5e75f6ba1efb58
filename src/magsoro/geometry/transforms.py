"""Rigid-frame helpers shared by the shapes and the engine's colliders."""

import numpy as np


def rotation_to_axis(axis) -> np.ndarray:
    """A rotation matrix whose third column is the unit vector ``axis``."""
    z = np.asarray(axis, dtype=np.float64).reshape(3)
    nz = np.linalg.norm(z)
    if nz == 0:
        raise ValueError("axis must be non-zero")
    z = z / nz
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)
