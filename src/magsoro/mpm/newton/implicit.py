"""Implicit time integration: each step minimises the incremental potential on the static solver's discretisation.

The unknowns are the static solver's (:mod:`magsoro.mpm.newton.static`): the displacements u of the free nodes of the
reference grid block, the particles at x_p = X_p + sum_i w_ip u_i. The node masses m_i are the particles' masses
scattered with the same weights (a lumped mass matrix M), and the nodes carry velocities v and accelerations a.
A step from t_n to t_{n+1} = t_n + dt solves, for u_{n+1},

    R(u_a, t_a) - M (a_m + c v_a) = 0                                                     (balance)

with R the static solver's node force (every elastic law, magnetic stress and gradient force, gravity, colliders
with Coulomb friction, pressure loads, eigenstrains, clamps as held nodes) and c the scene's mass damping
(simulation.damping, f = -c p, as in the explicit engine; a damping profile at the step's load time t_a). This is the stationarity condition of the incremental
potential 1/2 |u - u_pred|^2_M / (beta dt^2) + E(u) - W_ext(u) (Gast et al. 2015) for conservative loads; friction
enters as the static solver's lagged Coulomb law, its anchors updated after each step. Prony materials keep their
internal stresses (:mod:`magsoro.mpm.laws.viscous`): each trial F of a step takes them updated over [t_n, t_a] to itself,
the tangent their derivative, and they move on to F(u_{n+1}) when the step is accepted.

Two schemes, from one family of Newmark updates
    u_{n+1} = u_n + dt v_n + dt^2 (b0 a_n + beta a_{n+1}),   v_{n+1} = v_n + dt ((1 - gamma) a_n + gamma a_{n+1})
evaluated at the intermediate points u_a = (1 - alpha_f) u_{n+1} + alpha_f u_n, t_a = t_n + (1 - alpha_f) dt,
a_m = (1 - alpha_m) a_{n+1} + alpha_m a_n, v_a = (1 - alpha_f) v_{n+1} + alpha_f v_n:

- ``backward_euler``: beta = gamma = 1, b0 = 0, alpha_m = alpha_f = 0 (a_{n+1} = (v_{n+1} - v_n) / dt,
  v_{n+1} = (u_{n+1} - u_n) / dt). First order, unconditionally stable, dissipative: a mode of period T loses
  about 1 - exp(-2 pi^2 dt / T) of its amplitude per period for dt << T.
- ``generalized_alpha`` (Chung and Hulbert 1993): alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1),
  gamma = 1/2 - alpha_m + alpha_f, beta = (1 - alpha_m + alpha_f)^2 / 4, b0 = 1/2 - beta, with rho = rho_inf the
  spectral radius at dt/T -> infinity. Second order, unconditionally stable for linear problems; rho_inf = 1 keeps
  every mode (the trapezoidal rule), smaller values damp the modes the step does not resolve (the light nodes at a
  body's edge, contact chatter) while those it resolves lose little (third order in dt/T).

Newton's method with the static solver's line search and tangent; the tangent gains the mass term
-M ((1 - alpha_m)/(beta dt^2) + c (1 - alpha_f) gamma/(beta dt)), which makes it definite for small steps, so
Newton converges in a few iterations where the static solve needs load increments. A step that does not converge
is retried at half the step; steps grow after easy ones (:class:`magsoro.simulation.Simulation` drives the step
size from the ``[implicit]`` table).
"""

import logging
import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from magsoro.errors import SimulationError
from magsoro.mpm.newton.static import StaticSolver, check_supported, log

#: the step's force scale is never below the force of this strain over one cell face of the stiffest material
#: ((K + 4G/3) dx^(dim-1), 2D times the depth): with the default tolerance 1e-6 Newton then resolves the node forces of
#: strains of 1e-9, where a body coming to rest, unloaded, would otherwise chase round-off
FLOOR_STRAIN = 1.0e-3
#: a kept tangent is made anew when a Newton iteration with it lowers |R| by less than this factor, unless the
#: iterations left to the tolerance at the rate it showed are KEEP_ITERATIONS or fewer
REFRESH_RATE = 0.25
#: a kept tangent whose iteration lowered |R| by less than REFRESH_RATE is still kept while the rate it showed
#: (at most KEEP_RATE) reaches the tolerance in this many more iterations: an assembled and factorised tangent
#: costs about 35 iterations with a kept one on the 3D strip of benchmarks/implicit_vs_explicit.py (8937 unknowns),
#: whose run made 2 tangents with 6 here and 1 with 12 (58 and 63 Newton iterations; Anderson mixing's rate varies
#: from one iteration to the next)
KEEP_ITERATIONS = 12
KEEP_RATE = 0.7
#: a kept tangent serves a step whose length differs from its own by at most this fraction (steps that land on
#: output times differ from the nominal one in their last bits; with exact equality the 3D strip of
#: benchmarks/implicit_vs_explicit.py assembled and factorised a new tangent at every step: 21 in 20 steps)
KEEP_DT_RTOL = 1.0e-6
#: implicit.linear_solver = 'auto' factorises up to this many unknowns (the static solver's threshold,
#: linear.DIRECT_MAX_UNKNOWNS, is lower: it makes a new tangent every Newton iteration, where this integrator keeps
#: one factorisation for many solves: 7 ms a solve against 0.4 s a factorisation on the 3D strip's 8937 unknowns);
#: the bound is the factorisation's memory (a 3D tangent of about 70,000 unknowns needed more than 23 GB)
DIRECT_MAX_UNKNOWNS = 50_000
#: ... but only while a factorisation serves several Newton iterations: between the static solver's threshold and
#: DIRECT_MAX_UNKNOWNS, 'auto' turns to the iterative solver for the rest of the run once the steps made a new linear
#: solver for more than REUSE_MAX of their last REUSE_WINDOW (or more, whole steps) Newton iterations: contacts that
#: change the tangent at nearly every iteration (the triangle's pass on its friction plate at 10,200 unknowns took
#: 906 s direct and 292 s iterative for its first 0.1 s, benchmarks/README.md, "Contact rounds and kept tangents in
#: implicit steps"); a block sliding on a friction floor made 5 in its first 209
REUSE_WINDOW = 32
REUSE_MAX = 0.5
#: Anderson acceleration of the iterations with a kept tangent (class Anderson): the iterates it mixes, and how many
#: times longer than the plain step a mixed step may be
ANDERSON_DEPTH = 5
ANDERSON_MAX_GROWTH = 10.0
#: the schemes of ``[implicit] scheme``
SCHEMES = ("backward_euler", "generalized_alpha")
#: light nodes (class LightNodes): a node whose particles fill less than this fraction of its cell is tied to the
#: affine motion of its particles by a spring of up to LIGHT_STIFFNESS times a full cell's stiffness
LIGHT_FILL = 1.0e-2
LIGHT_STIFFNESS = 1.0e-3


