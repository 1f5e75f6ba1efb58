"""Circular current loops and the classic coil pairs built from them (Helmholtz, Maxwell).

A loop of radius a carrying N I ampere-turns, in its own cylindrical frame (r = rho/a, z in units of a,
S = (1 + r)^2 + z^2, D = (1 - r)^2 + z^2, kc = sqrt(D/S), B0 = mu0 N I / (pi a)):

    B_rho = B0 z / (sqrt(S) D) cel(kc, 1, 1, -kc^2)
    B_z   = B0 (1 + r) / (sqrt(S) D) cel(kc, 1, (1 - r)/(1 + r), kc^2)

(the textbook K/E form rewritten as single cel calls so nothing cancels near the axis; see
:mod:`magsoro.fields.elliptic`). grad B is analytic: differentiating the K/E form with dK/dm, dE/dm and
collecting the integrand again gives

    dB_z/dz   = B0/a * z / (D S^{3/2}) cel(kc, 1, P1/D, -P2/S)
    dB_z/drho = B0/a * 1 / (D S^{3/2}) cel(kc, 1, Q1/D, -Q2/S) = dB_rho/dz
    P1 = r^3 + 3 r^2 + r z^2 - r - 3 z^2 - 3,   P2 = r^3 - 3 r^2 + r z^2 - r + 3 z^2 + 3
    Q1 = r^4 + r^2 z^2 - 2 r^2 - 6 r z^2 + z^2 + 1,   Q2 = r^4 + r^2 z^2 - 2 r^2 + 6 r z^2 + z^2 + 1

and dB_rho/drho = -B_rho/rho - dB_z/dz (div B = 0). On the axis dB_z/dz reduces to -3 mu0 N I a^2 z /
(2 (a^2 + z^2)^{5/2}), the textbook value. The field is singular only on the wire itself.
"""

import numpy as np
import warp as wp

from magsoro.constants import MU0
from magsoro.fields.base import FieldSum, MovingSource, as_points, unit_vector as _unit
from magsoro.fields.cylinder import AXIS_EPS
from magsoro.fields.elliptic import (
    axisym_assemble_np,
    axisym_assemble_wp,
    axisym_frame_np,
    cel_np,
    cel_wp,
    loop_field_np,
    loop_field_wp,
)
from magsoro.fields.profiles import Keyframes


