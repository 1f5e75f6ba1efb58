"""Pictures and animations of a run's particle series (``magsoro render RUN_DIR --out FILE``).

Reads what ``magsoro run`` wrote (run.json with the scene as run, particles.pvd and frames/*.vtp) and draws
each chosen frame: the particles coloured by part, speed, strain or magnetisation, the scene's colliders
(translucent, at their position at that time), an arrow for the uniform applied field with its magnitude in mT,
a time label, a scale bar and an axis triad. Output is a PNG (one frame), a GIF or an MP4 (several frames).

Two drawing backends, both headless:

* **PyVista** (VTK, the optional extra ``magsoro[render]``): particles as shaded sphere sprites, orthographic
  camera, rendered off-screen (on a machine without an X server VTK falls back to EGL/OSMesa).
* **matplotlib** (always installed, Agg): the fallback when PyVista cannot be imported, and the drawing of 2D
  runs (a flat, exact 2D picture, which is what a plane-strain run is).

What each colour needs from the frames (every frame ``magsoro run`` writes has all four arrays):

* ``part``: ``body``, the body index (bodies in scene order, named from run.json).
* ``speed``: ``velocity``; |v| in mm/s.
* ``strain``: ``I1bar`` = J^(-2/3) tr(F^T F); the equivalent (von Mises) deviatoric logarithmic strain
  sqrt((I1bar - 3) / 3), in %. It equals sqrt(2/3 |dev ln U|^2) to second order in the strain (uniaxial
  stretch lambda = 1.2: 18.9 % against ln 1.2 = 18.2 %); volume change (J) is not part of it. The frames do
  not carry F itself, so this is the strain scalar they allow.
* ``magnetisation``: ``magnetization_direction``, the current unit direction of F Br; the colour is the angle
  (degrees) by which it has turned since the run's first frame (t = 0, F = I, the reference Br direction),
  signed in 2D (counter-clockwise positive), 0 to 180 in 3D; arrows on a subsample show the current
  direction. Particles without remanence are grey.
"""

from __future__ import annotations

import io
import math
import os
import shutil
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magsoro.errors import MagsoroError, output_error


class RenderError(MagsoroError):
    """Bad input to ``magsoro render`` (argument, run folder, missing data); the message names the argument."""


COLOR_MODES = {
    "part": "body",
    "speed": "velocity",
    "strain": "I1bar",
    "magnetisation": "magnetization_direction",
}
COLOR_ALIASES = {"magnetization": "magnetisation", "body": "part"}
VIEWS = ("iso", "x", "y", "z")
FORMATS = (".png", ".gif", ".mp4")
BACKENDS = ("auto", "pyvista", "matplotlib")
BACKEND_ENV = "MAGSORO_RENDER_BACKEND"  # auto | pyvista | matplotlib: what "auto" means in this process
MAX_ANIMATION_FRAMES = 120  # default cap of an animation's frames (spread over the run); --frames all lifts it
MAX_ARROWS = 150  # magnetisation arrows drawn per frame
FFMPEG_HINT = "pip install imageio-ffmpeg (or 'magsoro[render]'), or put an ffmpeg executable on PATH"

# camera directions (elevation, azimuth in degrees, matplotlib's convention) and the world 'up' of each view
_VIEW_ANGLES = {"iso": (30.0, -60.0), "x": (0.0, 0.0), "y": (0.0, -90.0), "z": (90.0, -90.0)}
_BODY_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]
_COLLIDER_COLOUR = "#708090"
_FIELD_COLOUR = "#c0142c"
_HELD_COLOUR = "#3a3a3a"  # particles a clamp holds (the frames' ``clamped`` flag), whatever the colour mode


# ------------------------------------------------------------------------------------------------ the run
@dataclass
class RunSeries:
    """What a run folder holds for drawing: its run.json, dimension and the frames (stamp, file)."""

    directory: Path
    info: dict
    dim: int
    stamps: list[float]
    files: list[Path]
    kind: str  # "dynamic", "static" (stamps are load levels) or "equilibrium"
    body_names: list[str]

    @property
    def scene(self) -> dict:
        s = self.info.get("scene")
        return s if isinstance(s, dict) else {}

    @property
    def name(self) -> str:
        return str(self.scene.get("name") or self.directory.resolve().name)


def is_axisymmetric(info: dict) -> bool:
    """Whether run.json ``info`` is of an axisymmetric scene (simulation.dim = "axisymmetric")."""
    sim = (info.get("scene") or {}).get("simulation") if isinstance(info.get("scene"), dict) else None
    return isinstance(sim, dict) and (sim.get("dim") == "axisymmetric" or sim.get("plane") == "axisymmetric")


#: the part of the revolution drawn (radians): three quarters, so that the cut shows the (r, z) section
REVOLVED_ANGLE = 1.5 * math.pi


def revolve_rings(x_mm: np.ndarray, dirs, spacing: float):
    """The rings of an axisymmetric frame (positions in mm, x the radius, y the axis) as points of the body of
    revolution over REVOLVED_ANGLE: each particle repeated at angles about one ``spacing`` apart along its ring
    (at least once), at (r cos t, z, r sin t). Returns (the particle each point comes from, the points, their
    directions turned with them, or None)."""
    r = np.abs(x_mm[:, 0])
    step = spacing if spacing > 0 else max(float(r.max()) / 20.0, 1e-9)
    counts = np.maximum(1, np.ceil(REVOLVED_ANGLE * r / step).astype(int))
    ring = np.repeat(np.arange(len(x_mm)), counts)
    k = np.concatenate([np.arange(c) for c in counts]) if len(counts) else np.zeros(0, dtype=int)
    t = (k + 0.5) / counts[ring] * REVOLVED_ANGLE
    c, s_ = np.cos(t), np.sin(t)
    pts = np.stack([x_mm[ring, 0] * c, x_mm[ring, 1], x_mm[ring, 0] * s_], axis=1)
    turned = None
    if dirs is not None:
        d = dirs[ring]
        turned = np.stack([d[:, 0] * c, d[:, 1], d[:, 0] * s_], axis=1)
    return ring, pts, turned


def open_run(run_dir) -> RunSeries:
    """The run in ``run_dir``; RenderError naming RUN_DIR when it is missing, not a run, or has no frames."""
    from magsoro.io.outdir import read_run_info
    from magsoro.viz.report import read_frames

    d = Path(run_dir)
    if not d.exists():
        raise RenderError(f"RUN_DIR: {d} does not exist; give a folder written by 'magsoro run'")
    if not d.is_dir():
        raise RenderError(f"RUN_DIR: {d} is a file; give a folder written by 'magsoro run'")
    info = read_run_info(d)
    if info is None:
        raise RenderError(f"RUN_DIR: {d} is not a magsoro run (no run.json of ours); give a folder written by 'magsoro run'")
    frames = read_frames(d)
    if not frames:
        raise RenderError(f"RUN_DIR: {d} has no particle frames (particles.pvd missing or empty; the scene may set "
                          f"output.particles = false)")
    scene = info.get("scene") if isinstance(info.get("scene"), dict) else {}
    dim = info.get("dim") or (scene.get("simulation") or {}).get("dim") or 3
    kind = "static" if "static" in info else "equilibrium" if "equilibrium" in info else "dynamic"
    names = [str(b.get("body", i)) for i, b in enumerate(info.get("bodies") or []) if isinstance(b, dict)]
    return RunSeries(d, info, int(dim), [t for t, _ in frames], [f for _, f in frames], kind, names)


