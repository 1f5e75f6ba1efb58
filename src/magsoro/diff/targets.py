"""Shape targets of the optimiser: losses on a state with their gradients (numpy, float64).

Every target is ``target(x, F) -> (L, dL/dx, dL/dF)`` with x (N, dim) m and F (N, dim, dim), so it plugs into
:meth:`magsoro.diff.rollout.Rollout.run`. Target files (TOML) are described in docs/differentiable.md.
"""

from pathlib import Path

import numpy as np

from magsoro.errors import MagsoroError

TARGET_TYPES = ("tip", "centreline", "fold_angle")


class TipTarget:
    """L = |mean(x[indices]) - position|^2, m^2: the tip (or any particle group) at a target point."""

    def __init__(self, indices, position):
        self.indices = np.asarray(indices, dtype=np.int64)
        self.position = np.asarray(position, dtype=np.float64)

    def point(self, x):
        return x[self.indices].mean(axis=0)

    def __call__(self, x, F):
        d = self.point(x) - self.position
        gx = np.zeros_like(x)
        gx[self.indices] = 2.0 * d / len(self.indices)
        return float(d @ d), gx, None

    def error(self, x) -> float:
        """Distance to the target, m."""
        return float(np.linalg.norm(self.point(x) - self.position))


class CentrelineTarget:
    """L = mean_j |c_j - points_j|^2, m^2, with c_j the mean current position of the particles in the j-th of
    M equal bins of the reference coordinate s = X . axis (M = number of target points)."""

    def __init__(self, reference, indices, axis, points):
        self.points = np.asarray(points, dtype=np.float64)
        M = len(self.points)
        if M < 2:
            raise MagsoroError("a centreline target needs at least 2 points")
        idx = np.asarray(indices, dtype=np.int64)
        axis = np.asarray(axis, dtype=np.float64)
        axis = axis / np.linalg.norm(axis)
        s = reference[idx] @ axis
        edges = np.linspace(s.min(), s.max(), M + 1)
        b = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, M - 1)
        self.bins = [idx[b == j] for j in range(M)]
        if any(len(g) == 0 for g in self.bins):
            raise MagsoroError(f"centreline target: {M} points are more than the particles resolve along the axis; use fewer points")

    def centreline(self, x):
        return np.array([x[g].mean(axis=0) for g in self.bins])

    def __call__(self, x, F):
        c = self.centreline(x)
        d = c - self.points
        M = len(self.points)
        gx = np.zeros_like(x)
        for j, g in enumerate(self.bins):
            gx[g] = 2.0 * d[j] / (M * len(g))
        return float(np.sum(d * d) / M), gx, None

    def error(self, x) -> float:
        """Root-mean-square distance of the centreline points to the target, m."""
        d = self.centreline(x) - self.points
        return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


class FoldAngleTarget:
    """L = (theta - angle)^2, rad^2. theta is the angle from a_A to a_B, with a_b = mean over body b of F a the
    current direction of the reference direction ``axis``; signed (counter-clockwise about z) in 2D, unsigned in 3D."""

    def __init__(self, groups, axis, angle_deg, dim):
        self.groups = [np.asarray(g, dtype=np.int64) for g in groups]
        self.axis = np.asarray(axis, dtype=np.float64)[:dim]
        self.angle = np.deg2rad(float(angle_deg))
        self.dim = dim

    def _dirs(self, F):
        return [F[g] @ self.axis for g in self.groups]

    def theta(self, F):
        a, b = (d.mean(axis=0) for d in self._dirs(F))
        if self.dim == 2:
            return float(np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b))
        return float(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))

    def __call__(self, x, F):
        a, b = (d.mean(axis=0) for d in self._dirs(F))
        th = self.theta(F)
        r = th - self.angle
        if self.dim == 2:
            # d atan2(cross, dot): dtheta/da = (-a_perp-like) ; with cross = a x b, dot = a.b
            cr, dt_ = a[0] * b[1] - a[1] * b[0], a @ b
            den = cr * cr + dt_ * dt_
            dcr_da, dcr_db = np.array([b[1], -b[0]]), np.array([-a[1], a[0]])
            da = (dt_ * dcr_da - cr * b) / den
            db = (dt_ * dcr_db - cr * a) / den
        else:
            c = np.cross(a, b)
            cn = np.linalg.norm(c)
            dt_ = a @ b
            den = cn * cn + dt_ * dt_
            u = c / cn if cn > 0 else np.zeros(3)
            da = (dt_ * np.cross(b, u) - cn * b) / den
            db = (dt_ * np.cross(u, a) - cn * a) / den
        gF = np.zeros_like(F)
        for g, dd in zip(self.groups, (da, db)):
            gF[g] += 2.0 * r * np.outer(dd, self.axis) / len(g)
        return r * r, np.zeros((F.shape[0], self.dim)), gF

    def error(self, x, F=None) -> float:
        """|theta - angle| in degrees."""
        return float(np.rad2deg(abs(self.theta(F) - self.angle)))


