"""What ``magsoro live`` knows of the scene besides the engine: the poses of the magnet sources, the scene the
page's settings make ("save as scene"), and the colliders as outlines to draw.

A source's *pose* moves and turns it rigidly: x -> R (x - c) + c + d, with c its scene position (its pivot), d the
offset (m) and R = Rz(rz) Ry(ry) Rx(rx) (angles in degrees about the fixed x, y, z axes, the convention of a mesh's
``rotation``). Its field then is B'(p) = R B(R^T (p - c - d) + c) and grad B' = R grad B R^T. In a saved scene the
same pose is written into the source's own keys: position c + d, its path's points moved as x is, and its moment,
axis or orientation turned by R; a strength (gain) g multiplies its moment, remanence or current.
"""

from __future__ import annotations

import math

import numpy as np

POSE_KEYS = ("x", "y", "z", "rx", "ry", "rz")  # offsets (m) along x, y, z; rotations (degrees) about x, y, z
IDENTITY_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
UNIFORM_TYPES = ("uniform", "rotating", "keyframes")


def _cos_sin(degrees: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees, exact at multiples of 90 (a quarter turn leaves no 6e-17 behind)."""
    if degrees % 90.0 == 0.0:
        k = int(degrees // 90.0) % 4
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[k]
    r = math.radians(degrees)
    return math.cos(r), math.sin(r)


def pose_matrix(rx: float, ry: float, rz: float) -> np.ndarray:
    """R = Rz Ry Rx for rotations in degrees about the fixed x, y, z axes."""
    (ca, sa), (cb, sb), (cc, sc) = (_cos_sin(v) for v in (rx, ry, rz))
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
    Ry = np.array([[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]])
    Rz = np.array([[cc, -sc, 0.0], [sc, cc, 0.0], [0.0, 0.0, 1.0]])
    return Rz @ Ry @ Rx


def pose_parts(pose) -> tuple[np.ndarray, np.ndarray]:
    """(offset d (m, 3), rotation R) of a pose tuple (x, y, z, rx, ry, rz)."""
    return np.asarray(pose[:3], dtype=np.float64), pose_matrix(*pose[3:])


def is_identity(pose) -> bool:
    return all(v == 0.0 for v in pose)


def spec_pivot(spec) -> np.ndarray:
    """The point a scene source turns about: its ``position`` (m)."""
    return np.asarray(spec.position, dtype=np.float64).reshape(3)


def spec_reference_point(spec, t: float) -> np.ndarray:
    """Where the source is at time ``t`` (s) before any pose: along its path, else at its position."""
    path = getattr(spec, "path", None)
    if path is None:
        return spec_pivot(spec)
    from magsoro.fields.profiles import Keyframes

    return Keyframes(path.times, path.positions).value(t)


def spec_direction(spec) -> np.ndarray:
    """The source's magnetic direction (unit, 3) before any pose: a dipole's moment, a cylinder's axis times the sign
    of its remanence, a cuboid's remanence in the world, a coil's axis times the sign of its current."""
    t = spec.type
    if t == "dipole":
        d = np.asarray(spec.moment, dtype=np.float64)
    elif t == "cylinder_magnet":
        d = np.asarray(spec.axis, dtype=np.float64) * (1.0 if spec.remanence >= 0 else -1.0)
    elif t == "cuboid_magnet":
        O = np.eye(3) if spec.orientation is None else np.asarray(spec.orientation, dtype=np.float64)
        d = O @ np.asarray(spec.remanence, dtype=np.float64)
    else:
        d = np.asarray(spec.axis, dtype=np.float64) * (1.0 if spec.current >= 0 else -1.0)
    n = float(np.linalg.norm(d))
    return d / n if n > 0 else np.zeros(3)


def spec_size(spec) -> float:
    """A length (m) to draw the source at: its largest dimension, a coil's diameter, 0 for a point dipole."""
    t = spec.type
    if t == "cylinder_magnet":
        return float(max(spec.diameter, spec.length))
    if t == "cuboid_magnet":
        return float(max(spec.dimensions))
    if t in ("loop", "helmholtz", "maxwell"):
        return float(2.0 * spec.radius)
    return 0.0


def _f(v) -> float:
    return float(v) + 0.0  # -0.0 written as 0.0


def posed_spec(spec, pose, gain: float):
    """The scene entry ``spec`` of a non-uniform source moved and turned by ``pose`` and scaled by ``gain``, as a new
    validated entry of the same type (keys left as they are where nothing changed, so they stay bit-equal)."""
    data = spec.model_dump(by_alias=True)
    t = spec.type
    if not is_identity(pose):
        d, R = pose_parts(pose)
        c = spec_pivot(spec)
        data["position"] = [_f(v) for v in c + d]
        if data.get("path") is not None:
            pts = np.asarray(data["path"]["positions"], dtype=np.float64)
            data["path"]["positions"] = [[_f(v) for v in (R @ (p - c) + c + d)] for p in pts]
        if t == "dipole":
            data["moment"] = [_f(v) for v in R @ np.asarray(spec.moment, dtype=np.float64)]
        elif t == "cuboid_magnet":
            O = np.eye(3) if spec.orientation is None else np.asarray(spec.orientation, dtype=np.float64)
            data["orientation"] = [[_f(v) for v in row] for row in R @ O]
        else:  # cylinder magnets and coils: a symmetry axis
            data["axis"] = [_f(v) for v in R @ np.asarray(spec.axis, dtype=np.float64)]
    if gain != 1.0:
        if t == "dipole":
            data["moment"] = [_f(gain * v) for v in data["moment"]]
        elif t == "cylinder_magnet":
            data["remanence"] = _f(gain * data["remanence"])
        elif t == "cuboid_magnet":
            data["remanence"] = [_f(gain * v) for v in data["remanence"]]
        else:
            data["current"] = _f(gain * data["current"])
    return type(spec).model_validate(data)


def scene_with_controls(scene, controls, channel_specs: dict, dim: int):
    """A copy of ``scene`` with the page's settings written into it: the uniform field set by hand replacing the
    scene's uniform sources (``uniform``, ``rotating``, ``keyframes``: one constant ``uniform`` entry in the place of
    the first, with its name), and each non-uniform source moved, turned and scaled (:func:`posed_spec`).
    ``channel_specs``: source name -> its index in ``scene.fields``."""
    from magsoro.scene.schema import UniformField

    out = scene.model_copy(deep=True)
    fields = list(out.fields)
    for name, index in channel_specs.items():
        if index is None:
            continue
        pose = controls.poses.get(name, IDENTITY_POSE)
        gain = float(controls.gains.get(name, 1.0))
        if not is_identity(pose) or gain != 1.0:
            fields[index] = posed_spec(fields[index], pose, gain)
    if not controls.follow_scene:
        B = [float(v) + 0.0 for v in controls.vector()]
        if dim == 2:
            B[2] = 0.0
        firsts = [i for i, f in enumerate(fields) if f.type in UNIFORM_TYPES]
        name = fields[firsts[0]].name if firsts else None
        entry = UniformField(type="uniform", B=B, **({"name": name} if name is not None else {}))
        at = firsts[0] if firsts else 0
        fields = [f for f in fields if f.type not in UNIFORM_TYPES]
        fields.insert(min(at, len(fields)), entry)
    out.fields = fields
    return out


# ------------------------------------------------------------------------------------------ colliders as outlines
def _circle(centre, u, v, r, n=48) -> list:
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return (centre + r * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)).tolist()


