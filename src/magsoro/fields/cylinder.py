"""Axially magnetised cylindrical permanent magnet: exact closed form and the multipole expansion of seed 001.

Two models of the same magnet (diameter D, length L, remanence Br along its axis):

``model="exact"``
    Closed form of Derby & Olbert (Am. J. Phys. 78, 229, 2010), the axial part of Caciagli et al.
    (J. Magn. Magn. Mater. 456, 423, 2018). With r = rho/R, z_pm = (z +- L/2)/R, gamma = (1 - r)/(1 + r),
    alpha_pm = 1/sqrt(z_pm^2 + (1 + r)^2), k_pm = sqrt((z_pm^2 + (1 - r)^2)/(z_pm^2 + (1 + r)^2)):

        B_rho = Br/pi [alpha_+ cel(k_+, 1, 1, -1) - alpha_- cel(k_-, 1, 1, -1)]
        B_z   = Br/pi / (1 + r) [z_+ alpha_+ cel(k_+, gamma^2, 1, gamma) - z_- alpha_- cel(k_-, gamma^2, 1, gamma)]

    grad B is analytic, not a finite difference: the magnet is a solenoid of surface current K = Br/mu0 on
    z' in [-L/2, L/2], B = int K B_loop(rho, z - z') dz', so dB/dz = K [B_loop(rho, z + L/2) - B_loop(rho, z - L/2)]
    exactly: the z-derivatives are the fields of two current loops on the end faces. curl B = 0 gives
    dB_z/drho = dB_rho/dz and div B = 0 gives dB_rho/drho = -B_rho/rho - dB_z/dz. B_rho/rho is computed directly
    except within 1e-6 radii of the axis, where it takes its on-axis limit -dB_z/dz / 2 (error O(r^2)).
    Valid everywhere except on the rim edges (inside the magnet it is the B of the magnetised material).

``model="multipole"``
    Petruska & Abbott's spherical multipole expansion (IEEE Trans. Magn. 49, 811, 2013), seed 001 eqs 3-4:

        B(p) = mu0/(4 pi) |m|/V sum_{n odd} (L/2)^{n+2} / |p|^{n+2} ((n + 1) D_n r_hat - dD_n/dtheta theta_hat)

    Integrating eq 4 over phi' with the addition theorem gives D_n = 4 pi P_n(cos theta) I_n with
    I_n(beta) = int_{x0}^{1} P_n(x) x^{-(n+3)} dx, x0 = 1/sqrt(1 + beta^2), beta = D/L (I_1 = beta^2/2 makes the
    n = 1 term exactly the dipole). Equivalently B = -Br grad g with the scalar potential
    g = (L/2) sum I_n P_n(cos theta) ((L/2)/|p|)^{n+1}; B and grad B are the first and second derivatives of g,
    so grad B is exact for the truncated series. Terms n = 1, 3, ..., order (order <= 17, seed 001 uses 17).
    Valid only outside the bounding sphere, radius sqrt(R^2 + L^2/4).
"""

import numpy as np
import warp as wp

from magsoro.constants import MU0
from magsoro.fields.base import MovingSource, as_points, unit_vector as _unit
from magsoro.fields.elliptic import (
    PI_F64,
    axisym_assemble_np,
    axisym_assemble_wp,
    axisym_frame_np,
    cel_np,
    cel_wp,
    loop_field_np,
    loop_field_wp,
)
from magsoro.fields.profiles import Keyframes

MAX_ORDER = 17
"""Highest multipole order n the device form carries (seed 001: nine non-zero terms, n = 17)."""

N_COEFFS = (MAX_ORDER + 1) // 2

# Within this many radii of the axis B_rho/rho takes its on-axis limit: cel(kc, 1, 1, -1) ~ -pi k^2/16 is
# computed with absolute error ~1e-16, so B_rho/rho has relative error ~1e-16/r; at r = 1e-6 that is 1e-10,
# and the limit's own error there is O(r^2) = 1e-12.
AXIS_EPS = 1.0e-6


