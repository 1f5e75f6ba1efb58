"""Homogeneously magnetised cuboid (block) magnet: closed form of the surface-charge model.

A uniform polarisation J (= mu0 M, tesla) is equivalent to magnetic surface charges sigma = M.n on the faces.
For the z component, with half sizes (a, b, c) and corners (x_k, y_l, z_m), U = x - x_k, V = y - y_l,
W = z - z_m, R = |(U, V, W)| and s = (-1)^(k+l+m) (index 1 = lower face, 2 = upper), the field of the two
charged faces is (Yang et al., Supercond. Sci. Technol. 3, 591, 1990; Camacho & Sosa, Rev. Mex. Fis. E 59, 8,
2013):

    B_x = J_z/(4 pi) sum s (-ln(V + R))
    B_y = J_z/(4 pi) sum s (-ln(U + R))
    B_z = J_z/(4 pi) sum s atan(U V / (W R))          (+ J_z inside the magnet)

x and y components follow by cyclic permutation of the axes. grad B is the analytic derivative:
dB_x/dx = sum s (-U / (R (V + R))), dB_x/dy = sum s (-1/R), dB_x/dz = sum s (-W / (R (V + R))),
dB_y/dy = sum s (-V / (R (U + R))), dB_y/dz = sum s (-W / (R (U + R))), the rest from symmetry
(curl B = 0) and dB_z/dz = -(dB_x/dx + dB_y/dy) (div B = 0).

Numerics (as in Magpylib's implementation): the observer is first reflected into the octant x, y, z >= 0 of
the body frame, using B(P; J) = S B(SP; SJ) and grad B(P; J) = S grad B(SP; SJ) S for a mirror S (the cube is
mirror-symmetric and J is a polar vector in the charge picture). There x + a > 0, so in each corner pair at most
one V + R can suffer cancellation (V < 0), and it is evaluated as (U^2 + W^2)/(R - V), which is exact. The field
is singular only on the edges.
"""

import numpy as np
import warp as wp

from magsoro.constants import MU0
from magsoro.fields.base import MovingSource, as_points
from magsoro.fields.elliptic import PI_F64
from magsoro.fields.profiles import Keyframes

# permutations taking the magnetisation component to the local z axis: local axis i' is original axis PERM[i']
_PERM_Z = (0, 1, 2)
_PERM_X = (1, 2, 0)
_PERM_Y = (2, 0, 1)


def rotation_matrix(orientation) -> np.ndarray:
    """3x3 rotation matrix (body to world) from a matrix, a scipy Rotation, or a quaternion (x, y, z, w)."""
    if orientation is None:
        return np.eye(3)
    if hasattr(orientation, "as_matrix"):
        return np.asarray(orientation.as_matrix(), dtype=np.float64).reshape(3, 3)
    o = np.asarray(orientation, dtype=np.float64)
    if o.shape == (4,):
        n = np.linalg.norm(o)
        if not n > 0:
            raise ValueError("orientation quaternion must be non-zero")
        x, y, z, w = o / n
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
    if o.shape == (3, 3):
        if not (np.allclose(o @ o.T, np.eye(3), atol=1e-9) and np.linalg.det(o) > 0):
            raise ValueError("orientation matrix must be a proper rotation (orthonormal, det +1)")
        return o.copy()
    raise ValueError(f"orientation must be a 3x3 rotation matrix or a quaternion (x, y, z, w), got shape {o.shape}")