def _body_indices(built, names, key):
    body = built.model.host["body"]
    out = []
    for name in names:
        if name not in built.body_names:
            raise MagsoroError(f"target {key}: no body named '{name}'; bodies: {', '.join(built.body_names)}")
        out.append(np.flatnonzero(body == built.body_names.index(name)))
    return out


def make_target(spec: dict, built, base_dir: Path | None = None):
    """Target object from a parsed target table (see docs/differentiable.md)."""
    kind = spec.get("type")
    dim = built.model.dim
    allowed = {"tip": {"type", "probe", "body", "position"}, "centreline": {"type", "bodies", "axis", "points", "file"},
               "fold_angle": {"type", "bodies", "axis", "angle"}}
    if kind not in TARGET_TYPES:
        raise MagsoroError(f"target.type must be one of {', '.join(TARGET_TYPES)}, got {kind!r}")
    unknown = sorted(set(spec) - allowed[kind])
    if unknown:
        raise MagsoroError(f"target: unknown key '{unknown[0]}' for type '{kind}'; allowed: {', '.join(sorted(allowed[kind]))}")

    def vector(name, n):
        v = spec.get(name)
        if v is None or len(v) != n:
            raise MagsoroError(f"target.{name}: need {n} numbers, got {v!r}")
        return np.asarray(v, dtype=np.float64)

    if kind == "tip":
        if "probe" in spec:
            probes = {p.name: p for p in built.probes}
            if spec["probe"] not in probes:
                raise MagsoroError(f"target.probe: no probe named '{spec['probe']}'; probes: {', '.join(probes) or 'none'}")
            idx = probes[spec["probe"]].indices
        elif "body" in spec:
            idx = _body_indices(built, [spec["body"]], "body")[0]
        else:
            raise MagsoroError("target: a tip target needs 'probe' (a scene probe) or 'body'")
        return TipTarget(idx, vector("position", dim))
    if kind == "centreline":
        names = spec.get("bodies", built.body_names)
        idx = np.concatenate(_body_indices(built, names, "bodies"))
        if "file" in spec:
            path = Path(spec["file"]) if base_dir is None else Path(base_dir) / spec["file"]
            if not path.is_file():
                raise MagsoroError(f"target.file: '{path}' not found")
            pts = np.loadtxt(path, delimiter=",", ndmin=2, comments="#")
        elif "points" in spec:
            pts = np.asarray(spec["points"], dtype=np.float64)
        else:
            raise MagsoroError("target: a centreline target needs 'points' or 'file'")
        if pts.ndim != 2 or pts.shape[1] != dim:
            raise MagsoroError(f"target.points: need rows of {dim} coordinates (m), got shape {pts.shape}")
        axis = np.asarray(spec.get("axis", [1.0] + [0.0] * (dim - 1)), dtype=np.float64)
        return CentrelineTarget(built.model.host["positions"], idx, axis[:dim], pts)
    names = spec.get("bodies")
    if names is None or len(names) != 2:
        raise MagsoroError("target.bodies: a fold_angle target needs two body names")
    if "angle" not in spec:
        raise MagsoroError("target.angle: required (degrees)")
    axis = np.asarray(spec.get("axis", [1.0, 0.0, 0.0]), dtype=np.float64)
    return FoldAngleTarget(_body_indices(built, names, "bodies"), axis, spec["angle"], dim)
