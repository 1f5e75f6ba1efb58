"""What every robot of the library shares: its registry entry, how its scene is loaded (full or ``--preview``),
the curve it reports (CSV + PNG with the paper's values) and an animation of its motion (GIF).

A robot module (``magsoro/robots/<name>.py``) defines ``ROBOT = Robot(...)`` whose ``reproduce(ctx)`` runs the
scene (usually a sweep of field strengths), writes its files into ``ctx.out`` and returns a
:class:`ReproduceResult`. The scene itself is ``scenes/<name>.toml`` in the repository, so
``magsoro run scenes/<name>.toml`` shows the same robot.
"""

from __future__ import annotations

import csv
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from magsoro.bundled import data_folder
from magsoro.errors import MagsoroError


class RobotError(MagsoroError):
    """A robot cannot be reproduced (unknown name, scene folder missing, a run that failed)."""


def stderr_log(msg: str) -> None:
    """The default progress logger: one line on stderr."""
    print(msg, file=sys.stderr, flush=True)


@dataclass
class Context:
    """What ``reproduce`` gets: the output folder (created), ``preview`` (coarse and short: the scene's
    [preview] table), the device, a progress logger (stderr) and ``workers``: how many processes
    :func:`run_jobs` may run a reproduction's independent simulations in (1: one after the other, in this
    process)."""

    out: Path
    preview: bool = False
    device: str | None = None
    log: Callable[[str], None] = field(default=stderr_log)
    workers: int = 1


@dataclass
class ReproduceResult:
    """Files written and what they show. ``summary``: one sentence comparing with the paper (the README /
    gallery line); ``rows``: acceptance checks as validation rows (``magsoro validate --all``); ``info``: run
    facts (particles, steps, wall time, resolution); ``figures``: further results of the same run, each a CSV and a
    PNG with a caption (shown under the main curve in the gallery)."""

    name: str
    csv: Path
    png: Path
    animation: Path | None = None
    summary: str = ""
    rows: list = field(default_factory=list)
    info: dict = field(default_factory=dict)
    figures: list = field(default_factory=list)  # further results: {"csv": Path, "png": Path, "caption": str}

    @property
    def passed(self) -> bool:
        """True when every acceptance check in ``rows`` passed."""
        return all(r.passed for r in self.rows)


@dataclass
class Robot:
    """A registry entry: ``name`` (scene file ``scenes/<name>.toml``), ``title``, ``source`` (seed and
    section), ``quantity`` (what the paper plots), ``sentence`` (the gallery sentence) and ``reproduce``."""

    name: str
    title: str
    source: str
    quantity: str
    sentence: str
    reproduce: Callable[[Context], ReproduceResult]
    in_ci: bool = False  # its preview is run by the default (not slow) test suite

    @property
    def scene_path(self) -> Path:
        """The robot's scene file, ``scenes/<name>.toml`` in the repository or the installed copy."""
        return scenes_dir() / f"{self.name}.toml"


def scenes_dir() -> Path:
    """The scenes/ folder (``MAGSORO_SCENES`` overrides): the copy installed with the package, or the checkout's
    (:mod:`magsoro.bundled`). The robot scenes, their meshes and data and their reproduce scripts live there."""
    env = os.environ.get("MAGSORO_SCENES")
    if env:
        path = Path(env)
    else:
        try:
            path = data_folder("scenes")
        except FileNotFoundError as exc:
            raise RobotError(f"{exc}; or set MAGSORO_SCENES to a scenes/ folder") from None
    if not path.is_dir():
        raise RobotError(f"scenes folder '{path}' not found (MAGSORO_SCENES): set it to a scenes/ folder, or unset "
                         "it to use the one installed with magsoro")
    return path


# -- scenes -----------------------------------------------------------------------------------------------
#: the scene-notes lists (Simulation.scene_notes) of the simulations made by :func:`simulation` since the last
#: :func:`scene_notes` call
_run_notes: list = []


def scene_notes() -> list[str]:
    """The scene notes (a body in the domain walls' reach, a body the particle lattice rounds; Simulation.scene_notes)
    of the simulations :func:`simulation` made since the last call, without repeats; the record is then cleared."""
    out = []
    for notes in _run_notes:
        out += [n for n in notes if n not in out]
    _run_notes.clear()
    return out


