"""Bulirsch's generalized complete elliptic integral and the current-loop field built on it.

``cel(kc, p, c, s) = integral_0^{pi/2} (c cos^2 phi + s sin^2 phi) / ((cos^2 phi + p sin^2 phi)
sqrt(cos^2 phi + kc^2 sin^2 phi)) dphi`` (R. Bulirsch, Numer. Math. 13, 1969), evaluated with the
arithmetic-geometric-mean iteration given by Derby & Olbert (Am. J. Phys. 78, 229, 2010). One function covers
K, E and the third kind, and the combinations a magnet field needs can be written as a single ``cel`` whose
arguments are cancellation-free (see :func:`loop_field_np`), which is why the field code uses it rather than K
and E separately.

Both a vectorised numpy form (host) and a ``@wp.func`` form (device) are given; they run the same iteration
so host and device agree to rounding.
"""

import numpy as np
import warp as wp

# The AGM converges quadratically: once the relative gap is below CEL_TOL the error of the result is of order
# CEL_TOL**2, i.e. at float64 rounding. A tolerance near sqrt(eps) (1.5e-8) is the classic choice.
CEL_TOL = 1.0e-8
CEL_MAX_ITER = 40

# Float64 constants for device code. Warp evaluates an arithmetic expression written inside a kernel (such as
# ``wp.float64(0.5 * np.pi)``) in float32 before the cast, losing 3e-8 relative; named constants keep float64.
PI_F64 = wp.constant(wp.float64(np.pi))
HALF_PI_F64 = wp.constant(wp.float64(0.5 * np.pi))


def cel_np(kc, p, c, s) -> np.ndarray:
    """Vectorised ``cel(kc, p, c, s)`` (arrays broadcast). ``kc == 0`` (a logarithmic singularity) gives NaN."""
    kc, p, c, s = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (kc, p, c, s)))
    kc = kc.astype(np.float64, copy=True)
    bad = kc == 0.0
    kc[bad] = 1.0
    k = np.abs(kc)
    pp = p.copy()
    cc = c.copy()
    ss = s.copy()
    em = np.ones_like(k)
    pos = p > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        # p > 0: plain substitution
        pp_pos = np.sqrt(np.where(pos, p, 1.0))
        ss_pos = s / pp_pos
        # p <= 0: Bulirsch's transformation to a positive parameter
        f = kc * kc
        q = 1.0 - f
        g = 1.0 - p
        f = f - p
        q = q * (s - c * p)
        pp_neg = np.sqrt(f / g)
        cc_neg = (c - s) / g
        ss_neg = -q / (g * g * pp_neg) + cc_neg * pp_neg
    pp = np.where(pos, pp_pos, pp_neg)
    cc = np.where(pos, c, cc_neg)
    ss = np.where(pos, ss_pos, ss_neg)

    f = cc
    cc = cc + ss / pp
    g = k / pp
    ss = 2.0 * (ss + f * g)
    pp = g + pp
    g = em
    em = k + em
    kk = k
    active = np.abs(g - k) > g * CEL_TOL
    for _ in range(CEL_MAX_ITER):
        if not np.any(active):
            break
        k_n = 2.0 * np.sqrt(kk)
        kk_n = k_n * em
        f = cc
        cc_n = cc + ss / pp
        g_n = kk_n / pp
        ss_n = 2.0 * (ss + f * g_n)
        pp_n = g_n + pp
        em_n = k_n + em
        g_old = em
        k = np.where(active, k_n, k)
        kk = np.where(active, kk_n, kk)
        cc = np.where(active, cc_n, cc)
        ss = np.where(active, ss_n, ss)
        pp = np.where(active, pp_n, pp)
        g = np.where(active, g_old, g)
        em = np.where(active, em_n, em)
        active = active & (np.abs(g - k) > g * CEL_TOL)
    out = (np.pi / 2.0) * (ss + cc * em) / (em * (em + pp))
    return np.where(bad, np.nan, out)


@wp.func
def cel_wp(kc: wp.float64, p: wp.float64, c: wp.float64, s: wp.float64):
    """Device ``cel(kc, p, c, s)``; same iteration as :func:`cel_np`. Returns NaN for ``kc == 0``."""
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    two = wp.float64(2.0)
    if kc == zero:
        return wp.float64(wp.nan)
    k = wp.abs(kc)
    pp = p
    cc = c
    ss = s
    em = one
    if p > zero:
        pp = wp.sqrt(p)
        ss = s / pp
    else:
        f = kc * kc
        q = one - f
        g = one - pp
        f = f - pp
        q = q * (ss - c * pp)
        pp = wp.sqrt(f / g)
        cc = (c - ss) / g
        ss = -q / (g * g * pp) + cc * pp
    f = cc
    cc = cc + ss / pp
    g = k / pp
    ss = two * (ss + f * g)
    pp = g + pp
    g = em
    em = k + em
    kk = k
    tol = wp.float64(CEL_TOL)
    for _it in range(CEL_MAX_ITER):
        if wp.abs(g - k) <= g * tol:
            break
        k_new = two * wp.sqrt(kk)
        kk_new = k_new * em
        cc_new = cc + ss / pp
        gg = kk_new / pp
        ss_new = two * (ss + cc * gg)
        pp_new = gg + pp
        g = em
        em = k_new + em
        k = k_new
        kk = kk_new
        cc = cc_new
        ss = ss_new
        pp = pp_new
    return HALF_PI_F64 * (ss + cc * em) / (em * (em + pp))