@dataclass(frozen=True)
class Scheme:
    """Coefficients of one member of the Newmark / generalised-alpha family (module docstring)."""

    name: str
    beta: float
    gamma: float
    b0: float  # weight of a_n in the displacement update beside beta's a_{n+1}
    alpha_m: float
    alpha_f: float

    @classmethod
    def make(cls, name: str, rho_inf: float = 0.0) -> "Scheme":
        if name == "backward_euler":
            return cls(name, 1.0, 1.0, 0.0, 0.0, 0.0)
        if name == "generalized_alpha":
            rho = float(rho_inf)
            if not 0.0 <= rho <= 1.0:
                raise ValueError(f"implicit.rho_inf must lie in [0, 1], got {rho_inf}")
            am, af = (2.0 * rho - 1.0) / (rho + 1.0), rho / (rho + 1.0)
            gamma = 0.5 - am + af
            beta = 0.25 * (1.0 - am + af) ** 2
            return cls(name, beta, gamma, 0.5 - beta, am, af)
        raise ValueError(f"implicit.scheme must be one of {', '.join(SCHEMES)}, got '{name}'")


class Anderson:
    """Anderson acceleration (type II, Walker and Ni 2011) of the modified Newton iteration u <- u + f(u),
    f(u) = -K^-1 R(u) with the kept tangent K. With dU the changes of the last ``depth`` iterates and dF the changes
    of their f, the step taken is f - (dU + dF) g, g the least-squares fit of f by dF's columns. The map is that of
    one tangent (``tangent``, its linear solver): a new tangent or contact active set starts a new history. Steps
    are on the unknowns (flat arrays)."""

    def __init__(self, depth: int, tangent):
        self.depth, self.tangent = int(depth), tangent
        self.f = None  # the current iterate's f
        self.taken = None  # the step returned for it, until the iterate moves
        self.last = None  # how far the last iterate moved
        self.dU, self.dF = [], []

    def step(self, f: np.ndarray) -> np.ndarray:
        """The step from the current iterate, whose f is ``f``."""
        f = np.asarray(f, dtype=np.float64)
        if self.f is not None and self.last is not None:
            self.dU.append(self.last)
            self.dF.append(f - self.f)
            if len(self.dU) > self.depth:
                del self.dU[0], self.dF[0]
        self.f, self.last, out = f, None, f
        if self.dF:
            dF = np.stack(self.dF, axis=1)
            gamma = np.linalg.lstsq(dF, f, rcond=1e-10)[0]
            mixed = f - (np.stack(self.dU, axis=1) + dF) @ gamma
            # a fit on nearly parallel columns can throw the step far: the plain step then
            if np.all(np.isfinite(mixed)) and np.linalg.norm(mixed) <= ANDERSON_MAX_GROWTH * np.linalg.norm(f):
                out = mixed
        self.taken = out
        return out

    def restart(self) -> None:
        """A new step: its first iterate pairs with no earlier one (the loads and inertia moved f), but the pairs
        made so far stay (R's change with u does not depend on them)."""
        self.f = self.taken = self.last = None

    def moved(self, alpha: float) -> None:
        """The iterate moved by ``alpha`` times the step :meth:`step` returned last."""
        self.last = alpha * self.taken


