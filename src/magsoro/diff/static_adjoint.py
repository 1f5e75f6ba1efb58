"""Gradients of a static shape target by the adjoint of the converged Newton system (``magsoro optimize --static``).

The static solver (:mod:`magsoro.mpm.newton.static`) finds node displacements u with R(u, theta) = 0 for the design
theta (a body's magnetisation, a body's shear modulus). A target L(x, F) of the particles' positions and
deformation gradients then has, by the implicit function theorem,

    dL/dtheta = lambda . dR/dtheta,    J^T lambda = -dL/du,

with J = dR/du the solver's own tangent at the equilibrium (on its unknowns, the light nodes extrapolated as the
solver has them), dL/du gathered from the particles (x_p = X_p + sum_i w_ip u_i, F_p = I + sum_i u_i (x) g_ip),
and dR/dtheta by central differences of the residual at the fixed equilibrium (the residual is linear in the
remanence and in the moduli of the Neo-Hookean law, so the differences are exact to round-off). One linear solve
per gradient, whatever the number of variables; each variable costs two residual evaluations (one scatter each).

Each evaluation solves the equilibrium from the unloaded state through the scene's levels, the path a `magsoro
run --static` takes, so the loss is a function of the design alone. ``warm=True`` starts from the last
evaluation's equilibrium instead (faster, falling back to the full path when it fails); a slender body can have
several equilibria under one load (past a buckling or snap-through point), and a warm start may then follow a branch
that loading from rest does not reach. The target is the one of ``magsoro optimize`` (:mod:`magsoro.diff.targets`)
at the last level.
"""

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from magsoro.diff.design import Design, body_variables, check_request
from magsoro.errors import MagsoroError, SimulationError

STATIC_KINDS = ("magnetisation", "material")
#: central-difference step of dR/dtheta, relative to each variable's scale
THETA_STEP = 1e-6


class StaticDesign(Design):
    """Design variables of a static problem: ``magnetisation`` (a remanence vector, T, per magnetised or listed
    body) and ``material`` (the shear modulus, Pa, of each Neo-Hookean or listed body; the bulk modulus keeps
    its ratio). Writes back like :class:`~magsoro.diff.design.Design`."""

    def __init__(self, sim, kinds, bodies=None):
        built = sim.built
        self.sim, self.scene = sim, sim.scene
        self.rollout = SimpleNamespace(model=sim.model)  # what Design.write_back reads
        self.dim = sim.model.dim
        check_request(kinds, STATIC_KINDS, bodies, built.body_names,
                      "--vars: '{kind}' is not a variable of a static design; choose from {allowed}")
        h = sim.model.host
        self.body_index = {name: np.flatnonzero(h["body"] == i) for i, name in enumerate(built.body_names)}
        self.base = {key: h[key].copy() for key in ("remanence", "shear_modulus", "bulk_modulus")}
        chosen = bodies if bodies is not None else built.body_names
        self.vars = [v for kind in kinds for v in body_variables(kind, h, self.body_index, chosen, bodies)]
        if not self.vars:
            raise MagsoroError("--vars: no body carries the variables asked for")
        self.sizes = [v.value.size for v in self.vars]

    def apply(self, flat) -> None:
        """Set the model's remanence and moduli (host and device) from the flat physical vector."""
        m = self.sim.model
        Br = self.base["remanence"].copy()
        G = self.base["shear_modulus"].copy()
        K = self.base["bulk_modulus"].copy()
        for v, val in zip(self.vars, self._split(flat)):
            v.value = val.copy()
            idx = self.body_index[v.info["body"]]
            if v.kind == "magnetisation":
                Br[idx] = val
            else:
                K[idx] = self.base["bulk_modulus"][idx] / self.base["shear_modulus"][idx] * val[0]
                G[idx] = val[0]
        h, s = m.host, m.np_scalar
        h["remanence"][:], h["shear_modulus"][:], h["bulk_modulus"][:] = Br, G, K
        m.Br.assign(Br.astype(s))
        m.shear.assign(G.astype(s))
        m.bulk.assign(K.astype(s))