def select_frames(spec: str | None, stamps: list[float], animated: bool) -> tuple[list[int], str]:
    """Frame indices chosen by ``spec`` (None: the last frame for a picture, every frame up to
    :data:`MAX_ANIMATION_FRAMES` spread over the run for an animation), and a note ('' when nothing to say).

    ``spec`` is a comma-separated list of: an index (0 first, -1 last), a slice as in Python (``0:10:2``,
    ``::5``), ``t=TIME`` (the frame nearest TIME, in s; for a static run the nearest level), ``first``, ``last``
    or ``all``."""
    n = len(stamps)
    allowed = ("an index (0, -1), a slice (0:10:2, ::5), t=TIME in s (nearest frame), first, last or all, "
               f"comma-separated; the run has {n} frame{'s' if n != 1 else ''} (0..{n - 1})")
    if spec is None:
        if not animated:
            return [n - 1], ""
        if n > MAX_ANIMATION_FRAMES:
            idx = np.unique(np.round(np.linspace(0, n - 1, MAX_ANIMATION_FRAMES)).astype(int)).tolist()
            return idx, f"{len(idx)} of {n} frames, spread over the run (--frames all for every frame)"
        return list(range(n)), ""
    out: list[int] = []
    items = [s.strip() for s in str(spec).split(",")]
    if not any(items):
        raise RenderError(f"--frames: empty; give {allowed}")
    for item in items:
        low = item.lower()
        try:
            if low == "all":
                out.extend(range(n))
            elif low == "first":
                out.append(0)
            elif low == "last":
                out.append(n - 1)
            elif low.startswith("t="):
                t = float(low[2:])
                if not math.isfinite(t):
                    raise ValueError
                out.append(int(np.argmin(np.abs(np.asarray(stamps) - t))))
            elif ":" in item:
                parts = item.split(":")
                if len(parts) > 3:
                    raise ValueError
                a, b, c = (int(p) if p.strip() else None for p in parts + [""] * (3 - len(parts)))
                if c == 0:
                    raise RenderError(f"--frames: '{item}': a slice step cannot be 0; give {allowed}")
                picked = list(range(n))[slice(a, b, c)]
                if not picked:
                    raise RenderError(f"--frames: '{item}' selects no frame; give {allowed}")
                out.extend(picked)
            else:
                k = int(item)
                if not -n <= k < n:
                    raise RenderError(f"--frames: index {k} is out of range; the run has {n} frames (0..{n - 1}, or -{n}..-1)")
                out.append(k % n)
        except ValueError:
            raise RenderError(f"--frames: '{item}' is not a frame selection; give {allowed}") from None
    seen: set[int] = set()
    unique = [k for k in out if not (k in seen or seen.add(k))]
    return unique, ""


def normalise_color(color: str) -> str:
    c = COLOR_ALIASES.get(str(color).lower(), str(color).lower())
    if c not in COLOR_MODES:
        raise RenderError(f"--color: '{color}' is not a colour mode; allowed: {', '.join(COLOR_MODES)}")
    return c


def check_output(out) -> str:
    """The output format ('.png', '.gif', '.mp4') of ``out``; RenderError naming --out when it is not one of
    them, when its folder does not exist, or for .mp4 when no ffmpeg can be found."""
    path = Path(out)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise RenderError(f"--out: '{out}' must end in .png (one frame), .gif or .mp4 (an animation)")
    if path.is_dir():
        raise RenderError(f"--out: {out} is a folder; name a file ending in {suffix}")
    if not path.resolve().parent.is_dir():
        raise RenderError(f"--out: the folder {path.parent} does not exist")
    if suffix == ".mp4" and find_ffmpeg() is None:
        raise RenderError(f"--out: writing .mp4 needs ffmpeg, which was not found: {FFMPEG_HINT}; .gif works without it")
    return suffix


def find_ffmpeg() -> str | None:
    """An ffmpeg executable: imageio-ffmpeg's bundled one, else ``ffmpeg`` on PATH, else None."""
    try:
        import imageio_ffmpeg

        exe = imageio_ffmpeg.get_ffmpeg_exe()
        if exe and Path(exe).is_file():
            return exe
    except Exception:  # not installed, or its binary missing: try PATH
        pass
    return shutil.which("ffmpeg")


# ------------------------------------------------------------------------------------------ scene overlays
def _validated(items, adapter_type, what: str, notes: list[str]):
    from pydantic import TypeAdapter, ValidationError

    adapter = TypeAdapter(adapter_type)
    out = []
    for i, item in enumerate(items or []):
        try:
            out.append(adapter.validate_python(item))
        except ValidationError:
            notes.append(f"{what}[{i}] of the scene could not be read; not drawn")
    return out


class Overlays:
    """The scene's colliders and uniform applied field as functions of a frame's stamp."""

    def __init__(self, series: RunSeries):
        from magsoro.scene.schema import AnyCollider, AnyField

        self.series = series
        self.notes: list[str] = []
        scene = series.scene
        sim = scene.get("simulation") or {}
        self.plane_z = float(sim.get("plane_z", 0.0) or 0.0)
        self.duration = float(sim.get("duration", 0.0) or 0.0)
        static = series.info.get("static") if isinstance(series.info.get("static"), dict) else {}
        self.t_loads = float(static.get("t_loads", self.duration) or self.duration)

        self.colliders = []
        for spec in _validated(scene.get("colliders"), AnyCollider, "colliders", self.notes):
            from magsoro.scene.build import make_collider

            try:
                self.colliders.append(make_collider(spec, series.dim, self.plane_z))
            except (ValueError, MagsoroError) as exc:
                self.notes.append(f"a {spec.type} collider could not be built ({exc}); not drawn")

        self.uniform = []
        skipped = []
        for spec in _validated(scene.get("fields"), AnyField, "fields", self.notes):
            if spec.type in ("uniform", "rotating") or (spec.type == "keyframes" and spec.file is None):
                from magsoro.scene.build import make_field

                try:
                    self.uniform.append(make_field(spec, None))
                except (ValueError, MagsoroError) as exc:
                    self.notes.append(f"a {spec.type} field could not be built ({exc}); not drawn")
            elif spec.type == "keyframes":
                skipped.append("keyframes from a file")
            else:
                skipped.append(spec.type)
        self.non_uniform = skipped
        if skipped:
            self.notes.append(f"field: {', '.join(sorted(set(skipped)))} source{'s' if len(skipped) > 1 else ''} "
                              f"not drawn (no single arrow stands for a non-uniform field)")

    def time_of(self, stamp: float) -> tuple[float, float]:
        """(time at which the loads act, field scale) for a frame stamp: static runs stamp load levels."""
        if self.series.kind == "static":
            return self.t_loads, float(stamp)
        return float(stamp), 1.0

    def field(self, stamp: float) -> np.ndarray | None:
        """Sum of the uniform applied fields (T) at the frame, or None when the scene has none."""
        if not self.uniform:
            return None
        t, scale = self.time_of(stamp)
        return scale * sum((np.asarray(f.uniform_value(t), dtype=np.float64) for f in self.uniform), np.zeros(3))

    def collider_shapes(self, stamp: float) -> list[dict]:
        """Colliders at the frame as dicts: kind, centre (m), rotation (local -> world), size (as in
        :mod:`magsoro.mpm.colliders`), and the Collider itself (for its signed distance)."""
        t, _ = self.time_of(stamp)
        out = []
        for c in self.colliders:
            out.append({"kind": c.kind, "centre": np.array(c.position_at(t), dtype=np.float64), "R": c.rotation.copy(),
                        "size": c.size.copy(), "collider": c, "t": t})
        return out