def _unit_z_np(x, y, z, a, b, c):
    """Per unit J_z, observer in the positive octant: B (N, 3) and grad B (N, 3, 3) times 4 pi."""
    N = len(x)
    bx = np.zeros(N)
    by = np.zeros(N)
    bz = np.zeros(N)
    gxx = np.zeros(N)
    gxy = np.zeros(N)
    gxz = np.zeros(N)
    gyy = np.zeros(N)
    gyz = np.zeros(N)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, xk in ((1, -a), (2, a)):
            U = x - xk
            for l, yl in ((1, -b), (2, b)):
                V = y - yl
                for m, zm in ((1, -c), (2, c)):
                    W = z - zm
                    s = 1.0 if (k + l + m) % 2 == 0 else -1.0
                    R = np.sqrt(U * U + V * V + W * W)
                    uw = U * U + W * W
                    vw = V * V + W * W
                    # 1/(V + R) and ln(V + R) without cancellation for V < 0 (only V = y - b can be < 0 here)
                    inv_vr = np.where(V >= 0, 1.0 / (V + R), (R - V) / uw)
                    inv_ur = np.where(U >= 0, 1.0 / (U + R), (R - U) / vw)
                    ln_vr = np.where(V >= 0, np.log(V + R), np.log(uw) - np.log(R - V))
                    ln_ur = np.where(U >= 0, np.log(U + R), np.log(vw) - np.log(R - U))
                    bx -= s * ln_vr
                    by -= s * ln_ur
                    bz += s * np.sign(W) * np.arctan2(U * V, np.abs(W) * R)
                    gxx -= s * U * inv_vr / R
                    gxy -= s / R
                    gxz -= s * W * inv_vr / R
                    gyy -= s * V * inv_ur / R
                    gyz -= s * W * inv_ur / R
    gzz = -(gxx + gyy)
    B = np.stack([bx, by, bz], axis=1)
    grad_B = np.stack(
        [np.stack([gxx, gxy, gxz], 1), np.stack([gxy, gyy, gyz], 1), np.stack([gxz, gyz, gzz], 1)], axis=1
    )
    return B, grad_B


def cuboid_body_field_np(pb, half, J, with_grad=True):
    """B (tesla) and grad B (tesla/metre) of a cuboid at body-frame points ``pb`` (N, 3).

    ``half`` = half sizes (a, b, c) in metres, ``J`` = polarisation (tesla) in the body frame.
    """
    S = np.where(pb < 0, -1.0, 1.0)
    q = np.abs(pb)
    Jr = S * J[None, :]  # reflected polarisation per point
    B = np.zeros_like(pb)
    grad_B = np.zeros((len(pb), 3, 3))
    for comp, perm in ((2, _PERM_Z), (0, _PERM_X), (1, _PERM_Y)):
        if J[comp] == 0.0:
            continue
        p = list(perm)
        b_loc, g_loc = _unit_z_np(q[:, p[0]], q[:, p[1]], q[:, p[2]], half[p[0]], half[p[1]], half[p[2]])
        w = Jr[:, comp] / (4.0 * np.pi)
        B[:, p] += w[:, None] * b_loc
        grad_B[:, np.array(p)[:, None], np.array(p)[None, :]] += w[:, None, None] * g_loc
    B = S * B
    grad_B = S[:, :, None] * grad_B * S[:, None, :]
    inside = np.all(np.abs(pb) < half[None, :], axis=1)
    B[inside] += J
    return B, grad_B


@wp.func
def _cuboid_unit_z_wp(x: wp.float64, y: wp.float64, z: wp.float64, a: wp.float64, b: wp.float64, c: wp.float64):
    """Device form of :func:`_unit_z_np` for one point: (B, grad B) times 4 pi per unit J_z."""
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    bx = zero
    by = zero
    bz = zero
    gxx = zero
    gxy = zero
    gxz = zero
    gyy = zero
    gyz = zero
    for k in range(2):
        U = x + a
        if k == 1:
            U = x - a
        for l in range(2):
            V = y + b
            if l == 1:
                V = y - b
            for m in range(2):
                W = z + c
                if m == 1:
                    W = z - c
                # loop indices run 0, 1 for corner indices 1, 2: s = (-1)^(k+l+m+3)
                s = one
                if (k + l + m) % 2 == 0:
                    s = -one
                R = wp.sqrt(U * U + V * V + W * W)
                uw = U * U + W * W
                vw = V * V + W * W
                inv_vr = zero
                ln_vr = zero
                if V >= zero:
                    inv_vr = one / (V + R)
                    ln_vr = wp.log(V + R)
                else:
                    inv_vr = (R - V) / uw
                    ln_vr = wp.log(uw) - wp.log(R - V)
                inv_ur = zero
                ln_ur = zero
                if U >= zero:
                    inv_ur = one / (U + R)
                    ln_ur = wp.log(U + R)
                else:
                    inv_ur = (R - U) / vw
                    ln_ur = wp.log(vw) - wp.log(R - U)
                sw = zero
                if W > zero:
                    sw = one
                elif W < zero:
                    sw = -one
                bx = bx - s * ln_vr
                by = by - s * ln_ur
                bz = bz + s * sw * wp.atan2(U * V, wp.abs(W) * R)
                gxx = gxx - s * U * inv_vr / R
                gxy = gxy - s / R
                gxz = gxz - s * W * inv_vr / R
                gyy = gyy - s * V * inv_ur / R
                gyz = gyz - s * W * inv_ur / R
    gzz = -(gxx + gyy)
    return wp.vec3d(bx, by, bz), wp.mat33d(gxx, gxy, gxz, gxy, gyy, gyz, gxz, gyz, gzz)