def multipole_coefficients(beta: float, order: int = MAX_ORDER) -> np.ndarray:
    """I_n(beta) = int_{x0}^{1} P_n(x) x^{-(n+3)} dx for n = 1, 3, ..., 2*N_COEFFS-1 (zero above ``order``).

    x0 = 1/sqrt(1 + beta^2), beta = diameter / length. The integrand is a smooth polynomial-over-power on a
    range bounded away from 0, so 80-point Gauss-Legendre is exact to rounding.
    """
    x0 = 1.0 / np.sqrt(1.0 + beta * beta)
    nodes, weights = np.polynomial.legendre.leggauss(80)
    x = 0.5 * (1.0 - x0) * nodes + 0.5 * (1.0 + x0)
    w = 0.5 * (1.0 - x0) * weights
    out = np.zeros(N_COEFFS)
    for j in range(N_COEFFS):
        n = 2 * j + 1
        if n > order:
            break
        c = np.zeros(n + 1)
        c[n] = 1.0
        out[j] = np.sum(w * np.polynomial.legendre.legval(x, c) * x ** (-(n + 3)))
    return out


# ---------------------------------------------------------------------------------------------------------------
# exact model
# ---------------------------------------------------------------------------------------------------------------


def _cyl_exact_np(rho, z, R, b, Br, with_grad):
    r = rho / R
    zn = z / R
    bn = b / R
    gam = (1.0 - r) / (1.0 + r)
    parts = []
    for zs in (zn + bn, zn - bn):
        s = (1.0 + r) ** 2 + zs * zs
        alpha = 1.0 / np.sqrt(s)
        kc = np.sqrt(((1.0 - r) ** 2 + zs * zs) / s)
        t_rho = alpha * cel_np(kc, 1.0, 1.0, -1.0)
        t_z = zs * alpha * cel_np(kc, gam * gam, 1.0, gam)
        parts.append((t_rho, t_z))
    b_rho = Br / np.pi * (parts[0][0] - parts[1][0])
    b_z = Br / np.pi / (1.0 + r) * (parts[0][1] - parts[1][1])
    if not with_grad:
        return b_rho, b_z, None, None, None
    lp_r, lp_z = loop_field_np(r, zn + bn)
    lm_r, lm_z = loop_field_np(r, zn - bn)
    scale = Br / (np.pi * R)
    dbz_dz = scale * (lp_z - lm_z)
    dbz_drho = scale * (lp_r - lm_r)
    with np.errstate(divide="ignore", invalid="ignore"):
        b_rho_over_rho = np.where(r > AXIS_EPS, b_rho / rho, -0.5 * dbz_dz)
    return b_rho, b_z, b_rho_over_rho, dbz_dz, dbz_drho


