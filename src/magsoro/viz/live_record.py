"""Files ``magsoro live`` writes, only into the folder given with ``--out``: scenes saved from the page and
recordings of the run.

Names never come from the page as paths. A saved scene is ``NAME.toml`` with NAME of letters, digits, '_' and '-'
(at most 64), a recording the next free ``record_NNN`` folder; neither replaces anything that exists (a taken
scene name gets ``_2``, ``_3``, ...). A recording is a run folder as ``magsoro run`` writes it, through the same
:class:`~magsoro.io.recorder.RunWriter` (run.json, metrics.csv, frames/*.vtp, particles.pvd, final.npz), so
``magsoro render`` and ``magsoro report`` read it; its run.json says it came from the live view ('live').
"""

from __future__ import annotations

import math
import os
import re
import time
from pathlib import Path

from magsoro.errors import MagsoroError, OutputError, output_error

NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")
MAX_NUMBER = 999  # record_001 .. record_999; NAME.toml .. NAME_999.toml
MAX_RECORD_FRAMES = 2000  # frames of one recording; it stops there, saying so
MAX_RECORD_BYTES = 2 * 1024**3  # about the most one recording writes: fewer frames for a large model
FRAME_BYTES_PER_PARTICLE = 80  # a .vtp frame's size per particle (positions, velocity, body, J, I1bar, m; XML)
MAX_CHANGES = 1000  # control changes kept in a recording's run.json


class SaveError(MagsoroError):
    """A save or a recording that cannot be made; the message is shown on the page."""


def out_folder(path) -> Path:
    """The ``--out`` folder, made when missing; MagsoroError when it is a file or cannot be made."""
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise MagsoroError(f"--out: {d} is a file; give a folder for saved scenes and recordings")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise MagsoroError(f"--out: cannot make {d}: {exc.strerror or exc}") from None
    return d.resolve()


def check_name(name) -> str:
    if not isinstance(name, str) or not NAME_RE.fullmatch(name):
        raise SaveError(f"a scene name must be 1 to 64 letters, digits, '_' or '-' (starting with a letter or digit), "
                        f"got {str(name)[:80]!r}")
    return name


def claim_file(folder: Path, name: str, suffix: str) -> Path:
    """Create ``folder/NAME.suffix`` (or NAME_2, NAME_3, ...), empty and new (never a file or link that exists)."""
    for k in range(1, MAX_NUMBER + 1):
        path = folder / (f"{name}{suffix}" if k == 1 else f"{name}_{k}{suffix}")
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            continue
        except OSError as exc:
            raise SaveError(str(output_error(path, exc))) from None
        os.close(fd)
        return path
    raise SaveError(f"{folder}: {name}{suffix} and {MAX_NUMBER - 1} numbered variants exist; choose another name")


def claim_folder(folder: Path, stem: str = "record") -> Path:
    """Make the next free ``folder/STEM_NNN`` (never one that exists)."""
    for k in range(1, MAX_NUMBER + 1):
        path = folder / f"{stem}_{k:03d}"
        try:
            path.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise SaveError(str(output_error(path, exc))) from None
        return path
    raise SaveError(f"{folder}: {stem}_001 .. {stem}_{MAX_NUMBER} all exist; move some away")


def save_scene(scene, folder: Path, name: str) -> Path:
    """Write ``scene`` as ``folder/NAME.toml`` (a new file; :func:`magsoro.scene.write_scene`: it loads back to an
    equal scene); SaveError with the reason when it cannot be written."""
    from magsoro.scene import write_scene

    path = claim_file(folder, check_name(name), ".toml")
    try:
        write_scene(scene, path)
    except (MagsoroError, OSError) as exc:
        path.unlink(missing_ok=True)
        raise SaveError(f"the scene could not be saved: {exc}") from None
    return path


def scene_echo(scene) -> dict:
    """The scene as run.json's 'scene' table (what render and report read: colliders, fields, probes)."""
    import tomllib

    try:
        return tomllib.loads(scene.to_toml())
    except MagsoroError:  # a magnetisation set in Python: the rest of the scene still tells what was run
        return scene.model_dump(mode="json", by_alias=True, exclude_none=True)


class Recording:
    """Frames of a live run written into ``folder`` every ``every`` seconds of simulated time from now on, at most
    :data:`MAX_RECORD_FRAMES` (fewer for a large model: about :data:`MAX_RECORD_BYTES` in all); it then stops,
    saying so."""

    def __init__(self, folder: Path, sim, scene, every: float, controls: dict):
        from magsoro.io.recorder import RunWriter

        self.folder = folder
        self.every = float(every)
        self.t0 = float(sim.time)
        self.steps0 = int(sim.steps)
        self.wall0 = time.perf_counter()
        self.count = 0
        n = max(1, int(sim.model.n_particles))
        self.max_frames = max(2, min(MAX_RECORD_FRAMES, MAX_RECORD_BYTES // (FRAME_BYTES_PER_PARTICLE * n)))
        self.changes: list[dict] = []
        self.stopped_because: str | None = None
        try:
            self.writer = RunWriter(folder, sim, scene_echo(scene))
        except OutputError as exc:
            raise SaveError(str(exc)) from None
        self.writer.info["live"] = {
            "from": self.t0, "every": self.every, "controls": controls, "changes": self.changes,
            "note": "recorded from magsoro live: run.json's scene is the scene with the page's settings when the "
                    "recording started; 'changes' lists the settings changed while it recorded (time, controls)",
        }
        self.record(sim)

    @property
    def next_time(self) -> float:
        return self.t0 + self.count * self.every

    def due(self, t: float) -> bool:
        return t >= self.next_time - 1e-9 * max(self.every, abs(t))

    def record(self, sim) -> None:
        """Write a frame and a metrics row of the current state (stamped with its time)."""
        if self.count >= self.max_frames:
            self.stopped_because = f"the recording reached its limit of {self.max_frames} frames"
            return
        self.writer.record(sim)
        self.count += 1

    def changed(self, t: float, controls: dict) -> None:
        if len(self.changes) < MAX_CHANGES:
            self.changes.append({"time": t, "controls": controls})

    def finish(self, sim, message: str) -> None:
        """Close the folder: final.npz and run.json 'completed' (the run went on; the recording ended here)."""
        from magsoro.simulation import RunResult

        wall = time.perf_counter() - self.wall0
        result = RunResult("completed", int(sim.steps), float(sim.time), wall, message)
        self.writer.info["live"]["to"] = float(sim.time)
        self.writer.info["live"]["steps"] = int(sim.steps) - self.steps0
        self.writer.finish(result, wall)

    def as_json(self) -> dict:
        return {"folder": self.folder.name, "frames": self.count, "max_frames": self.max_frames, "from": self.t0,
                "every": self.every, "next": self.next_time if math.isfinite(self.next_time) else None}