# ------------------------------------------------------------------------------------------------- colours
@dataclass
class ColourScale:
    mode: str
    label: str
    vmin: float = 0.0
    vmax: float = 1.0
    cmap: str = "viridis"
    names: list[str] = field(default_factory=list)  # part mode: body names in body-index order
    short: str = ""  # the colour bar's title where space is short (PyVista draws it horizontally)

    @property
    def categorical(self) -> bool:
        return self.mode == "part"


def colour_values(mode: str, data: dict, dim: int, reference_direction: np.ndarray | None, where: str) -> np.ndarray:
    """Per-particle colour values of a frame (NaN: no value, drawn grey)."""
    name = COLOR_MODES[mode]
    if name not in data:
        raise RenderError(f"--color {mode}: the run's frames have no '{name}' array ({where}); "
                          f"allowed here: {', '.join(m for m, a in COLOR_MODES.items() if a in data) or 'none'}")
    a = np.asarray(data[name])
    if mode == "part":
        return a.astype(np.int64).reshape(-1)
    if mode == "speed":
        return np.linalg.norm(a.reshape(len(a), -1).astype(np.float64), axis=1) * 1e3  # mm/s
    if mode == "strain":
        return np.sqrt(np.maximum(a.astype(np.float64) - 3.0, 0.0) / 3.0) * 100.0  # %
    m = a.reshape(len(a), 3).astype(np.float64)
    ref = reference_direction if reference_direction is not None else m
    valid = (np.linalg.norm(m, axis=1) > 0.5) & (np.linalg.norm(ref, axis=1) > 0.5)
    if dim == 2:
        ang = np.degrees(np.arctan2(ref[:, 0] * m[:, 1] - ref[:, 1] * m[:, 0], np.einsum("ij,ij->i", ref[:, :2], m[:, :2])))
    else:
        ang = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", ref, m), -1.0, 1.0)))
    return np.where(valid, ang, np.nan)


def colour_scale(mode: str, values: list[np.ndarray], dim: int, names: list[str]) -> ColourScale:
    """One colour scale for all drawn frames, so an animation's colours mean the same throughout."""
    if mode == "part":
        n = int(max((v.max() for v in values if len(v)), default=0)) + 1
        full = [names[i] if i < len(names) else f"body {i}" for i in range(n)]
        return ColourScale(mode, "part (body)", 0, max(n - 1, 1), names=full)
    finite = [v[np.isfinite(v)] for v in values]
    top = max((float(f.max()) for f in finite if f.size), default=0.0)
    if mode == "speed":
        return ColourScale(mode, "speed (mm/s)", 0.0, top if top > 0 else 1.0, "viridis", short="speed (mm/s)")
    if mode == "strain":
        return ColourScale(mode, "equivalent strain (%)", 0.0, top if top > 0 else 1.0, "magma", short="strain (%)")
    if dim == 2:
        lo = min((float(f.min()) for f in finite if f.size), default=0.0)
        half = max(abs(lo), abs(top), 1.0)
        return ColourScale(mode, "magnetisation turned since t = 0 (deg, ccw +)", -half, half, "coolwarm", short="m turned (deg)")
    return ColourScale(mode, "magnetisation turned since t = 0 (deg)", 0.0, max(top, 1.0), "plasma", short="m turned (deg)")


