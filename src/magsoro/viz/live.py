"""``magsoro live``: a running simulation in the browser, with the field under the user's hand.

Three threads, all standard library:

- the *stepping* thread owns the :class:`~magsoro.simulation.Simulation`: it applies the controls the page asked
  for, advances the state in chunks of about :data:`CHUNK_WALL` seconds of wall time, publishes the particle
  positions (at most ``max_points``, float32) and watches the page's heartbeat;
- the *HTTP* thread (:class:`http.server.ThreadingHTTPServer` on 127.0.0.1) serves the page
  (:mod:`magsoro.viz.live_assets`) and its JSON endpoints;
- the caller's thread waits (:meth:`LiveServer.wait`) and takes Ctrl-C.

The field reaches the engine through its ordinary input, ``Control.sources``: the scene's sources are replaced,
once, by wrappers whose settings the stepping thread changes between chunks (:class:`LiveUniform` for the sum of
the uniform sources, :class:`ScaledSource` for each non-uniform one, with its strength and its pose). The engine
rebuilds nothing when a setting changes: the wrappers keep their identity, the uniform part is read on the host
every step, and a scaled source's pose and gain travel as the last entries of its device parameters. A source
moved by the page bounds the time step anew (:meth:`~magsoro.simulation.Simulation.set_sources` with the same
wrappers).

Endpoints (JSON unless said): ``GET /`` the page; ``GET /info`` what does not change (scene, bodies, limits,
sources, colliders as outlines, the default camera, probe columns); ``GET /state`` time, speed, controls, the field
the engine uses, where the sources and colliders are, the recording; ``GET /frame`` positions as little-endian
float32 (N, 3) metres followed by N float32 colour values (header ``X-Color``: part, speed, strain or
magnetisation, as ``magsoro render --color``); ``GET /probe?column=NAME&since=SEQ`` the probe samples after SEQ;
``POST /control`` ``{"field": {...}, "gains": {...}, "poses": {...}}``; ``POST /view`` ``{"color": MODE}``;
``POST /command`` ``{"action": "pause" | "resume" | "reset" | "step" | "save_scene" | "record_start" |
"record_stop"}``; ``POST /bye`` (the page is closing). Every request is a heartbeat. Refused input answers 400 with
``{"error": "..."}``, a message the page shows as it is.

Files are written only with ``--out DIR``, only into DIR, under names the server makes
(:mod:`magsoro.viz.live_record`): "save_scene" writes DIR/NAME.toml, "record_start" a run folder DIR/record_NNN.
"""

from __future__ import annotations

import collections
import json
import math
import sys
import threading
import time
import traceback
import urllib.parse
from dataclasses import dataclass, field, replace
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import warp as wp

from magsoro.errors import MagsoroError, OutputError, SimulationError
from magsoro.fields.base import FieldSource, as_points
from magsoro.viz.camera import bend_view
from magsoro.viz.live_record import Recording, SaveError, check_name, claim_folder, out_folder
from magsoro.viz.live_scene import (
    IDENTITY_POSE,
    POSE_KEYS,
    collider_outline,
    is_identity,
    pose_parts,
    scene_with_controls,
    spec_direction,
    spec_pivot,
    spec_reference_point,
    spec_size,
)

CHUNK_WALL = 0.04  # s of wall time per chunk of steps: controls act within this, frames come this often
MAX_POINTS = 20_000  # particles sent to the page at most (evenly spaced subset)
MAX_BODY = 16 * 1024  # bytes: the largest request body accepted
BYE_GRACE = 2.0  # s after the page said goodbye before the server stops (a reload comes back within it)
PROBE_WALL = 0.1  # s of wall time between two samples of the probes (the live plot) at most
MAX_PROBE_SAMPLES = 4000  # probe samples kept for the plot (the oldest go first)
COLOR_MODES = ("part", "speed", "strain", "magnetisation")  # as magsoro render --color
_COLOR_LIST = " | ".join(f'"{m}"' for m in COLOR_MODES)
DEFAULT_IDLE = 75.0  # s without a request before the server stops: above Chrome's one-minute timer throttling of hidden tabs


class ControlError(MagsoroError):
    """Input from the page that is refused; the message is shown on the page as it is."""


# ---------------------------------------------------------------------------------------------- field wrappers
class LiveUniform(FieldSource):
    """The uniform part of the applied field: the scene's uniform sources summed (``follow_scene``), or a
    constant ``vector`` (T) set from the page. ``bound`` (T) is the largest magnitude it may take, reported as
    its peak so the time step allows for any value the page may set."""

    uniform = True

    def __init__(self, scene_sources, bound: float):
        self.scene_sources = list(scene_sources)
        self.bound = float(bound)
        self.follow_scene = True
        self.vector = np.zeros(3)

    def scene_value(self, t: float) -> np.ndarray:
        """The scene's own uniform field at time ``t`` (s), T."""
        out = np.zeros(3)
        for s in self.scene_sources:
            out += np.asarray(s.uniform_value(t), dtype=np.float64)
        return out

    def scene_peak(self) -> float:
        """Largest |B| (T) the scene's uniform sources give over time (sum of their peaks)."""
        return float(sum(s.peak() if hasattr(s, "peak") else s.max_magnitude(np.zeros((1, 3))) for s in self.scene_sources))

    def uniform_value(self, t):
        return self.scene_value(t) if self.follow_scene else self.vector.copy()

    def B(self, points, t=0.0):
        return np.tile(self.uniform_value(t), (len(as_points(points)), 1))

    def grad_B(self, points, t=0.0):
        return np.zeros((len(as_points(points)), 3, 3))

    def peak(self) -> float:
        return max(self.bound, self.scene_peak())

    def max_magnitude(self, points, t=0.0):
        return self.peak()


