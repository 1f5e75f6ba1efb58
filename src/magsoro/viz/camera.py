"""The default camera of a view: one that looks at the plane a robot bends in, not always down z.

A magnetic body bends about the axis of the torque m x B: its bending plane holds the magnetisation m and the field
B. Seen down z, a strip along x magnetised along x in a field along z bends out of the screen, towards the viewer,
and looks still. :func:`bend_view` picks the plane from the scene as it starts (the reference positions, the
remanence, the applied field, the non-uniform sources' places, gravity) and returns the camera as three unit
vectors: screen right, screen up and towards the viewer (right x up = towards). A finished run also knows how the
bodies moved (:func:`motion_direction`, used by ``magsoro report``): the motion of a bend lies in its plane too.
"""

from __future__ import annotations

import numpy as np

SNAP_DEGREES = 20.0  # a plane normal within this of a coordinate axis is snapped to it (a clean view along x, y or z)
PERPENDICULAR = 0.2  # a direction counts as out of line with another when sin(angle) exceeds this
_AXES = "xyz"


def _unit(v) -> np.ndarray | None:
    v = np.asarray(v, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(v))
    return v / n if n > 0 and np.isfinite(n) else None


def principal_axes(points: np.ndarray) -> np.ndarray:
    """The bodies' principal directions (rows), longest extent first: the eigenvectors of the positions' covariance."""
    x = np.asarray(points, dtype=np.float64)
    x = x[np.isfinite(x).all(axis=1)]
    if len(x) < 2:
        return np.eye(3)
    w, v = np.linalg.eigh(np.cov(x.T))
    return v[:, np.argsort(w)[::-1]].T


def dominant_direction(vectors: np.ndarray) -> np.ndarray | None:
    """The direction most of ``vectors`` (N, 3) lie along, sign ignored (a magnetisation that turns along a body
    has no useful mean); None when they are all zero."""
    v = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    v = v[np.isfinite(v).all(axis=1)]
    if not len(v) or not np.any(v):
        return None
    w, e = np.linalg.eigh(v.T @ v)
    return _unit(e[:, int(np.argmax(w))])


def _out_of_line(a: np.ndarray, b: np.ndarray) -> bool:
    return float(np.linalg.norm(np.cross(a, b))) > PERPENDICULAR


def motion_direction(frames, min_fraction: float = 1e-3) -> np.ndarray | None:
    """The direction the particles moved along most over ``frames`` (F, N, 3: the same particles in every frame),
    sign ignored: the dominant direction of every displacement from the first frame. None when nothing moved by
    more than ``min_fraction`` of the bodies' size (a still run, a single frame)."""
    x = np.asarray(frames, dtype=np.float64)
    if x.ndim != 3 or x.shape[0] < 2 or x.shape[1] == 0:
        return None
    d = (x[1:] - x[:1]).reshape(-1, x.shape[2])
    d = d[np.isfinite(d).all(axis=1)]
    first = x[0][np.isfinite(x[0]).all(axis=1)]
    size = float(np.max(np.ptp(first, axis=0))) if len(first) else 0.0
    if not len(d) or not float(np.max(np.linalg.norm(d, axis=1))) > min_fraction * size:
        return None
    out = np.zeros((len(d), 3))
    out[:, : d.shape[1]] = d
    return dominant_direction(out)


def bend_normal(points, remanence=None, field=None, motion=None) -> tuple[np.ndarray, str]:
    """The normal of the plane a body bends in, and why: the plane of the magnetisation and the way the bodies
    moved (``motion``, a run's) or the field when they are out of line (the torque m x B turns the body in it);
    else the plane of the body's length and the motion, the field or its magnetisation; else the plane of its
    longest and thinnest extents (a plate bends through its thickness)."""
    axes = principal_axes(points)
    length, thickness = axes[0], axes[2]
    m = dominant_direction(remanence) if remanence is not None else None
    b = _unit(field) if field is not None else None
    v = _unit(motion) if motion is not None else None
    for d, what in ((v, "the motion"), (b, "the field")):
        if m is not None and d is not None and _out_of_line(m, d):
            return _unit(np.cross(m, d)), f"the plane of the magnetisation and {what}"
    for d, what in ((v, "the motion"), (b, "the field"), (m, "the magnetisation")):
        if d is not None and _out_of_line(length, d):
            return _unit(np.cross(length, d)), f"the plane of the body's length and {what}"
    return _unit(np.cross(length, thickness)), "the plane of the body's longest and thinnest extents"


def bend_view(points, dim: int, remanence=None, field=None, gravity=None, motion=None) -> dict:
    """The default camera: ``{"right", "up", "towards"}`` (unit 3-vectors, lists), ``"plane"`` ("x-z", or "tilted"
    when no coordinate plane is near) and ``"why"``. 2D: down z, x to the right, y up. 3D: towards the normal of
    :func:`bend_normal` (snapped to a coordinate axis within :data:`SNAP_DEGREES`), with up against gravity when
    gravity lies in the view, else along z or y, whichever lies more in it. ``motion``: the direction the bodies
    moved along in a run (:func:`motion_direction`), which goes before the field."""
    if dim == 2:
        return {"right": [1.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "towards": [0.0, 0.0, 1.0], "plane": "x-y",
                "why": "a 2D scene lies in the x-y plane"}
    pts = np.zeros((len(points), 3))
    pts[:, : np.shape(points)[1]] = points
    n, why = bend_normal(pts, remanence, field, motion)
    k = int(np.argmax(np.abs(n)))
    snapped = abs(n[k]) >= np.cos(np.radians(SNAP_DEGREES))
    if snapped:
        n = np.eye(3)[k]
    candidates = []
    g = _unit(gravity) if gravity is not None else None
    if g is not None:
        candidates.append(-g)
    candidates += [np.eye(3)[2], np.eye(3)[1], np.eye(3)[0]]
    up = None
    for c in candidates:  # the first that lies well in the view plane
        p = c - (c @ n) * n
        if np.linalg.norm(p) > 0.7:
            up = p / np.linalg.norm(p)
            break
    if up is None:
        c = max(candidates, key=lambda c: np.linalg.norm(c - (c @ n) * n))
        up = _unit(c - (c @ n) * n)
    right = np.cross(up, n)
    if right[int(np.argmax(np.abs(right)))] < 0:  # look from the side where right points along +x, +y or +z
        n, right = -n, -right
    plane = "-".join(a for a, c in zip(_AXES, n) if abs(c) < 0.5) if snapped else "tilted"
    clean = lambda v: [float(round(c, 12)) + 0.0 for c in v]  # noqa: E731 - -0.0 and 1e-17 read badly on a page
    return {"right": clean(right), "up": clean(up), "towards": clean(n), "plane": plane, "why": why}