# -------------------------------------------------------------------------------------------------- layout
def _view_vectors(view: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(towards the camera, screen up, screen right) unit vectors of a view."""
    elev, azim = np.radians(_VIEW_ANGLES[view])
    d = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
    up = np.array([0.0, 1.0, 0.0]) if view == "z" else np.array([0.0, 0.0, 1.0])
    right = np.cross(-d, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, -d)
    return d, up / np.linalg.norm(up), right


def nice_length(target: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above ``target`` (> 0)."""
    k = math.floor(math.log10(target))
    for m in (5.0, 2.0, 1.0):
        if m * 10**k <= target:
            return m * 10**k
    return 10**k


def length_label(mm: float) -> str:
    if mm >= 1000:
        return f"{mm / 1000:g} m"
    if mm >= 1:
        return f"{mm:g} mm"
    return f"{mm * 1000:g} µm"


def time_label(series: RunSeries, stamp: float, k: int) -> str:
    n = len(series.stamps)
    if series.kind == "static":
        return f"level {stamp:.3g} (static)   frame {k}/{n - 1}"
    top = max(abs(t) for t in series.stamps) or 1.0
    unit, scale = ("s", 1.0) if top >= 1 else ("ms", 1e3) if top >= 1e-3 else ("µs", 1e6)
    extra = " (equilibrium run)" if series.kind == "equilibrium" else ""
    return f"t = {stamp * scale:.4g} {unit}{extra}   frame {k}/{n - 1}"


def field_label(B: np.ndarray | None, dim: int) -> str:
    if B is None:
        return "no uniform applied field"
    mT = B * 1e3
    # components below 1e-9 of |B| are round-off of a rotated or interpolated field (a cosine of 90 degrees)
    mT = np.where(np.abs(mT) > 1e-9 * np.linalg.norm(mT), mT, 0.0)
    text = f"B = {np.linalg.norm(mT):.3g} mT ({mT[0]:.3g}, {mT[1]:.3g}, {mT[2]:.3g})"
    if dim == 2 and abs(mT[2]) > 1e-9 * max(np.linalg.norm(mT), 1e-30):
        text += ", Bz out of plane"
    return text


@dataclass
class Layout:
    """What stays fixed over the frames: the view, the region shown, particle size, scale bar, arrow anchor."""

    dim: int
    view: str
    centre: np.ndarray  # mm
    half: np.ndarray  # mm, half extents of the particles' box over all frames
    extent: float  # mm, largest edge of that box
    radius: float  # mm, drawn particle radius (half the particle spacing)
    towards_camera: np.ndarray
    up: np.ndarray
    right: np.ndarray
    bar_start: np.ndarray
    bar_axis: np.ndarray
    bar_length: float  # mm
    arrow_anchor: np.ndarray
    arrow_length: float  # mm
    triad_origin: np.ndarray
    triad_length: float

    def fit_points(self) -> np.ndarray:
        c, h = self.centre, self.half
        corners = np.array([[c[0] + sx * h[0], c[1] + sy * h[1], c[2] + sz * h[2]] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        extra = [self.bar_start, self.bar_start + self.bar_length * self.bar_axis, self.arrow_anchor,
                 self.triad_origin, self.triad_origin + self.triad_length * np.ones(3)]
        # the field arrow may point any way about its anchor, with its label above: keep all of that in view
        reach = self.arrow_length * np.eye(3)[: self.dim]
        if self.dim == 2:
            reach = np.vstack([reach, [0.0, 0.0, 0.0]])
        return np.vstack([corners, *extra, self.arrow_anchor + 0.8 * reach, self.arrow_anchor - 0.6 * reach])


def particle_spacing(x: np.ndarray) -> float:
    """Median nearest-neighbour distance of the particles (same unit as ``x``)."""
    from scipy.spatial import cKDTree

    x = x[np.isfinite(x).all(axis=1)]
    if len(x) < 2:
        return 0.0
    d, _ = cKDTree(x).query(x, k=2)
    d = d[:, 1]
    d = d[d > 0]
    return float(np.median(d)) if d.size else 0.0


def make_layout(dim: int, view: str, positions_mm: list[np.ndarray]) -> Layout:
    allx = np.concatenate([p[np.isfinite(p).all(axis=1)] for p in positions_mm]) if positions_mm else np.zeros((1, 3))
    if not len(allx):
        allx = np.zeros((1, 3))
    lo, hi = allx.min(axis=0), allx.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    extent = float(max(2 * half.max(), 1e-6))
    spacing = particle_spacing(positions_mm[0]) if positions_mm else 0.0
    radius = 0.5 * spacing if spacing > 0 else 0.01 * extent
    d, up, right = _view_vectors(view if dim == 3 else "z")
    bar_axis = np.eye(3)[int(np.argmax(np.abs(right)))] * np.sign(right[int(np.argmax(np.abs(right)))])
    bar_length = nice_length(0.3 * extent)
    gap = 0.12 * extent
    if dim == 2:
        bar_start = np.array([lo[0], lo[1] - gap, 0.0])
        anchor = np.array([lo[0] + 0.5 * 0.3 * extent, hi[1] + gap + 0.5 * 0.3 * extent, 0.0])
        triad = np.array([hi[0] - 0.1 * extent, lo[1] - gap, 0.0])
    else:
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        low = corners[np.argmin(corners @ up + 1e-3 * corners @ right)]
        bar_start = low - gap * up
        bar_start = bar_start - bar_axis * (bar_start @ bar_axis - (corners @ bar_axis).min())
        anchor = corners[np.argmax(corners @ (up - right))] + (gap + 0.3 * extent) * up
        triad = corners[np.argmax(corners @ (right - up))] + gap * (right - up)
    return Layout(dim, view, centre, half, extent, radius, d, up, right, bar_start, bar_axis, bar_length, anchor,
                  0.3 * extent, triad, 0.1 * extent)


# ---------------------------------------------------------------------------------------------- the frames
@dataclass
class FramePicture:
    """One frame to draw: positions and colour values (mm), overlays, labels."""

    x: np.ndarray
    values: np.ndarray
    arrows: tuple[np.ndarray, np.ndarray] | None
    colliders: list[dict]
    field: np.ndarray | None  # T
    label: str
    held: np.ndarray | None = None  # per particle: held by a clamp (drawn in _HELD_COLOUR)


def _arrows(x_mm, direction, k=MAX_ARROWS):
    norm = np.linalg.norm(direction, axis=1)
    idx = np.flatnonzero(norm > 0.5)
    if not idx.size:
        return None
    idx = idx[np.unique(np.linspace(0, idx.size - 1, min(k, idx.size)).astype(int))]
    return x_mm[idx], direction[idx] / norm[idx, None]


@dataclass
class RenderResult:
    out: Path
    backend: str
    frames: int
    particles: int
    seconds: float
    notes: list[str]


# ----------------------------------------------------------------------------------------------- backends
def pyvista_available() -> tuple[bool, str]:
    try:
        import pyvista  # noqa: F401
    except Exception as exc:  # ImportError, or a broken VTK install
        return False, f"{type(exc).__name__}: {exc}"
    return True, ""


def choose_backend(requested: str, dim: int) -> tuple[str, str]:
    """(backend, note). ``requested`` auto|pyvista|matplotlib; "auto" reads MAGSORO_RENDER_BACKEND, then uses
    PyVista when it imports, else matplotlib. 2D runs are drawn with matplotlib."""
    requested = (requested or "auto").lower()
    if requested not in BACKENDS:
        raise RenderError(f"--backend: '{requested}' is not a backend; allowed: {', '.join(BACKENDS)}")
    if requested == "auto":
        env = os.environ.get(BACKEND_ENV, "auto").strip().lower() or "auto"
        if env not in BACKENDS:
            raise RenderError(f"{BACKEND_ENV}: '{env}' is not a backend; allowed: {', '.join(BACKENDS)}")
        requested = env
    if dim == 2:
        note = "2D run: drawn flat with matplotlib" + (" (pyvista is for 3D runs)" if requested == "pyvista" else "")
        return "matplotlib", note
    if requested == "matplotlib":
        return "matplotlib", ""
    ok, why = pyvista_available()
    if ok:
        return "pyvista", ""
    if requested == "pyvista":
        raise RenderError(f"--backend pyvista: PyVista cannot be imported ({why}); pip install 'magsoro[render]'")
    return "matplotlib", f"PyVista not importable ({why}); fell back to matplotlib (pip install 'magsoro[render]' for shaded spheres)"


def _rgb(figure_canvas) -> np.ndarray:
    figure_canvas.draw()
    return np.asarray(figure_canvas.buffer_rgba())[..., :3].copy()


class MatplotlibBackend:
    name = "matplotlib"

    def __init__(self, layout: Layout, scale: ColourScale, size: tuple[int, int], title: str):
        import matplotlib

        matplotlib.use("Agg")
        self.layout, self.scale, self.size, self.title = layout, scale, size, title
        self.dpi = 100

    def describe(self) -> str:
        import matplotlib

        return f"matplotlib {matplotlib.__version__} (Agg)"

    def _colours(self, values):
        import matplotlib.pyplot as plt
        from matplotlib.colors import Normalize, to_rgba

        s = self.scale
        if s.categorical:
            return np.array([to_rgba(_BODY_COLOURS[int(v) % 10]) for v in values]) if len(values) else np.zeros((0, 4))
        rgba = plt.get_cmap(s.cmap)(Normalize(s.vmin, s.vmax)(np.nan_to_num(values, nan=s.vmin)))
        rgba[~np.isfinite(values)] = to_rgba("lightgrey")
        return rgba

    def _picture_colours(self, pic: FramePicture):
        from matplotlib.colors import to_rgba

        rgba = self._colours(pic.values)
        if pic.held is not None and len(rgba):
            rgba[pic.held] = to_rgba(_HELD_COLOUR)
        return rgba

    def _legend(self, fig, ax):
        import matplotlib.pyplot as plt
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize
        from matplotlib.lines import Line2D

        s = self.scale
        if s.categorical:
            handles = [Line2D([], [], marker="o", ls="", color=_BODY_COLOURS[i % 10], label=n) for i, n in enumerate(s.names)]
            ax.legend(handles=handles, loc="lower right", fontsize=8, framealpha=0.8)
        else:
            cax = fig.add_axes([0.9, 0.25, 0.02, 0.5])
            cb = fig.colorbar(ScalarMappable(Normalize(s.vmin, s.vmax), plt.get_cmap(s.cmap)), cax=cax)
            cb.set_label(s.label, fontsize=8)
            cb.ax.tick_params(labelsize=7)

    def _texts(self, fig, pic: FramePicture, notes: list[str]):
        fig.text(0.02, 0.97, self.title, fontsize=10, va="top", weight="bold")
        fig.text(0.02, 0.93, pic.label, fontsize=9, va="top")
        fig.text(0.02, 0.895, field_label(pic.field, self.layout.dim), fontsize=8, va="top", color=_FIELD_COLOUR)
        for i, n in enumerate(notes[:4]):
            fig.text(0.02, 0.02 + 0.03 * i, n, fontsize=7, va="bottom", color="dimgray")

    def draw(self, pic: FramePicture, notes: list[str]) -> np.ndarray:
        import matplotlib.pyplot as plt

        w, h = self.size
        fig = plt.figure(figsize=(w / self.dpi, h / self.dpi), dpi=self.dpi)
        try:
            if self.layout.dim == 2:
                self._draw_2d(fig, pic)
            else:
                self._draw_3d(fig, pic)
            self._texts(fig, pic, notes)
            img = _rgb(fig.canvas)
        finally:
            plt.close(fig)
        return img

    # -- 2D: flat and exact
    def _draw_2d(self, fig, pic: FramePicture):
        L = self.layout
        ax = fig.add_axes([0.04, 0.08, 0.83, 0.78])
        pts = L.fit_points()
        lo, hi = pts.min(axis=0) - 0.05 * L.extent, pts.max(axis=0) + 0.05 * L.extent
        # equal scale on both axes: widen the range that is short for the axes' shape
        box = ax.get_window_extent(renderer=fig.canvas.get_renderer())
        px_per_mm = min(box.width / (hi[0] - lo[0]), box.height / (hi[1] - lo[1]))
        c = 0.5 * (lo + hi)
        ax.set_xlim(c[0] - 0.5 * box.width / px_per_mm, c[0] + 0.5 * box.width / px_per_mm)
        ax.set_ylim(c[1] - 0.5 * box.height / px_per_mm, c[1] + 0.5 * box.height / px_per_mm)
        ax.set_axis_off()
        size_pt = max(2 * L.radius * px_per_mm * 72 / self.dpi, 0.5)
        self._colliders_2d(ax, pic.colliders)
        ax.scatter(pic.x[:, 0], pic.x[:, 1], s=size_pt**2, c=self._picture_colours(pic), linewidths=0, zorder=2)
        if pic.arrows is not None:
            p, d = pic.arrows
            ax.quiver(p[:, 0], p[:, 1], d[:, 0], d[:, 1], angles="xy", scale_units="xy", scale=1 / (3 * L.radius + 0.02 * L.extent),
                      color="black", width=0.002, zorder=3)
        b = L.bar_start
        ax.plot([b[0], b[0] + L.bar_length], [b[1], b[1]], color="black", lw=3, solid_capstyle="butt", zorder=4)
        ax.text(b[0] + 0.5 * L.bar_length, b[1] - 0.03 * L.extent, length_label(L.bar_length), ha="center", va="top", fontsize=9)
        t = L.triad_origin
        for vec, name in ((np.array([1.0, 0.0]), "x"), (np.array([0.0, 1.0]), "y")):
            ax.annotate("", xy=(t[0] + L.triad_length * vec[0], t[1] + L.triad_length * vec[1]), xytext=(t[0], t[1]),
                        arrowprops=dict(arrowstyle="->", color="dimgray", lw=1))
            ax.text(t[0] + 1.25 * L.triad_length * vec[0], t[1] + 1.25 * L.triad_length * vec[1], name, fontsize=8,
                    color="dimgray", ha="center", va="center")
        if pic.field is not None and np.linalg.norm(pic.field[:2]) > 0:
            u = pic.field[:2] / np.linalg.norm(pic.field[:2])
            a = L.arrow_anchor
            tail = a[:2] - 0.5 * L.arrow_length * u
            ax.annotate("", xy=tuple(tail + L.arrow_length * u), xytext=tuple(tail),
                        arrowprops=dict(arrowstyle="-|>", color=_FIELD_COLOUR, lw=2.5, mutation_scale=18), zorder=5)
            ax.text(a[0], a[1] + 0.5 * L.arrow_length * abs(u[1]) + 0.03 * L.extent, f"B {np.linalg.norm(pic.field) * 1e3:.3g} mT",
                    color=_FIELD_COLOUR, ha="center", va="bottom", fontsize=9)
        self._legend(fig, ax)

    def _colliders_2d(self, ax, colliders):
        if not colliders:
            return
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        gx, gy = np.meshgrid(np.linspace(x0, x1, 300), np.linspace(y0, y1, 300))
        for c in colliders:
            z = np.full(gx.size, c["collider"].position_at(c["t"])[2])
            pts = np.stack([gx.ravel() * 1e-3, gy.ravel() * 1e-3, z], axis=1)
            sd = c["collider"].signed_distance(pts, c["t"]).reshape(gx.shape)
            if sd.min() < 0:
                ax.contourf(gx, gy, sd, levels=[sd.min() - 1, 0], colors=[_COLLIDER_COLOUR], alpha=0.3, zorder=1)
                ax.contour(gx, gy, sd, levels=[0], colors=[_COLLIDER_COLOUR], linewidths=1, zorder=1)

    # -- 3D: orthographic scatter
    def _draw_3d(self, fig, pic: FramePicture):
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        L = self.layout
        ax = fig.add_axes([0.0, 0.0, 0.88, 0.88], projection="3d")
        ax.set_proj_type("ortho")
        elev, azim = _VIEW_ANGLES[L.view]
        ax.view_init(elev=elev, azim=azim)
        pts = L.fit_points()
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        c = 0.5 * (lo + hi)
        half = np.maximum(0.5 * (hi - lo), 0.02 * L.extent)
        for setter, ci, hi_ in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), c, half):
            setter(ci - hi_, ci + hi_)
        ax.set_box_aspect(tuple(half), zoom=1.25)
        ax.set_axis_off()
        # marker size: the projected box spans about the axes' smaller side
        bbox = ax.get_window_extent(renderer=fig.canvas.get_renderer())
        proj_span = max(np.ptp(pts @ L.right), np.ptp(pts @ L.up) * bbox.width / max(bbox.height, 1), 1e-9)
        px_per_mm = 0.85 * bbox.width / proj_span
        size_pt = float(np.clip(2 * L.radius * px_per_mm * 72 / self.dpi, 0.6, 40))
        for col in pic.colliders:
            for poly in _collider_polys(col, c, half):
                ax.add_collection3d(Poly3DCollection([poly], facecolor=_COLLIDER_COLOUR, edgecolor="none", alpha=0.22))
        x = pic.x
        ax.scatter(x[:, 0], x[:, 1], x[:, 2], s=size_pt**2, c=self._picture_colours(pic), depthshade=True, linewidths=0)
        if pic.arrows is not None:
            p, d = pic.arrows
            q = d * (3 * L.radius + 0.03 * L.extent)
            ax.quiver(p[:, 0], p[:, 1], p[:, 2], q[:, 0], q[:, 1], q[:, 2], color="black", linewidth=0.6, arrow_length_ratio=0.3)
        b, e = L.bar_start, L.bar_start + L.bar_length * L.bar_axis
        ax.plot(*zip(b, e), color="black", lw=3)
        mid = 0.5 * (b + e) - 0.05 * L.extent * L.up
        ax.text(*mid, length_label(L.bar_length), ha="center", va="top", fontsize=9)
        t = L.triad_origin
        for i, name in enumerate("xyz"):
            v = np.eye(3)[i] * L.triad_length
            ax.plot(*zip(t, t + v), color="dimgray", lw=1)
            ax.text(*(t + 1.3 * v), name, fontsize=8, color="dimgray", ha="center", va="center")
        if pic.field is not None and np.linalg.norm(pic.field) > 0:
            u = pic.field / np.linalg.norm(pic.field) * L.arrow_length
            a = L.arrow_anchor - 0.5 * u
            ax.quiver(a[0], a[1], a[2], u[0], u[1], u[2], color=_FIELD_COLOUR, linewidth=2.5, arrow_length_ratio=0.25)
            ax.text(*(L.arrow_anchor + 0.6 * L.arrow_length * L.up), f"B {np.linalg.norm(pic.field) * 1e3:.3g} mT",
                    color=_FIELD_COLOUR, ha="center", fontsize=9)
        self._legend(fig, ax)

    def close(self):
        pass


def _collider_polys(col: dict, view_centre: np.ndarray, view_half: np.ndarray) -> list[np.ndarray]:
    """Faces (mm) of a collider for matplotlib, cut to the box shown where it reaches beyond it."""
    kind, c, R, size = col["kind"], col["centre"] * 1e3, col["R"], col["size"]
    lo_v, hi_v = view_centre - 1.2 * view_half, view_centre + 1.2 * view_half
    if kind == "half_space":
        n = size / np.linalg.norm(size)
        p0 = view_centre - ((view_centre - c) @ n) * n
        u = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        s = 1.2 * float(np.linalg.norm(view_half))
        return [np.array([p0 + s * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])]
    if kind == "box":
        h = size * 1e3
        lo, hi = np.maximum(c - h, lo_v), np.minimum(c + h, hi_v)  # boxes are axis-aligned in scenes
        if np.any(hi <= lo):
            return []
        cs = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
        return [cs[f] for f in faces]
    if kind == "sphere":
        r = size[0] * 1e3
        th, ph = np.linspace(0, np.pi, 13), np.linspace(0, 2 * np.pi, 25)

        def P(a, b):
            return c + r * np.array([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a)])

        return [np.array([P(th[i], ph[j]), P(th[i + 1], ph[j]), P(th[i + 1], ph[j + 1]), P(th[i], ph[j + 1])])
                for i in range(12) for j in range(24)]
    if kind == "cylinder":
        r, hl = size[0] * 1e3, size[1] * 1e3
        ph = np.linspace(0, 2 * np.pi, 33)

        def ring(z):
            return np.array([c + R @ np.array([r * np.cos(a), r * np.sin(a), z]) for a in ph])

        top, bot = ring(hl), ring(-hl)
        sides = [np.array([bot[j], bot[j + 1], top[j + 1], top[j]]) for j in range(32)]
        return sides + [top[:-1], bot[:-1]]
    return []