def loop_gradient_np(r, z):
    """(dB_z/dz, dB_z/drho) of the unit loop of :func:`~magsoro.fields.elliptic.loop_field_np`, per radius."""
    r = np.asarray(r, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    z2 = z * z
    r2 = r * r
    S = (1.0 + r) ** 2 + z2
    D = (1.0 - r) ** 2 + z2
    kc = np.sqrt(D / S)
    p1 = r * r2 + 3.0 * r2 + r * z2 - r - 3.0 * z2 - 3.0
    p2 = r * r2 - 3.0 * r2 + r * z2 - r + 3.0 * z2 + 3.0
    q1 = r2 * r2 + r2 * z2 - 2.0 * r2 - 6.0 * r * z2 + z2 + 1.0
    q2 = r2 * r2 + r2 * z2 - 2.0 * r2 + 6.0 * r * z2 + z2 + 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        pre = 1.0 / (D * S * np.sqrt(S))
        dbz_dz = pre * z * cel_np(kc, 1.0, p1 / D, -p2 / S)
        dbz_dr = pre * cel_np(kc, 1.0, q1 / D, -q2 / S)
    return dbz_dz, dbz_dr


@wp.func
def loop_gradient_wp(r: wp.float64, z: wp.float64):
    """Device form of :func:`loop_gradient_np`."""
    one = wp.float64(1.0)
    two = wp.float64(2.0)
    three = wp.float64(3.0)
    z2 = z * z
    r2 = r * r
    S = (one + r) * (one + r) + z2
    D = (one - r) * (one - r) + z2
    kc = wp.sqrt(D / S)
    p1 = r * r2 + three * r2 + r * z2 - r - three * z2 - three
    p2 = r * r2 - three * r2 + r * z2 - r + three * z2 + three
    q1 = r2 * r2 + r2 * z2 - two * r2 - wp.float64(6.0) * r * z2 + z2 + one
    q2 = r2 * r2 + r2 * z2 - two * r2 + wp.float64(6.0) * r * z2 + z2 + one
    pre = one / (D * S * wp.sqrt(S))
    dbz_dz = pre * z * cel_wp(kc, one, p1 / D, -p2 / S)
    dbz_dr = pre * cel_wp(kc, one, q1 / D, -q2 / S)
    return dbz_dz, dbz_dr


@wp.func
def current_loop_field(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
    """B and grad B of a current loop; prm = [cx, cy, cz, ax, ay, az, a, B0 = mu0 N I / (pi a)]."""
    zero = wp.float64(0.0)
    a = wp.vec3d(prm[3], prm[4], prm[5])
    radius = prm[6]
    b0 = prm[7]
    rel = p - wp.vec3d(prm[0], prm[1], prm[2])
    z = wp.dot(rel, a)
    rvec = rel - z * a
    rho = wp.length(rvec)
    rhat = wp.vec3d(zero, zero, zero)
    if rho > zero:
        rhat = rvec / rho
    r = rho / radius
    zn = z / radius
    br, bz = loop_field_wp(r, zn)
    gzz, gzr = loop_gradient_wp(r, zn)
    g0 = b0 / radius
    dbz_dz = g0 * gzz
    b_rho_over_rho = wp.float64(-0.5) * dbz_dz
    if r > wp.float64(AXIS_EPS):
        b_rho_over_rho = b0 * br / rho
    return axisym_assemble_wp(a, rhat, b0 * br, b0 * bz, b_rho_over_rho, dbz_dz, g0 * gzr)


class CurrentLoop(MovingSource):
    """Thin circular current loop (or a compact coil of ``turns`` turns).

    Parameters
    ----------
    radius : float, metres
    current : float, amperes. Positive current circulates right-handed about ``axis`` (B along +axis at the
        centre).
    position : 3-vector, metres. Centre of the loop.
    axis : 3-vector. Loop normal, normalised internally.
    path : optional :class:`~magsoro.fields.profiles.Keyframes` of centre positions (metres) over time.
    turns : float. Number of turns (the loop carries ``turns * current`` ampere-turns).
    axis_path : optional :class:`~magsoro.fields.profiles.Keyframes` of axis vectors over time (normalised).

    Notes
    -----
    Centre field mu0 N I / (2 a), tesla.
    """

    def __init__(
        self,
        radius: float,
        current: float,
        position=(0.0, 0.0, 0.0),
        axis=(0.0, 0.0, 1.0),
        path: Keyframes | None = None,
        turns: float = 1.0,
        axis_path: Keyframes | None = None,
    ):
        if not (np.isfinite(radius) and radius > 0):
            raise ValueError(f"loop radius must be > 0 m, got {radius}")
        if not (np.isfinite(current) and np.isfinite(turns)):
            raise ValueError("loop current (A) and turns must be finite")
        self.radius = float(radius)
        self.current = float(current)
        self.turns = float(turns)
        self.position = np.asarray(position, dtype=np.float64).reshape(3)
        self.axis = _unit(axis, "axis")
        if path is not None and path.values.shape[1] != 3:
            raise ValueError("a loop path needs 3 position components")
        if axis_path is not None and axis_path.values.shape[1] != 3:
            raise ValueError("a loop axis_path needs 3 components")
        self.path = path
        self.axis_path = axis_path

    @property
    def b0(self) -> float:
        """Field scale mu0 N I / (pi a), tesla."""
        return MU0 * self.turns * self.current / (np.pi * self.radius)

    def moment(self, t: float = 0.0) -> np.ndarray:
        """Magnetic moment N I pi a^2 along the axis, A m^2."""
        return self.turns * self.current * np.pi * self.radius**2 * self.axis_at(t)

    def _evaluate(self, points, t, with_grad):
        p = as_points(points)
        a = self.axis_at(t)
        rho, z, rhat = axisym_frame_np(p, self.position_at(t), a)
        r = rho / self.radius
        zn = z / self.radius
        br, bz = loop_field_np(r, zn)
        b0 = self.b0
        if not with_grad:
            return (b0 * br)[:, None] * rhat + (b0 * bz)[:, None] * a, None
        gzz, gzr = loop_gradient_np(r, zn)
        g0 = b0 / self.radius
        with np.errstate(divide="ignore", invalid="ignore"):
            ror = np.where(r > AXIS_EPS, b0 * br / rho, -0.5 * g0 * gzz)
        return axisym_assemble_np(a, rhat, b0 * br, b0 * bz, ror, g0 * gzz, g0 * gzr)

    def B(self, points, t=0.0):
        return self._evaluate(points, t, False)[0]

    def grad_B(self, points, t=0.0):
        return self._evaluate(points, t, True)[1]

    def field_and_gradient(self, points, t=0.0):
        """(B (N, 3) tesla, grad B (N, 3, 3) tesla/metre) in one pass."""
        return self._evaluate(points, t, True)

    def device_func(self):
        return current_loop_field

    def device_params(self, t):
        return np.concatenate([self.position_at(t), self.axis_at(t), [self.radius, self.b0]])

    def __repr__(self):
        return (
            f"CurrentLoop(radius={self.radius}, current={self.current}, position={self.position.tolist()}, "
            f"axis={self.axis.tolist()}, turns={self.turns})"
        )


class _CoilPair(FieldSum):
    """Two coaxial loops at ``position -+ spacing/2 * axis``; the second carries ``sign`` times the current."""

    spacing_factor = 1.0
    sign = 1.0

    def __init__(self, radius: float, current: float, position=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), turns: float = 1.0):
        if not (np.isfinite(radius) and radius > 0):
            raise ValueError(f"coil radius must be > 0 m, got {radius}")
        self.radius = float(radius)
        self.current = float(current)
        self.turns = float(turns)
        self.position = np.asarray(position, dtype=np.float64).reshape(3)
        self.axis = _unit(axis, "axis")
        self.spacing = self.spacing_factor * self.radius
        half = 0.5 * self.spacing * self.axis
        self.loops = [
            CurrentLoop(radius, current, self.position - half, self.axis, turns=turns),
            CurrentLoop(radius, self.sign * current, self.position + half, self.axis, turns=turns),
        ]
        super().__init__(self.loops)

    def __repr__(self):
        return (
            f"{type(self).__name__}(radius={self.radius}, current={self.current}, position={self.position.tolist()}, "
            f"axis={self.axis.tolist()}, turns={self.turns})"
        )


class HelmholtzPair(_CoilPair):
    """Helmholtz coil pair: two loops of ``radius`` (m) a distance ``radius`` apart, same ``current`` (A).

    The field at the centre is (4/5)^{3/2} mu0 N I / a along ``axis`` and is uniform to fourth order.
    ``position`` is the midpoint (m), ``turns`` the turns per coil. ``sources()`` returns the two
    :class:`CurrentLoop` s, so the engine evaluates each on the device.
    """

    spacing_factor = 1.0
    sign = 1.0

    def center_field(self) -> float:
        """|B| at the centre, tesla."""
        return (4.0 / 5.0) ** 1.5 * MU0 * self.turns * self.current / self.radius


class MaxwellPair(_CoilPair):
    """Maxwell gradient (anti-Helmholtz) pair: loops sqrt(3) ``radius`` apart with opposite currents.

    The field vanishes at the centre and dB_axial/d(axial) is uniform to fourth order; positive ``current``
    flows right-handed about ``axis`` in the loop at ``position - spacing/2 axis`` and the other way in the
    loop at ``position + spacing/2 axis``, which makes the axial gradient negative.
    """

    spacing_factor = float(np.sqrt(3.0))
    sign = -1.0

    def center_gradient(self) -> float:
        """dB_axial/d(axial) at the centre, tesla/metre (analytic: -48 sqrt(3) mu0 N I / (49 sqrt(7) a^2))."""
        return -48.0 * np.sqrt(3.0) / (49.0 * np.sqrt(7.0)) * MU0 * self.turns * self.current / self.radius**2
