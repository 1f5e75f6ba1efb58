"""Gradient-based design: a scene, a target and design variables -> optimised design, loss history, scene file.

>>> prob = Problem.from_files("scene.toml", "target.toml", ["magnetisation"])      # doctest: +SKIP
>>> result = optimise(prob, method="adam", iterations=40)                          # doctest: +SKIP
>>> prob.write_scene("out/scene_optimized.toml")                                    # doctest: +SKIP
"""

import math
import time
from pathlib import Path

import numpy as np

from magsoro.diff.design import Design
from magsoro.diff.rollout import Rollout
from magsoro.diff.targets import make_target
from magsoro.io.tomlwrite import dumps
from magsoro.errors import MagsoroError
from magsoro.io.files import read_toml_file
from magsoro.scene import load_scene
from magsoro.scene.build import build


def _absolute_paths(data, base: Path):
    """Make the relative file references of a raw scene table absolute, so the scene can be written elsewhere."""
    def fix(v):
        p = Path(v)
        return str((base / p).resolve()) if not p.is_absolute() else v

    if isinstance(data.get("robot"), str):
        data["robot"] = fix(data["robot"])
    if isinstance(data.get("robot"), dict) and "file" in data["robot"]:
        data["robot"]["file"] = fix(data["robot"]["file"])
    if "material_library" in data:
        data["material_library"] = [fix(p) for p in data["material_library"]]

    def walk(node):
        if isinstance(node, dict):
            for k, v in node.items():
                if k == "file" and isinstance(v, str):
                    node[k] = fix(v)
                else:
                    walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)

    for key in ("bodies", "fields", "clamps", "colliders", "probes"):
        walk(data.get(key, []))
    if isinstance(data.get("robot"), dict):
        walk(data["robot"].get("parts", []))
    return data


class Problem:
    """A scene, a target and design variables, with a differentiable rollout of fixed time step.

    ``duration`` (s, default the scene's), ``dt`` (s, default the scene's fixed step or its CFL bound at the
    scene's field), ``segment`` (steps per checkpoint segment), ``margin`` (m, grid block margin),
    ``precision`` (overrides the scene's).
    """

    def __init__(self, scene_path, target_spec: dict, kinds, bodies=None, duration=None, dt=None, segment=None,
                 margin=None, precision=None, target_base=None, device="cpu"):
        self.scene_path = Path(scene_path)
        self.scene = load_scene(self.scene_path)
        sim = self.scene.simulation
        if precision is not None:
            sim.precision = precision
        if sim.magnetic_interaction != "none":
            raise MagsoroError(f"{self.scene_path}: simulation.magnetic_interaction: the differentiable rollout has no "
                               f"magnetic interaction between bodies; set it to 'none' to optimise this scene")
        self.built = build(self.scene, device=device, source=str(self.scene_path))
        self.raw = _absolute_paths(read_toml_file(self.scene_path, MagsoroError, "scene file"), self.scene_path.parent.resolve())
        self.duration = float(duration if duration is not None else sim.duration)
        if dt is None:
            dt = sim.dt
        if dt is None:
            from magsoro.mpm.solver import Solver

            solver = Solver(self.built.model, self.built.settings)
            dt = solver.stable_dt(self.built.control)
        self.n_steps = max(1, int(math.ceil(self.duration / dt - 1e-9)))
        self.dt = self.duration / self.n_steps
        self.rollout = Rollout(self.built, self.dt, self.n_steps, segment=segment, margin=margin)
        self.target = make_target(target_spec, self.built, target_base)
        self.design = Design(self.scene, self.rollout, list(kinds), bodies)
        self.evaluations = 0

    @classmethod
    def from_files(cls, scene_path, target_path, kinds, **kw):
        target_path = Path(target_path)
        spec = read_toml_file(target_path, MagsoroError, "target file")
        return cls(scene_path, spec, kinds, target_base=target_path.parent, **kw)

    def loss_and_grad(self, values, grad=True):
        """Loss and dL/d(values) (physical units) for the flat design ``values``."""
        self.design.apply(values)
        L, g = self.rollout.run(self.target, grad=grad)
        self.evaluations += 1
        return L, (self.design.gradient(g) if grad else None)

    def final_state(self, values=None):
        if values is not None:
            self.design.apply(values)
        return self.rollout.forward()

    def error(self, state) -> float:
        if hasattr(self.target, "theta"):
            return self.target.error(state["x"], state["F"])
        return self.target.error(state["x"])

    def write_scene(self, path) -> Path:
        """Write the scene with the current design, its fixed dt and the optimisation horizon."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = self.design.write_back(self.raw, path.parent)
        data["simulation"]["dt"] = float(self.dt)
        data["simulation"]["duration"] = float(self.duration)
        if self.scene.simulation.precision != data["simulation"].get("precision", "float32"):
            data["simulation"]["precision"] = self.scene.simulation.precision
        # the design was optimised with the rollout's (updated-Lagrangian) kernels: a re-run of the written scene
        # reproduces it only in that form, which an 'auto' scene would not choose for one body
        data["simulation"]["formulation"] = self.rollout.settings.formulation
        path.write_text(f"# written by magsoro optimize from {self.scene_path.name}\n" + dumps(data))
        return path


def optimise(problem: Problem, method="adam", iterations=50, lr=0.05, callback=None, tol=1e-12):
    """Minimise the target loss over the design. Variables are scaled by their typical size and the loss by its
    initial value. ``method``: 'adam' (step ``lr`` in scaled units) or 'lbfgs' (scipy L-BFGS-B, at most
    ``iterations`` iterations). Returns a dict with the history [(evaluation, loss)], the initial and best
    values and losses, and the wall time. The problem is left at the best design found."""
    d = problem.design
    x0 = d.values()
    scale = d.scales()
    t0 = time.perf_counter()
    L0, _ = problem.loss_and_grad(x0, grad=False)
    if not L0 > 0:
        raise MagsoroError(f"the initial loss is {L0}; nothing to optimise")
    history = []
    best = [L0, x0.copy()]

    def f(z):
        x = z * scale
        L, g = problem.loss_and_grad(x)
        history.append((len(history), L))
        if L < best[0]:
            best[0], best[1] = L, x.copy()
        if callback is not None:
            callback(len(history), L, L0)
        return L / L0, g * scale / L0

    z = x0 / scale
    if method == "adam":
        m = np.zeros_like(z)
        v = np.zeros_like(z)
        b1, b2, eps = 0.9, 0.999, 1e-8
        for it in range(1, iterations + 1):
            val, g = f(z)
            if val < tol:
                break
            m = b1 * m + (1 - b1) * g
            v = b2 * v + (1 - b2) * g * g
            mh = m / (1 - b1**it)
            vh = v / (1 - b2**it)
            z = z - lr * mh / (np.sqrt(vh) + eps)
        f(z)  # loss of the last step too
    elif method == "lbfgs":
        from scipy.optimize import minimize

        minimize(f, z, jac=True, method="L-BFGS-B", options={"maxiter": iterations, "ftol": tol, "gtol": 1e-10})
    else:
        raise MagsoroError(f"--method must be 'adam' or 'lbfgs', got {method!r}")
    d.apply(best[1])
    return {
        "initial_values": x0,
        "values": best[1],
        "initial_loss": L0,
        "loss": best[0],
        "history": history,
        "wall_time": time.perf_counter() - t0,
        "evaluations": problem.evaluations,
    }