class ScaledSource(FieldSource):
    """A non-uniform source with its B and grad B multiplied by ``gain`` (0 .. ``max_gain``), a coil's current or a
    magnet's strength, and moved and turned by a pose about ``pivot`` (m; :mod:`magsoro.viz.live_scene`):
    B'(p) = gain R B(R^T (p - pivot - offset) + pivot). The device form calls the source's own function at the
    moved point and turns and scales its result with the entries this wrapper appends to its parameters (R, pivot,
    offset, gain); an unmoved source gets R = I and a zero pivot, which leave its field bit for bit as it was."""

    uniform = False

    def __init__(self, inner: FieldSource, max_gain: float, pivot=None):
        self.inner = inner
        self.gain = 1.0
        self.max_gain = float(max_gain)
        self.pivot = np.zeros(3) if pivot is None else np.asarray(pivot, dtype=np.float64).reshape(3)
        self.offset = np.zeros(3)
        self.rotation = np.eye(3)
        self.pose = IDENTITY_POSE
        self.posed = False
        self._func = None

    def set_pose(self, pose) -> None:
        """Move by ``pose`` = (x, y, z m, rx, ry, rz degrees) from the scene's pose."""
        self.pose = tuple(float(v) for v in pose)
        self.offset, self.rotation = pose_parts(self.pose)
        self.posed = not is_identity(self.pose)

    def _local(self, points) -> np.ndarray:
        p = as_points(points)
        return (p - self.pivot - self.offset) @ self.rotation + self.pivot if self.posed else p

    def B(self, points, t=0.0):
        b = np.asarray(self.inner.B(self._local(points), t), dtype=np.float64)
        return self.gain * (b @ self.rotation.T if self.posed else b)

    def grad_B(self, points, t=0.0):
        g = np.asarray(self.inner.grad_B(self._local(points), t), dtype=np.float64)
        R = self.rotation
        return self.gain * (np.einsum("ij,njk,lk->nil", R, g, R) if self.posed else g)

    def max_magnitude(self, points, t=0.0):
        return self.max_gain * self.inner.max_magnitude(self._local(points), t)

    def device_func(self):
        if self._func is None:  # one function per wrapper: the kernel compiles once, resets reuse it
            self._func = _scaled_func(self.inner.device_func())
        return self._func

    def device_params(self, t):
        pivot = self.pivot if self.posed else np.zeros(3)
        return np.concatenate([np.asarray(self.inner.device_params(t), dtype=np.float64).ravel(), self.rotation.ravel(),
                               pivot, self.offset, [float(self.gain)]])

    def __repr__(self):
        return f"ScaledSource({self.inner!r}, gain={self.gain:g})"


def _scaled_func(func):
    @wp.func
    def scaled(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
        n = prm.shape[0]
        R = wp.mat33d(prm[n - 16], prm[n - 15], prm[n - 14], prm[n - 13], prm[n - 12], prm[n - 11],
                      prm[n - 10], prm[n - 9], prm[n - 8])
        c = wp.vec3d(prm[n - 7], prm[n - 6], prm[n - 5])
        d = wp.vec3d(prm[n - 4], prm[n - 3], prm[n - 2])
        gain = prm[n - 1]
        b, g = func(wp.transpose(R) @ (p - c - d) + c, prm)
        return (R @ b) * gain, (R @ g @ wp.transpose(R)) * gain

    return scaled


# ---------------------------------------------------------------------------------------------- controls
@dataclass(frozen=True)
class Limits:
    """What the page may set: |B| of the uniform field in [0, max_field] T, gains in [0, max_gain], a source's offset
    in [-max_offset, max_offset] m along each axis and its rotations in [-180, 180] degrees."""

    dim: int
    max_field: float
    max_gain: float
    sources: tuple[str, ...]  # names of the non-uniform sources with a gain and a pose
    max_offset: float = 1.0


@dataclass(frozen=True)
class Controls:
    """The drive the page asks for. ``follow_scene``: the uniform field is the scene's (its profile in time);
    otherwise it is ``cartesian`` (Bx, By, Bz in T) when set as components, else ``magnitude`` (T) along the
    direction of ``azimuth`` (degrees, in the x-y plane from +x towards +y) and ``elevation`` (degrees, out of the
    x-y plane towards +z; 0 in 2D). ``gains``: source name -> strength; ``poses``: source name -> (x, y, z m,
    rx, ry, rz degrees) moved from the scene's pose (:mod:`magsoro.viz.live_scene`)."""

    follow_scene: bool = True
    magnitude: float = 0.0
    azimuth: float = 90.0
    elevation: float = 0.0
    gains: dict = field(default_factory=dict)
    cartesian: tuple | None = None
    poses: dict = field(default_factory=dict)

    def vector(self) -> np.ndarray:
        if self.cartesian is not None:
            return np.array(self.cartesian, dtype=np.float64)
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        return self.magnitude * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])

    def as_json(self) -> dict:
        return {"follow_scene": self.follow_scene, "magnitude": self.magnitude, "azimuth": self.azimuth,
                "elevation": self.elevation, "B": [float(v) + 0.0 for v in self.vector()], "gains": dict(self.gains),
                "poses": {k: dict(zip(POSE_KEYS, v)) for k, v in self.poses.items()}}


_FIELD_KEYS = {"magnitude": "T", "azimuth": "degrees", "elevation": "degrees"}
_COMPONENTS = ("Bx", "By", "Bz")


