"""Rigid colliders: half-space, box, sphere, cylinder; sticky, slip, Coulomb-friction or (half-spaces) symmetry
contact; optional prescribed motion (position keyframes, whose slope gives the collider velocity used in the contact law).

The kernels see each collider at a time as a :class:`DeviceCollider` struct: kind
(:class:`~magsoro.mpm.settings.ColliderKind`), mode (:class:`~magsoro.mpm.settings.ColliderMode`), friction
coefficient, position (m), rotation matrix local->world, size, velocity (m/s). Size: half-space -> outward unit normal;
box -> half extents; sphere -> radius; cylinder -> radius, half length (axis = local z). The host writes them as
numpy records of the same layout (:func:`collider_records`).
"""

import numpy as np
import warp as wp

from magsoro.fields.profiles import Keyframes
from magsoro.geometry.transforms import rotation_to_axis
from magsoro.mpm.settings import COLLIDER_MODES, ColliderKind, ColliderMode, ColliderModeName

# the shapes' codes as the kernels' ints
HALF_SPACE, BOX, SPHERE, CYLINDER = (wp.constant(int(k)) for k in ColliderKind)
#: kind name -> code, mode name -> code
KINDS = {k.name.lower(): int(k) for k in ColliderKind}
MODES = COLLIDER_MODES
#: the domain walls act on the nodes within this many cells of the domain's edge (:mod:`magsoro.mpm.kernels.grid`'s
#: ``walls``, which writes it as its literal): the builder keeps bodies out of that band, the static solver models
#: or watches it, runs note a body that comes within its reach
WALL_CELLS = 2


@wp.struct
class DeviceCollider:
    """A collider as the kernels see it at one time."""

    kind: wp.int32  # ColliderKind
    mode: wp.int32  # ColliderMode
    friction: wp.float64  # Coulomb coefficient
    position: wp.vec3d  # m
    rotation: wp.mat33d  # local -> world
    size: wp.vec3d  # half-space outward unit normal; box half extents; sphere radius; cylinder radius, half length
    velocity: wp.vec3d  # m/s (the slope of its path)


#: the numpy record of a DeviceCollider (its fields and layout): what the host writes and copies to the device
RECORD = DeviceCollider.numpy_dtype()


@wp.func
def _box_sdf(q: wp.vec3d, h: wp.vec3d):
    """Signed distance and outward normal of an axis-aligned box of half extents h at the origin."""
    zero = wp.float64(0.0)
    d = wp.vec3d(wp.abs(q[0]) - h[0], wp.abs(q[1]) - h[1], wp.abs(q[2]) - h[2])
    outside = wp.vec3d(wp.max(d[0], zero), wp.max(d[1], zero), wp.max(d[2], zero))
    dist_out = wp.length(outside)
    n = wp.vec3d(zero, zero, zero)
    if dist_out > zero:
        for a in range(3):
            if q[a] < zero:
                outside[a] = -outside[a]
        return dist_out, outside / dist_out
    # inside: nearest face
    a_max = int(0)
    for a in range(1, 3):
        if d[a] > d[a_max]:
            a_max = a
    if q[a_max] < zero:
        n[a_max] = wp.float64(-1.0)
    else:
        n[a_max] = wp.float64(1.0)
    return d[a_max], n


@wp.func
def collider_sdf(col: DeviceCollider, p: wp.vec3d):
    """Signed distance (m, negative inside), outward unit normal and surface velocity of the collider at p."""
    kind = int(col.kind)
    centre = col.position
    R = col.rotation
    size = col.size
    vel = col.velocity
    zero = wp.float64(0.0)
    phi = zero
    n = wp.vec3d(zero, zero, zero)
    if kind == HALF_SPACE:
        n = size
        phi = wp.dot(p - centre, n)
    elif kind == SPHERE:
        r = p - centre
        rl = wp.length(r)
        phi = rl - size[0]
        n = wp.vec3d(zero, zero, wp.float64(1.0))
        if rl > zero:
            n = r / rl
    else:
        q = wp.transpose(R) * (p - centre)
        nl = wp.vec3d(zero, zero, zero)
        if kind == BOX:
            phi, nl = _box_sdf(q, size)
        else:
            # cylinder: a 2D box in (radial, axial) coordinates
            rad = wp.sqrt(q[0] * q[0] + q[1] * q[1])
            qq = wp.vec3d(rad, q[2], zero)
            phi2, n2 = _box_sdf(qq, wp.vec3d(size[0], size[1], wp.float64(1.0e30)))
            phi = phi2
            radial_dir = wp.vec3d(wp.float64(1.0), zero, zero)
            if rad > zero:
                radial_dir = wp.vec3d(q[0] / rad, q[1] / rad, zero)
            nl = n2[0] * radial_dir + wp.vec3d(zero, zero, n2[1])
        n = R * nl
    return phi, n, vel


