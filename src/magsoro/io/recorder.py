"""Write a run's results to a directory: run.json, metrics.csv, frames/*.vtp + particles.pvd, final.npz.

Every file is replaced atomically; run.json says 'running' until the run ends, then 'completed', 'failed' or
'interrupted', so a reader can always tell a finished result from a partial one.
"""

from __future__ import annotations

import io
import platform
import time
from pathlib import Path

import numpy as np

from magsoro._version import __version__
from magsoro.io.files import atomic_save_npz, atomic_write_json, atomic_write_text
from magsoro.io.vtk import write_pvd, write_vtp


class RunWriter:
    def __init__(self, out_dir, sim, scene_echo: dict, particles: bool = True):
        import warp as wp

        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.sim = sim
        self.particles = particles
        self.frames: list[tuple[float, str]] = []
        self.rows: list[list[float]] = []
        self.columns = ["time"] + sim.probe_columns()
        if particles:
            (self.dir / "frames").mkdir(exist_ok=True)
        self.info = {
            "status": "running",
            "message": "",
            "magsoro_version": __version__,
            "warp_version": wp.config.version,
            "python": platform.python_version(),
            "machine": platform.node(),
            "device": sim.model.device,
            "device_name": wp.get_device(sim.model.device).name,
            "precision": sim.model.precision,
            "dim": sim.model.dim,
            "n_particles": sim.model.n_particles,
            "formulation": sim.solver.settings.formulation,
            "bodies": sim.built.fill_report,
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "scene": scene_echo,
        }
        # remove leftovers of an earlier run in the same folder, so no stale file looks like ours
        for stale in ("final.npz", "last_good.npz", "metrics.csv", "particles.pvd"):
            (self.dir / stale).unlink(missing_ok=True)
        if particles:
            for f in (self.dir / "frames").glob("frame_*.vtp"):
                f.unlink()
        atomic_write_json(self.dir / "run.json", self.info)

    def record(self, sim) -> None:
        self.rows.append([sim.time] + list(sim.probe_values().values()))
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
            self.frames.append((sim.time, name))
            write_pvd(self.dir / "particles.pvd", self.frames)

    def finish(self, result, wall_total: float) -> None:
        sim = self.sim
        p = sim.particles()
        if result.status == "failed":
            atomic_save_npz(self.dir / "last_good.npz", time=sim.time, **p)
        else:
            atomic_save_npz(self.dir / "final.npz", time=sim.time, **p)
        self.info.update(
            status=result.status,
            message=result.message,
            steps=result.steps,
            time=result.time,
            wall_time=result.wall_time,
            wall_time_total=wall_total,
            steps_per_second=result.steps / result.wall_time if result.wall_time > 0 else None,
            dt={"fixed": sim.fixed_dt is not None, "min": sim.dt_min, "max": sim.dt_max, "mean": result.time / result.steps if result.steps and "equilibrium" not in self.info else None},
            grid=sim.solver.grid_info(),
            frames=len(self.frames),
            finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        )
        atomic_write_json(self.dir / "run.json", self.info)
