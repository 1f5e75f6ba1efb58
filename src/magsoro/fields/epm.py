"""External permanent magnet (EPM) pose from a wanted field: the dipole inverse of seed 004 eqs 14-16.

The EPM is modelled as a point dipole of moment magnitude |m| (seed 004 eq 14): the field at a point
``at`` from a magnet at ``at - r`` (r = |r| r_hat, pointing from the magnet to the point) is

    B = mu0 |m| / (4 pi |r|^3) (3 r_hat r_hat^T - I) m_hat.

For any direction r_hat the matrix 3 r_hat r_hat^T - I is invertible, with inverse (3/2) r_hat r_hat^T - I, so
a wanted B is produced by (seed 004 eq 16)

    m_hat = ((3/2) r_hat r_hat^T - I) B_hat / |((3/2) r_hat r_hat^T - I) B_hat|
    |r|^3 = mu0 |m| / (4 pi |B| |((3/2) r_hat r_hat^T - I) B_hat|),
    |((3/2) r_hat r_hat^T - I) B_hat| = sqrt(1 - (3/4) cos^2 alpha),  cos alpha = r_hat . B_hat.

Every direction r_hat therefore gives a valid pose: the solutions form a two-parameter family, with distance
between (mu0 |m| / (4 pi |B|))^{1/3} (r_hat perpendicular to B) and (mu0 |m| / (2 pi |B|))^{1/3} (r_hat along B,
the "axial" pose, where m_hat = B_hat). Seed 004 eq 15 is this axial case; as printed there the fraction is
inverted (2 pi |H| / (mu0 |m|) has units of 1/m^3), the version here is the dimensionally correct one.

:func:`epm_pose` picks one member of the family:

- default: the axial pose (farthest from the point for a given |m|, magnet behind the point along -B);
- ``distance``: the poses at that distance form a cone cos^2 alpha = (4/3)(1 - s^2),
  s = mu0 |m| / (4 pi |B| d^3), and the one whose magnet sits highest (largest z) is taken;
- ``zero_component``: among the poses (at ``distance`` if given), the one that keeps that field component
  closest to zero over ``zero_points`` (or, without points, keeps it flattest around ``at``: smallest
  |grad B_k|), as seed 004 minimises H_z to spare the Hall sensors. B at ``at`` stays exact either way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magsoro.constants import MU0

_COMPONENTS = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class EPMPose:
    """A dipole magnet pose: ``position`` (metres) and ``moment`` (A m^2, vector)."""

    position: np.ndarray
    moment: np.ndarray

    @property
    def direction(self) -> np.ndarray:
        """Unit moment direction."""
        return self.moment / np.linalg.norm(self.moment)

    def field(self, points) -> np.ndarray:
        """Dipole B (tesla) of this pose at (N, 3) points (metres)."""
        from magsoro.fields.dipole import Dipole

        return Dipole(self.moment, self.position).B(points)

    def as_dict(self) -> dict:
        """``{'position': [m, m, m], 'moment': [A m^2, ...]}`` as plain lists (what ``--json`` prints)."""
        return {"position": [float(v) for v in self.position], "moment": [float(v) for v in self.moment]}


def _unit(v):
    return v / np.linalg.norm(v)


def pose_for_direction(field, moment: float, r_hat, at=(0.0, 0.0, 0.0)) -> EPMPose:
    """The exact dipole pose producing ``field`` (tesla) at ``at`` (m) with the magnet at ``at - |r| r_hat``.

    ``moment`` is |m| in A m^2; seed 004 eq 16 gives the direction, the distance follows from |B|.
    """
    B = np.asarray(field, dtype=np.float64).reshape(3)
    bn = np.linalg.norm(B)
    r_hat = _unit(np.asarray(r_hat, dtype=np.float64).reshape(3))
    v = 1.5 * r_hat * (r_hat @ B) / bn - B / bn  # ((3/2) r r^T - I) B_hat
    vn = np.linalg.norm(v)
    dist = (MU0 * moment / (4.0 * np.pi * bn * vn)) ** (1.0 / 3.0)
    return EPMPose(np.asarray(at, dtype=np.float64).reshape(3) - dist * r_hat, moment * v / vn)


def distance_range(field_magnitude: float, moment: float) -> tuple[float, float]:
    """(nearest, farthest) magnet distance (m) at which a dipole of ``moment`` (A m^2) can give |B| (T)."""
    base = MU0 * moment / (4.0 * np.pi * field_magnitude)
    return base ** (1.0 / 3.0), (2.0 * base) ** (1.0 / 3.0)


def _perp_basis(b):
    helper = np.array([1.0, 0.0, 0.0]) if abs(b[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _unit(np.cross(b, helper))
    return e1, np.cross(b, e1)


def _component_index(c) -> int:
    if isinstance(c, str):
        if c.lower() not in _COMPONENTS:
            raise ValueError(f"zero_component must be 'x', 'y', 'z' or 0, 1, 2, got {c!r}")
        return _COMPONENTS[c.lower()]
    if int(c) not in (0, 1, 2):
        raise ValueError(f"zero_component must be 'x', 'y', 'z' or 0, 1, 2, got {c!r}")
    return int(c)


def epm_pose(
    field,
    moment: float,
    at=(0.0, 0.0, 0.0),
    distance: float | None = None,
    zero_component=None,
    zero_points=None,
) -> EPMPose:
    """Magnet position and moment vector giving the wanted ``field`` at ``at`` (dipole model, seed 004).

    Parameters
    ----------
    field : 3-vector, tesla. Wanted B at ``at``; must be non-zero.
    moment : float, A m^2. Dipole moment magnitude of the magnet (Br V / mu0 for a permanent magnet).
    at : 3-vector, metres. Point where the field is wanted.
    distance : optional float, metres. Required magnet-to-point distance; must lie in :func:`distance_range`.
    zero_component : optional 'x' | 'y' | 'z' (or 0..2). Choose, among the valid poses, one keeping this field
        component near zero at ``zero_points`` (N, 3 metres), or flattest around ``at`` when no points are given.

    Returns
    -------
    EPMPose
        Magnet position (m) and moment vector (A m^2); ``pose.field([at])`` equals ``field`` to rounding.
    """
    B = np.asarray(field, dtype=np.float64).reshape(3)
    at = np.asarray(at, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(B)) or np.linalg.norm(B) == 0:
        raise ValueError(f"the wanted field must be a finite non-zero vector in tesla, got {field!r}")
    if not (np.isfinite(moment) and moment > 0):
        raise ValueError(f"moment must be a positive magnitude in A m^2, got {moment!r}")
    bn = np.linalg.norm(B)
    b_hat = B / bn
    e1, e2 = _perp_basis(b_hat)

    if distance is not None:
        d_min, d_max = distance_range(bn, moment)
        if not (d_min * (1 - 1e-12) <= distance <= d_max * (1 + 1e-12)):
            raise ValueError(
                f"a {moment:g} A m^2 dipole gives |B| = {bn:g} T only between {d_min:.6g} and {d_max:.6g} m, "
                f"not at {distance:g} m"
            )
        s = MU0 * moment / (4.0 * np.pi * bn * distance**3)
        cos_a = np.sqrt(np.clip(4.0 / 3.0 * (1.0 - s * s), 0.0, 1.0))
        sin_a = np.sqrt(1.0 - cos_a * cos_a)

        def direction(params):
            # params = (psi, nappe): the cone about +B_hat (nappe > 0) or about -B_hat
            sign = 1.0 if params[1] >= 0 else -1.0
            return sign * (cos_a * b_hat + sin_a * (np.cos(params[0]) * e1 + np.sin(params[0]) * e2))

        candidates = [np.array([psi, nappe]) for nappe in (1.0, -1.0) for psi in np.linspace(0.0, 2 * np.pi, 72, endpoint=False)]
        # the magnet at at - d r_hat is highest when r_hat points down the most: on the nappe about +B_hat
        # r_z = cos_a b_z + sin_a (cos psi e1_z + sin psi e2_z) is least at psi = atan2(-e2_z, -e1_z), on the other
        # nappe r_z = -(...) is least at psi = atan2(e2_z, e1_z)
        up = cos_a * b_hat[2] - sin_a * np.hypot(e1[2], e2[2])
        down = -cos_a * b_hat[2] - sin_a * np.hypot(e1[2], e2[2])
        if up <= down:
            default = np.array([np.arctan2(-e2[2], -e1[2]), 1.0])
        else:
            default = np.array([np.arctan2(e2[2], e1[2]), -1.0])
    else:

        def direction(params):
            theta, psi = params
            return np.cos(theta) * b_hat + np.sin(theta) * (np.cos(psi) * e1 + np.sin(psi) * e2)

        candidates = [np.array([th, ps]) for th in np.linspace(0.0, np.pi, 13) for ps in np.linspace(0.0, 2 * np.pi, 24, endpoint=False)]
        default = np.array([0.0, 0.0])  # axial pose: r_hat = B_hat, m_hat = B_hat

    if zero_component is None:
        return pose_for_direction(B, moment, direction(default), at)

    from scipy.optimize import minimize  # only this branch needs it; keeps `import magsoro.fields` light

    k = _component_index(zero_component)
    pts = None if zero_points is None else np.asarray(zero_points, dtype=np.float64).reshape(-1, 3)

    def cost(params):
        pose = pose_for_direction(B, moment, direction(params), at)
        if pts is not None:
            return float(np.sum(pose.field(pts)[:, k] ** 2)) / (bn * bn)
        from magsoro.fields.dipole import Dipole

        g = Dipole(pose.moment, pose.position).grad_B(at)[0]
        return float(np.sum(g[k] ** 2))

    best = min(candidates, key=cost)
    if distance is not None:
        # optimise the cone angle psi only; the nappe stays fixed
        nappe = best[1]
        res = minimize(lambda q: cost(np.array([q[0], nappe])), best[:1], method="Nelder-Mead",
                       options={"xatol": 1e-10, "fatol": 1e-30, "maxiter": 2000})
        refined = np.array([res.x[0], nappe])
    else:
        res = minimize(cost, best, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-30, "maxiter": 4000})
        refined = res.x
    params = refined if cost(refined) <= cost(best) else best
    return pose_for_direction(B, moment, direction(params), at)
