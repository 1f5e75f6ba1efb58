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
the uniform sources, :class:`ScaledSource` for each non-uniform one). The engine rebuilds nothing when a setting
changes: the wrappers keep their identity, the uniform part is read on the host every step, and a scaled
source's gain travels as the last entry of its device parameters.

Endpoints (JSON unless said): ``GET /`` the page, ``GET /info`` what does not change (scene, bodies, limits,
sources), ``GET /state`` time, speed, controls and the field the engine uses, ``GET /frame`` positions as
little-endian float32 (N, 3) metres, ``POST /control`` ``{"field": {...}, "gains": {...}}``, ``POST /command``
``{"action": "pause" | "resume" | "reset"}``, ``POST /bye`` (the page is closing). Every request is a heartbeat.
Refused input answers 400 with ``{"error": "..."}``, a message the page shows as it is.
"""

from __future__ import annotations

import collections
import json
import math
import sys
import threading
import time
import traceback
from dataclasses import dataclass, field, replace
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import warp as wp

from magsoro.errors import MagsoroError, SimulationError
from magsoro.fields.base import FieldSource, as_points

CHUNK_WALL = 0.04  # s of wall time per chunk of steps: controls act within this, frames come this often
MAX_POINTS = 20_000  # particles sent to the page at most (evenly spaced subset)
MAX_BODY = 16 * 1024  # bytes: the largest request body accepted
BYE_GRACE = 2.0  # s after the page said goodbye before the server stops (a reload comes back within it)
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
    """A non-uniform source with its B and grad B multiplied by ``gain`` (0 .. ``max_gain``): a coil's current,
    a magnet's strength. The device form calls the source's own function and scales its result by the last
    parameter entry, which this wrapper appends."""

    uniform = False

    def __init__(self, inner: FieldSource, max_gain: float):
        self.inner = inner
        self.gain = 1.0
        self.max_gain = float(max_gain)
        self._func = None

    def B(self, points, t=0.0):
        return self.gain * np.asarray(self.inner.B(points, t))

    def grad_B(self, points, t=0.0):
        return self.gain * np.asarray(self.inner.grad_B(points, t))

    def max_magnitude(self, points, t=0.0):
        return self.max_gain * self.inner.max_magnitude(points, t)

    def device_func(self):
        if self._func is None:  # one function per wrapper: the kernel compiles once, resets reuse it
            self._func = _scaled_func(self.inner.device_func())
        return self._func

    def device_params(self, t):
        return np.concatenate([np.asarray(self.inner.device_params(t), dtype=np.float64).ravel(), [float(self.gain)]])

    def __repr__(self):
        return f"ScaledSource({self.inner!r}, gain={self.gain:g})"


def _scaled_func(func):
    @wp.func
    def scaled(p: wp.vec3d, prm: wp.array(dtype=wp.float64)):
        b, g = func(p, prm)
        gain = prm[prm.shape[0] - 1]
        return b * gain, g * gain

    return scaled


# ---------------------------------------------------------------------------------------------- controls
@dataclass(frozen=True)
class Limits:
    """What the page may set: |B| of the uniform field in [0, max_field] T, gains in [0, max_gain]."""

    dim: int
    max_field: float
    max_gain: float
    sources: tuple[str, ...]  # names of the non-uniform sources with a gain


@dataclass(frozen=True)
class Controls:
    """The drive the page asks for. ``follow_scene``: the uniform field is the scene's (its profile in time);
    otherwise it is ``magnitude`` (T) along the direction of ``azimuth`` (degrees, in the x-y plane from +x
    towards +y) and ``elevation`` (degrees, out of the x-y plane towards +z; 0 in 2D)."""

    follow_scene: bool = True
    magnitude: float = 0.0
    azimuth: float = 90.0
    elevation: float = 0.0
    gains: dict = field(default_factory=dict)

    def vector(self) -> np.ndarray:
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        return self.magnitude * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])

    def as_json(self) -> dict:
        return {"follow_scene": self.follow_scene, "magnitude": self.magnitude, "azimuth": self.azimuth,
                "elevation": self.elevation, "gains": dict(self.gains)}


_FIELD_KEYS = {"magnitude": "T", "azimuth": "degrees", "elevation": "degrees"}


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


def parse_control(payload, current: Controls, limits: Limits) -> Controls:
    """The controls after the change ``payload`` (the body of ``POST /control``) asks for; :class:`ControlError`
    naming the key when it is not a JSON object of known keys, a value is not a number or out of range, or a
    source is unknown. Nothing changes unless the whole request is valid."""
    if not isinstance(payload, dict):
        raise ControlError(f"a control must be a JSON object like {{\"field\": {{\"magnitude\": 0.01}}}}, got {json.dumps(payload)[:80]}")
    unknown = sorted(set(payload) - {"field", "gains"})
    if unknown:
        raise ControlError(f"unknown key '{unknown[0]}'; allowed: field, gains")
    out = current
    if "field" in payload:
        f = payload["field"]
        if not isinstance(f, dict):
            raise ControlError(f"field: must be an object with magnitude, azimuth, elevation or follow_scene, got {json.dumps(f)[:80]}")
        bad = sorted(set(f) - {*_FIELD_KEYS, "follow_scene"})
        if bad:
            raise ControlError(f"field: unknown key '{bad[0]}'; allowed: magnitude, azimuth, elevation, follow_scene")
        ranges = {"magnitude": (0.0, limits.max_field), "azimuth": (-180.0, 180.0), "elevation": (-90.0, 90.0)}
        if limits.dim == 2:
            ranges["elevation"] = (0.0, 0.0)  # plane strain in x-y: a field out of the plane has no meaning here
        changes = {k: _number(f[k], f"field.{k}", _FIELD_KEYS[k], *ranges[k]) for k in _FIELD_KEYS if k in f}
        if "follow_scene" in f:
            if not isinstance(f["follow_scene"], bool):
                raise ControlError(f"field.follow_scene: must be true or false, got {json.dumps(f['follow_scene'])}")
            changes["follow_scene"] = f["follow_scene"]
        elif changes:
            changes["follow_scene"] = False  # setting the field by hand leaves the scene's profile
        out = replace(out, **changes)
    if "gains" in payload:
        g = payload["gains"]
        if not isinstance(g, dict):
            raise ControlError(f"gains: must be an object {{source name: gain}}, got {json.dumps(g)[:80]}")
        gains = dict(out.gains)
        for name, value in g.items():
            if name not in limits.sources:
                have = ", ".join(limits.sources) if limits.sources else "none (the scene has no non-uniform source)"
                raise ControlError(f"gains: no field source named '{name}'; sources with a gain: {have}")
            gains[name] = _number(value, f"gains.{name}", "x the scene's strength", 0.0, limits.max_gain)
        out = replace(out, gains=gains)
    return out


def parse_command(payload) -> str:
    """The action of a ``POST /command`` body; :class:`ControlError` for anything but pause, resume, reset."""
    actions = ("pause", "resume", "reset")
    if not isinstance(payload, dict) or set(payload) != {"action"}:
        raise ControlError(f"a command must be {{\"action\": \"pause\" | \"resume\" | \"reset\"}}, got {json.dumps(payload)[:80]}")
    if payload["action"] not in actions:
        raise ControlError(f"unknown action {json.dumps(payload['action'])[:40]}; allowed: {', '.join(actions)}")
    return payload["action"]


# ---------------------------------------------------------------------------------------------- fields of a run
class LiveFields:
    """The scene's sources behind live controls: one :class:`LiveUniform` for all uniform parts, one
    :class:`ScaledSource` per non-uniform part, grouped by scene entry (``fields[i]``, named by its ``name``
    or ``TYPE_i``) under one gain."""

    def __init__(self, scene, sources, max_field: float | None, max_gain: float):
        uniform, self.channels = [], {}
        for i, src in enumerate(sources):
            spec = scene.fields[i] if i < len(scene.fields) and len(scene.fields) == len(sources) else None
            name = (spec.name or f"{spec.type}_{i}") if spec is not None else f"source_{i}"
            while name in self.channels:  # a scene name that looks like a generated one: keep both sources
                name += f"_{i}"
            parts = src.sources()
            uniform += [e for e in parts if e.uniform]
            scaled = [ScaledSource(e, max_gain) for e in parts if not e.uniform]
            if scaled:
                self.channels[name] = scaled
        self.uniform = LiveUniform(uniform, 0.0)
        peak = self.uniform.scene_peak()
        self.max_field = float(max_field) if max_field is not None else max(2.0 * peak, 0.02)
        self.uniform.bound = self.max_field
        self.max_gain = float(max_gain)
        self.duration = float(scene.simulation.duration)

    def sources(self) -> list:
        return [self.uniform] + [s for group in self.channels.values() for s in group]

    def limits(self, dim: int) -> Limits:
        return Limits(dim, self.max_field, self.max_gain, tuple(self.channels))

    def initial_controls(self, dim: int) -> Controls:
        """The scene's field as the starting point of the sliders: its uniform field at t = 0 (at the end of
        the run when it is zero then, as for a ramp), all gains 1."""
        b = self.uniform.scene_value(0.0)
        if not np.linalg.norm(b) > 0:
            b = self.uniform.scene_value(self.duration)
        mag = float(np.linalg.norm(b if dim == 3 else b[:2]))  # 2D: the in-plane part, what the sliders set
        az, el = 90.0, 0.0
        if mag > 0:
            az = math.degrees(math.atan2(b[1], b[0]))
            el = 0.0 if dim == 2 else math.degrees(math.asin(max(-1.0, min(1.0, b[2] / mag))))
        return Controls(True, min(mag, self.max_field), round(az, 6), round(el, 6), {k: 1.0 for k in self.channels})

    def apply(self, c: Controls) -> None:
        """Set the wrappers (call between steps, from the thread that steps)."""
        self.uniform.follow_scene = c.follow_scene
        self.uniform.vector = c.vector()
        for name, group in self.channels.items():
            for s in group:
                s.gain = float(c.gains.get(name, 1.0))

    def install(self, sim) -> None:
        """Put the wrappers in ``sim``'s control and bound its time step for the largest field the page may set."""
        # the wrappers' peaks are the limits of the sliders: the time step is bounded for those
        sim.set_sources(self.sources())


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


