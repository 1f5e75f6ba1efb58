"""High-level scripting API: build a run from a scene, step it, read probes and particles as numpy.

>>> sim = Simulation.from_file("scenes/cantilever_2d.toml")      # doctest: +SKIP
>>> sim.run(duration=0.01, callback=lambda s: print(s.time))     # doctest: +SKIP
>>> sim.probe_values()["tip_y"]                                   # doctest: +SKIP
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from magsoro.errors import SimulationError
from magsoro.mpm.solver import Solver
from magsoro.scene import Scene, load_scene
from magsoro.scene.build import Built, build


@dataclass
class RunResult:
    status: str  # completed | failed | interrupted
    steps: int
    time: float
    wall_time: float
    message: str = ""


class Simulation:
    """A scene made runnable: Model, Control, Solver and the current State.

    ``device`` overrides the scene's ``simulation.device``.
    """

    def __init__(self, scene: Scene, device: str | None = None, source: str = "scene"):
        self.scene = scene
        self.built: Built = build(scene, device=device, source=source)
        self.model = self.built.model
        self.control = self.built.control
        self.solver = Solver(self.model, self.built.settings)
        self.state = self.solver.new_state(self.built.initial_velocity)
        self._spare = self.solver.new_state()
        self.probes = self.built.probes
        sim = scene.simulation
        self.fixed_dt = sim.dt
        self._field_peak = self.solver.field_magnitude(self.control)
        self._wave_speed = self.model.wave_speed(self._field_peak)
        self.dt = self.fixed_dt if self.fixed_dt is not None else self.solver.settings.cfl * self.model.dx / self._wave_speed
        self.dt_min = self.dt_max = self.dt
        self.steps = 0
        self.last_good_time = 0.0

    @classmethod
    def from_file(cls, path, device: str | None = None) -> "Simulation":
        return cls(load_scene(path), device=device, source=str(path))

    # -- reading -------------------------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.state.time

    @property
    def dim(self) -> int:
        return self.model.dim

    def probe_columns(self) -> list[str]:
        cols = []
        for p in self.probes:
            cols.extend(p.columns(self.dim))
        return cols

    def probe_values(self) -> dict[str, float]:
        """Current value of every probe column (m)."""
        x = self.state.x.numpy()
        out = {}
        for p in self.probes:
            out.update(zip(p.columns(self.dim), p.evaluate(x).tolist()))
        return out

    def particles(self) -> dict[str, np.ndarray]:
        """Particle arrays as numpy: x, v, F, body, clamped, J = det F, I1bar = J^(-2/3) tr(F^T F) (the
        isochoric stretch invariant, 3 when undeformed), magnetization (current direction of F Br, unit)."""
        s = self.state.numpy()
        F = s["F"].astype(np.float64)
        J = np.linalg.det(F)
        I1 = np.einsum("nij,nij->n", F, F) + (1.0 if self.dim == 2 else 0.0)
        Br = self.model.host["remanence"]
        m = np.einsum("nij,nj->ni", F, Br[:, : self.dim])
        if self.dim == 2:
            m = np.concatenate([m, Br[:, 2:3]], axis=1)
        norm = np.linalg.norm(m, axis=1, keepdims=True)
        direction = np.divide(m, norm, out=np.zeros_like(m), where=norm > 0)
        return {
            "x": s["x"],
            "v": s["v"],
            "F": s["F"],
            "body": self.model.host["body"],
            "clamped": self.model.host["clamped"].astype(np.uint8),
            "J": J,
            "I1bar": np.abs(J) ** (-2.0 / 3.0) * I1,
            "magnetization": direction,
        }

    # -- stepping ------------------------------------------------------------------------------------------
    def _next_dt(self, remaining: float) -> float:
        if self.fixed_dt is None:
            vmax = self.solver.last_max_speed() if self.steps else 0.0
            self.dt = self.solver.settings.cfl * self.model.dx / (self._wave_speed + vmax)
        dt = self.dt
        if remaining < dt * (1 + 1e-9):
            dt = remaining
        elif remaining < 2 * dt:
            dt = 0.5 * remaining  # avoid a sliver step at the end of an interval
        self.dt_min, self.dt_max = min(self.dt_min, dt), max(self.dt_max, dt)
        return dt

    def step(self, dt: float | None = None) -> None:
        """One step of ``dt`` seconds (default: the current automatic or fixed step)."""
        dt = self._next_dt(math.inf) if dt is None else dt
        self.solver.step(self.state, self._spare, self.control, dt)
        self.state, self._spare = self._spare, self.state
        self.steps += 1

    def advance_to(self, t_end: float, callback: Callable | None = None) -> None:
        """Step until simulated time ``t_end`` (s), landing on it exactly."""
        while self.state.time < t_end - 1e-12 * max(1.0, t_end):
            dt = self._next_dt(t_end - self.state.time)
            self.solver.step(self.state, self._spare, self.control, dt)
            self.state, self._spare = self._spare, self.state
            self.steps += 1
            if callback is not None:
                callback(self)

    def run(
        self,
        duration: float | None = None,
        callback: Callable | None = None,
        record: Callable | None = None,
        record_every: float | None = None,
        progress: Callable | None = None,
    ) -> RunResult:
        """Run for ``duration`` seconds (default: the scene's). ``callback(sim)`` is called after every step,
        ``record(sim)`` at t = 0 and every ``record_every`` seconds (default: output.every or duration / 50),
        ``progress(sim)`` after each record. SimulationError and KeyboardInterrupt end the run with status
        'failed' / 'interrupted'; the state kept is then the last good one."""
        duration = self.scene.simulation.duration if duration is None else float(duration)
        every = record_every or self.scene.output.every or duration / 50.0
        t0 = self.state.time
        t_end = t0 + duration
        wall0 = _time.perf_counter()
        n_records = int(math.floor(duration / every + 1e-9))
        targets = [t0 + k * every for k in range(1, n_records + 1)]
        if not targets or targets[-1] < t_end - 1e-12 * max(1.0, t_end):
            targets.append(t_end)
        status, message = "completed", ""
        try:
            if record is not None:
                record(self)
            for target in targets:
                self.advance_to(target, callback)
                self.last_good_time = self.state.time
                if record is not None:
                    record(self)
                if progress is not None:
                    progress(self)
        except SimulationError as exc:
            status = "failed"
            message = f"step {exc.step}, t = {exc.time:.6g} s: {exc}"
        except KeyboardInterrupt:
            status = "interrupted"
            message = f"interrupted by the user at t = {self.state.time:.6g} s"
        return RunResult(status, self.steps, self.state.time, _time.perf_counter() - wall0, message)