def scene_data(name: str) -> dict:
    """The raw TOML dict of ``scenes/<name>.toml`` (edit it, then :func:`simulation`)."""
    from magsoro.scene.load import read_scene_toml

    return read_scene_toml(scenes_dir() / f"{name}.toml")


def scene(name: str, data: dict | None = None, preview: bool = False):
    """Validated :class:`~magsoro.scene.Scene` of robot ``name`` from ``data`` (default: its file), with the
    [preview] settings applied when ``preview``. Relative file names resolve against scenes/."""
    from magsoro.scene.load import apply_preview, parse_scene

    path = scenes_dir() / f"{name}.toml"
    data = scene_data(name) if data is None else data
    if preview:
        data = apply_preview(data, str(path))
    sc = parse_scene(data, str(path), path.parent)
    sc.source_path = path
    return sc


def simulation(name: str, data: dict | None = None, preview: bool = False, device: str | None = None):
    """A ready :class:`~magsoro.simulation.Simulation` of robot ``name`` (see :func:`scene`)."""
    from magsoro.simulation import Simulation

    sim = Simulation(scene(name, data, preview), device=device, source=str(scenes_dir() / f"{name}.toml"))
    _run_notes.append(sim.scene_notes)  # reproduce() reports the scene notes of every run it made
    return sim


# -- independent simulations in parallel ----------------------------------------------------------------------
@dataclass
class Job:
    """One of a reproduction's independent simulations, for :func:`run_jobs`: ``fn(ctx, *args, **kwargs)``.
    ``fn`` is a module-level function and ``args``, ``kwargs`` and its return value can be pickled (a worker
    process runs it); ``label`` prefixes its progress lines there."""

    fn: Callable
    ctx: Context
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    label: str = ""


class _Prefixed:
    """A worker's progress logger: stderr lines that start with its job's label."""

    def __init__(self, label: str):
        self.label = label

    def __call__(self, msg: str) -> None:
        stderr_log(f"[{self.label}] {msg}" if self.label else msg)


def _run_job(job: Job, quiet: bool = False):
    """In a worker process: run ``job`` (``quiet``: Warp's banner and load lines off, as in the parent); returns
    (ok, value or exception, scene notes, traceback text)."""
    import pickle
    import traceback

    if quiet:
        from magsoro.console import configure_warp

        configure_warp()
    scene_notes()
    try:
        value = job.fn(job.ctx, *job.args, **job.kwargs)
        return True, value, scene_notes(), ""
    except Exception as exc:  # noqa: BLE001 - handed to the parent, which raises it
        text = traceback.format_exc()
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:  # noqa: BLE001 - an exception that cannot travel: the parent gets its text
            exc = None
        return False, exc, scene_notes(), text


#: how often (s) run_jobs looks for finished jobs
JOB_POLL_S = 0.2


#: run_jobs(balanced=True) runs up to this many processes per worker at once
BALANCED_PER_WORKER = 2