def _number(value, key: str, unit: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ControlError(f"{key}: must be a number ({unit}), got {json.dumps(value)}")
    try:
        v = float(value)
    except OverflowError:  # an integer beyond any float
        v = math.inf
    if not math.isfinite(v):
        raise ControlError(f"{key}: must be a finite number ({unit}), got {value!r}")
    if not lo <= v <= hi:
        raise ControlError(f"{key}: {v:g} {unit} is out of range [{lo:g}, {hi:g}] {unit}")
    return v


def _polar(b: np.ndarray, dim: int, azimuth: float) -> tuple[float, float, float]:
    """(magnitude T, azimuth, elevation degrees) of a field vector; the azimuth kept when |B| = 0."""
    mag = float(np.linalg.norm(b))
    if mag == 0:
        return 0.0, azimuth, 0.0
    el = 0.0 if dim == 2 else math.degrees(math.asin(max(-1.0, min(1.0, b[2] / mag))))
    return mag, math.degrees(math.atan2(b[1], b[0])), el


def _field_change(f, current: Controls, limits: Limits) -> dict:
    if not isinstance(f, dict):
        raise ControlError(f"field: must be an object with magnitude, azimuth, elevation, Bx, By, Bz or follow_scene, got {json.dumps(f)[:80]}")
    bad = sorted(set(f) - {*_FIELD_KEYS, *_COMPONENTS, "follow_scene"})
    if bad:
        raise ControlError(f"field: unknown key '{bad[0]}'; allowed: magnitude, azimuth, elevation, Bx, By, Bz, follow_scene")
    polar, cart = [k for k in _FIELD_KEYS if k in f], [k for k in _COMPONENTS if k in f]
    if polar and cart:
        raise ControlError(f"field: give magnitude, azimuth, elevation or Bx, By, Bz, not both ({polar[0]} and {cart[0]})")
    changes: dict = {}
    if polar:
        ranges = {"magnitude": (0.0, limits.max_field), "azimuth": (-180.0, 180.0), "elevation": (-90.0, 90.0)}
        if limits.dim == 2:
            ranges["elevation"] = (0.0, 0.0)  # plane strain in x-y: a field out of the plane has no meaning here
        changes = {k: _number(f[k], f"field.{k}", _FIELD_KEYS[k], *ranges[k]) for k in polar}
        if current.cartesian is not None:  # from components to polar: start from the angles of the current vector
            mag, az, el = _polar(current.vector(), limits.dim, current.azimuth)
            changes = {"magnitude": mag, "azimuth": az, "elevation": el, **changes}
        changes["cartesian"] = None
    if cart:
        top = limits.max_field
        b = current.vector().copy()
        for i, k in enumerate(_COMPONENTS):
            if k in f:
                lo, hi = (0.0, 0.0) if (limits.dim == 2 and k == "Bz") else (-top, top)
                b[i] = _number(f[k], f"field.{k}", "T", lo, hi) + 0.0
        mag = float(np.linalg.norm(b))
        if mag > top * (1 + 1e-12):
            raise ControlError(f"field: |B| = {mag:g} T is out of range [0, {top:g}] T")
        m, az, el = _polar(b, limits.dim, current.azimuth)
        changes = {"cartesian": tuple(float(v) + 0.0 for v in b), "magnitude": m, "azimuth": az, "elevation": el}
    if "follow_scene" in f:
        if not isinstance(f["follow_scene"], bool):
            raise ControlError(f"field.follow_scene: must be true or false, got {json.dumps(f['follow_scene'])}")
        changes["follow_scene"] = f["follow_scene"]
    elif changes:
        changes["follow_scene"] = False  # setting the field by hand leaves the scene's profile
    return changes


def _source_name(name, limits: Limits, what: str) -> str:
    if name not in limits.sources:
        have = ", ".join(limits.sources) if limits.sources else "none (the scene has no non-uniform source)"
        raise ControlError(f"{what}: no field source named '{name}'; sources with a {what[:-1]}: {have}")
    return name


def _poses_change(p, current: Controls, limits: Limits) -> dict:
    if not isinstance(p, dict):
        raise ControlError(f"poses: must be an object {{source name: {{x, y, z (m), rx, ry, rz (degrees)}}}}, got {json.dumps(p)[:80]}")
    poses = dict(current.poses)
    for name, change in p.items():
        _source_name(name, limits, "poses")
        if not isinstance(change, dict):
            raise ControlError(f"poses.{name}: must be an object with x, y, z (m), rx, ry, rz (degrees), got {json.dumps(change)[:80]}")
        bad = sorted(set(change) - set(POSE_KEYS))
        if bad:
            raise ControlError(f"poses.{name}: unknown key '{bad[0]}'; allowed: {', '.join(POSE_KEYS)}")
        pose = list(poses.get(name, IDENTITY_POSE))
        for i, k in enumerate(POSE_KEYS):
            if k in change:
                unit, lim = ("m", limits.max_offset) if i < 3 else ("degrees", 180.0)
                pose[i] = _number(change[k], f"poses.{name}.{k}", unit, -lim, lim) + 0.0
        poses[name] = tuple(pose)
    return poses


def parse_control(payload, current: Controls, limits: Limits) -> Controls:
    """The controls after the change ``payload`` (the body of ``POST /control``) asks for; :class:`ControlError`
    naming the key when it is not a JSON object of known keys, a value is not a number or out of range, or a
    source is unknown. Nothing changes unless the whole request is valid."""
    if not isinstance(payload, dict):
        raise ControlError(f"a control must be a JSON object like {{\"field\": {{\"magnitude\": 0.01}}}}, got {json.dumps(payload)[:80]}")
    unknown = sorted(set(payload) - {"field", "gains", "poses"})
    if unknown:
        raise ControlError(f"unknown key '{unknown[0]}'; allowed: field, gains, poses")
    out = current
    if "field" in payload:
        out = replace(out, **_field_change(payload["field"], current, limits))
    if "gains" in payload:
        g = payload["gains"]
        if not isinstance(g, dict):
            raise ControlError(f"gains: must be an object {{source name: gain}}, got {json.dumps(g)[:80]}")
        gains = dict(out.gains)
        for name, value in g.items():
            _source_name(name, limits, "gains")
            gains[name] = _number(value, f"gains.{name}", "x the scene's strength", 0.0, limits.max_gain)
        out = replace(out, gains=gains)
    if "poses" in payload:
        out = replace(out, poses=_poses_change(payload["poses"], current, limits))
    return out


ACTIONS = ("pause", "resume", "reset", "step", "save_scene", "record_start", "record_stop")
_ACTION_LIST = " | ".join(f'"{a}"' for a in ACTIONS)
MAX_STEP = 100_000  # time steps one "step" command may ask for


def parse_command(payload) -> tuple[str, dict]:
    """(action, options) of a ``POST /command`` body: ``{"action": A}`` with A one of :data:`ACTIONS`; "step" may
    carry ``"steps"`` (1 .. MAX_STEP time steps, default 1), "save_scene" a ``"name"`` (letters, digits, '_', '-',
    default "live_scene"). :class:`ControlError` for anything else."""
    allowed = {"step": {"steps"}, "save_scene": {"name"}}
    if not isinstance(payload, dict) or "action" not in payload:
        raise ControlError(f"a command must be {{\"action\": {_ACTION_LIST}}}, got {json.dumps(payload)[:80]}")
    action = payload["action"]
    if action not in ACTIONS:
        raise ControlError(f"unknown action {json.dumps(action)[:40]}; allowed: {', '.join(ACTIONS)}")
    extra = sorted(set(payload) - {"action"} - allowed.get(action, set()))
    if extra:
        keys = ", ".join(sorted(allowed.get(action, ()))) or "none"
        raise ControlError(f"a command must be {{\"action\": ...}} with no other key than its options; '{extra[0]}' is not "
                           f"one of {action}'s (allowed: {keys})")
    options = {}
    if action == "step":
        n = payload.get("steps", 1)
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_STEP:
            raise ControlError(f"step: steps must be a whole number in [1, {MAX_STEP}], got {json.dumps(n)[:40]}")
        options["steps"] = n
    if action == "save_scene":
        name = payload.get("name", "live_scene")
        try:
            options["name"] = check_name(name)
        except SaveError as exc:
            raise ControlError(f"save_scene: {exc}") from None
    return action, options


# ---------------------------------------------------------------------------------------------- fields of a run
class LiveFields:
    """The scene's sources behind live controls: one :class:`LiveUniform` for all uniform parts, one
    :class:`ScaledSource` per non-uniform part, grouped by scene entry (``fields[i]``, named by its ``name``
    or ``TYPE_i``) under one gain and one pose (turning about the entry's ``position``)."""

    def __init__(self, scene, sources, max_field: float | None, max_gain: float):
        uniform, self.channels = [], {}
        self.specs: dict = {}  # source name -> (index in scene.fields, its entry), or (None, None) without one
        for i, src in enumerate(sources):
            spec = scene.fields[i] if i < len(scene.fields) and len(scene.fields) == len(sources) else None
            name = (spec.name or f"{spec.type}_{i}") if spec is not None else f"source_{i}"
            while name in self.channels:  # a scene name that looks like a generated one: keep both sources
                name += f"_{i}"
            parts = src.sources()
            uniform += [e for e in parts if e.uniform]
            placed = spec is not None and hasattr(spec, "position")  # a magnet or coil entry: it turns about its position
            pivot = spec_pivot(spec) if placed else np.asarray(getattr(src, "position", np.zeros(3)), dtype=np.float64)
            scaled = [ScaledSource(e, max_gain, pivot) for e in parts if not e.uniform]
            if scaled:
                self.channels[name] = scaled
                self.specs[name] = (i, spec) if placed else (None, None)
        self.uniform = LiveUniform(uniform, 0.0)
        peak = self.uniform.scene_peak()
        self.max_field = float(max_field) if max_field is not None else max(2.0 * peak, 0.02)
        self.uniform.bound = self.max_field
        self.max_gain = float(max_gain)
        self.duration = float(scene.simulation.duration)
        lo, hi = np.asarray(scene.simulation.domain_lo, dtype=float), np.asarray(scene.simulation.domain_hi, dtype=float)
        self.max_offset = float(np.max(hi - lo))  # a source moves at most a domain's width along each axis

    def sources(self) -> list:
        return [self.uniform] + [s for group in self.channels.values() for s in group]

    def limits(self, dim: int) -> Limits:
        return Limits(dim, self.max_field, self.max_gain, tuple(self.channels), self.max_offset)

    def initial_controls(self, dim: int) -> Controls:
        """The scene's field as the starting point of the sliders: its uniform field at t = 0 (at the end of
        the run when it is zero then, as for a ramp), all gains 1, every source where the scene puts it."""
        b = self.uniform.scene_value(0.0)
        if not np.linalg.norm(b) > 0:
            b = self.uniform.scene_value(self.duration)
        mag = float(np.linalg.norm(b if dim == 3 else b[:2]))  # 2D: the in-plane part, what the sliders set
        az, el = 90.0, 0.0
        if mag > 0:
            az = math.degrees(math.atan2(b[1], b[0]))
            el = 0.0 if dim == 2 else math.degrees(math.asin(max(-1.0, min(1.0, b[2] / mag))))
        return Controls(True, min(mag, self.max_field), round(az, 6), round(el, 6), {k: 1.0 for k in self.channels},
                        None, {k: IDENTITY_POSE for k in self.channels})

    def apply(self, c: Controls) -> bool:
        """Set the wrappers (call between steps, from the thread that steps); True when a source moved (the time
        step is then bounded anew: :meth:`install`)."""
        self.uniform.follow_scene = c.follow_scene
        self.uniform.vector = c.vector()
        moved = False
        for name, group in self.channels.items():
            pose = tuple(c.poses.get(name, IDENTITY_POSE))
            for s in group:
                s.gain = float(c.gains.get(name, 1.0))
                if s.pose != pose:
                    s.set_pose(pose)
                    moved = True
        return moved

    def install(self, sim) -> None:
        """Put the wrappers in ``sim``'s control and bound its time step for the largest field the page may set."""
        # the wrappers' peaks are the limits of the sliders at the sources' current poses: the time step is bounded
        # for those (Simulation.set_sources keeps the wrappers, so the engine rebuilds nothing)
        sim.set_sources(self.sources())

    def scene_indices(self) -> dict:
        """Source name -> its index in the scene's fields (None for a source without a scene entry)."""
        return {name: index for name, (index, _) in self.specs.items()}

    def markers(self, c: Controls, t: float) -> list[dict]:
        """Where each source is drawn at time ``t`` (s): name, type, position (m), direction (unit), size (m)."""
        out = []
        for name, (_, spec) in self.specs.items():
            if spec is None:
                continue
            pose = c.poses.get(name, IDENTITY_POSE)
            d, R = pose_parts(pose)
            c0 = spec_pivot(spec)
            ref = spec_reference_point(spec, t)
            out.append({"name": name, "type": spec.type, "position": (R @ (ref - c0) + c0 + d).tolist(),
                        "direction": (R @ spec_direction(spec)).tolist(), "size": spec_size(spec)})
        return out


def engine_uniform_field(sim) -> np.ndarray:
    """The uniform field (T) the engine adds at the current time: the sum over ``sim.control.sources``, what
    the solver reads each step."""
    out = np.zeros(3)
    for s in sim.control.sources:
        for e in s.sources():
            if e.uniform:
                out += np.asarray(e.uniform_value(sim.time), dtype=np.float64)
    return out


def subsample(n: int, k: int) -> np.ndarray:
    """At most ``k`` evenly spaced indices of ``n`` (all when n <= k)."""
    if n <= k:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, k).astype(np.int64))