class PyVistaBackend:
    name = "pyvista"

    def __init__(self, layout: Layout, scale: ColourScale, size: tuple[int, int], title: str):
        if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
            # no display: VTK would try X first, print a warning, then fall back; go to the fallback directly
            _quiet_vtk()
        import pyvista as pv

        self.pv = pv
        self.layout, self.scale, self.size, self.title = layout, scale, size, title
        self.plotter = pv.Plotter(off_screen=True, window_size=list(size))

    def describe(self) -> str:
        import vtkmodules

        return f"pyvista {self.pv.__version__} (VTK {getattr(vtkmodules, '__version__', '?')}, off-screen)"

    def _camera(self):
        L, p = self.layout, self.plotter
        pts = L.fit_points()
        c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        w, h = self.size
        span_r = np.ptp(pts @ L.right)
        span_u = np.ptp(pts @ L.up)
        p.enable_parallel_projection()
        cam = p.camera
        # room around the picture for the texts (top) and the colour bar (right): the drawing takes the middle
        # 72 % of the height and 74 % of the width, centred at 43 % of the width
        cam.parallel_scale = 0.5 * max(span_u / 0.72, span_r / 0.74 * h / w)
        c = c + L.right * 0.07 * (2 * cam.parallel_scale * w / h)
        cam.focal_point = tuple(c)
        cam.position = tuple(c + L.towards_camera * 10 * L.extent)
        cam.up = tuple(L.up)
        cam.clipping_range = (0.01 * L.extent, 40 * L.extent)
        return 0.5 * h / cam.parallel_scale  # pixels per mm

    def draw(self, pic: FramePicture, notes: list[str]) -> np.ndarray:
        pv, p, L, s = self.pv, self.plotter, self.layout, self.scale
        p.suppress_rendering = True  # after the first screenshot every add_* would render the whole scene again
        p.clear()  # removes the lights too: put the default light kit back, or the spheres come out flat
        p.enable_lightkit()
        p.set_background("white")
        px_per_mm = self._camera()
        free = np.ones(len(pic.x), bool) if pic.held is None else ~pic.held
        cloud = pv.PolyData(np.ascontiguousarray(pic.x[free], dtype=np.float64))
        point_px = float(np.clip(2 * L.radius * px_per_mm, 2.0, 60.0))
        common = dict(render_points_as_spheres=True, point_size=point_px, reset_camera=False)
        if not free.all():
            p.add_mesh(pv.PolyData(np.ascontiguousarray(pic.x[~free], dtype=np.float64)), color=_HELD_COLOUR, **common)
        values = np.asarray(pic.values)[free]
        if s.categorical:
            from matplotlib.colors import to_rgb

            rgb = np.array([to_rgb(_BODY_COLOURS[int(v) % 10]) for v in values]) if len(values) else np.zeros((0, 3))
            cloud["rgb"] = (rgb * 255).astype(np.uint8)
            p.add_mesh(cloud, scalars="rgb", rgb=True, **common)
            p.add_legend(labels=[[n, _BODY_COLOURS[i % 10]] for i, n in enumerate(s.names)], bcolor="white",
                         loc="lower right", size=(0.14, min(0.035 * len(s.names) + 0.01, 0.5)))
        else:
            cloud["value"] = np.asarray(values, dtype=np.float64)
            p.add_mesh(cloud, scalars="value", cmap=s.cmap, clim=(s.vmin, s.vmax), nan_color="lightgrey",
                       scalar_bar_args=dict(title=s.short or s.label, vertical=True, position_x=0.88, position_y=0.2, height=0.6,
                                            width=0.05, color="black", title_font_size=self._fs(12),
                                            label_font_size=self._fs(11), fmt="%.3g"),
                       **common)
        for col in pic.colliders:
            mesh = self._collider_mesh(col)
            if mesh is not None:
                p.add_mesh(mesh, color=_COLLIDER_COLOUR, opacity=0.25, reset_camera=False, smooth_shading=True)
        if pic.arrows is not None:
            pos, d = pic.arrows
            g = pv.PolyData(np.ascontiguousarray(pos, dtype=np.float64))
            g["d"] = d
            glyphs = g.glyph(orient="d", scale=False, factor=4 * L.radius + 0.05 * L.extent, geom=pv.Arrow())
            p.add_mesh(glyphs, color="black", reset_camera=False)
        # the scale bar, triad and field arrow are moved towards the camera, in front of the body, so that it
        # never hides them; an orthographic view draws them at the same place on the picture
        depth = max(float(np.max(L.fit_points()[:8] @ L.towards_camera)), 0.0)

        def front(q, reach=0.0):
            return q + L.towards_camera * (depth - q @ L.towards_camera + reach + 0.05 * L.extent)

        b = front(L.bar_start, L.bar_length * abs(L.bar_axis @ L.towards_camera))
        e = b + L.bar_length * L.bar_axis
        p.add_mesh(pv.Line(b, e), color="black", line_width=4, reset_camera=False)
        self._label(0.5 * (b + e) - 0.06 * L.extent * L.up, length_label(L.bar_length), "black")
        t = front(L.triad_origin, L.triad_length)
        for i, name in enumerate("xyz"):
            v = np.eye(3)[i] * L.triad_length
            p.add_mesh(pv.Line(t, t + v), color="dimgray", line_width=2, reset_camera=False)
            self._label(t + 1.35 * v, name, "dimgray", size=12)
        if pic.field is not None and np.linalg.norm(pic.field) > 0:
            u = pic.field / np.linalg.norm(pic.field)
            anchor = front(L.arrow_anchor, L.arrow_length)
            start = anchor - 0.5 * L.arrow_length * u
            p.add_mesh(pv.Arrow(start=start, direction=u, scale=L.arrow_length, tip_length=0.25, tip_radius=0.08, shaft_radius=0.03),
                       color=_FIELD_COLOUR, reset_camera=False)
            self._label(anchor + 0.65 * L.arrow_length * L.up, f"B {np.linalg.norm(pic.field) * 1e3:.3g} mT", _FIELD_COLOUR)
        h, f = self.size[1], self.size[1] / 720
        p.add_text(self.title, position=(10, h - 28 * f), font_size=self._fs(11), color="black")
        p.add_text(pic.label, position=(10, h - 52 * f), font_size=self._fs(10), color="black")
        p.add_text(field_label(pic.field, L.dim), position=(10, h - 74 * f), font_size=self._fs(9), color=_FIELD_COLOUR)
        for i, n in enumerate(notes[:4]):
            p.add_text(n, position=(10, 6 + 18 * f * i), font_size=self._fs(8), color="dimgray")
        # the camera sits 10 extents away; keep everything between it and 30 extents behind the body visible
        # (adding actors may have re-fitted the clipping range to the particles alone)
        p.camera.clipping_range = (0.5 * L.extent, 40 * L.extent)
        p.suppress_rendering = False
        p.render()  # screenshot() renders by itself only the first time
        return np.asarray(p.screenshot(return_img=True))[..., :3].copy()

    def _fs(self, points: float) -> int:
        """A font size for this picture: ``points`` at 720 pixels high, scaled with the height."""
        return max(int(round(points * self.size[1] / 720)), 5)

    def _label(self, point, text, colour, size=14):
        self.plotter.add_point_labels(np.asarray([point], dtype=np.float64), [text], font_size=self._fs(size), text_color=colour,
                                      shape=None, show_points=False, always_visible=True, bold=False,
                                      justification_horizontal="center", reset_camera=False)

    def _collider_mesh(self, col: dict):
        pv, L = self.pv, self.layout
        kind, c, R, size = col["kind"], col["centre"] * 1e3, col["R"], col["size"]
        if kind == "half_space":
            n = size / np.linalg.norm(size)
            p0 = L.centre - ((L.centre - c) @ n) * n
            s = 2.5 * float(np.linalg.norm(L.half)) + L.extent
            return pv.Plane(center=p0, direction=n, i_size=s, j_size=s)
        if kind == "box":
            h = size * 1e3
            lo_v, hi_v = L.centre - 3 * L.half - L.extent, L.centre + 3 * L.half + L.extent
            lo, hi = np.maximum(c - h, lo_v), np.minimum(c + h, hi_v)
            if np.any(hi <= lo):
                return None
            return pv.Box(bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        if kind == "sphere":
            return pv.Sphere(radius=size[0] * 1e3, center=c, theta_resolution=48, phi_resolution=48)
        if kind == "cylinder":
            return pv.Cylinder(center=c, direction=R[:, 2], radius=size[0] * 1e3, height=2 * size[1] * 1e3, resolution=64)
        return None

    def close(self):
        try:
            self.plotter.close()
        except Exception:
            pass


def _quiet_vtk():
    """Keep VTK's 'bad X server connection' warning (it then renders off-screen anyway) off the terminal."""
    try:
        from vtkmodules.vtkCommonCore import vtkLogger

        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except Exception:
        pass


def _draw_all(backend_name, layout, scale, size, title, pictures, notes) -> tuple[list[np.ndarray], str]:
    drawer = (PyVistaBackend if backend_name == "pyvista" else MatplotlibBackend)(layout, scale, size, title)
    try:
        images = [drawer.draw(pic, notes) for pic in pictures]
        return images, drawer.describe()
    finally:
        drawer.close()


# -------------------------------------------------------------------------------------------------- writing
def write_images(out: Path, images: list[np.ndarray], fps: float) -> None:
    """PNG (one image), GIF (Pillow) or MP4 (ffmpeg, H.264) from RGB arrays; written whole or not at all."""
    from PIL import Image

    from magsoro.io.files import atomic_write_bytes

    suffix = out.suffix.lower()
    if suffix in (".png", ".gif"):
        buf = io.BytesIO()
        frames = [Image.fromarray(np.ascontiguousarray(im, dtype=np.uint8)) for im in images]
        if suffix == ".png":
            frames[0].save(buf, format="PNG", optimize=False)
        else:
            # one palette per frame; disposal 1 keeps nothing stale when a frame is transparent-free anyway
            pal = [f.convert("P", palette=Image.Palette.ADAPTIVE, colors=255) for f in frames]
            pal[0].save(buf, format="GIF", save_all=True, append_images=pal[1:], duration=max(int(round(1000 / fps)), 20),
                        loop=0, disposal=1, optimize=False)
        atomic_write_bytes(out, buf.getvalue())
        return
    exe = find_ffmpeg()
    if exe is None:
        raise RenderError(f"--out: writing .mp4 needs ffmpeg, which was not found: {FFMPEG_HINT}")
    h, w = images[0].shape[:2]
    h2, w2 = h - h % 2, w - w % 2  # H.264 in yuv420p wants even sizes
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp.mp4")
    cmd = [exe, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w2}x{h2}", "-r", f"{fps:g}",
           "-i", "-", "-an", "-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags", "+faststart", str(tmp)]
    data = b"".join(np.ascontiguousarray(im[:h2, :w2], dtype=np.uint8).tobytes() for im in images)
    try:
        proc = subprocess.run(cmd, input=data, capture_output=True, timeout=600)
        if proc.returncode != 0:
            reason = (proc.stderr.decode(errors="replace").strip().splitlines() or ["?"])[-1]
            raise RenderError(f"--out: ffmpeg could not write {out}: {reason}")
        os.replace(tmp, out)
    except OSError as exc:
        raise output_error(out, exc) from None
    finally:
        tmp.unlink(missing_ok=True)