# ---------------------------------------------------------------------------------------------------------------
# Circular current loop, in its own cylindrical frame and in units of its radius.
#
# The textbook form B_rho ~ z/rho [-K + E (a^2+rho^2+z^2)/D], B_z ~ [K + E (a^2-rho^2-z^2)/D] loses all digits
# near the axis (the bracket of B_rho vanishes like rho^2). Writing K = int 1/Delta and
# E = int (cos^2 + kc^2 sin^2)/Delta and collecting the integrand gives single cel calls without the
# cancellation (derivation in docs/fields.md):
#   B_rho = mu0 I / (pi a) * z / (sqrt(S) D) * cel(kc, 1, 1, -kc^2)
#   B_z   = mu0 I / (pi a) * (1 + r) / (sqrt(S) D) * cel(kc, 1, (1 - r)/(1 + r), kc^2)
# with r = rho/a, z in units of a, S = (1 + r)^2 + z^2, D = (1 - r)^2 + z^2, kc^2 = D/S.
# ---------------------------------------------------------------------------------------------------------------


def loop_field_np(r, z):
    """(B_rho, B_z) of a unit loop: radius 1, current such that mu0 I / (pi a) = 1, at (r, z) in radii."""
    r = np.asarray(r, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    S = (1.0 + r) ** 2 + z * z
    D = (1.0 - r) ** 2 + z * z
    kc2 = D / S
    kc = np.sqrt(kc2)
    with np.errstate(divide="ignore", invalid="ignore"):
        pre = 1.0 / (np.sqrt(S) * D)
        br = pre * z * cel_np(kc, 1.0, 1.0, -kc2)
        bz = pre * (1.0 + r) * cel_np(kc, 1.0, (1.0 - r) / (1.0 + r), kc2)
    return br, bz


@wp.func
def loop_field_wp(r: wp.float64, z: wp.float64):
    """Device form of :func:`loop_field_np`."""
    one = wp.float64(1.0)
    S = (one + r) * (one + r) + z * z
    D = (one - r) * (one - r) + z * z
    kc2 = D / S
    kc = wp.sqrt(kc2)
    pre = one / (wp.sqrt(S) * D)
    br = pre * z * cel_wp(kc, one, one, -kc2)
    bz = pre * (one + r) * cel_wp(kc, one, (one - r) / (one + r), kc2)
    return br, bz


# ---------------------------------------------------------------------------------------------------------------
# Axisymmetric fields: assemble B and grad B in the world frame from the cylindrical components.
#   B = B_rho rho_hat + B_z a
#   grad B = dBrho/drho rho_hat rho_hat^T + (B_rho/rho) (I - a a^T - rho_hat rho_hat^T)
#            + dBrho/dz rho_hat a^T + dBz/drho a rho_hat^T + dBz/dz a a^T
# ---------------------------------------------------------------------------------------------------------------


def axisym_frame_np(points, center, axis):
    """Cylindrical coordinates about ``axis`` through ``center``: (rho (N,), z (N,), rho_hat (N, 3))."""
    rel = points - center
    z = rel @ axis
    rvec = rel - z[:, None] * axis
    rho = np.linalg.norm(rvec, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rhat = np.where(rho[:, None] > 0, rvec / rho[:, None], 0.0)
    return rho, z, rhat


def axisym_assemble_np(axis, rhat, b_rho, b_z, b_rho_over_rho, dbz_dz, dbz_drho):
    """World-frame (B (N, 3), grad B (N, 3, 3)) of an axisymmetric curl- and divergence-free field.

    Uses dBrho/dz = dBz/drho (curl B = 0) and dBrho/drho = -B_rho/rho - dBz/dz (div B = 0), which hold outside
    sources, so only the two z-derivatives and B_rho/rho are needed.
    """
    a = axis
    B = b_rho[:, None] * rhat + b_z[:, None] * a
    dbr_drho = -b_rho_over_rho - dbz_dz
    rr = rhat[:, :, None] * rhat[:, None, :]
    perp = np.eye(3) - np.outer(a, a)
    ra = rhat[:, :, None] * a[None, None, :]
    ar = a[None, :, None] * rhat[:, None, :]
    grad_B = (
        dbr_drho[:, None, None] * rr
        + b_rho_over_rho[:, None, None] * (perp[None] - rr)
        + dbz_drho[:, None, None] * (ra + ar)
        + dbz_dz[:, None, None] * np.outer(a, a)[None]
    )
    return B, grad_B


@wp.func
def axisym_assemble_wp(
    a: wp.vec3d,
    rhat: wp.vec3d,
    b_rho: wp.float64,
    b_z: wp.float64,
    b_rho_over_rho: wp.float64,
    dbz_dz: wp.float64,
    dbz_drho: wp.float64,
):
    """Device form of :func:`axisym_assemble_np` for one point."""
    B = b_rho * rhat + b_z * a
    dbr_drho = -b_rho_over_rho - dbz_dz
    rr = wp.outer(rhat, rhat)
    aa = wp.outer(a, a)
    perp = wp.identity(n=3, dtype=wp.float64) - aa
    grad_B = dbr_drho * rr + b_rho_over_rho * (perp - rr) + dbz_drho * (wp.outer(rhat, a) + wp.outer(a, rhat)) + dbz_dz * aa
    return B, grad_B