def _rotation(value) -> np.ndarray:
    if value is None:
        return np.eye(3)
    R = np.asarray(value, dtype=np.float64)
    if R.shape != (3, 3):
        raise ValueError("a collider rotation must be a 3x3 matrix")
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError("a collider rotation must be a proper rotation matrix (orthonormal, det +1)")
    return R


class Collider:
    """A rigid obstacle. Build with :meth:`half_space`, :meth:`box`, :meth:`sphere` or :meth:`cylinder`.

    ``mode`` is 'sticky' (contact nodes move with the collider), 'slip' (frictionless), 'friction'
    (Coulomb with coefficient ``friction``) or 'symmetry' (a half-space as a mirror plane: the normal velocity of
    every node within half a cell of it is removed, approaching or not). ``path`` (Keyframes of positions, m, over
    s) moves it.
    """

    def __init__(self, kind: str, position, size, rotation=None, mode: ColliderModeName = "slip", friction: float = 0.0,
                 path: Keyframes | None = None):
        if kind not in KINDS:
            raise ValueError(f"collider kind must be one of {sorted(KINDS)}, got {kind!r}")
        if mode not in MODES:
            raise ValueError(f"collider mode must be one of {sorted(MODES)}, got {mode!r}")
        if friction < 0:
            raise ValueError(f"friction coefficient must be >= 0, got {friction}")
        self.kind, self.mode, self.friction = kind, mode, float(friction)
        self.position = np.asarray(position, dtype=np.float64).reshape(3)
        self.size = np.asarray(size, dtype=np.float64).reshape(3)
        self.rotation = _rotation(rotation)
        if path is not None and path.values.shape[1] != 3:
            raise ValueError("a collider path needs 3 position components")
        self.path = path

    @classmethod
    def half_space(cls, point, normal, **kw):
        n = np.asarray(normal, dtype=np.float64).reshape(3)
        if np.linalg.norm(n) == 0:
            raise ValueError("half-space normal must be non-zero")
        return cls("half_space", point, n / np.linalg.norm(n), **kw)

    @classmethod
    def box(cls, center, half_extents, **kw):
        return cls("box", center, half_extents, **kw)

    @classmethod
    def sphere(cls, center, radius, **kw):
        return cls("sphere", center, (radius, 0.0, 0.0), **kw)

    @classmethod
    def cylinder(cls, center, radius, half_length, axis=(0, 0, 1), **kw):
        R = kw.pop("rotation", None)
        if R is None:
            R = rotation_to_axis(axis)
        return cls("cylinder", center, (radius, half_length, 0.0), rotation=R, **kw)

    @property
    def mode_code(self) -> ColliderMode:
        """The contact mode as the kernels' code."""
        return ColliderMode.named(self.mode)

    def position_at(self, t: float) -> np.ndarray:
        """Position (m, 3) at time ``t`` (s): along its path, else where it was placed."""
        return self.path.value(t) if self.path is not None else self.position

    def velocity_at(self, t: float) -> np.ndarray:
        """Velocity (m/s, 3) at time ``t`` (s): the slope of its path (zero without one)."""
        return self.path.rate(t) if self.path is not None else np.zeros(3)

    def record(self, t: float) -> np.ndarray:
        """The collider at time ``t`` (s) as the kernels see it: a numpy record of :class:`DeviceCollider`'s layout
        (:data:`RECORD`)."""
        r = np.zeros((), dtype=RECORD)
        r["kind"] = KINDS[self.kind]
        r["mode"] = self.mode_code
        r["friction"] = self.friction
        r["position"] = self.position_at(t)
        if self.path is not None:
            r["velocity"] = self.velocity_at(t)
        r["rotation"] = self.rotation
        r["size"] = self.size
        return r

    def signed_distance(self, points, t: float = 0.0) -> np.ndarray:
        """Host-side signed distance (m) of (N, 3) points; negative inside."""
        p = np.asarray(points, dtype=np.float64) - self.position_at(t)
        if self.kind == "half_space":
            return p @ self.size
        if self.kind == "sphere":
            return np.linalg.norm(p, axis=1) - self.size[0]
        q = p @ self.rotation
        if self.kind == "box":
            d = np.abs(q) - self.size
        else:
            d = np.stack([np.hypot(q[:, 0], q[:, 1]) - self.size[0], np.abs(q[:, 2]) - self.size[1]], axis=1)
        return np.linalg.norm(np.maximum(d, 0), axis=1) + np.minimum(d.max(axis=1), 0)


def collider_records(colliders: list[Collider], t: float) -> np.ndarray:
    """The colliders at time ``t`` (s) as an array of :data:`RECORD` (a DeviceCollider each), ready for
    ``wp.array(..., dtype=DeviceCollider)``; without colliders one zeroed record (the kernels' array is never empty,
    and their collider count is 0)."""
    if not colliders:
        return np.zeros(1, dtype=RECORD)
    return np.stack([c.record(t) for c in colliders])