@wp.func
def cylinder_exact_field(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
    """B and grad B of an axial cylinder magnet; prm = [cx, cy, cz, ax, ay, az, R, L/2, Br]."""
    one = wp.float64(1.0)
    zero = wp.float64(0.0)
    pi = PI_F64
    a = wp.vec3d(prm[3], prm[4], prm[5])
    R = prm[6]
    bh = prm[7]
    Br = prm[8]
    rel = p - wp.vec3d(prm[0], prm[1], prm[2])
    z = wp.dot(rel, a)
    rvec = rel - z * a
    rho = wp.length(rvec)
    rhat = wp.vec3d(zero, zero, zero)
    if rho > zero:
        rhat = rvec / rho
    r = rho / R
    zn = z / R
    bn = bh / R
    gam = (one - r) / (one + r)
    # face z + L/2
    zs = zn + bn
    s = (one + r) * (one + r) + zs * zs
    alpha = one / wp.sqrt(s)
    kc = wp.sqrt(((one - r) * (one - r) + zs * zs) / s)
    tr_p = alpha * cel_wp(kc, one, one, -one)
    tz_p = zs * alpha * cel_wp(kc, gam * gam, one, gam)
    lr_p, lz_p = loop_field_wp(r, zs)
    # face z - L/2
    zs = zn - bn
    s = (one + r) * (one + r) + zs * zs
    alpha = one / wp.sqrt(s)
    kc = wp.sqrt(((one - r) * (one - r) + zs * zs) / s)
    tr_m = alpha * cel_wp(kc, one, one, -one)
    tz_m = zs * alpha * cel_wp(kc, gam * gam, one, gam)
    lr_m, lz_m = loop_field_wp(r, zs)

    b_rho = Br / pi * (tr_p - tr_m)
    b_z = Br / pi / (one + r) * (tz_p - tz_m)
    scale = Br / (pi * R)
    dbz_dz = scale * (lz_p - lz_m)
    dbz_drho = scale * (lr_p - lr_m)
    b_rho_over_rho = wp.float64(-0.5) * dbz_dz
    if r > wp.float64(AXIS_EPS):
        b_rho_over_rho = b_rho / rho
    return axisym_assemble_wp(a, rhat, b_rho, b_z, b_rho_over_rho, dbz_dz, dbz_drho)


# ---------------------------------------------------------------------------------------------------------------
# multipole model
# ---------------------------------------------------------------------------------------------------------------


def _cyl_multipole_np(rel, a, half_length, Br, coeffs, with_grad):
    """B, grad B from g = sum I_n P_n(u) x^{-(n+1)} (x = |rel| / (L/2), u = cos theta); see module docstring."""
    h = half_length
    rn = np.linalg.norm(rel, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rh = rel / rn[:, None]
    u = rh @ a
    x = rn / h
    xi = 1.0 / x
    N = len(rel)
    g_r = np.zeros(N)
    g_u = np.zeros(N)
    g_rr = np.zeros(N)
    g_ru = np.zeros(N)
    g_uu = np.zeros(N)
    # Legendre recurrences for P_n, P_n', P_n'' (all regular at the poles u = +-1)
    p_prev, p = np.ones(N), u.copy()
    d_prev, d = np.zeros(N), np.ones(N)
    dd_prev, dd = np.zeros(N), np.zeros(N)
    pw = xi * xi  # x^{-(n+1)} for n = 1
    for n in range(1, MAX_ORDER + 1):
        if n % 2 == 1:
            c = coeffs[(n - 1) // 2]
            if c != 0.0:
                g_r += -(n + 1) * c * p * pw * xi
                g_u += c * d * pw
                g_rr += (n + 1) * (n + 2) * c * p * pw * xi * xi
                g_ru += -(n + 1) * c * d * pw * xi
                g_uu += c * dd * pw
        p_next = ((2 * n + 1) * u * p - n * p_prev) / (n + 1)
        d_next = d_prev + (2 * n + 1) * p
        dd_next = dd_prev + (2 * n + 1) * d
        p_prev, p = p, p_next
        d_prev, d = d, d_next
        dd_prev, dd = dd, dd_next
        pw = pw * xi
    w = (a[None, :] - u[:, None] * rh) * xi[:, None]  # normalised grad u
    B = -Br * (g_r[:, None] * rh + g_u[:, None] * w)
    if not with_grad:
        return B, None
    rr = rh[:, :, None] * rh[:, None, :]
    eye = np.eye(3)[None]
    ar = a[None, :, None] * rh[:, None, :] + rh[:, :, None] * a[None, None, :]
    hess = (
        g_rr[:, None, None] * rr
        + g_ru[:, None, None] * (rh[:, :, None] * w[:, None, :] + w[:, :, None] * rh[:, None, :])
        + g_uu[:, None, None] * (w[:, :, None] * w[:, None, :])
        + (g_r * xi)[:, None, None] * (eye - rr)
        + (g_u * xi * xi)[:, None, None] * (-ar - u[:, None, None] * eye + 3.0 * u[:, None, None] * rr)
    )
    return B, -Br / h * hess


@wp.func
def cylinder_multipole_field(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
    """Multipole B and grad B; prm = [cx, cy, cz, ax, ay, az, Br, L/2, I_1, I_3, ..., I_17]."""
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    a = wp.vec3d(prm[3], prm[4], prm[5])
    Br = prm[6]
    h = prm[7]
    rel = p - wp.vec3d(prm[0], prm[1], prm[2])
    rn = wp.length(rel)
    if rn == zero:
        return wp.vec3d(zero, zero, zero), wp.mat33d(zero, zero, zero, zero, zero, zero, zero, zero, zero)
    rh = rel / rn
    u = wp.dot(rh, a)
    xi = h / rn
    g_r = zero
    g_u = zero
    g_rr = zero
    g_ru = zero
    g_uu = zero
    p_prev = one
    pn = u
    d_prev = zero
    d = one
    dd_prev = zero
    dd = zero
    pw = xi * xi
    for n in range(1, MAX_ORDER + 1):
        fn = wp.float64(n)
        if n % 2 == 1:
            c = prm[8 + (n - 1) // 2]
            g_r += -(fn + one) * c * pn * pw * xi
            g_u += c * d * pw
            g_rr += (fn + one) * (fn + wp.float64(2.0)) * c * pn * pw * xi * xi
            g_ru += -(fn + one) * c * d * pw * xi
            g_uu += c * dd * pw
        p_next = ((wp.float64(2.0) * fn + one) * u * pn - fn * p_prev) / (fn + one)
        d_next = d_prev + (wp.float64(2.0) * fn + one) * pn
        dd_next = dd_prev + (wp.float64(2.0) * fn + one) * d
        p_prev = pn
        pn = p_next
        d_prev = d
        d = d_next
        dd_prev = dd
        dd = dd_next
        pw = pw * xi
    w = (a - u * rh) * xi
    B = -Br * (g_r * rh + g_u * w)
    rr = wp.outer(rh, rh)
    eye = wp.identity(n=3, dtype=wp.float64)
    ar = wp.outer(a, rh) + wp.outer(rh, a)
    hess = (
        g_rr * rr
        + g_ru * (wp.outer(rh, w) + wp.outer(w, rh))
        + g_uu * wp.outer(w, w)
        + (g_r * xi) * (eye - rr)
        + (g_u * xi * xi) * (-ar - u * eye + wp.float64(3.0) * u * rr)
    )
    return B, (-Br / h) * hess


class CylinderMagnet(MovingSource):
    """Axially magnetised cylindrical permanent magnet.

    Parameters
    ----------
    diameter : float, metres
    length : float, metres (along the axis)
    remanence : float, tesla. Remanent flux density Br (= mu0 M) along ``axis``; negative flips the poles.
    position : 3-vector, metres. Centre of the magnet.
    axis : 3-vector. Magnetisation (and symmetry) axis, normalised internally.
    model : ``"exact"`` (closed form with complete elliptic integrals, valid everywhere off the rim) or
        ``"multipole"`` (Petruska & Abbott expansion of seed 001 eqs 3-4, valid outside the bounding sphere).
    order : int, 1..17. Highest multipole order n kept (odd n only contribute); only for ``model="multipole"``.
    path : optional :class:`~magsoro.fields.profiles.Keyframes` of centre positions (metres) over time;
        overrides ``position``.
    axis_path : optional :class:`~magsoro.fields.profiles.Keyframes` of axis vectors over time, interpolated
        linearly then normalised; overrides ``axis``.

    Notes
    -----
    ``B(points, t)`` -> (N, 3) tesla, ``grad_B(points, t)`` -> (N, 3, 3) tesla/metre, grad_B[n, i, j] = dB_i/dx_j.
    """

    def __init__(
        self,
        diameter: float,
        length: float,
        remanence: float,
        position=(0.0, 0.0, 0.0),
        axis=(0.0, 0.0, 1.0),
        model: str = "exact",
        order: int = MAX_ORDER,
        path: Keyframes | None = None,
        axis_path: Keyframes | None = None,
    ):
        if not (np.isfinite(diameter) and diameter > 0):
            raise ValueError(f"cylinder diameter must be > 0 m, got {diameter}")
        if not (np.isfinite(length) and length > 0):
            raise ValueError(f"cylinder length must be > 0 m, got {length}")
        if not np.isfinite(remanence):
            raise ValueError(f"cylinder remanence must be finite (tesla), got {remanence}")
        if model not in ("exact", "multipole"):
            raise ValueError(f"cylinder model must be 'exact' or 'multipole', got {model!r}")
        if int(order) != order or not 1 <= int(order) <= MAX_ORDER:
            raise ValueError(f"multipole order must be an integer in 1..{MAX_ORDER}, got {order!r}")
        self.diameter = float(diameter)
        self.length = float(length)
        self.remanence = float(remanence)
        self.position = np.asarray(position, dtype=np.float64).reshape(3)
        self.axis = _unit(axis, "axis")
        self.model = model
        self.order = int(order)
        if path is not None and path.values.shape[1] != 3:
            raise ValueError("a cylinder path needs 3 position components")
        if axis_path is not None and axis_path.values.shape[1] != 3:
            raise ValueError("a cylinder axis_path needs 3 components")
        self.path = path
        self.axis_path = axis_path
        self.beta = self.diameter / self.length
        self.coefficients = multipole_coefficients(self.beta, self.order)

    # geometry ---------------------------------------------------------------------------------------------------
    @property
    def radius(self) -> float:
        """Radius, metres."""
        return 0.5 * self.diameter

    @property
    def volume(self) -> float:
        """Volume, m^3."""
        return np.pi * self.radius**2 * self.length

    @property
    def bounding_radius(self) -> float:
        """Radius of the smallest sphere enclosing the magnet, metres (multipole model valid outside it)."""
        return float(np.hypot(self.radius, 0.5 * self.length))

    def moment(self, t: float = 0.0) -> np.ndarray:
        """Dipole moment Br V / mu0 along the axis, A m^2 (seed 001 eq 9 inverted)."""
        return self.remanence * self.volume / MU0 * self.axis_at(t)

    # host forms -------------------------------------------------------------------------------------------------
    def _evaluate(self, points, t, with_grad):
        p = as_points(points)
        c = self.position_at(t)
        a = self.axis_at(t)
        if self.model == "multipole":
            return _cyl_multipole_np(p - c, a, 0.5 * self.length, self.remanence, self.coefficients, with_grad)
        rho, z, rhat = axisym_frame_np(p, c, a)
        b_rho, b_z, b_ror, dbz_dz, dbz_drho = _cyl_exact_np(
            rho, z, self.radius, 0.5 * self.length, self.remanence, with_grad
        )
        if not with_grad:
            return b_rho[:, None] * rhat + b_z[:, None] * a, None
        return axisym_assemble_np(a, rhat, b_rho, b_z, b_ror, dbz_dz, dbz_drho)

    def B(self, points, t=0.0):
        return self._evaluate(points, t, False)[0]

    def grad_B(self, points, t=0.0):
        return self._evaluate(points, t, True)[1]

    def field_and_gradient(self, points, t=0.0):
        """(B (N, 3) tesla, grad B (N, 3, 3) tesla/metre) in one pass."""
        return self._evaluate(points, t, True)

    # device form ------------------------------------------------------------------------------------------------
    def device_func(self):
        return cylinder_exact_field if self.model == "exact" else cylinder_multipole_field

    def device_params(self, t):
        c = self.position_at(t)
        a = self.axis_at(t)
        if self.model == "exact":
            return np.concatenate([c, a, [self.radius, 0.5 * self.length, self.remanence]])
        return np.concatenate([c, a, [self.remanence, 0.5 * self.length], self.coefficients])

    def __repr__(self):
        return (
            f"CylinderMagnet(diameter={self.diameter}, length={self.length}, remanence={self.remanence}, "
            f"position={self.position.tolist()}, axis={self.axis.tolist()}, model={self.model!r}"
            + (f", order={self.order}" if self.model == "multipole" else "")
            + ")"
        )
