"""Write a run's results to a directory: run.json, metrics.csv, frames/*.vtp + particles.pvd, final.npz.

final.npz holds the particle arrays and what another run needs to start from it (``magsoro run --from``,
:mod:`magsoro.io.start`).

Every file is replaced atomically; run.json says 'running' until the run ends, then 'completed', 'failed' or
'interrupted', so a reader can always tell a finished result from a partial one. While it runs, run.json carries
the process id and a heartbeat time, so a run killed without a chance to write (SIGKILL) reads as stale
(:func:`magsoro.io.outdir.run_state`). A write that fails (disk full, read-only folder) raises
:class:`~magsoro.errors.OutputError`; the run then ends 'failed' with the reason, in run.json when the disk still
takes that small file.
"""

from __future__ import annotations

import contextlib
import io
import os
import platform
import threading
import time
from pathlib import Path

import numpy as np

from magsoro._version import __version__
from magsoro.errors import OutputError
from magsoro.io.files import atomic_save_npz, atomic_write_json, atomic_write_text
from magsoro.io.outdir import HEARTBEAT_S, RUN_FILES
from magsoro.io.vtk import write_pvd, write_vtp


class RunWriter:
    def __init__(self, out_dir, sim, scene_echo: dict, particles: bool = True):
        import warp as wp

        self.dir = Path(out_dir)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            if particles:
                (self.dir / "frames").mkdir(exist_ok=True)
        except OSError as exc:
            from magsoro.errors import output_error

            raise output_error(self.dir, exc) from None
        self.sim = sim
        self.particles = particles
        self.frames: list[tuple[float, str]] = []
        self.rows: list[list[float]] = []
        self.columns = ["time"] + sim.probe_columns()
        self._last_beat = time.monotonic()
        self._beat_lock = threading.Lock()  # beat() from the stepping thread and from beating()'s thread
        self.info = {
            "status": "running",
            "message": "",
            "magsoro_version": __version__,
            "warp_version": wp.config.version,
            "python": platform.python_version(),
            "machine": platform.node(),
            "pid": os.getpid(),
            "device": sim.model.device,
            "device_name": wp.get_device(sim.model.device).name,
            "precision": sim.model.precision,
            "dim": sim.model.dim,
            "n_particles": sim.model.n_particles,
            "formulation": sim.solver.settings.formulation,
            "integrator": sim.integrator_info() if hasattr(sim, "integrator_info") else {"kind": "explicit"},
            "magnetic_interaction": {"mode": sim.solver.settings.magnetic_interaction,
                                     "every": sim.solver.settings.interaction_every, "refreshes": 0},
            "bodies": sim.built.fill_report,
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "heartbeat": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "heartbeat_unix": time.time(),
            "scene": scene_echo,
            # what this run writes here, and so all that --overwrite may remove (magsoro.io.outdir.RUN_FILES)
            "files": list(RUN_FILES),
        }
        if getattr(sim, "started_from", None) is not None:  # --from / [initial] from: the state this run continues
            self.info["initial"] = dict(sim.started_from)
        # remove leftovers of an earlier run in the same folder, so no stale file looks like ours
        for stale in ("final.npz", "last_good.npz", "metrics.csv", "particles.pvd"):
            (self.dir / stale).unlink(missing_ok=True)
        if particles:
            for f in (self.dir / "frames").glob("frame_*.vtp"):
                f.unlink()
        atomic_write_json(self.dir / "run.json", self.info)

    def beat(self, sim=None, force: bool = False) -> None:
        """Rewrite run.json with the current heartbeat time (and simulated time and step), at most every
        HEARTBEAT_S wall seconds unless ``force``; cheap enough to be called after every step."""
        now = time.monotonic()
        if not force and now - self._last_beat < HEARTBEAT_S:
            return
        with self._beat_lock:
            self._last_beat = now
            self.info["heartbeat"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
            self.info["heartbeat_unix"] = time.time()
            if sim is not None:
                self.info["progress"] = {"time": sim.time, "steps": sim.steps}
            atomic_write_json(self.dir / "run.json", self.info)

    @contextlib.contextmanager
    def beating(self):
        """Beat every HEARTBEAT_S from a helper thread while the block runs: for a static solve, whose Newton
        iterations at one level can take many minutes without a record, so that run.json keeps telling a run
        that is working from one whose process is gone (:func:`magsoro.io.outdir.run_state`)."""
        stop = threading.Event()

        def keep_beating():
            while not stop.wait(HEARTBEAT_S):
                try:
                    self.beat(force=True)
                except OutputError:  # a full disk: the main thread meets it at its next write
                    pass

        thread = threading.Thread(target=keep_beating, name="magsoro-heartbeat", daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()

    def record(self, sim, stamp: float | None = None) -> None:
        """Append a metrics row and a frame of the current state, stamped with the simulated time (or
        ``stamp``: the load level of a static run, whose first column is then 'level')."""
        stamp = sim.time if stamp is None else float(stamp)
        self.beat(sim, force=True)
        self.rows.append([stamp] + list(sim.probe_values().values()))
        buf = io.StringIO()
        buf.write(",".join(self.columns) + "\n")
        for r in self.rows:
            buf.write(",".join(f"{v:.9g}" for v in r) + "\n")
        atomic_write_text(self.dir / "metrics.csv", buf.getvalue())
        if self.particles:
            p = sim.particles()
            name = f"frames/frame_{len(self.frames):05d}.vtp"
            write_vtp(
                self.dir / name,
                p["x"],
                {
                    "velocity": p["v"].astype(np.float32),
                    "body": p["body"].astype(np.int32),
                    "clamped": p["clamped"],
                    "J": p["J"].astype(np.float32),
                    "I1bar": p["I1bar"].astype(np.float32),
                    "magnetization_direction": p["magnetization"].astype(np.float32),
                },
            )
            self.frames.append((stamp, name))
            write_pvd(self.dir / "particles.pvd", self.frames)

    def finish(self, result, wall_total: float) -> None:
        """Write the state kept (final.npz, or last_good.npz after a failure) and the closing run.json. When the
        state cannot be written, run.json says so; when run.json itself cannot be written, OutputError."""
        sim = self.sim
        p = sim.particles()
        message = result.message
        name = "last_good.npz" if result.status == "failed" else "final.npz"
        try:
            extra = sim.restart_arrays() if hasattr(sim, "restart_arrays") else {}  # what --from needs to continue
            atomic_save_npz(self.dir / name, time=sim.time, **p, **extra)
        except OutputError as exc:
            message = f"{message}; {name} not written: {exc}" if message else f"{name} not written: {exc}"
        self.info.update(
            status=result.status,
            message=message,
            steps=result.steps,
            time=result.time,
            wall_time=result.wall_time,
            wall_time_total=wall_total,
            steps_per_second=result.steps / result.wall_time if result.wall_time > 0 else None,
            dt={"fixed": sim.fixed_dt is not None, "min": sim.dt_min, "max": sim.dt_max, "mean": result.time / result.steps if result.steps and "equilibrium" not in self.info else None},
            grid=sim.solver.grid_info(),
            integrator=sim.integrator_info() if hasattr(sim, "integrator_info") else {"kind": "explicit"},
            frames=len(self.frames),
            magnetic_interaction={**self.info["magnetic_interaction"],
                                  "refreshes": sim.solver.interaction.refreshes if sim.solver.interaction else 0},
            graph_windows={"windows": sim.solver.graph_windows, "of": sim.windows, "captures": sim.solver.graph_captures,
                           "replays": sim.solver.graph_replays},
            notes=list(getattr(sim, "notes", [])),
            signal=getattr(result, "signal", None),  # the signal that stopped an interrupted run (15: SIGTERM)
            finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            heartbeat=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            heartbeat_unix=time.time(),
        )
        atomic_write_json(self.dir / "run.json", self.info)