def _clip_polygon(poly: np.ndarray, normal: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The part of the convex polygon ``poly`` (K, 3) where (x - point) . normal <= 0 (Sutherland-Hodgman)."""
    out = []
    k = len(poly)
    for i in range(k):
        a, b = poly[i], poly[(i + 1) % k]
        da, db = (a - point) @ normal, (b - point) @ normal
        if da <= 0:
            out.append(a)
        if (da < 0 < db) or (db < 0 < da):
            out.append(a + (b - a) * (da / (da - db)))
    return np.array(out)


def _plane_in_box(point, normal, lo, hi) -> np.ndarray:
    """The polygon where the plane through ``point`` with ``normal`` cuts the box [lo, hi] (ordered), or empty."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    pts = []
    for a, b in edges:
        da, db = (corners[a] - point) @ normal, (corners[b] - point) @ normal
        if da == 0:
            pts.append(corners[a])
        if (da < 0 < db) or (db < 0 < da):
            pts.append(corners[a] + (corners[b] - corners[a]) * (da / (da - db)))
    if len(pts) < 3:
        return np.zeros((0, 3))
    pts = np.unique(np.round(np.array(pts), 15), axis=0)
    centre = pts.mean(axis=0)
    u = pts[0] - centre
    u /= np.linalg.norm(u) or 1.0
    w = np.cross(normal, u)
    order = np.argsort(np.arctan2((pts - centre) @ w, (pts - centre) @ u))
    return pts[order]


def collider_outline(collider, dim: int, lo, hi, plane_z: float) -> dict:
    """One collider as the page draws it: ``loops`` (closed polylines, m, at its position at t = 0), ``fill`` (the
    loops enclose the solid), ``kind``, ``mode``. A half-space is the part of the domain it fills (2D) or its plane
    inside the domain (3D); a box, sphere or cylinder its outline (2D: its section by the scene plane)."""
    lo3, hi3 = np.zeros(3), np.zeros(3)
    lo3[:dim], hi3[:dim] = np.asarray(lo, dtype=np.float64)[:dim], np.asarray(hi, dtype=np.float64)[:dim]
    if dim == 2:
        lo3[2] = hi3[2] = plane_z
    p, R, size = np.asarray(collider.position, dtype=np.float64), collider.rotation, collider.size
    loops = []
    if collider.kind == "half_space":
        n = size / np.linalg.norm(size)
        if dim == 2:
            rect = np.array([[lo3[0], lo3[1], plane_z], [hi3[0], lo3[1], plane_z], [hi3[0], hi3[1], plane_z], [lo3[0], hi3[1], plane_z]])
            solid = _clip_polygon(rect, n, p)  # the material stays where n . (x - p) >= 0: the solid is the rest
        else:
            solid = _plane_in_box(p, n, lo3, hi3)
        if len(solid) >= 3:
            loops.append(solid.tolist())
    elif collider.kind == "box":
        h = size.copy()
        if dim == 2:
            sq = np.array([[-h[0], -h[1], 0.0], [h[0], -h[1], 0.0], [h[0], h[1], 0.0], [-h[0], h[1], 0.0]])
            loops.append((p + sq @ R.T).tolist())
        else:
            for z in (-h[2], h[2]):
                sq = np.array([[-h[0], -h[1], z], [h[0], -h[1], z], [h[0], h[1], z], [-h[0], h[1], z]])
                loops.append((p + sq @ R.T).tolist())
            for x, y in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                loops.append((p + np.array([[x * h[0], y * h[1], -h[2]], [x * h[0], y * h[1], h[2]]]) @ R.T).tolist())
    elif collider.kind == "sphere":
        r = float(size[0])
        e = np.eye(3)
        loops.append(_circle(p, e[0], e[1], r))
        if dim == 3:
            loops += [_circle(p, e[0], e[2], r), _circle(p, e[1], e[2], r)]
    elif collider.kind == "cylinder":
        r, h = float(size[0]), float(size[1])
        u, v, a = R[:, 0], R[:, 1], R[:, 2]
        if dim == 2 and abs(a[2]) > 0.999:  # the scene plane cuts it across: a disc
            loops.append(_circle(p, u, v, r))
        else:
            loops += [_circle(p - h * a, u, v, r), _circle(p + h * a, u, v, r)]
            for k in range(4):
                ang = k * np.pi / 2
                q = r * (np.cos(ang) * u + np.sin(ang) * v)
                loops.append([(p - h * a + q).tolist(), (p + h * a + q).tolist()])
    return {"kind": collider.kind, "mode": collider.mode, "loops": loops,
            "fill": collider.kind == "half_space" or dim == 2}