def run_jobs(ctx: Context, jobs: list[Job], balanced: bool = False) -> list:
    """The results of ``jobs``, in their order. With ``ctx.workers`` > 1 and more than one job they run at once in
    that many worker processes (spawned, each job in a fresh one, numerical libraries single-threaded and the
    engine's CPU threads shared out), in the order given (give the longest first); otherwise one after the other
    here. ``balanced``: the jobs take about as long as each other, so up to BALANCED_PER_WORKER times as many
    processes run at once and the cores share them out evenly (three equal jobs on two workers: about 1.5 times
    one job's time instead of twice). The workers' scene notes join this process's (:func:`scene_notes`). The
    first job that fails stops the others and its exception is raised here, with the worker's traceback as a
    note."""
    workers = max(1, int(ctx.workers))
    workers = min(workers * (BALANCED_PER_WORKER if balanced and workers > 1 else 1), len(jobs))
    if workers <= 1:
        return [j.fn(j.ctx, *j.args, **j.kwargs) for j in jobs]
    import multiprocessing

    from magsoro.mpm.runtime import usable_cores
    from magsoro.sweep.worker import SINGLE_THREAD_ENV

    jobs = [Job(j.fn, _portable(j.ctx, j.label), j.args, j.kwargs, j.label) for j in jobs]
    quiet = "warp" in sys.modules and bool(sys.modules["warp"].config.quiet)  # the workers' Warp as this one's
    env = {**SINGLE_THREAD_ENV, "MAGSORO_THREADS": str(max(1, usable_cores() // workers))}
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)  # the workers inherit it (a replacement worker too: kept until the pool is gone)
    try:
        with multiprocessing.get_context("spawn").Pool(workers, maxtasksperchild=1) as pool:
            pending = {i: pool.apply_async(_run_job, (j, quiet)) for i, j in enumerate(jobs)}
            results: dict = {}
            while pending:
                for i in [i for i, p in pending.items() if p.ready()]:
                    ok, value, notes, text = pending.pop(i).get()
                    _run_notes.append(notes)
                    if not ok:
                        name = jobs[i].label or jobs[i].fn.__name__
                        if value is None:
                            raise RobotError(f"{name}: failed in a worker process:\n{text}")
                        value.add_note(f"(in the worker process of '{name}')\n{text}")
                        raise value
                    results[i] = value
                if pending:
                    time.sleep(JOB_POLL_S)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return [results[i] for i in range(len(jobs))]


def _portable(ctx: Context, label: str) -> Context:
    """``ctx`` for a worker process: its logger replaced by one that prefixes ``label`` (any logger given here
    stays here) and one worker (a job does not start workers of its own)."""
    from dataclasses import replace

    return replace(ctx, log=_Prefixed(label), workers=1)


def run(sim, duration: float | None = None, every: float | None = None, frames: "FrameRecorder | None" = None,
        callback: Callable | None = None):
    """Run ``sim`` for ``duration`` (default: the scene's), recording ``frames`` every ``every`` s when given.
    A failed run raises :class:`RobotError` naming the step and time."""
    record = frames.record if frames is not None else None
    result = sim.run(duration, callback=callback, record=record, record_every=every)
    if result.status != "completed":
        raise RobotError(f"{sim.scene.name or 'scene'}: run {result.status}: {result.message}")
    return result


# -- outputs ----------------------------------------------------------------------------------------------
def write_csv(path: Path, columns: dict[str, list | np.ndarray]) -> Path:
    """Columns to a CSV file, atomically; a column shorter than the longest ends in empty cells (:func:`read_csv`
    reads them as nan): runs sampled at their own steps side by side."""
    from magsoro.io.files import atomic_write_text

    names = list(columns)
    n = max((len(c) for c in columns.values()), default=0)
    lines = [",".join(names)]
    for i in range(n):
        lines.append(",".join(_fmt(columns[k][i]) if i < len(columns[k]) else "" for k in names))
    atomic_write_text(Path(path), "\n".join(lines) + "\n")
    return Path(path)


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    v = float(v)
    return "" if not math.isfinite(v) else f"{v:.6g}"


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """A CSV written by :func:`write_csv` (numeric columns) back as arrays."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], rows[1:]
    return {h: np.array([float(r[j]) if r[j] != "" else np.nan for r in body]) for j, h in enumerate(head)}


def plot_curve(path: Path, x, series: dict[str, np.ndarray], xlabel: str, ylabel: str, title: str,
               paper: dict[str, tuple] | None = None, note: str = "", hlines: dict[str, float] | None = None,
               legend_loc: str = "best", points: dict[str, tuple] | None = None) -> Path:
    """PNG of simulated ``series`` (label -> y over ``x``, lines with markers) and the ``paper``'s values
    (label -> (x, y), open markers; ``hlines``: label -> y, dashed lines, for values the paper gives without an
    x). ``points``: label -> (x, y), further simulated values drawn as large diamonds (a check at a few levels).
    ``note`` goes under the title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.2, 3.8), dpi=120)
    for label, y in series.items():
        ax.plot(x, y, "o-", ms=4, label=f"magsoro: {label}")
    for label, (px, py) in (points or {}).items():
        ax.plot(px, py, "D", ms=8, mfc="none", mew=1.5, label=f"magsoro: {label}")
    for label, (px, py) in (paper or {}).items():
        ax.plot(px, py, "s", mfc="none", ms=7, mew=1.5, label=f"paper: {label}")
    for k, (label, y) in enumerate((hlines or {}).items()):
        ax.axhline(y, ls=("--", ":", "-.")[k % 3], color="0.3", lw=1.2, label=f"paper: {label}")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title + (f"\n{note}" if note else ""), fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc=legend_loc)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return Path(path)