@wp.func
def _sgn(v: wp.float64):
    if v < wp.float64(0.0):
        return wp.float64(-1.0)
    return wp.float64(1.0)


@wp.func
def cuboid_field(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
    """B and grad B of a cuboid magnet; prm = [cx, cy, cz, R00..R22 (row-major, body to world), a, b, c, Jx, Jy, Jz].

    (a, b, c) are half sizes (m), J the polarisation in the body frame (T).
    """
    zero = wp.float64(0.0)
    Rm = wp.mat33d(prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9], prm[10], prm[11])
    pb = wp.transpose(Rm) * (p - wp.vec3d(prm[0], prm[1], prm[2]))
    a = prm[12]
    b = prm[13]
    c = prm[14]
    J = wp.vec3d(prm[15], prm[16], prm[17])
    sx = _sgn(pb[0])
    sy = _sgn(pb[1])
    sz = _sgn(pb[2])
    x = wp.abs(pb[0])
    y = wp.abs(pb[1])
    z = wp.abs(pb[2])
    Jx = sx * J[0]
    Jy = sy * J[1]
    Jz = sz * J[2]
    inv4pi = wp.float64(0.25) / PI_F64
    B = wp.vec3d(zero, zero, zero)
    grad_B = wp.mat33d(zero, zero, zero, zero, zero, zero, zero, zero, zero)
    if Jz != zero:
        bl, gl = _cuboid_unit_z_wp(x, y, z, a, b, c)
        B = B + (Jz * inv4pi) * bl
        grad_B = grad_B + (Jz * inv4pi) * gl
    if Jx != zero:
        # local (x', y', z') = (y, z, x)
        bl, gl = _cuboid_unit_z_wp(y, z, x, b, c, a)
        w = Jx * inv4pi
        B = B + w * wp.vec3d(bl[2], bl[0], bl[1])
        grad_B = grad_B + w * wp.mat33d(
            gl[2, 2], gl[2, 0], gl[2, 1],
            gl[0, 2], gl[0, 0], gl[0, 1],
            gl[1, 2], gl[1, 0], gl[1, 1],
        )  # fmt: skip
    if Jy != zero:
        # local (x', y', z') = (z, x, y)
        bl, gl = _cuboid_unit_z_wp(z, x, y, c, a, b)
        w = Jy * inv4pi
        B = B + w * wp.vec3d(bl[1], bl[2], bl[0])
        grad_B = grad_B + w * wp.mat33d(
            gl[1, 1], gl[1, 2], gl[1, 0],
            gl[2, 1], gl[2, 2], gl[2, 0],
            gl[0, 1], gl[0, 2], gl[0, 0],
        )  # fmt: skip
    Sd = wp.mat33d(sx, zero, zero, zero, sy, zero, zero, zero, sz)
    B = Sd * B
    grad_B = Sd * grad_B * Sd
    if x < a and y < b and z < c:
        B = B + J
    return Rm * B, Rm * grad_B * wp.transpose(Rm)


