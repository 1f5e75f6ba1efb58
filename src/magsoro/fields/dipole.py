"""Point dipole: the far field of a small permanent magnet (seed 004 eq 14)."""


import numpy as np
import warp as wp

from magsoro import MU0
from magsoro.fields.base import MovingSource, as_points
from magsoro.fields.profiles import Keyframes


# computed in Python double precision: arithmetic on literals inside a wp.func would be done in float32
MU0_OVER_4PI = wp.constant(wp.float64(MU0 / (4.0 * np.pi)))


@wp.func
def dipole_field(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
    """B and grad B of a point dipole; prm = [px, py, pz, mx, my, mz]."""
    r = p - wp.vec3d(prm[0], prm[1], prm[2])
    m = wp.vec3d(prm[3], prm[4], prm[5])
    r2 = wp.dot(r, r)
    zero = wp.float64(0.0)
    if r2 == zero:
        return wp.vec3d(zero, zero, zero), wp.mat33d(zero, zero, zero, zero, zero, zero, zero, zero, zero)
    rn = wp.sqrt(r2)
    k = MU0_OVER_4PI
    inv3 = wp.float64(1.0) / (r2 * rn)
    mr = wp.dot(m, r)
    B = k * inv3 * (wp.float64(3.0) * mr / r2 * r - m)
    c = wp.float64(3.0) * k * inv3 / r2
    eye = wp.identity(n=3, dtype=wp.float64)
    G = c * (mr * eye + wp.outer(m, r) + wp.outer(r, m) - wp.float64(5.0) * mr / r2 * wp.outer(r, r))
    return B, G


class Dipole(MovingSource):
    """Point magnetic dipole.

    Parameters
    ----------
    moment : 3-vector, A m^2
    position : 3-vector, metres (centre of the dipole)
    path : optional :class:`~magsoro.fields.profiles.Keyframes` of positions over time (metres), overriding
        ``position`` when given, so a magnet can be swept past a robot.

    B = mu0/(4 pi) (3 r (m.r)/r^5 - m/r^3), r = x - position.
    """

    def __init__(self, moment, position=(0.0, 0.0, 0.0), path: Keyframes | None = None):
        self.moment = np.asarray(moment, dtype=np.float64).reshape(3)
        self.position = np.asarray(position, dtype=np.float64).reshape(3)
        if path is not None and path.values.shape[1] != 3:
            raise ValueError("a dipole path needs 3 position components")
        self.path = path

    def B(self, points, t=0.0):
        r = as_points(points) - self.position_at(t)
        rn = np.linalg.norm(r, axis=1, keepdims=True)
        mr = r @ self.moment
        with np.errstate(divide="ignore", invalid="ignore"):
            out = MU0 / (4 * np.pi) * (3 * r * (mr[:, None] / rn**5) - self.moment / rn**3)
        out[rn[:, 0] == 0] = 0.0
        return out

    def grad_B(self, points, t=0.0):
        r = as_points(points) - self.position_at(t)
        m = self.moment
        r2 = np.einsum("ni,ni->n", r, r)
        mr = r @ m
        with np.errstate(divide="ignore", invalid="ignore"):
            c = 3 * MU0 / (4 * np.pi) / r2**2.5
            G = (
                mr[:, None, None] * np.eye(3)
                + m[None, :, None] * r[:, None, :]
                + r[:, :, None] * m[None, None, :]
                - 5 * (mr / r2)[:, None, None] * r[:, :, None] * r[:, None, :]
            ) * c[:, None, None]
        G[r2 == 0] = 0.0
        return G

    def device_func(self):
        return dipole_field

    def device_params(self, t):
        return np.concatenate([self.position_at(t), self.moment])

    def __repr__(self):
        return f"Dipole(moment={self.moment.tolist()}, position={self.position.tolist()})"