def probe_units(sim) -> dict:
    """Probe column -> its unit: m for positions, T for field probes, N for collider forces."""
    units = {}
    for p in sim.probes:
        unit = {"field": "T", "collider_force": "N"}.get(p.kind, "m")
        units.update({c: unit for c in p.columns(sim.dim)})
    return units


def _drive_direction(fields: LiveFields, sim) -> np.ndarray | None:
    """The field the bodies feel as the run starts, for the default camera: the scene's uniform field (at t = 0, or at
    the end of the run when it is zero then), else the direction from the bodies to the first magnet source."""
    b = fields.uniform.scene_value(0.0)
    if not np.linalg.norm(b) > 0:
        b = fields.uniform.scene_value(fields.duration)
    if np.linalg.norm(b) > 0:
        return b
    x = np.asarray(sim.model.host["positions"], dtype=np.float64)
    centre = np.zeros(3)
    centre[: x.shape[1]] = x.mean(axis=0)
    for _, spec in fields.specs.values():
        if spec is not None:
            return spec_pivot(spec) - centre
    return None


class LiveSession:
    """The simulation, its controls and what the page reads, shared between the threads."""

    def __init__(self, scene, source: str, device: str | None = None, max_points: int = MAX_POINTS,
                 max_field: float | None = None, max_gain: float = 2.0, idle_timeout: float = DEFAULT_IDLE,
                 paused: bool = False, out_dir=None):
        from magsoro.simulation import Simulation

        if not (isinstance(max_points, int) and 1 <= max_points <= MAX_POINTS):
            raise MagsoroError(f"max_points must be an integer in [1, {MAX_POINTS}], got {max_points!r}")
        for name, v in (("max_field", max_field), ("max_gain", max_gain), ("idle_timeout", idle_timeout)):
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise MagsoroError(f"{name} must be a finite number > 0, got {v!r}")
        self.out_dir = out_folder(out_dir) if out_dir is not None else None
        self.scene, self.source, self.device = scene, source, device
        self._Simulation = Simulation
        self.sim = Simulation(scene, device=device, source=source)  # scene errors surface here, before serving
        self.fields = LiveFields(scene, self.sim.control.sources, max_field, max_gain)
        self.fields.install(self.sim)
        self.dim = self.sim.dim
        self.limits = self.fields.limits(self.dim)
        self.idle_timeout = float(idle_timeout)
        self.index = subsample(self.sim.model.n_particles, max_points)
        self._lock = threading.Lock()
        self.requested = self.applied = self.fields.initial_controls(self.dim)
        self.fields.apply(self.applied)
        self.paused = bool(paused)
        self.error: str | None = None
        self.phase = "starting"  # starting (first chunk: kernels may compile) | running | paused | failed | resetting
        self._reset_requested = False
        self._steps_requested = 0
        self._record_requested: str | None = None  # "start" | "stop", for the stepping thread
        self.recording: Recording | None = None
        self.record_message: str | None = None  # how the last recording ended, or why it did not start
        self.saved: list[str] = []  # scene files saved, names in out_dir
        self._wake = threading.Event()
        self.frame_id = 0
        self._frame = b""
        self._frame_color = None
        self._published = (0.0, 0)  # (time, steps) of the published frame
        self._drawn = {"markers": [], "colliders": []}  # where the sources and colliders are at that time
        self._rates = collections.deque(maxlen=64)  # (wall, sim time, steps) after each chunk
        self._chunk_steps = 8
        self.color = "part"
        host = self.sim.model.host
        self._body_values = np.asarray(host["body"])[self.index].astype(np.float32)
        self._reference_m = self._reference_magnetisation()
        self.probe_units = probe_units(self.sim)
        self._probes = collections.deque(maxlen=MAX_PROBE_SAMPLES)  # (seq, time, values) samples of every column
        self._probe_seq = 0
        self._probe_wall = -math.inf
        self.probe_error: str | None = None
        self.view = bend_view(host["positions"], self.dim, host["remanence"], _drive_direction(self.fields, self.sim),
                              scene.simulation.gravity)
        lo, hi, plane_z = self.sim.model.domain_lo, self.sim.model.domain_hi, self.sim.solver.settings.plane_z
        self.colliders = [collider_outline(c, self.dim, lo, hi, plane_z) for c in self.sim.control.colliders]
        self.engine_field = engine_uniform_field(self.sim)
        self.last_seen: float | None = None  # monotonic time of the page's last request
        self.bye_at: float | None = None
        self.stop_reason: str | None = None
        self._stop = threading.Event()
        self.stopped = threading.Event()
        self._sample_probes(force=True)
        self._publish()

    def _reference_magnetisation(self) -> np.ndarray:
        """Unit remanence direction of the shown particles (the magnetisation colour's reference, as at F = I)."""
        br = np.asarray(self.sim.model.host["remanence"], dtype=np.float64)[self.index]
        n = np.linalg.norm(br, axis=1, keepdims=True)
        return np.divide(br, n, out=np.zeros_like(br), where=n > 0)

    # -- from the HTTP thread -------------------------------------------------------------------------------
    def touch(self) -> None:
        self.last_seen = time.monotonic()
        self.bye_at = None

    def bye(self) -> None:
        self.last_seen = time.monotonic()
        self.bye_at = self.last_seen

    def request_control(self, payload) -> Controls:
        with self._lock:
            self.requested = parse_control(payload, self.requested, self.limits)
            self._wake.set()
            return self.requested

    def set_view(self, payload) -> dict:
        """``POST /view`` ``{"color": MODE}``: what the frames' values are (:data:`COLOR_MODES`)."""
        if not isinstance(payload, dict) or set(payload) != {"color"}:
            raise ControlError(f"a view setting must be {{\"color\": {_COLOR_LIST}}}, got {json.dumps(payload)[:80]}")
        mode = payload["color"]
        if mode not in COLOR_MODES:
            raise ControlError(f"color: unknown mode {json.dumps(mode)[:40]}; allowed: {', '.join(COLOR_MODES)}")
        with self._lock:
            self.color = mode
            self._wake.set()
        return {"color": mode}

    def command(self, payload) -> dict:
        action, options = parse_command(payload)
        out = {"action": action}
        with self._lock:
            if action == "reset":
                self._reset_requested = True
            elif action == "step":
                self.paused = True
                self._rates.clear()
                self._steps_requested = min(MAX_STEP, self._steps_requested + options["steps"])
            elif action in ("pause", "resume"):
                self.paused = action == "pause"
                self._rates.clear()
            elif action in ("record_start", "record_stop"):
                self._need_out(action)
                if action == "record_start" and self.recording is not None:
                    raise ControlError(f"record_start: already recording into {self.recording.folder.name}")
                if action == "record_stop" and self.recording is None and self._record_requested != "start":
                    raise ControlError("record_stop: nothing is being recorded")
                self._record_requested = "start" if action == "record_start" else "stop"
            self._wake.set()
            wanted = self.requested
        if action == "save_scene":
            self._need_out(action)
            from magsoro.viz.live_record import save_scene

            scene = scene_with_controls(self.scene, wanted, self.fields.scene_indices(), self.dim)
            try:
                path = save_scene(scene, self.out_dir, options["name"])
            except SaveError as exc:
                raise ControlError(f"save_scene: {exc}") from None
            with self._lock:
                self.saved.append(path.name)
            out["file"] = path.name
            out["path"] = str(path)
        return out

    def _need_out(self, action: str) -> None:
        if self.out_dir is None:
            raise ControlError(f"{action}: this live view writes nothing; start it with --out DIR to save scenes and "
                               f"record into DIR")

    def info(self) -> dict:
        host = self.sim.model.host
        lo, hi = self.sim.model.domain_lo, self.sim.model.domain_hi
        top, off = self.limits.max_field, self.limits.max_offset
        return {
            "scene": self.scene.name or str(self.source),
            "dim": self.dim,
            "particles": int(self.sim.model.n_particles),
            "shown": len(self.index),
            "dx": float(self.sim.model.dx),
            "domain_lo": np.asarray(lo, dtype=float).tolist(),
            "domain_hi": np.asarray(hi, dtype=float).tolist(),
            "plane_z": float(self.sim.solver.settings.plane_z),
            "bodies": list(self.sim.built.body_names),
            "body": np.asarray(host["body"])[self.index].astype(int).tolist(),
            "clamped": np.asarray(host["clamped"])[self.index].astype(int).tolist(),
            "limits": {"magnitude": [0.0, top], "azimuth": [-180.0, 180.0],
                       "elevation": [0.0, 0.0] if self.dim == 2 else [-90.0, 90.0], "gain": [0.0, self.limits.max_gain],
                       "B": [-top, top], "Bz": [0.0, 0.0] if self.dim == 2 else [-top, top], "offset": [-off, off],
                       "angle": [-180.0, 180.0], "steps": [1, MAX_STEP]},
            "sources": list(self.limits.sources),
            "has_scene_uniform": bool(self.fields.uniform.scene_sources),
            "idle_timeout": self.idle_timeout,
            "view": self.view,
            "colliders": self.colliders,
            "probes": [{"column": c, "unit": u} for c, u in self.probe_units.items()],
            "color_modes": list(COLOR_MODES),
            "out_dir": str(self.out_dir) if self.out_dir is not None else None,
        }

    def status(self) -> dict:
        with self._lock:
            t, steps = self._published
            speed, rate = self._speed()
            rec = self.recording
            return {
                "time": t, "steps": steps, "frame": self.frame_id, "phase": self.phase, "paused": self.paused,
                "error": self.error, "speed": speed, "steps_per_s": rate, "dt": float(self.sim.dt),
                "controls": self.requested.as_json(), "applied": self.applied.as_json(),
                "engine_field": self.engine_field.tolist(), "stopping": self.stop_reason,
                "color": self._frame_color, "markers": self._drawn["markers"], "colliders": self._drawn["colliders"],
                "steps_pending": self._steps_requested, "probe_seq": self._probe_seq, "probe_error": self.probe_error,
                "recording": rec.as_json() if rec is not None else None, "record_message": self.record_message,
                "saved": list(self.saved[-5:]),
            }

    def frame(self) -> tuple[int, bytes, float, str]:
        """(frame id, positions (N, 3) then colour values (N) as little-endian float32, time, colour mode)."""
        with self._lock:
            return self.frame_id, self._frame, self._published[0], self._frame_color

    def probe_series(self, column, since) -> dict:
        """The samples of probe ``column`` after sequence number ``since``: ``{"column", "unit", "seq", "t", "v"}``."""
        if column not in self.probe_units:
            have = ", ".join(self.probe_units) or "none (the scene has no [[probes]])"
            raise ControlError(f"probe: no column named {json.dumps(column)[:80]}; columns: {have}")
        k = list(self.probe_units).index(column)
        with self._lock:
            rows = [r for r in self._probes if r[0] > since]
            seq = self._probe_seq
        return {"column": column, "unit": self.probe_units[column], "seq": seq,
                "t": [r[1] for r in rows], "v": [r[2][k] for r in rows]}

    # -- the stepping thread --------------------------------------------------------------------------------
    def run(self) -> None:
        """Step until :meth:`stop`; also stops the session when the page has gone."""
        try:
            while not self._stop.is_set():
                self._watch_page()
                with self._lock:
                    reset, self._reset_requested = self._reset_requested, False
                    record, self._record_requested = self._record_requested, None
                    wanted = self.requested
                    stepping = self._steps_requested > 0
                if reset:
                    self._reset()
                    continue
                if record is not None:
                    self._record(record)
                if wanted is not self.applied:
                    self._apply(wanted)
                if stepping and self.error is None:
                    self._step_some()
                    continue
                if self.paused or self.error is not None:
                    with self._lock:
                        self.phase = "failed" if self.error is not None else "paused"
                        self._steps_requested = 0
                        stale = self._frame_color != self.color
                    if stale:
                        self._publish()
                    self._wake.wait(0.05)
                    self._wake.clear()
                    continue
                self._chunk()
        finally:
            if self.recording is not None:
                self._stop_recording("the live view stopped")
            self.stopped.set()

    def _apply(self, wanted: Controls) -> None:
        moved = self.fields.apply(wanted)
        if moved:  # a source nearer the bodies may need a shorter time step
            try:
                self.fields.install(self.sim)
            except SimulationError as exc:
                self.error = f"after moving a source: {exc}"
        with self._lock:
            self.applied = wanted
            self.engine_field = engine_uniform_field(self.sim)
        if self.recording is not None:
            self.recording.changed(self.sim.time, wanted.as_json())
        if self.paused or self.error is not None:
            self._publish()  # the sources' markers move while paused

    def _advance(self, t_end: float) -> None:
        """Step to ``t_end`` (s), landing on each frame time of a recording on the way and writing it there."""
        sim = self.sim
        eps = 1e-12 * max(1.0, abs(t_end))
        while sim.time < t_end - eps:
            rec = self.recording
            sim.advance_to(t_end if rec is None else min(t_end, rec.next_time))
            self._record_if_due()

    def _guarded(self, advance) -> None:
        """Run ``advance``; a failed step or a fault becomes the error the page shows (the thread lives on)."""
        try:
            advance()
        except SimulationError as exc:
            self.error = f"step {exc.step}, t = {exc.time:.6g} s: {exc}" if exc.step is not None else str(exc)
        except Exception as exc:  # noqa: BLE001 - a bug or a source that cannot evaluate: shown on the page, not a dead thread
            traceback.print_exc(file=sys.stderr)
            self.error = f"{type(exc).__name__}: {exc}"

    def _chunk(self) -> None:
        sim = self.sim
        wall0 = time.perf_counter()
        self._guarded(lambda: self._advance(sim.time + self._chunk_steps * sim.dt))
        elapsed = time.perf_counter() - wall0
        # steps per chunk follow the wall time a chunk took, changing by at most 2x at a time
        self._chunk_steps = int(max(1, min(1_000_000, self._chunk_steps * min(2.0, max(0.5, CHUNK_WALL / max(elapsed, 1e-6))))))
        with self._lock:
            if self.error is None:
                self.phase = "running"
                self._rates.append((time.perf_counter(), sim.time, sim.steps))
            else:
                self.phase = "failed"
                self._rates.clear()
            self.engine_field = engine_uniform_field(sim)
        self._sample_probes()
        self._publish()

    def _step_some(self) -> None:
        """Time steps the page asked for with "step", for at most about :data:`CHUNK_WALL` of wall time."""
        sim = self.sim
        wall0 = time.perf_counter()
        with self._lock:
            self.phase = "stepping"
        while self.error is None and time.perf_counter() - wall0 < CHUNK_WALL:
            with self._lock:
                if self._steps_requested <= 0:
                    break
                self._steps_requested -= 1
            self._guarded(self._one_step)
        with self._lock:
            if self.error is not None:
                self._steps_requested = 0
            self.phase = "failed" if self.error is not None else ("stepping" if self._steps_requested else "paused")
            self.engine_field = engine_uniform_field(sim)
        self._sample_probes(force=True)
        self._publish()

    def _one_step(self) -> None:
        """One time step (the implicit integrator: one of its steps), then a recording's frame when one is due."""
        sim = self.sim
        if sim.integrator == "implicit":
            sim.advance_to(sim.time + sim.dt)
        else:
            sim.step()
        self._record_if_due()

    def _record_if_due(self) -> None:
        """A recording's frame when its time has come; the recording ends when it is full or cannot write."""
        rec = self.recording
        if rec is None or not rec.due(self.sim.time):
            return
        try:
            rec.record(self.sim)
        except OutputError as exc:
            rec.stopped_because = f"a frame could not be written: {exc}"
        if rec.stopped_because is not None:
            self._stop_recording(rec.stopped_because)

    def _record(self, request: str) -> None:
        if request == "stop":
            if self.recording is not None:
                self._stop_recording("stopped from the page")
            return
        if self.recording is not None:
            return
        try:
            folder = claim_folder(self.out_dir)
            scene = scene_with_controls(self.scene, self.applied, self.fields.scene_indices(), self.dim)
            every = self.scene.output.every or self.fields.duration / 50.0
            self.recording = Recording(folder, self.sim, scene, every, self.applied.as_json())
            self.record_message = None
        except (SaveError, OutputError) as exc:
            self.record_message = f"recording not started: {exc}"

    def _stop_recording(self, reason: str) -> None:
        rec, self.recording = self.recording, None
        try:
            rec.finish(self.sim, f"recorded from magsoro live, t = {rec.t0:.6g} to {self.sim.time:.6g} s ({reason})")
            self.record_message = f"{rec.folder.name}: {rec.count} frames written ({reason})"
        except OutputError as exc:
            self.record_message = f"{rec.folder.name}: {rec.count} frames written, but it could not be closed: {exc}"

    def _reset(self) -> None:
        with self._lock:
            self.phase = "resetting"
            self._steps_requested = 0
        if self.recording is not None:
            self._stop_recording("the run was reset")
        try:
            sim = self._Simulation(self.scene, device=self.device, source=self.source)
            self.fields.install(sim)
        except Exception as exc:  # noqa: BLE001 - shown on the page; the old state stays
            traceback.print_exc(file=sys.stderr)
            self.error = f"reset failed: {type(exc).__name__}: {exc}"
            return
        self.fields.apply(self.applied)
        with self._lock:
            self.sim = sim
            self.error = None
            self._rates.clear()
            self._chunk_steps = 8
            self.phase = "paused" if self.paused else "running"
            self.engine_field = engine_uniform_field(sim)
            self._probes.clear()
            self.probe_error = None
        self._sample_probes(force=True)
        self._publish()

    def _sample_probes(self, force: bool = False) -> None:
        """A row of every probe column, at most every :data:`PROBE_WALL` s of wall time (the plot's samples)."""
        now = time.perf_counter()
        if not self.probe_units or self.probe_error is not None or (not force and now - self._probe_wall < PROBE_WALL):
            return
        self._probe_wall = now
        try:
            values = self.sim.probe_values()
        except Exception as exc:  # noqa: BLE001 - the plot says why it stopped; the run goes on
            self.probe_error = f"{type(exc).__name__}: {exc}"
            return
        row = [float(values[c]) for c in self.probe_units]
        with self._lock:
            self._probe_seq += 1
            self._probes.append((self._probe_seq, float(self.sim.time), row))

    def _colour_values(self, mode: str) -> np.ndarray:
        """The shown particles' values for colour ``mode``, as ``magsoro render`` computes them from a frame: the body
        index, |v| (mm/s), the equivalent strain (%) or the angle (degrees) the magnetisation turned."""
        if mode == "part":
            return self._body_values
        from magsoro.viz.render import colour_values

        p = self.sim.particles()
        data = {"velocity": p["v"][self.index], "I1bar": p["I1bar"][self.index],
                "magnetization_direction": p["magnetization"][self.index]}
        return np.asarray(colour_values(mode, data, self.dim, self._reference_m, "live"), dtype=np.float32)

    def _publish(self) -> None:
        sim = self.sim
        x = sim.state.x.numpy()[self.index]
        pts = np.zeros((len(self.index), 3), dtype="<f4")
        pts[:, : x.shape[1]] = x
        mode = self.color
        values = self._colour_values(mode).astype("<f4")
        t = float(sim.time)
        with self._lock:
            controls = self.applied
        drawn = {"markers": self.fields.markers(controls, t),
                 "colliders": [(np.asarray(c.position_at(t)) - c.position).tolist() for c in sim.control.colliders]}
        with self._lock:
            self._frame = pts.tobytes() + values.tobytes()
            self._frame_color = mode
            self._published = (t, int(sim.steps))
            self._drawn = drawn
            self.frame_id += 1

    def _speed(self) -> tuple[float, float]:
        """(simulated s per wall s, steps per wall s) over the last second or so of chunks."""
        if self.paused or self.error is not None or len(self._rates) < 2:
            return 0.0, 0.0
        w1, t1, s1 = self._rates[-1]
        k = 0
        while k < len(self._rates) - 2 and w1 - self._rates[k][0] > 1.5:
            k += 1
        w0, t0, s0 = self._rates[k]
        dw = w1 - w0
        return ((t1 - t0) / dw, (s1 - s0) / dw) if dw > 0 else (0.0, 0.0)

    def _watch_page(self) -> None:
        now = time.monotonic()
        if self.bye_at is not None and now - self.bye_at > BYE_GRACE:
            self.stop("the page was closed")
        elif self.last_seen is not None and now - self.last_seen > self.idle_timeout:
            self.stop(f"no request from the page for {self.idle_timeout:g} s (closed or unreachable)")

    def stop(self, reason: str) -> None:
        if self.stop_reason is None:
            self.stop_reason = reason
        self._stop.set()
        self._wake.set()