class LightNodes:
    """The light nodes' spring: E_L(u) = 1/2 sum_i k_i |u_i - (A u)_i|^2 over the nodes whose particles fill less
    than LIGHT_FILL of their cell, with (A u)_i the displacement at node i of its particles' affine motion, as APIC's
    transfer (Jiang et al. 2015) puts it there:

        (A u)_i = sum_p m_p w_ip (u_p + grad u_p (X_i - X_p)) / m_i,  u_p = sum_j w_jp u_j,  grad u_p = sum_j u_j (x) grad w_jp.

    A reproduces every displacement affine in X exactly (quadratic B-splines reproduce linear fields, and the MLS
    gradient their gradients), so rigid motions, finite rotations included, and uniform strains cost nothing, and the
    term is of the order of the displacement's second derivatives elsewhere, as a ghost penalty (Burman 2010) is.

    Why: MLS weight gradients are proportional to the weights, so a node that only the far tails of its particles'
    B-splines reach (weight w) has stiffness of order w^2 and lumped mass of order w: a mode of frequency about
    sqrt(w) times a cell's, which for w ~ 1e-5 at dx 2 mm in silicone has a period of about 0.2 s. A step of
    milliseconds resolves it, so backward Euler does not damp it, and each change of the stresses at a body's surface
    sets such nodes swinging by several cells: the triangle of seed 002 lying still on its friction plate needed 6-12
    Newton iterations per 12.5 ms step with them, its light nodes moving up to 16 cells in a step (benchmarks/README.md,
    "Light nodes in implicit steps"). The explicit engine does not see the mode: its grid starts each step from the
    particles' velocities, which is the affine motion above. The spring's stiffness, k_i = LIGHT_STIFFNESS
    (1 - fill_i / LIGHT_FILL) (K + 4G/3)_i dx^(dim-2) (times the depth in 2D, the ring's length 2 pi r
    axisymmetric), fades to zero at LIGHT_FILL, so nodes whose own particles hold them are left alone."""

    def __init__(self, static):
        from scipy import sparse

        from magsoro.mpm.newton.static_contact import particle_sections

        model, h = static.model, static.model.host
        dim, dx, n_nodes = static.dim, float(model.dx), static.n_nodes
        nodes, w, grad = static.particle_stencil()
        P = static.interpolation()
        volumes = np.asarray(h["volumes"], dtype=np.float64)
        _, length = particle_sections(model, float(static.solver.settings.depth) if dim == 2 else 1.0)
        vol = P.T @ volumes
        filled = vol > 0
        fill = np.zeros(n_nodes)
        fill[filled] = (P.T @ (volumes / length))[filled] / dx ** dim
        light = np.flatnonzero(filled & (fill < LIGHT_FILL) & (static.node_mass > 0.0))
        self.count = len(light)
        if not len(light):
            self.K = None
            return
        safe = np.where(filled, vol, 1.0)
        p_wave = (P.T @ (volumes * model.p_wave_modulus()))[light] / safe[light]
        ring = (P.T @ (volumes * length))[light] / safe[light]  # the depth, the ring's length, or 1 in 3D
        k = LIGHT_STIFFNESS * (1.0 - fill[light] / LIGHT_FILL) * p_wave * dx ** (dim - 2) * ring
        row_of = np.full(n_nodes, -1, dtype=np.int64)
        row_of[light] = np.arange(len(light))
        X_nodes = static.node_positions()[2]  # the nodes' reference positions
        X = np.asarray(h["positions"], dtype=np.float64)[:, :dim]
        mass = np.asarray(h["mass"], dtype=np.float64)
        p_idx, s_idx = np.nonzero(row_of[nodes] >= 0)  # (particle, stencil slot) pairs that reach a light node
        node_i = nodes[p_idx, s_idx]
        share = mass[p_idx] * w[p_idx, s_idx] / static.node_mass[node_i]
        reach = np.einsum("ktd,kd->kt", grad[p_idx], X_nodes[node_i] - X[p_idx])
        vals = share[:, None] * (w[p_idx] + reach)
        rows = np.repeat(row_of[node_i], nodes.shape[1])
        A = sparse.csr_matrix((vals.ravel(), (rows, nodes[p_idx].ravel())), shape=(len(light), n_nodes))
        D = (sparse.csr_matrix((np.ones(len(light)), (np.arange(len(light)), light)), shape=(len(light), n_nodes)) - A)
        self.K = (D.T @ sparse.diags(k) @ D).tocsr()  # on the nodes, per component
        Kf = self.K[static.free][:, static.free]
        self.tangent = (static.E.T @ sparse.kron(Kf, sparse.identity(dim), format="csr") @ static.E).tocsc()

    def forces(self, u_nodes: np.ndarray) -> np.ndarray:
        """-dE_L/du on the nodes (n_nodes, dim)."""
        return -(self.K @ u_nodes)


@dataclass
class StepResult:
    """One attempted step: whether it converged, its Newton iterations, the final |R| relative to the step's force
    scale, and why it failed."""

    converged: bool
    iterations: int
    relative_residual: float
    message: str = ""
    fatal: bool = False  # a smaller step cannot help (the body reached a domain wall the solver does not model)


#: settle the colliders' contact set on each fresh tangent's linearised step (StaticSolver._settle_contacts). The
#: contacts between bodies and within one are left to the Newton iterates: in a step a fold moves by about a cell,
#: and the rounds on the self-contact of scenes/everting_tube.toml's tube (preview grid) made 36 factorisations a
#: step where the iterates make 5, with the same front to 1.5 % of its advance (docs/records/engine-measurements.md)
SETTLE_CONTACTS = True


def check_implicit_supported(sim) -> None:
    """Raise SimulationError naming the scene key the implicit integrator cannot take yet."""
    check_supported(sim, who="the implicit integrator (simulation.integrator = 'implicit')", viscous=True)
    if sim.solver.interaction is not None:
        raise SimulationError("the implicit integrator has no bodies' own field yet: set simulation.magnetic_interaction "
                              "= 'none' or simulation.integrator = 'explicit'")