# ----------------------------------------------------------------------------------------------- the entry
def render_run(run_dir, out, color: str = "part", view: str | None = None, frames: str | None = None,
               backend: str = "auto", size: tuple[int, int] = (960, 720), fps: float = 10.0,
               max_particles: int | None = None) -> RenderResult:
    """Draw the frames of the run in ``run_dir`` into ``out`` (.png, .gif or .mp4) and return what was done.

    ``color``: part, speed, strain or magnetisation (see the module docstring for what each shows and needs).
    ``view``: iso, x, y or z (the axis the camera looks along; 3D runs); 2D runs have the flat view only.
    ``frames``: see :func:`select_frames`. ``backend``: auto (PyVista when importable, else matplotlib; the
    environment variable MAGSORO_RENDER_BACKEND sets what auto means), pyvista or matplotlib.
    ``size``: (width, height) in pixels. ``fps``: frames per second of an animation.
    ``max_particles``: draw at most this many (an evenly spaced subset) to keep big runs quick.
    Raises RenderError (one line naming the argument) on bad input.
    """
    from magsoro.io.vtk import read_vtp

    t0 = time.perf_counter()
    color = normalise_color(color)
    out = Path(out)
    suffix = check_output(out)
    w, h = (int(size[0]), int(size[1]))
    if not (64 <= w <= 8192 and 64 <= h <= 8192):
        raise RenderError(f"--size: {w}x{h} pixels; each side must be 64 to 8192")
    if not (fps > 0 and math.isfinite(fps)):
        raise RenderError(f"--fps: {fps}; must be > 0")
    if max_particles is not None and max_particles < 1:
        raise RenderError(f"--max-particles: {max_particles}; must be >= 1")
    view = None if view is None else str(view).lower()
    if view is not None and view not in VIEWS:
        raise RenderError(f"--view: '{view}' is not a view; allowed: {', '.join(VIEWS)}")
    series = open_run(run_dir)
    axisymmetric = series.dim == 2 and is_axisymmetric(series.info)
    if series.dim == 2 and view not in (None, "z") and not axisymmetric:
        raise RenderError(f"--view: a 2D run has only the flat view 'z' (x right, y up); got '{view}'")
    view = view or ("iso" if series.dim == 3 else "z")
    # an axisymmetric run: its (r, z) section (the flat view), or the body of revolution (a 3D view)
    revolve = axisymmetric and view != "z"
    draw_dim = 3 if revolve else series.dim
    chosen, note = select_frames(frames, series.stamps, animated=suffix != ".png")
    if suffix == ".png" and len(chosen) != 1:
        raise RenderError(f"--frames: a .png holds one frame, {len(chosen)} were selected; write a .gif or .mp4 for several")
    if suffix != ".png" and len(chosen) < 2:
        note = (note + "; " if note else "") + "an animation of one frame"
    backend_name, backend_note = choose_backend(backend, draw_dim)
    notes = [n for n in (backend_note, note) if n]
    if axisymmetric:
        notes.append("axisymmetric run: " + ("the body revolved about its axis (y), three quarters shown" if revolve
                                             else "its (r, z) section, x the radius and y the axis"))
    status = str(series.info.get("status", "?"))
    if status != "completed":
        notes.append(f"the run's status is '{status}': {len(series.stamps)} frames written so far")

    overlays = Overlays(series)
    notes += overlays.notes
    ref = None
    if color == "magnetisation":
        _, d0 = read_vtp(series.files[0])
        if COLOR_MODES[color] in d0:
            ref = np.asarray(d0[COLOR_MODES[color]], dtype=np.float64).reshape(-1, 3)
    keep = None
    positions, values, dirs, held = [], [], [], []
    for k in chosen:
        pts, data = read_vtp(series.files[k])
        if keep is None:
            n_all = len(pts)
            keep = np.arange(n_all)
            if max_particles is not None and n_all > max_particles:
                keep = np.unique(np.linspace(0, n_all - 1, max_particles).astype(int))
                notes.append(f"{len(keep)} of {n_all} particles drawn (--max-particles)")
        elif len(pts) != n_all:
            raise RenderError(f"RUN_DIR: {series.files[k]} has {len(pts)} particles, the first drawn frame {n_all}")
        where = f"{series.files[k].name}"
        v = colour_values(color, data, series.dim, None if ref is None or len(ref) != n_all else ref, where)
        x = np.asarray(pts, dtype=np.float64)[keep] * 1e3
        finite = np.isfinite(x).all(axis=1)  # a failed run's last frame may hold non-finite particles
        x, vk = x[finite], v[keep][finite]
        hk = np.asarray(data["clamped"]).ravel()[keep][finite] != 0 if "clamped" in data else None
        dk = (np.asarray(data[COLOR_MODES[color]], dtype=np.float64).reshape(-1, 3)[keep][finite]
              if color == "magnetisation" else None)
        if series.dim == 2:
            x[:, 2] = 0.0
        if revolve:
            ring, x, dk = revolve_rings(x, dk, particle_spacing(x))
            vk = vk[ring]
            hk = None if hk is None else hk[ring]
        positions.append(x)
        values.append(vk)
        held.append(hk)
        if dk is not None:
            dirs.append(dk)
    layout = make_layout(draw_dim, view, positions)
    scale = colour_scale(color, values, series.dim, series.body_names)
    title = f"{series.name}: {scale.label}" if not scale.categorical else f"{series.name}: parts"
    pictures = [FramePicture(positions[i], values[i], _arrows(positions[i], dirs[i]) if dirs else None,
                             [] if revolve else overlays.collider_shapes(series.stamps[k]), overlays.field(series.stamps[k]),
                             time_label(series, series.stamps[k], k), held[i]) for i, k in enumerate(chosen)]
    if any(h is not None and h.any() for h in held):
        notes.append("dark grey: particles held by a clamp")
    try:
        images, described = _draw_all(backend_name, layout, scale, (w, h), title, pictures, notes)
    except Exception as exc:
        if backend_name != "pyvista" or str(backend).lower() == "pyvista":
            raise
        # PyVista imported but could not draw (no OpenGL context, say): auto falls back
        notes.append(f"PyVista failed ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
                     f"drawn with matplotlib instead")
        images, described = _draw_all("matplotlib", layout, scale, (w, h), title, pictures, notes)
    write_images(out, images, fps)
    return RenderResult(out, described, len(images), len(keep), time.perf_counter() - t0, notes)