# ---------------------------------------------------------------------------------------------- HTTP
class _Handler(BaseHTTPRequestHandler):
    server_version = "magsoro-live"
    session: LiveSession  # set on the subclass made per server
    port: int

    def log_message(self, format, *args):  # the page polls several times a second: keep the terminal quiet
        pass

    def _send(self, code: int, body: bytes, ctype: str, extra: dict | None = None) -> None:
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        for k, v in (extra or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, code: int, obj) -> None:
        self._send(code, json.dumps(obj).encode(), "application/json")

    def _trusted(self) -> bool:
        """Only this server's own origin: refuse a foreign Host (DNS rebinding) or a foreign page's POST."""
        ours = {f"127.0.0.1:{self.port}", f"localhost:{self.port}"}
        if self.headers.get("Host") not in ours:
            self._json(403, {"error": f"this server answers only at http://127.0.0.1:{self.port}/"})
            return False
        origin = self.headers.get("Origin")
        if origin is not None and origin not in {f"http://{h}" for h in ours}:
            self._json(403, {"error": f"requests from {origin} are refused"})
            return False
        return True

    def do_GET(self):  # names fixed by http.server
        if not self._trusted():
            return
        s = self.session
        path = self.path.split("?", 1)[0]
        if path == "/favicon.ico":
            self._send(204, b"", "image/x-icon")
            return
        s.touch()
        if path in ("/", "/index.html"):
            from magsoro.viz.live_assets import PAGE

            self._send(200, PAGE.encode(), "text/html; charset=utf-8")
        elif path == "/info":
            self._json(200, s.info())
        elif path == "/state":
            self._json(200, s.status())
        elif path == "/frame":
            fid, data, t, color = s.frame()
            self._send(200, data, "application/octet-stream", {"X-Frame": str(fid), "X-Time": repr(t), "X-Color": color})
        elif path == "/probe":
            query = urllib.parse.parse_qs(self.path.split("?", 1)[1] if "?" in self.path else "", max_num_fields=4)
            try:
                since = query.get("since", ["0"])[-1]
                if not (since.isdigit() and len(since) <= 12):
                    raise ControlError(f"probe: since must be a whole number >= 0, got {since[:40]!r}")
                self._json(200, s.probe_series(query.get("column", [""])[-1], int(since)))
            except ControlError as exc:
                self._json(400, {"error": str(exc)})
        else:
            self._json(404, {"error": f"no such page: {path}"})

    def do_POST(self):
        if not self._trusted():
            return
        s = self.session
        path = self.path.split("?", 1)[0]
        try:
            n = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            n = -1
        if n < 0 or n > MAX_BODY:
            self._json(413, {"error": f"request body must be at most {MAX_BODY} bytes"})
            return
        raw = self.rfile.read(n)
        if path == "/bye":
            s.bye()
            self._send(204, b"", "text/plain")
            return
        s.touch()
        if path not in ("/control", "/command", "/view"):
            self._json(404, {"error": f"no such endpoint: POST {path}"})
            return
        try:
            payload = json.loads(raw.decode("utf-8"), parse_constant=_refuse_constant)
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            self._json(400, {"error": f"the request is not valid JSON: {type(exc).__name__ if isinstance(exc, RecursionError) else exc}"})
            return
        try:
            if path == "/control":
                controls = s.request_control(payload)
                self._json(200, {"ok": True, "controls": controls.as_json()})
            elif path == "/view":
                self._json(200, {"ok": True, **s.set_view(payload)})
            else:
                self._json(200, {"ok": True, **s.command(payload)})
        except ControlError as exc:
            self._json(400, {"error": str(exc)})