class StaticProblem:
    """A scene solved statically, a target at its last level and static design variables, with the adjoint
    gradient. The interface of :class:`magsoro.diff.optimize.Problem` (``loss_and_grad``, ``final_state``,
    ``error``, ``write_scene``, ``design``, ``built``, ``target``, ``evaluations``)."""

    def __init__(self, scene_path, target_spec: dict, kinds, bodies=None, target_base=None, levels=None, warm=False):
        from magsoro.diff.optimize import _absolute_paths
        from magsoro.diff.targets import make_target
        from magsoro.io.files import read_toml_file
        from magsoro.mpm.newton.static import check_supported
        from magsoro.scene import load_scene
        from magsoro.simulation import Simulation, prepare_static

        self.scene_path = Path(scene_path)
        scene = load_scene(self.scene_path)
        try:
            prepare_static(scene)  # float64 and the total form, as `magsoro run --static`
        except MagsoroError as exc:
            raise MagsoroError(f"{self.scene_path}: {exc}") from None
        self.sim = Simulation(scene, source=str(self.scene_path))
        try:
            check_supported(self.sim)
        except SimulationError as exc:
            raise MagsoroError(f"{self.scene_path}: --static: {exc}") from None
        if self.sim.solver.interaction is not None:
            # the adjoint solves with the assembled tangent, which leaves out the bodies' own field
            raise MagsoroError(f"{self.scene_path}: simulation.magnetic_interaction: optimize --static has no adjoint of "
                               f"the bodies' own field yet; set it to 'none', or optimize by the dynamics (without --static)")
        self.scene, self.built = scene, self.sim.built
        self.raw = _absolute_paths(read_toml_file(self.scene_path, MagsoroError, "scene file"), self.scene_path.parent.resolve())
        self.levels = [float(v) for v in (levels if levels is not None else scene.static.levels)]
        self.t = float(scene.simulation.duration)
        self.warm = bool(warm)
        self.target = make_target(target_spec, self.built, target_base)
        self.design = StaticDesign(self.sim, list(kinds), bodies)
        self.solver = None
        self.evaluations = 0
        self.solves = []  # (Newton iterations, wall time) per equilibrium solved

    @classmethod
    def from_files(cls, scene_path, target_path, kinds, **kw):
        from magsoro.io.files import read_toml_file

        target_path = Path(target_path)
        spec = read_toml_file(target_path, MagsoroError, "target file")
        return cls(scene_path, spec, kinds, target_base=target_path.parent, **kw)

    # -- the equilibrium ---------------------------------------------------------------------------------------
    def _solve(self) -> None:
        """The equilibrium of the current design: from the last one (warm), or from the unloaded state through
        the levels (the first time, with ``warm=False``, or when the warm start does not converge: a design far
        from the last one)."""
        from magsoro.mpm.newton.static import StaticSolver

        cfg = self.scene.static
        for fresh in ([False, True] if self.warm and self.solver is not None else [True]):
            if fresh:
                self.solver = StaticSolver(self.sim, self.t, tolerance=cfg.tolerance, max_iterations=cfg.max_iterations)
            message = ""
            for level in (self.levels if fresh else self.levels[-1:]):
                res = self.solver.solve_level(level)
                self.solves.append((res.iterations, res.wall_time))
                if not res.converged:
                    message = f"level {level:g}: {res.message}"
                    break
            if not message:
                self.solver.node_forces(self.solver.u_nodes, self.solver.field_level, self.solver.gravity_level)
                return
        self.solver = None
        raise MagsoroError(f"the static solve did not converge for the design {self.design.values().tolist()} "
                           f"({message})")

    def _state(self) -> dict:
        st = self.solver
        return {"x": st.x.numpy().astype(np.float64), "F": st.F.numpy().astype(np.float64)}

    def final_state(self, values=None) -> dict:
        if values is not None:
            self.design.apply(values)
        self._solve()
        return self._state()

    def error(self, state) -> float:
        if hasattr(self.target, "theta"):
            return self.target.error(state["x"], state["F"])
        return self.target.error(state["x"])

    # -- loss and gradient ---------------------------------------------------------------------------------------
    def _node_gradient(self, gx, gF) -> np.ndarray:
        """dL/du (n_nodes, dim) from dL/dx and dL/dF of the particles (clamped ones do not follow the nodes)."""
        st = self.solver
        nodes, w, g = st.particle_stencil()
        free = ~self.sim.model.host["clamped"]
        dim = st.dim
        out = np.zeros((st.n_nodes, dim))
        if gx is not None:
            contrib = w[free][:, :, None] * gx[free][:, None, :]  # (N, S, dim)
            for a in range(dim):
                out[:, a] += np.bincount(nodes[free].ravel(), weights=contrib[:, :, a].ravel(), minlength=st.n_nodes)
        if gF is not None:
            contrib = np.einsum("pcb,psb->psc", gF[free], g[free])  # dL/dF_cb g_b
            for a in range(dim):
                out[:, a] += np.bincount(nodes[free].ravel(), weights=contrib[:, :, a].ravel(), minlength=st.n_nodes)
        return out

    def loss_and_grad(self, values, grad=True):
        """Loss at the last level's equilibrium and dL/d(values) (physical units) by the adjoint."""
        from scipy.sparse.linalg import splu

        values = np.asarray(values, dtype=np.float64)
        self.design.apply(values)
        self._solve()
        self.evaluations += 1
        state = self._state()
        L, gx, gF = self.target(state["x"], state["F"])
        if not grad:
            return float(L), None
        st = self.solver
        level, gravity = st.field_level, st.gravity_level
        J = st.tangent(st.u_nodes, level, gravity)
        lam = splu(J.T.tocsc()).solve(-st.forces_on_unknowns(self._node_gradient(gx, gF)))
        scales = self.design.scales()
        out = np.zeros(values.size)
        for k in range(values.size):
            h = THETA_STEP * scales[k]
            rs = []
            for sign in (1.0, -1.0):
                trial = values.copy()
                trial[k] += sign * h
                self.design.apply(trial)
                rs.append(st.residual(st.u_nodes, level, gravity))
            out[k] = float(lam @ ((rs[0] - rs[1]) / (2.0 * h)))
        self.design.apply(values)
        st.node_forces(st.u_nodes, level, gravity)  # the solver's x and F back at the design's equilibrium
        return float(L), out

    def write_scene(self, path) -> Path:
        """Write the scene with the current design (its static levels kept)."""
        from magsoro.io.tomlwrite import dumps

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = self.design.write_back(self.raw, path.parent)
        path.write_text(f"# written by magsoro optimize --static from {self.scene_path.name}\n" + dumps(data))
        return path


__all__ = ["STATIC_KINDS", "StaticDesign", "StaticProblem"]