def plot_courses(path: Path, courses: dict[str, tuple], xlabel: str, ylabel: str, title: str, note: str = "",
                 dashed=lambda label: False) -> Path:
    """PNG of simulated curves that each have their own x (label -> (x, y): a run's course against its load),
    lines without markers, ``dashed(label)`` ones dashed. ``note`` goes under the title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.2, 3.8), dpi=120)
    for label, (x, y) in courses.items():
        ax.plot(x, y, "--" if dashed(label) else "-", label=f"magsoro: {label}")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title + (f"\n{note}" if note else ""), fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return Path(path)


def _save(fig, path: Path) -> None:
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp" + path.suffix)
    fig.savefig(tmp)
    os.replace(tmp, path)


class FrameRecorder:
    """Collects particle positions for an animation: pass ``frames.record`` as a run's ``record`` callback
    (or call it yourself). ``axes`` picks the two coordinates drawn (e.g. (0, 2) for x-z); ``label(sim)``
    gives the caption of each frame (default: the time)."""

    def __init__(self, axes=(0, 1), label: Callable | None = None, max_particles: int = 20000):
        self.axes = tuple(axes)
        self.label = label
        self.max_particles = max_particles
        self.frames: list[tuple[np.ndarray, str]] = []
        self.color: np.ndarray | None = None
        self.extras: list[Callable] = []

    def record(self, sim) -> None:
        x = sim.state.x.numpy()
        if self.color is None:
            n = len(x)
            self._pick = np.arange(n) if n <= self.max_particles else np.linspace(0, n - 1, self.max_particles).astype(int)
            self.color = sim.model.host["body"][self._pick]
            order = np.argsort(x[self._pick][:, 3 - sum(self.axes)] if x.shape[1] == 3 else np.zeros(len(self._pick)))
            self._pick = self._pick[order]
            self.color = self.color[order]
        caption = self.label(sim) if self.label else f"t = {sim.time * 1e3:.1f} ms"
        self.frames.append((x[self._pick][:, list(self.axes)].copy(), caption))

    def write_gif(self, path: Path, title: str = "", fps: int = 12, lims=None, patches: Callable | None = None) -> Path:
        """The frames as an animated GIF (matplotlib + Pillow); axes in mm. ``patches(ax, k)`` may draw
        obstacles or magnets on frame ``k``."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.animation import FuncAnimation, PillowWriter

        if not self.frames:
            raise RobotError("no frames recorded")
        allx = np.concatenate([f[0] for f in self.frames]) * 1e3
        if lims is None:
            lo, hi = allx.min(axis=0), allx.max(axis=0)
            pad = 0.08 * (hi - lo).max()
            lims = ((lo[0] - pad, hi[0] + pad), (lo[1] - pad, hi[1] + pad))
        fig, ax = plt.subplots(figsize=(5, 4), dpi=90)
        names = "xyz"
        n = len(self.frames[0][0])
        size = max(0.5, min(6.0, 6000.0 / n))

        def draw(k):
            ax.clear()
            pts, caption = self.frames[k]
            ax.scatter(pts[:, 0] * 1e3, pts[:, 1] * 1e3, s=size, c=self.color, cmap="tab10", vmin=0, vmax=9,
                       linewidths=0)
            if patches is not None:
                patches(ax, k)
            ax.set_xlim(*lims[0])
            ax.set_ylim(*lims[1])
            ax.set_aspect("equal")
            ax.set_xlabel(f"{names[self.axes[0]]} (mm)")
            ax.set_ylabel(f"{names[self.axes[1]]} (mm)")
            ax.set_title(f"{title}\n{caption}", fontsize=9)

        anim = FuncAnimation(fig, draw, frames=len(self.frames))
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.gif")
        anim.save(tmp, writer=PillowWriter(fps=fps))
        os.replace(tmp, path)
        plt.close(fig)
        return path


def timed(fn: Callable, *args, **kwargs):
    """``(fn(*args, **kwargs), wall seconds)``."""
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0