class _HTTPServer(ThreadingHTTPServer):
    daemon_threads = True  # a poll in progress does not hold up the stop

    def handle_error(self, request, client_address):
        if isinstance(sys.exc_info()[1], ConnectionError):  # the page went away mid-answer: nothing to report
            return
        super().handle_error(request, client_address)


def _refuse_constant(name):
    raise ValueError(f"{name} is not a number JSON allows")


class LiveServer:
    """A :class:`LiveSession` behind an HTTP server on 127.0.0.1:``port`` (0: a free port).

    >>> srv = LiveServer(load_scene("scenes/cantilever_2d.toml"), "scenes/cantilever_2d.toml", port=0)  # doctest: +SKIP
    >>> srv.start(); print(srv.url); srv.wait()                                                        # doctest: +SKIP
    """

    def __init__(self, scene, source: str, port: int = 8765, **session_options):
        if not (isinstance(port, int) and 0 <= port <= 65535):
            raise MagsoroError(f"--port must be in [0, 65535], got {port!r}")
        self.session = LiveSession(scene, source, **session_options)
        handler = type("LiveHandler", (_Handler,), {"session": self.session, "port": 0})
        try:
            self.httpd = _HTTPServer(("127.0.0.1", port), handler)
        except OSError as exc:
            raise MagsoroError(f"cannot listen on 127.0.0.1:{port}: {exc.strerror or exc}; "
                               f"choose another --port, or --port 0 for any free one") from None
        self.port = self.httpd.server_address[1]
        handler.port = self.port
        self.url = f"http://127.0.0.1:{self.port}/"
        self._threads: list[threading.Thread] = []

    def start(self) -> None:
        http = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.1}, name="magsoro-live-http", daemon=True)
        step = threading.Thread(target=self.session.run, name="magsoro-live-step", daemon=True)
        self._threads = [http, step]
        http.start()
        step.start()

    def wait(self, timeout: float | None = None) -> str | None:
        """Block until the session stops (page closed, heartbeat lost, :meth:`close`); then shut the server down
        and return the reason. With ``timeout`` (s): None when still running then."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.session.stopped.wait(0.2):  # short waits: Ctrl-C reaches the main thread between them
            if deadline is not None and time.monotonic() > deadline:
                return None
        self.close()
        return self.session.stop_reason

    def close(self, reason: str = "stopped") -> None:
        """Stop stepping and serving (idempotent)."""
        self.session.stop(reason)
        if self._threads:
            # a chunk in progress ends first; a first chunk still compiling kernels is left to its daemon thread
            self.session.stopped.wait(10.0)
        if self.httpd is not None:
            if self._threads:
                self.httpd.shutdown()
            self.httpd.server_close()
            self.httpd = None
        for t in self._threads:
            t.join(5.0)
