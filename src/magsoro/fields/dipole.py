"""Point dipole: the far field of a small permanent magnet (seed 004 eq 14).

The package's one home for the dipole law: the host functions :func:`dipole_B`, :func:`dipole_grad_B` and
:func:`dipole_field_force`, the device function :func:`dipole_field` and the :class:`Dipole` source.
"""


import numpy as np
import warp as wp

from magsoro.constants import MU0
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
    grad_B = c * (mr * eye + wp.outer(m, r) + wp.outer(r, m) - wp.float64(5.0) * mr / r2 * wp.outer(r, r))
    return B, grad_B


def dipole_B(points, moment, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """B (N, 3), T, at (N, 3) ``points`` (m) of a point dipole of ``moment`` (A m^2) at ``position`` (m):
    mu0/(4 pi) (3 r (m.r)/r^5 - m/r^3), r = x - position; 0 at the dipole itself."""
    moment = np.asarray(moment, dtype=np.float64)
    r = as_points(points) - position
    rn = np.linalg.norm(r, axis=1, keepdims=True)
    mr = r @ moment
    with np.errstate(divide="ignore", invalid="ignore"):
        out = MU0 / (4 * np.pi) * (3 * r * (mr[:, None] / rn**5) - moment / rn**3)
    out[rn[:, 0] == 0] = 0.0
    return out


def dipole_grad_B(points, moment, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """grad B (N, 3, 3), T/m, [n, i, j] = dB_i/dx_j, of the point dipole of :func:`dipole_B`; 0 at the dipole."""
    m = np.asarray(moment, dtype=np.float64)
    r = as_points(points) - position
    r2 = np.einsum("ni,ni->n", r, r)
    mr = r @ m
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 3 * MU0 / (4 * np.pi) / r2**2.5
        grad_B = (
            mr[:, None, None] * np.eye(3)
            + m[None, :, None] * r[:, None, :]
            + r[:, :, None] * m[None, None, :]
            - 5 * (mr / r2)[:, None, None] * r[:, :, None] * r[:, None, :]
        ) * c[:, None, None]
    grad_B[r2 == 0] = 0.0
    return grad_B


def dipole_field_force(points, moments, moment, position):
    """B (P, 3), T, and the force f = (grad B)^T m_p (P, 3), N, on small moments ``moments`` (P, 3), A m^2, at
    ``points`` (P, 3), m, in the field of a point dipole of ``moment`` at ``position``: one closed form, without
    the (P, 3, 3) gradient. The points must not be at the dipole.

    dB_i/dx_k = c (M.r d_ik + M_i r_k + r_i M_k - 5 (M.r) r_i r_k / r^2), c = 3 mu0 / (4 pi r^5)."""
    M = moment
    r = points - position
    r2 = np.einsum("pi,pi->p", r, r)
    rn = np.sqrt(r2)
    Mr = r @ M
    mr = np.einsum("pi,pi->p", moments, r)
    k = MU0 / (4.0 * np.pi)
    B = k * (3.0 * r * (Mr / (r2 * r2 * rn))[:, None] - M[None, :] / (r2 * rn)[:, None])
    c = 3.0 * k / (r2 * r2 * rn)
    f = c[:, None] * (Mr[:, None] * moments + (moments @ M)[:, None] * r + mr[:, None] * M[None, :]
                      - (5.0 * Mr * mr / r2)[:, None] * r)
    return B, f


class Dipole(MovingSource):
    """Point magnetic dipole.

    Parameters
    ----------
    moment : 3-vector, A m^2
    position : 3-vector, metres (centre of the dipole)
    path : optional :class:`~magsoro.fields.profiles.Keyframes` of positions over time (metres), overriding
        ``position`` when given, so a magnet can be swept past a robot.

    Notes
    -----
    B = mu0/(4 pi) (3 r (m.r)/r^5 - m/r^3), r = x - position.
    """

    def __init__(self, moment, position=(0.0, 0.0, 0.0), path: Keyframes | None = None):
        self.moment = np.asarray(moment, dtype=np.float64).reshape(3)
        self.position = np.asarray(position, dtype=np.float64).reshape(3)
        if path is not None and path.values.shape[1] != 3:
            raise ValueError("a dipole path needs 3 position components")
        self.path = path

    def B(self, points, t=0.0):
        return dipole_B(points, self.moment, self.position_at(t))

    def grad_B(self, points, t=0.0):
        return dipole_grad_B(points, self.moment, self.position_at(t))

    def device_func(self):
        return dipole_field

    def device_params(self, t):
        return np.concatenate([self.position_at(t), self.moment])

    def __repr__(self):
        return f"Dipole(moment={self.moment.tolist()}, position={self.position.tolist()})"