class ImplicitIntegrator(StaticSolver):
    _inertia = None  # (scheme, dt, u_n, v_n, a_n) while a step's Newton runs; None: the static solver's residual
    _anderson = None  # the Anderson history of the kept tangent's iterations (class Anderson), kept across steps
    _scattered = None  # the node displacements of the last evaluation of a step's balance (None: another since)
    direct_max_unknowns = DIRECT_MAX_UNKNOWNS
    takes_prony = True
    light = None  # the light nodes' spring (class LightNodes), None where no node is light

    """Steps a :class:`magsoro.simulation.Simulation` built in the total-Lagrangian form by the scheme ``scheme``
    (``"backward_euler"`` or ``"generalized_alpha"``, spectral radius ``rho_inf``). The fields and colliders follow
    their paths in time at full level (``field_level`` and ``gravity_level`` scale them, 1 by default). It starts
    from the simulation's state: at rest in the reference configuration, or from a state placed there (its
    displacements and velocities projected on the grid nodes by least squares)."""

    def __init__(self, sim, scheme: str = "generalized_alpha", rho_inf: float = 0.0, tolerance: float = 1e-6,
                 max_iterations: int = 20, linear_solver: str = "auto"):
        check_implicit_supported(sim)
        if sim.model.viscous:  # the Prony internal stresses of the state (magsoro.mpm.laws.viscous), and a step's trial
            self.H_n = wp.clone(sim.state.H)
            self.H_trial = wp.zeros_like(self.H_n)
        super().__init__(sim, sim.state.time, tolerance=tolerance, max_iterations=max_iterations,
                         linear_solver=linear_solver)
        self.scheme = Scheme.make(scheme, rho_inf)
        if self.body_contact is not None:
            # friction between bodies on each step's starting normal force: within a step a potential of the
            # tangential motion alone (magsoro.mpm.newton.body_contact); with the current one, Newton's iterates on a
            # sliding block swung between the normal and tangential directions and grew
            self.body_contact.lag_normal = True
        self._set_collider_time(self.t)
        self.field_time = self.t
        self.field_level = self.gravity_level = 1.0
        from scipy import sparse

        free_mass = np.repeat(self.node_mass[self.free], self.dim)
        mass_matrix = self.E.T @ sparse.diags(free_mass) @ self.E  # on the unknowns
        # an unknown that moves no node (an axisymmetric axis node's radial one, :meth:`_slaving`) carries no mass:
        # a unit-scale mass there keeps M regular; its force is zero, so it stays at rest
        idle = mass_matrix.diagonal() <= 0.0
        if np.any(idle):
            scale = float(np.median(free_mass[free_mass > 0])) if np.any(free_mass > 0) else 1.0
            mass_matrix = mass_matrix + sparse.diags(idle * scale)
        self.mass_matrix = mass_matrix.tocsc()
        self.light = LightNodes(self)
        if self.light.K is None:
            self.light = None
        self.v_nodes = np.zeros_like(self.u_nodes)
        self.a_nodes = np.zeros_like(self.u_nodes)
        self.steps = self.rejected = self.newton_iterations = self.tangents = 0
        self._reuse = []  # (Newton iterations, linear setups) of the steps of the last REUSE_WINDOW iterations ('auto')
        self._per_iteration = False  # 'auto' saw a new linear solver at nearly every iteration (REUSE_MAX)
        self._live = None  # (linear setups before, Newton iterations so far) of the step in progress ('auto')
        self._kept = None  # (dt, LinearSolver of a tangent) reused across Newton iterations and steps
        self._start_from_state()
        self.a_nodes = self.consistent_acceleration()

    @property
    def damping(self) -> float:
        """The mass damping c (1/s) of simulation.damping: during a step at its load time t_a (the residual and its
        tangent alike), else at the current time; a damping profile is followed in time."""
        t = self.t + self._dt_a() if self._inertia is not None else self.t
        return self.solver.settings.damping_at(t)

    def _check_held(self) -> None:
        """Nothing to refuse: the mass term holds every part's step, so a body that starts free, loaded or not
        (a gripper dropped onto its object, a block falling on a plate), moves under its loads."""

    def light_fraction(self) -> float:
        """No node is slaved: the mass term makes the step's tangent definite along the combinations of light nodes
        that move no particle (the static solver's reason to slave them in 3D), and slaving stiffens the body. The
        3D strip of scenes/strip_magnet.toml (2 mm cells, 2 cells across its thin sections) hanging below its
        magnet settles 66 um lower without slaving than with it, the explicit engine 74 um lower."""
        return 0.0

    # -- the state on the nodes -----------------------------------------------------------------------------
    def _free_dofs(self) -> np.ndarray:
        return (self.free[:, None] * self.dim + np.arange(self.dim)[None, :]).ravel()

    def _start_from_state(self) -> None:
        """Displacements and velocities of the simulation's current state on the nodes (zero at the reference)."""
        h = self.model.host
        state = self.sim.state
        dim = self.dim
        x = state.x.numpy().astype(np.float64)[:, :dim]
        d = x - h["positions"][:, :dim]
        v = state.v.numpy().astype(np.float64)[:, :dim]
        F = state.F.numpy().astype(np.float64)[:, :dim, :dim]
        if np.any(d != 0.0):
            self.u_nodes = self.hold(self.fit_nodes(d, F - np.eye(dim)), self.t)
        if np.any(v != 0.0):  # with dF/dt = C F, C the state's velocity gradient
            C = state.C.numpy().astype(np.float64)[:, :dim, :dim]
            self.v_nodes = self.fit_nodes(v, np.einsum("pab,pbc->pac", C, F))

    def consistent_acceleration(self) -> np.ndarray:
        """a = M^-1 R(u) at the current state (the acceleration the loads give; generalised-alpha starts from it)."""
        from scipy.sparse.linalg import splu

        saved = self._inertia
        self._inertia = None
        r = self._reduce(self._scatter(self.u_nodes, self.field_level, self.gravity_level))
        self._inertia = saved
        r = r - self.damping * (self.mass_matrix @ self.unknowns_of(self.v_nodes))
        if not r.size:
            return np.zeros_like(self.u_nodes)
        return self._expand(splu(self.mass_matrix).solve(r))

    def unknowns_of(self, node_values: np.ndarray) -> np.ndarray:
        """The unknowns' values of node values that the slaving reproduces (least squares on E)."""
        from scipy.sparse.linalg import lsqr

        flat = node_values[self.free].ravel()
        if self.E.shape[0] == self.E.shape[1]:
            return flat
        return lsqr(self.E, flat, atol=1e-14, btol=1e-14)[0]

    # -- the balance of one step ----------------------------------------------------------------------------
    def _kinematics(self, u_nodes: np.ndarray):
        """(a_{n+1}, v_{n+1}) of the step in progress for the trial ``u_nodes``."""
        s, dt, u0, v0, a0 = self._inertia
        a1 = (u_nodes - u0 - dt * v0 - dt * dt * s.b0 * a0) / (s.beta * dt * dt)
        v1 = v0 + dt * ((1.0 - s.gamma) * a0 + s.gamma * a1)
        return a1, v1

    def _scatter(self, u_nodes: np.ndarray, field_level: float, gravity_level: float) -> np.ndarray:
        self._scattered = None  # the step's balance last evaluated at (try_step)
        if self._inertia is None:
            f = super()._scatter(u_nodes, field_level, gravity_level)
            return f if self.light is None else f + self.light.forces(u_nodes)
        self._scattered = u_nodes
        s, dt, u0, v0, a0 = self._inertia
        # the contacts act at the step's end, u_{n+1}, the rest at u_a: a penalty spring evaluated at u_a, with its
        # active set changing within the step, pumped energy into a block resting on a friction floor until it
        # jumped (generalised-alpha, mu = 0.7); at u_{n+1} the contact is a backward-Euler constraint force
        contact, self.contact = self.contact, None
        u_a = (1.0 - s.alpha_f) * u_nodes + s.alpha_f * u0
        try:
            f = super()._scatter(u_a, field_level, gravity_level)
        finally:
            self.contact = contact
        if self.light is not None:
            f = f + self.light.forces(u_a)
        if contact is not None:
            f = f + contact.forces(u_nodes)
        a1, v1 = self._kinematics(u_nodes)
        am = (1.0 - s.alpha_m) * a1 + s.alpha_m * a0
        va = (1.0 - s.alpha_f) * v1 + s.alpha_f * v0
        return f - self.node_mass[:, None] * (am + self.damping * va)

    def tangent(self, u_nodes, field_level, gravity_level):
        if self._inertia is None:
            J = super().tangent(u_nodes, field_level, gravity_level)
            return J if self.light is None else (J - self.light.tangent).tocsc()
        contact, self.contact = self.contact, None  # the contacts' part at u_{n+1}, unscaled (_scatter)
        try:
            J = super().tangent(u_nodes, field_level, gravity_level)
        finally:
            self.contact = contact
        if self.light is not None:
            J = J - self.light.tangent
        s, dt = self._inertia[0], self._inertia[1]
        c = (1.0 - s.alpha_m) / (s.beta * dt * dt) + self.damping * (1.0 - s.alpha_f) * s.gamma / (s.beta * dt)
        J = (1.0 - s.alpha_f) * J - c * self.mass_matrix
        if contact is not None:
            contact.forces(u_nodes)  # its springs at u_{n+1}
            J = J + self.E.T @ contact.tangent(self.free) @ self.E
        return J.tocsc()

    # -- a step's balance, open for checks ------------------------------------------------------------------
    def begin_step(self, dt: float) -> None:
        """Make :meth:`residual` and :meth:`tangent` those of the step of ``dt`` from the current state (its loads
        at t_a, inertia, internal stresses), as Newton sees them, until :meth:`end_step`."""
        s = self.scheme
        self._set_time(self.t + (1.0 - s.alpha_f) * dt)
        self._inertia = (s, float(dt), self.u_nodes, self.v_nodes, self.a_nodes)

    def end_step(self) -> None:
        """Back to the static balance at the current state's time (after :meth:`begin_step`)."""
        self._inertia = None
        self._set_time(self.t)

    def nodes_of(self, unknowns: np.ndarray) -> np.ndarray:
        """Node displacements (n_nodes, dim) of values on the unknowns (held nodes zero)."""
        return self._expand(np.asarray(unknowns, dtype=np.float64))

    # -- Prony viscoelasticity: the internal stresses move with each trial F over the step --------------------
    def _viscous_argument(self):
        """The overstress of the placed particles: during a step, after the update of the state's internal stresses
        over [t_n, t_a] to the trial F (viscous.trial_overstress's stress); outside a step, the state's own."""
        from magsoro.mpm.laws.viscous import launch_viscous_update, make_viscous, viscous_struct

        if not self.model.viscous:
            return self.no_viscous
        if self._inertia is None:
            return viscous_struct(self.model, self.H_n)
        kv = make_viscous(self.dim, self.model.scalar, self.model.plane)
        launch_viscous_update(kv, self.model.n_particles, F=self.F, bodies=self.bodies,
                              viscous=viscous_struct(self.model, self.H_n), H_out=self.H_trial, dt=self.sc(self._dt_a()),
                              device=self.dev)
        return viscous_struct(self.model, self.H_trial)

    def _add_material_tangent(self, A) -> None:
        from magsoro.mpm.newton.static import F_STEP
        from magsoro.mpm.laws.viscous import launch_overstress_tangent, make_viscous, viscous_struct

        if not self.model.viscous or self._inertia is None:
            return
        kv = make_viscous(self.dim, self.model.scalar, self.model.plane)
        launch_overstress_tangent(kv, self.model.n_particles, F=self.F, bodies=self.bodies,
                                  viscous=viscous_struct(self.model, self.H_n), dt=self.sc(self._dt_a()), h=self.sc(F_STEP),
                                  A=A, device=self.dev)

    def _dt_a(self) -> float:
        """The time from t_n to the step's load time t_a."""
        s, dt = self._inertia[0], self._inertia[1]
        return (1.0 - s.alpha_f) * dt

    def _advance_viscous(self, u1: np.ndarray, dt: float) -> None:
        """The internal stresses at the end of an accepted step: updated over dt to F(u_{n+1})."""
        from magsoro.mpm.laws.viscous import launch_viscous_update, make_viscous, viscous_struct

        self._place(u1)
        kv = make_viscous(self.dim, self.model.scalar, self.model.plane)
        launch_viscous_update(kv, self.model.n_particles, F=self.F, bodies=self.bodies,
                              viscous=viscous_struct(self.model, self.H_n), H_out=self.H_trial, dt=self.sc(dt),
                              device=self.dev)
        self.H_n, self.H_trial = self.H_trial, self.H_n

    def _force_scale(self, t_a: float) -> float:
        """The step's force scale for the tolerance: the largest of the loads on the undeformed body, the internal
        forces of the current state and the nodes' weight, at the step's load time (inertia off)."""
        saved = self._inertia
        self._inertia = None
        shift = self._shift  # moving clamps: at rest for the undeformed body, where they stand for the state
        if self.model.clamp_paths:
            self._set_clamps(0.0 * shift)
        r0 = self._reduce(self._scatter(np.zeros_like(self.u_nodes), self.field_level, self.gravity_level))
        if self.model.clamp_paths:
            self._set_clamps(self._clamp_displacements(self.t))
        rn = self._reduce(self._scatter(self.u_nodes, self.field_level, self.gravity_level))
        if self.model.clamp_paths:
            self._set_clamps(shift)
        self._inertia = saved
        weight = float(self.node_mass.max()) * float(np.linalg.norm(self.gravity)) * self.gravity_level
        inertial = float(np.abs(self.node_mass[:, None] * self.a_nodes).max()) if self.a_nodes.size else 0.0
        if not r0.size:
            return 1e-30
        return max(float(np.abs(r0).max()), float(np.abs(rn - r0).max()), weight, inertial, self._force_floor())

    def _force_floor(self) -> float:
        p_wave = float(np.max(self.model.p_wave_modulus()))
        thickness = float(self.solver.settings.depth) if self.dim == 2 else 1.0
        return FLOOR_STRAIN * p_wave * float(self.model.dx) ** (self.dim - 1) * thickness

    def _set_time(self, t: float) -> None:
        """Loads at time ``t``: the fields and colliders along their paths, eigenstrains and pressures."""
        self.field_time = float(t)
        self._set_collider_time(t)
        self.model.update_stimuli(t)
        self.model.update_pressures(t)

    def try_step(self, dt: float, turn: bool = False) -> StepResult:
        """Advance from the current time by ``dt`` (s). On success the nodes' state, the time and the colliders'
        friction anchors move on; on failure nothing changes. ``turn``: the loads' rates jump at the current time
        (a keyframe of a path or table), so Newton starts from the last state instead of where the last velocity
        carries the body."""
        s = self.scheme
        self.begin_step(dt)
        scale = self._force_scale(self.field_time)
        setups = self.linear_setups
        self._live = (setups, 0)
        u0, v0, a0 = self.u_nodes, self.v_nodes, self.a_nodes
        # predictor: constant velocity (a_n's term can throw the lightest nodes at a body's edge, whose lumped masses
        # carry large accelerations, far enough to invert their particles' F); at a turn of the loads the last state
        # (the triangle of scenes/triangle_stroke.toml, its magnet turning from rising to moving level under it:
        # from the rising velocity the steps after the turn failed at 60, 30 and 15 ms on the preview grid, 90 s
        # of Newton iterations; from the last state none, benchmarks/README.md)
        guess = self.hold(u0 if turn else u0 + dt * v0, self.t + dt)  # moving clamps: where they are at the end
        try:
            u1, ok, its, norm, message = self._step_newton(guess, scale)
            crossing = self.wall_crossing(u1) if ok else None
            if crossing is not None:
                ok, message = False, (f"the body moved {crossing}; the implicit integrator models only the walls a body "
                                      f"starts at: enlarge the domain")
            if ok:
                a1, v1 = self._kinematics(u1)
        finally:
            self._inertia = None
        self.newton_iterations += its
        self._live = None
        self._note_reuse(its, self.linear_setups - setups)
        if not ok:
            self.rejected += 1
            self.end_step()
            return StepResult(False, its, norm / scale, message, fatal=crossing is not None)
        if self.model.viscous:
            self._advance_viscous(u1, float(dt))
        self.u_nodes, self.v_nodes, self.a_nodes = u1, v1, a1
        self.t += float(dt)
        self.steps += 1
        if self.contact is not None:  # new contacts keep their anchors, sliding ones follow (static_contact)
            if self._scattered is None or not np.array_equal(self._scattered, u1):  # the contacts' state at u1
                self._inertia = (s, float(dt), u0, v0, a0)
                self._scatter(u1, self.field_level, self.gravity_level)
                self._inertia = None
            self.contact.accept(u1)
        return StepResult(True, its, norm / scale)

    def _note_reuse(self, iterations: int, setups: int):
        """Keep the step's Newton iterations and linear setups for 'auto' (REUSE_WINDOW, REUSE_MAX)."""
        self._reuse.append((iterations, setups))
        while sum(i for i, _ in self._reuse[1:]) >= REUSE_WINDOW:
            self._reuse.pop(0)
        self._check_reuse()

    def _check_reuse(self):
        """Turn 'auto' iterative once the linear setups of the kept steps and of the step in progress exceed
        REUSE_MAX of their Newton iterations, or of REUSE_WINDOW while there are fewer: a step that already made
        more than REUSE_MAX * REUSE_WINDOW new linear solvers (the contact rounds of its first iterations) fills
        any window it will be part of, so the rule need not wait for the step's end (the triangle landing on its
        plate at 10,200 unknowns: 75 s of factorisations in its first Newton iteration, benchmarks/README.md)."""
        if self._per_iteration:
            return
        its = sum(i for i, _ in self._reuse)
        setups = sum(n for _, n in self._reuse)
        if self._live is not None:
            its += self._live[1]
            setups += self.linear_setups - self._live[0]
        if setups > REUSE_MAX * max(its, REUSE_WINDOW):
            self._per_iteration = True
            log.info("implicit: a new linear solver at %d of the last %d Newton iterations; 'auto' solves "
                     "iteratively from here", setups, its)

    def _linear_kind(self, unknowns: int) -> str:
        """'direct' or 'iterative': the scene's linear_solver; 'auto' direct up to the static solver's threshold
        (linear.DIRECT_MAX_UNKNOWNS), iterative above ``direct_max_unknowns``, and in between direct until the
        steps make a new linear solver at nearly every iteration (REUSE_MAX), iterative from then on."""
        if self.linear_solver != "auto":
            return self.linear_solver
        from magsoro.mpm.newton import linear

        if unknowns <= linear.DIRECT_MAX_UNKNOWNS:
            return "direct"
        if unknowns > self.direct_max_unknowns:
            return "iterative"
        self._check_reuse()
        return "iterative" if self._per_iteration else "direct"

    def _step_newton(self, u, scale):
        """Newton on the step's balance from ``u`` with a kept tangent (module docstring, "Newton"): the tangent of
        an earlier iteration or step, with its linear solver (a factorisation, or a multigrid hierarchy:
        ``implicit.linear_solver``, magsoro.mpm.newton.linear), is reused while the residual falls by REFRESH_RATE or more
        per iteration, and made anew at the current iterate when it does not (or when the step size changed). An
        iterative solve is asked for Eisenstat and Walker's forcing term (loose far from the solution), never
        tighter than what leaves a tenth of the tolerance in the linear residual.
        Returns (u, converged, iterations, |R|_inf, message)."""
        from magsoro.mpm.newton.linear import forcing_term
        from magsoro.mpm.newton.static import GROWTH, MAX_STEP

        fl, gl = self.field_level, self.gravity_level
        contact = self.contact
        if contact is not None:
            contact.begin()
        r_full = self._scatter(u, fl, gl)
        if not self._valid():
            # the predictor inverted a particle: start from the last state instead (its moving clamps at the step's end)
            u = self.hold(self._inertia[2], self.t + self._inertia[1])
            r_full = self._scatter(u, fl, gl)
        if contact is not None:
            contact.commit()
        r = self._reduce(r_full)
        norm = float(np.abs(r).max()) if r.size else 0.0
        dt = self._inertia[1]
        if self._kept is not None and abs(self._kept[0] - dt) > KEEP_DT_RTOL * dt:
            self._kept = None  # another step length: another mass term
        fresh = False  # whether the kept tangent was made at this solve's current iterate
        history = self._anderson  # the Anderson history of the iterations with the kept tangent
        if history is not None:
            history.restart()  # the step's loads and inertia shift f: no pair across steps
        forcing = (None, None)  # the last linear solve's residual norm and tolerance (Eisenstat-Walker)
        best = norm
        it = 0
        while True:
            if not math.isfinite(norm):
                return u, False, it, norm, "the residual is not finite"
            if norm <= self.tolerance * scale:
                if contact is None or not contact.release():
                    return u, True, it, norm, ""
                r = self._reduce(self._scatter(u, fl, gl))  # pulling points left the active set: solve on
                norm = float(np.abs(r).max())
                history = self._anderson = None
                continue
            if it == self.max_iterations:
                break
            J = None
            if self._kept is None:
                try:
                    J = self.tangent(u, fl, gl)
                    self._kept = (dt, self._linear_solver(J, u))
                except RuntimeError as exc:
                    return u, False, it, norm, f"singular tangent ({exc})"
                self.tangents += 1
                fresh = True
            lin = self._kept[1]
            norm2 = float(np.linalg.norm(r))
            rtol = forcing_term(norm2, *forcing, floor=0.1 * self.tolerance * scale / max(norm2, 1e-300))
            forcing = (norm2, rtol)
            before = (lin.total_iterations, lin.solves, lin.fallbacks)
            raw = lin.solve(-r, rtol=rtol)
            self._count_linear(lin, before)
            if J is not None and contact is not None and SETTLE_CONTACTS:
                # the contact set settled on the linearised step (the static solver's rounds): a body set down on a
                # floor otherwise swaps its touching points between iterates and the line search stalls
                raw, _, lin, settled = self._settle_contacts(u, J, r, raw, lin, rtol, bodies=False)
                if settled:
                    self._kept = (dt, lin)
                    history = self._anderson = None
            if history is None or history.tangent is not lin:
                history = Anderson(ANDERSON_DEPTH, lin)
            step = self._expand(history.step(raw))
            self._anderson = history
            biggest = float(np.abs(step).max()) if step.size else 0.0
            alpha = min(1.0, MAX_STEP * self.model.dx / biggest) if biggest > 0.0 else 1.0
            if contact is not None:
                alpha = min(alpha, contact.step_limit(u, alpha * step) * alpha)
            signature = contact.signature() if contact is not None else None
            accepted = False
            while alpha >= 1.0 / 256:
                r_full = self._scatter(u + alpha * step, fl, gl)
                if self._valid():
                    r_try = self._reduce(r_full)
                    n_try = float(np.abs(r_try).max())
                    changed = contact is not None and contact.signature() != signature
                    # a tangent made at this iterate: the static solver's non-monotone rule (|R| may rise for an
                    # iteration: a body's light edge nodes answer the first step nonlinearly), and any step that
                    # changes the contact set; a kept one's full step must lower |R| by KEEP_RATE, else the tangent
                    # is made anew here, contacts changed or not (a kept tangent's contact springs are another
                    # step's: taken anyway, its first iterate put the triangle of seed 002 43 cells off, |R| from
                    # 1e-3 to 50, and the step failed after 20 iterations)
                    if fresh:
                        takes = changed or n_try < GROWTH * best
                    else:
                        takes = self._keeps(n_try, norm, scale, it)
                    if math.isfinite(n_try) and takes:
                        accepted = True
                        break
                if not fresh:
                    break
                alpha *= 0.5
            if not accepted:
                if fresh:
                    return u, False, it + 1, norm, "the line search found no step that lowers the residual"
                self._kept = history = self._anderson = None  # a stale tangent: make it anew at this iterate
                continue
            it += 1
            self._live = (self._live[0], it)  # try_step set it
            slow = n_try > REFRESH_RATE * norm and (fresh or changed)
            u, r, norm = u + alpha * step, r_try, n_try
            history.moved(alpha)
            if changed:
                history = self._anderson = None  # another active set: another fixed-point map
            best = min(best, norm)
            if contact is not None:
                contact.commit()
            if log.isEnabledFor(logging.DEBUG):
                log.debug("newton %d: |R| %.3e, step %.3g of %.3g cells, %s tangent%s", it, norm, alpha,
                          biggest / self.model.dx, "new" if fresh else "kept",
                          f", contacts {contact.count()}" if contact is not None else "")
            if slow:
                self._kept = None  # Newton's own rate is lost: the next iteration makes the tangent anew
            fresh = False
        return u, False, self.max_iterations, norm, f"no convergence in {self.max_iterations} Newton iterations"

    def _keeps(self, n_try: float, norm: float, scale: float, it: int) -> bool:
        """Whether a kept tangent's step from |R| = ``norm`` to ``n_try`` is taken and the tangent kept: it lowered
        |R| by REFRESH_RATE, or by KEEP_RATE at a rate that reaches the tolerance within KEEP_ITERATIONS more
        iterations (and max_iterations)."""
        if not n_try < KEEP_RATE * norm:
            return False
        if n_try <= REFRESH_RATE * norm or n_try <= self.tolerance * scale:
            return True
        left = math.log(self.tolerance * scale / n_try) / math.log(n_try / norm)
        return left <= KEEP_ITERATIONS and it + 1 + left <= self.max_iterations

    # -- output -------------------------------------------------------------------------------------------
    def write_state(self) -> None:
        """Put the current step into the simulation's state: x and F at u_{n+1}, v interpolated from the nodes,
        C = dF/dt F^-1 (the velocity gradient), the time."""
        self._place(self.u_nodes)
        state = self.sim.state
        wp.copy(state.x, self.x)
        wp.copy(state.F, self.F)
        nodes, w, grad = self._stencil()
        vn = self.v_nodes[nodes]  # (N, S, dim)
        clamped = self.model.host["clamped"] != 0
        v = np.einsum("ps,psa->pa", w, vn)
        Fdot = np.einsum("psa,psb->pab", vn, grad)
        v[clamped] = 0.0
        Fdot[clamped] = 0.0
        F = self.F.numpy().astype(np.float64)
        C = np.einsum("pab,pbc->pac", Fdot, np.linalg.inv(F))
        state.v.assign(v.astype(self.model.np_scalar))
        state.C.assign(C.astype(self.model.np_scalar))
        if self.model.viscous:
            wp.copy(state.H, self.H_n)
        state.time = self.t

    def kinetic_energy(self) -> float:
        """1/2 v^T M v of the nodes (J; 2D: per the scene's depth as the masses are)."""
        return 0.5 * float(np.sum(self.node_mass[:, None] * self.v_nodes ** 2))


def integrator_summary(integrator: "ImplicitIntegrator | None", settings) -> dict:
    """run.json's ``implicit`` entry: the scheme and its counts."""
    out = {"scheme": settings.scheme, "rho_inf": settings.rho_inf if settings.scheme == "generalized_alpha" else None,
           "tolerance": settings.tolerance}
    if integrator is not None:
        out.update(steps=integrator.steps, rejected_steps=integrator.rejected,
                   newton_iterations=integrator.newton_iterations, tangents=integrator.tangents,
                   linear_solver="+".join(sorted(integrator.linear_kinds)), linear_solves=integrator.linear_solves,
                   linear_iterations=integrator.linear_iterations, linear_setups=integrator.linear_setups,
                   linear_fallbacks=integrator.linear_fallbacks, contact_round_cycles=integrator.round_cycles,
                   residual_evaluations=integrator.residual_evaluations,
                   unknowns=int(integrator.E.shape[1]))
    return out