# ---------------------------------------------------------------------------------------------- the session
class LiveSession:
    """The simulation, its controls and what the page reads, shared between the threads."""

    def __init__(self, scene, source: str, device: str | None = None, max_points: int = MAX_POINTS,
                 max_field: float | None = None, max_gain: float = 2.0, idle_timeout: float = DEFAULT_IDLE,
                 paused: bool = False):
        from magsoro.simulation import Simulation

        if not (isinstance(max_points, int) and 1 <= max_points <= MAX_POINTS):
            raise MagsoroError(f"max_points must be an integer in [1, {MAX_POINTS}], got {max_points!r}")
        for name, v in (("max_field", max_field), ("max_gain", max_gain), ("idle_timeout", idle_timeout)):
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise MagsoroError(f"{name} must be a finite number > 0, got {v!r}")
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
        self._wake = threading.Event()
        self.frame_id = 0
        self._frame = b""
        self._published = (0.0, 0)  # (time, steps) of the published frame
        self._rates = collections.deque(maxlen=64)  # (wall, sim time, steps) after each chunk
        self._chunk_steps = 8
        self.engine_field = engine_uniform_field(self.sim)
        self.last_seen: float | None = None  # monotonic time of the page's last request
        self.bye_at: float | None = None
        self.stop_reason: str | None = None
        self._stop = threading.Event()
        self.stopped = threading.Event()
        self._publish()

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

    def command(self, payload) -> str:
        action = parse_command(payload)
        with self._lock:
            if action == "reset":
                self._reset_requested = True
            else:
                self.paused = action == "pause"
                self._rates.clear()
            self._wake.set()
        return action

    def info(self) -> dict:
        host = self.sim.model.host
        lo, hi = self.sim.model.domain_lo, self.sim.model.domain_hi
        return {
            "scene": self.scene.name or str(self.source),
            "dim": self.dim,
            "particles": int(self.sim.model.n_particles),
            "shown": len(self.index),
            "dx": float(self.sim.model.dx),
            "domain_lo": np.asarray(lo, dtype=float).tolist(),
            "domain_hi": np.asarray(hi, dtype=float).tolist(),
            "bodies": list(self.sim.built.body_names),
            "body": np.asarray(host["body"])[self.index].astype(int).tolist(),
            "clamped": np.asarray(host["clamped"])[self.index].astype(int).tolist(),
            "limits": {"magnitude": [0.0, self.limits.max_field], "azimuth": [-180.0, 180.0],
                       "elevation": [0.0, 0.0] if self.dim == 2 else [-90.0, 90.0], "gain": [0.0, self.limits.max_gain]},
            "sources": list(self.limits.sources),
            "has_scene_uniform": bool(self.fields.uniform.scene_sources),
            "idle_timeout": self.idle_timeout,
        }

    def status(self) -> dict:
        with self._lock:
            t, steps = self._published
            speed, rate = self._speed()
            return {
                "time": t, "steps": steps, "frame": self.frame_id, "phase": self.phase, "paused": self.paused,
                "error": self.error, "speed": speed, "steps_per_s": rate, "dt": float(self.sim.dt),
                "controls": self.requested.as_json(), "applied": self.applied.as_json(),
                "engine_field": self.engine_field.tolist(), "stopping": self.stop_reason,
            }

    def frame(self) -> tuple[int, bytes, float]:
        with self._lock:
            return self.frame_id, self._frame, self._published[0]

    # -- the stepping thread --------------------------------------------------------------------------------
    def run(self) -> None:
        """Step until :meth:`stop`; also stops the session when the page has gone."""
        try:
            while not self._stop.is_set():
                self._watch_page()
                with self._lock:
                    reset, self._reset_requested = self._reset_requested, False
                    wanted = self.requested
                if reset:
                    self._reset()
                    continue
                if wanted is not self.applied:
                    self.fields.apply(wanted)
                    with self._lock:
                        self.applied = wanted
                        self.engine_field = engine_uniform_field(self.sim)
                if self.paused or self.error is not None:
                    with self._lock:
                        self.phase = "failed" if self.error is not None else "paused"
                    self._wake.wait(0.05)
                    self._wake.clear()
                    continue
                self._chunk()
        finally:
            self.stopped.set()

    def _chunk(self) -> None:
        sim = self.sim
        wall0 = time.perf_counter()
        try:
            sim.advance_to(sim.time + self._chunk_steps * sim.dt)
        except SimulationError as exc:
            self.error = f"step {exc.step}, t = {exc.time:.6g} s: {exc}" if exc.step is not None else str(exc)
        except Exception as exc:  # noqa: BLE001 - a bug or a source that cannot evaluate: shown on the page, not a dead thread
            traceback.print_exc(file=sys.stderr)
            self.error = f"{type(exc).__name__}: {exc}"
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
        self._publish()

    def _reset(self) -> None:
        with self._lock:
            self.phase = "resetting"
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
        self._publish()

    def _publish(self) -> None:
        x = self.sim.state.x.numpy()[self.index]
        pts = np.zeros((len(self.index), 3), dtype="<f4")
        pts[:, : x.shape[1]] = x
        with self._lock:
            self._frame = pts.tobytes()
            self._published = (float(self.sim.time), int(self.sim.steps))
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
            fid, data, t = s.frame()
            self._send(200, data, "application/octet-stream", {"X-Frame": str(fid), "X-Time": repr(t)})
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
        if path not in ("/control", "/command"):
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
            else:
                self._json(200, {"ok": True, "action": s.command(payload)})
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