class CuboidMagnet(MovingSource):
    """Homogeneously magnetised cuboid (block) magnet.

    Parameters
    ----------
    dimensions : 3-vector, metres. Full side lengths along the body x, y, z axes.
    remanence_vector : 3-vector, tesla. Remanent flux density (polarisation J = mu0 M) in the body frame;
        e.g. (0, 0, 1.3) for an N42 block magnetised along its z side.
    position : 3-vector, metres. Centre.
    orientation : body-to-world rotation: a 3x3 matrix, a quaternion (x, y, z, w) (scalar last, as scipy and
        Magpylib), a ``scipy.spatial.transform.Rotation``, or None (identity).
    path : optional :class:`~magsoro.fields.profiles.Keyframes` of centre positions (metres) over time.
    orientation_path : optional :class:`~magsoro.fields.profiles.Keyframes` of quaternions (x, y, z, w) over
        time, interpolated linearly and normalised (keep consecutive keyframes in the same hemisphere).

    Notes
    -----
    ``B(points, t)`` -> (N, 3) tesla (inside the magnet the B of the magnetised material), ``grad_B`` ->
    (N, 3, 3) tesla/metre with grad_B[n, i, j] = dB_i/dx_j.
    """

    def __init__(
        self,
        dimensions,
        remanence_vector,
        position=(0.0, 0.0, 0.0),
        orientation=None,
        path: Keyframes | None = None,
        orientation_path: Keyframes | None = None,
    ):
        dims = np.asarray(dimensions, dtype=np.float64).reshape(-1)
        if dims.shape != (3,) or not np.all(np.isfinite(dims)) or np.any(dims <= 0):
            raise ValueError(f"cuboid dimensions must be 3 positive lengths in metres, got {dimensions!r}")
        J = np.asarray(remanence_vector, dtype=np.float64).reshape(-1)
        if J.shape != (3,) or not np.all(np.isfinite(J)):
            raise ValueError(f"remanence_vector must be 3 finite numbers in tesla, got {remanence_vector!r}")
        self.dimensions = dims
        self.remanence_vector = J
        self.position = np.asarray(position, dtype=np.float64).reshape(3)
        self.rotation = rotation_matrix(orientation)
        if path is not None and path.values.shape[1] != 3:
            raise ValueError("a cuboid path needs 3 position components")
        if orientation_path is not None and orientation_path.values.shape[1] != 4:
            raise ValueError("a cuboid orientation_path needs quaternions (x, y, z, w)")
        self.path = path
        self.orientation_path = orientation_path

    @property
    def volume(self) -> float:
        """Volume, m^3."""
        return float(np.prod(self.dimensions))

    def rotation_at(self, t: float) -> np.ndarray:
        """Body-to-world rotation matrix at time ``t`` (s)."""
        if self.orientation_path is None:
            return self.rotation
        return rotation_matrix(self.orientation_path.value(t))

    def moment(self, t: float = 0.0) -> np.ndarray:
        """Dipole moment J V / mu0 in the world frame, A m^2."""
        return self.rotation_at(t) @ self.remanence_vector * self.volume / MU0

    def field_and_gradient(self, points, t=0.0):
        """(B (N, 3) tesla, grad B (N, 3, 3) tesla/metre) in one pass."""
        p = as_points(points)
        Rm = self.rotation_at(t)
        pb = (p - self.position_at(t)) @ Rm  # = R^T (p - c) per row
        Bb, Gb = cuboid_body_field_np(pb, 0.5 * self.dimensions, self.remanence_vector)
        return Bb @ Rm.T, np.einsum("ij,njk,lk->nil", Rm, Gb, Rm)

    def B(self, points, t=0.0):
        return self.field_and_gradient(points, t)[0]

    def grad_B(self, points, t=0.0):
        return self.field_and_gradient(points, t)[1]

    def device_func(self):
        return cuboid_field

    def device_params(self, t):
        return np.concatenate(
            [self.position_at(t), self.rotation_at(t).reshape(-1), 0.5 * self.dimensions, self.remanence_vector]
        )

    def __repr__(self):
        return (
            f"CuboidMagnet(dimensions={self.dimensions.tolist()}, remanence_vector={self.remanence_vector.tolist()}, "
            f"position={self.position.tolist()})"
        )
