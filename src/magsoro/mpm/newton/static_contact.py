"""Rigid colliders in the quasi-static solver (:mod:`magsoro.mpm.newton.static`): penalty with stick and Coulomb slip.

Two sets of contact points, both linear in the node unknowns u (x = X + W u):

- ``"particles"`` (scene key static.collider_contact = "surface", the default): the bodies' surface. Each particle,
  at x_p = X_p + sum_i w_ip u_i as the total form places it, is a ball of half its lattice spacing h_p
  (h_p^dim = its volume; 2D: its area), and touches a collider when its centre comes within h_p / 2 of it, so a
  body rests with its surface on the collider's wherever the collider cuts the grid.
- ``"nodes"`` (static.collider_contact = "nodes"; always for the domain walls): where the engine's
  total-Lagrangian form meets a collider (:mod:`magsoro.mpm.kernels.grid`): the grid nodes, each at its reference position
  plus the mass-weighted displacement of its particles, x~_i = X_i + sum_p m_p w_ip (x_p - X_p) / m_i, so
  W_ij = sum_p m_p w_ip w_jp / m_i, in contact below the engine's skin (0.1 cells). A node carrying mass lies up to
  about a cell outside its body, so a body that moves onto a collider stops about a cell off it, as it does in a
  dynamic run (and a pin a cell or two across acts fatter by about that much; docs/engine.md).

A point's level is its reach (h_p / 2, or the skin), or its signed distance at the start when it starts closer (the
engine stops a node's inward motion there; it does not push it out). In what follows "node" stands for either kind
of point.

The constraint phi >= s is imposed by a penalty: a node in contact is pushed out along the collider's normal n with
f_n = k (s - phi) n (s the level), k = PENALTY x (K + 4G/3) x dx^(dim-2) (2D: times the scene's depth, the node
forces' thickness): per cell, PENALTY times the P-wave modulus of the point's own material (a node's: the stiffest
of the particles on its stencil); a particle's k is the same per unit area, k (h_p / dx)^(dim-1). The point's own
modulus, not the scene's stiffest: a held point leaves once it pulls by RELEASE cells, and a soft strip held with a
stiff body's penalty could not lift off the floor at all. The penetration left at equilibrium is
f_n / k, so about p / (PENALTY (K + 4G/3)) cells for a contact pressure p: 1e-3 cells for p = 1 % of the P-wave
modulus. Every level reports the largest penetration (m) it left.

A "symmetry" collider (a mirror plane: half of a symmetric body, or the planes that hold an axisymmetric tube long)
holds the points within touching reach of it at the start on their level for good, pushing or pulling along its
normal (a two-sided spring that is never released); others that come to it later touch it as a slip collider.

Tangential: "slip" and "symmetry" colliders push along the normal only. "friction" and "sticky" ones tie a node that touches to
an anchor, the point of the surface under the node where it first touched (its position at the last converged
load increment, moved with the collider's path), by a spring k along the surface. With "friction" the tangential
force is capped at mu |f_n| (Coulomb): past the cap the node slides and its anchor follows it at the end of the
increment, so the force stays on the cone (a return map per load increment: the static answer depends on the
load path, as friction does). "sticky" ties all directions (the node also cannot leave: the engine's sticky nodes
move with the collider). Anchors are only updated between load increments, so within one Newton solve the
contact law is a fixed piecewise-linear spring and the tangent is exact except at the slip cap (whose direction
change is left out). The forces enter the node residual as W^T f, and the tangent as -W^T K_c W.
"""

import numpy as np
from scipy import sparse

from magsoro.mpm.settings import ColliderMode

#: penalty stiffness per cell, as a multiple of the point's P-wave modulus K + 4G/3
PENALTY = 10.0
#: the engine's contact skin (cells): a node touches a collider from this signed distance down
SKIN_CELLS = 0.1
#: friction's elastic slip (cells): a node sticks while it is within this tangential distance of its anchor, the
#: friction force growing to mu f_n over it; beyond, it slides at mu f_n (a regularised Coulomb law)
SLIP_CELLS = 5e-3
#: a Newton step is cut so that no node ends deeper than this (cells) past its contact level
STEP_DEPTH = 0.25
#: a point touches from this far (cells) above its level: a body placed on a collider (its lowest particles half a
#: spacing above it, as the builder puts them) touches it despite rounding in its positions. It must stay below
#: RELEASE, or a point released for pulling counts as touching again and the release never ends (at 1e-5 a block
#: resting on a friction floor in the implicit integrator did not finish its first steps); so a scene whose rounded
#: numbers leave a body further above a collider (scenes/pentahedron.toml's grid written as dx = 6.666667e-4 for
#: 2/3 mm: 9e-7 cells) is refused as free by the static solver: write such numbers to double precision
TOUCH_CELLS = 1e-9
#: a held node pulling by more than this (cells out of its level) at a converged state leaves the active set
RELEASE = 1e-6


def regularised_coulomb(force, blocks, dt, Pt, fn, dfn, mu, k, slip, active, touching):
    """The regularised Coulomb law of the colliders and of contact between bodies (module docstring), on the
    contacts ``active`` (a mask): subtracts the friction force from ``force`` (C, dim) and adds its stiffness to
    ``blocks`` (C, dim, dim: minus d force / d x). ``dt``: the tangential offset from the anchor, ``Pt`` the
    tangential projections, ``fn`` the normal force (>= 0), ``dfn`` -d f_n / dx, ``mu`` the Coulomb coefficient
    (a number or per contact), ``k`` the normal springs, ``slip`` the elastic slip (m), ``touching``: the contacts
    at their level (a reaching one's tangent takes mu k). Returns the (sticking, sliding) masks."""
    mu = np.broadcast_to(np.asarray(mu, dtype=np.float64), fn.shape)
    length = np.linalg.norm(dt, axis=1)
    sticking = active & (length <= slip)
    # sticking: a spring of stiffness mu f_n / slip
    pressed = sticking & (fn > 0.0)
    force[sticking] -= (mu[sticking] * fn[sticking] / slip)[:, None] * dt[sticking]
    blocks[pressed] += ((mu[pressed] * fn[pressed] / slip)[:, None, None] * Pt[pressed]
                        - (mu[pressed] / slip)[:, None, None] * np.einsum("pi,pj->pij", dt[pressed], dfn[pressed]))
    # not pressed yet (a point just reaching its level): the tangent takes mu k, so a step that will press it is
    # not free to slide; a held point that pulls (it lifts off, and leaves at a converged state) has no friction
    # force, and none in the tangent either: a stiffness there that its force lacks leaves Newton converging
    # linearly where a light body lifts off along most of its contact
    reaching = sticking & ~(fn > 0.0) & touching
    blocks[reaching] += (mu[reaching] * k[reaching])[:, None, None] * Pt[reaching]
    # sliding: mu f_n against the offset's direction; the cap grows with f_n, the direction turns
    sliding = active & ~sticking
    if sliding.any():
        t_hat = dt[sliding] / length[sliding, None]
        ms, fs, ls = mu[sliding], fn[sliding], length[sliding]
        force[sliding] -= (ms * fs)[:, None] * t_hat
        blocks[sliding] += ((ms * fs / ls)[:, None, None] * (Pt[sliding] - np.einsum("pi,pj->pij", t_hat, t_hat))
                            - ms[:, None, None] * np.einsum("pi,pj->pij", t_hat, dfn[sliding]))
    return sticking, sliding


def step_fraction(depth, limit: float, rounds: int) -> float:
    """The largest fraction (<= 1) of a Newton step after which ``depth(fraction)``, the deepest penetration (m),
    stays within ``limit``, or within the depth at the start where that is deeper (a state already past the limit,
    as a soft penalty's can be, would otherwise have every step cut to the least fraction): 1 when the whole step
    does, else bisection over ``rounds`` halvings, never below 1/256 (the colliders' and the body contact's step
    cut)."""
    limit = max(limit, 1.01 * depth(0.0))
    if depth(1.0) <= limit:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(rounds):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if depth(mid) <= limit else (lo, mid)
    return max(lo, 1.0 / 256)


def node_positions_map(static):
    """Where the engine's total form puts the grid nodes of a :class:`~magsoro.mpm.newton.static.StaticSolver`: node i at
    X_i + sum_p m_p w_ip (x_p - X_p) / m_i, the mass-weighted displacement of its particles, with clamped particles
    held at X_p (their mass counts in m_i, their displacement is zero). Linear in the node unknowns: x~ = X + W u.
    Returns (the nodes carrying mass, W (n_nodes x n_nodes, sparse), X (n_nodes, dim))."""
    model, h = static.model, static.model.host
    n_nodes = static.n_nodes
    P = static.interpolation()
    mass = P.T @ h["mass"]
    carrying = np.flatnonzero(mass > 0)
    inv = np.zeros(n_nodes)
    inv[carrying] = 1.0 / mass[carrying]
    moving = np.where(h["clamped"] != 0, 0.0, h["mass"])
    W = (sparse.diags(inv) @ P.T @ sparse.diags(moving) @ P).tocsr()
    X = (model.domain_lo + static.solver.org * model.dx) + static.coords * model.dx
    return carrying, W, X


def particle_sections(model, depth: float = 1.0):
    """Per particle of ``model``: its lattice spacing h in the plane the contacts work in, and the length its contact
    acts along, so that h^dim times that length is its volume: 1 in 3D, the scene's ``depth`` in 2D, and its ring's
    2 pi R in an axisymmetric scene (a penalty per unit length of the ring times its length). Returns (h, length)."""
    h = model.host
    volumes = np.asarray(h["volumes"], dtype=np.float64)
    if model.plane == "axisymmetric":
        length = 2.0 * np.pi * np.asarray(h["positions"], dtype=np.float64)[:, 0]
    else:
        length = np.full(len(volumes), depth if model.dim == 2 else 1.0)
    return (volumes / length) ** (1.0 / model.dim), length


class ColliderPenalty:
    """The colliders' node forces and their tangent for a :class:`~magsoro.mpm.newton.static.StaticSolver`."""

    def __init__(self, static, colliders, t: float, plane_z: float = 0.0, depth: float = 1.0, points: str = "nodes"):
        model = static.model
        self.static, self.colliders, self.t = static, list(colliders), float(t)
        self.dim, self.dx = model.dim, float(model.dx)
        self.plane_z = float(plane_z)
        self.slip = SLIP_CELLS * self.dx
        self.touch = TOUCH_CELLS * self.dx
        #: a step's cut: no node deeper than this (cells) past its level; scaled by 1/f where the penalty is (a
        #: softer penalty sinks a load's points deeper in proportion: static.soft_penalty's predictor)
        self.step_depth = STEP_DEPTH
        h = model.host
        p_wave = model.p_wave_modulus()
        thickness = depth if self.dim == 2 else 1.0
        # an axisymmetric scene's points are rings: their penalty is per unit length of the ring times its length
        # 2 pi r (a particle's r its reference radius R, a node's the mass-weighted R of its particles)
        ring = model.plane == "axisymmetric"
        self.ring = ring
        if ring:
            thickness = 1.0
        n_nodes = static.n_nodes
        if points == "nodes":
            # the engine's law: nodes at X + W u touch from the skin down
            self.touchable, self.W, self.X = static.node_positions()
            reach = np.full(len(self.touchable), SKIN_CELLS * self.dx)
            P = static.interpolation().tocoo()
            node_wave = np.zeros(n_nodes)
            np.maximum.at(node_wave, P.col[P.data > 0.0], p_wave[P.row[P.data > 0.0]])
            self.k = PENALTY * node_wave * self.dx ** (self.dim - 2) * thickness
            if ring:
                m_nodes = P.T @ h["mass"]
                radius = (P.T @ (h["mass"] * h["positions"][:, 0])) / np.where(m_nodes > 0, m_nodes, 1.0)
                self.k = self.k * 2.0 * np.pi * radius
        elif points == "particles":
            # the body's surface: each particle (x = X + P u, as the total form places it) is a ball of half its
            # lattice spacing, touching when its centre comes within that of the collider; the penalty per particle is
            # the nodes' per unit area (PENALTY (K + 4G/3) / dx) times the particle's share of the surface
            spacing, length = particle_sections(model, depth)
            self.touchable = np.flatnonzero(h["clamped"] == 0)
            self.W = static.interpolation()
            self.X = np.asarray(h["positions"], dtype=np.float64)
            reach = 0.5 * spacing[self.touchable]
            self.k = PENALTY * p_wave / self.dx * spacing ** (self.dim - 1) * length
        else:
            raise ValueError(f"points must be 'nodes' or 'particles', not {points!r}")
        # the level each point is held at: its reach, or where it starts when it starts closer (the engine stops a
        # node's inward motion there; it does not push it out), with the colliders where they are at the scene's
        # start (a collider that a path moves into a body later pushes it)
        X_touch = self.X[self.touchable]
        self.level = [np.minimum(reach, self.distance(c, X_touch, 0.0)) for c in self.colliders]
        self.anchor = [dict() for _ in self.colliders]  # node -> anchor point relative to the collider's position
        self.sticking = [dict() for _ in self.colliders]  # node -> whether it stuck in the last evaluation
        self._active = []  # per collider: nodes, normals, stiffness blocks of the last evaluation
        # the active set (module docstring): nodes held by each collider's normal spring during a Newton solve; they
        # join when they reach their level and leave only at a converged state where they pull
        self.held = [np.zeros(0, np.int64) for _ in self.colliders]
        #: per collider: the points a symmetry collider (a mirror plane) holds on their level for good, pulling or
        #: pushing: those within touching reach of it at the start (the body's face on the plane)
        self.bound = [np.zeros(0, np.int64) for _ in self.colliders]
        for ci, c in enumerate(self.colliders):
            if c.mode_code == ColliderMode.SYMMETRY:
                self.bound[ci] = self.touchable[self.distance(c, X_touch, 0.0) <= self.level[ci] + self.touch]
                self.held[ci] = self.bound[ci].copy()
        self._held_accepted = [h.copy() for h in self.held]
        #: per collider: the points within touching reach of it (level + touch) at the last forces() evaluation
        self.touching = [np.zeros(0, np.int64) for _ in self.colliders]
        self._gaps = [None for _ in self.colliders]
        self.penetration = 0.0
        self._last_x = self.X.copy()  # the nodes' contact positions at the last accepted increment
        self.reaction = np.zeros((len(self.colliders), 3))  # of the last forces() evaluation
        self._revision = None  # revise(): per collider, point -> (force, block) of the linearised set

    # -- geometry ---------------------------------------------------------------------------------------------
    def positions(self, u_nodes: np.ndarray) -> np.ndarray:
        """x~ (n_nodes, dim): the nodes where the colliders act."""
        return self.X + self.W @ u_nodes

    def _lift(self, pts: np.ndarray) -> np.ndarray:
        q = np.zeros((len(pts), 3))
        q[:, : self.dim] = pts
        if self.dim == 2:
            q[:, 2] = self.plane_z
        return q

    def distance(self, c, pts: np.ndarray, t: float | None = None) -> np.ndarray:
        """Signed distance (m) of collider ``c`` at ``pts`` (P, dim), the collider where its path has it at ``t``
        (default: the current time)."""
        return c.signed_distance(self._lift(pts), self.t if t is None else t)

    def signed_distance(self, c, pts: np.ndarray, t: float | None = None):
        """Signed distance (m) and outward unit normal (in-plane) of collider ``c`` at ``pts`` (P, dim), the collider
        where its path has it at ``t`` (default: the current time): the distance exactly, the normal by central
        differences of it (1e-6 cells). Costs 1 + 2 dim distance evaluations: where only the distance is
        needed, :meth:`distance`."""
        t = self.t if t is None else t
        phi = self.distance(c, pts, t)
        e = 1e-6 * self.dx
        grad = np.zeros((len(pts), self.dim))
        for a in range(self.dim):
            step = np.zeros(self.dim)
            step[a] = e
            grad[:, a] = (self.distance(c, pts + step, t) - self.distance(c, pts - step, t)) / (2 * e)
        norm = np.linalg.norm(grad, axis=1)
        return phi, grad / np.where(norm > 0, norm, 1.0)[:, None]

    def _origin(self, c) -> np.ndarray:
        return c.position_at(self.t)[: self.dim]

    # -- forces and tangent -------------------------------------------------------------------------------------
    def forces(self, u_nodes: np.ndarray) -> np.ndarray:
        """Node forces (n_nodes, dim) at ``u_nodes``: W^T f of the contact forces f at x~."""
        xt = self.positions(u_nodes)
        f = np.zeros_like(xt)
        self._active = []
        self.penetration = 0.0
        self.reaction = np.zeros((len(self.colliders), 3))  # N: the force on each collider (minus the points')
        for ci, c in enumerate(self.colliders):
            nodes = self.touchable
            phi = self.distance(c, xt[nodes])
            mode = c.mode_code
            normal_only = mode in (ColliderMode.SLIP, ColliderMode.SYMMETRY)  # no tangential law
            tied = np.array(list(self.anchor[ci]), dtype=np.int64) if not normal_only else np.zeros(0, np.int64)
            touching = nodes[phi <= self.level[ci] + self.touch]
            act = np.union1d(touching, self.held[ci])
            if mode == ColliderMode.STICKY:
                act = np.union1d(act, tied)
            self.touching[ci] = touching
            self._gaps[ci] = None
            if len(act) == 0:
                self._active.append(None)
                continue
            sel = np.searchsorted(nodes, act)
            ph, n = self.signed_distance(c, xt[act])  # the normals where they act only (the distances again)
            gap = self.level[ci][sel] - ph  # > 0: in contact; < 0 on a held node: it pulls until released
            self.penetration = max(self.penetration, float(np.max(gap, initial=0.0)))
            self._gaps[ci] = (act, gap)
            kc = self.k[act]
            fn_mag = kc * gap
            force = fn_mag[:, None] * n
            blocks = kc[:, None, None] * np.einsum("pi,pj->pij", n, n)
            fn_mag = np.maximum(fn_mag, 0.0)
            inside = gap >= -self.touch  # touching (a body placed on the collider: to rounding)
            if not normal_only:
                # the tangential law, on every point at once (module docstring)
                origin = self._origin(c)
                dim = self.dim
                anchors = np.full((len(act), dim), np.nan)
                known = np.zeros(len(act), bool)
                for j, node in enumerate(act):
                    a = self.anchor[ci].get(int(node))
                    if a is not None:
                        anchors[j], known[j] = a, True
                first = ~known & inside  # first touch: the surface point under the point's last converged position
                if first.any():
                    last = self._last_x[act[first]]
                    phl, nl = self.signed_distance(c, last)
                    anchors[first] = last - (phl - self.level[ci][sel[first]])[:, None] * nl - origin
                anchored = known | first  # the others (not touching, never anchored) carry no tangential force
                stuck = np.zeros(len(act), bool)
                d = xt[act] - (anchors + origin)
                if mode == ColliderMode.STICKY:
                    force[anchored] = -kc[anchored, None] * d[anchored]
                    blocks[anchored] = kc[anchored, None, None] * np.eye(dim)[None]
                    stuck[anchored] = True
                else:
                    # regularised Coulomb (module docstring): f_t = -mu f_n P_t d / max(|P_t d|, slip)
                    Pt = np.eye(dim)[None] - np.einsum("pi,pj->pij", n, n)
                    dt = np.einsum("pij,pj->pi", Pt, np.where(anchored[:, None], d, 0.0))
                    dfn = np.where((gap > 0.0)[:, None], kc[:, None] * n, 0.0)  # -d f_n / dx
                    sticking, _ = regularised_coulomb(force, blocks, dt, Pt, fn_mag, dfn, c.friction, kc, self.slip,
                                                      anchored, inside)
                    stuck[sticking] = True
                self.sticking[ci] = {int(node): bool(s) for node, s in zip(act, stuck)}
            f[act] += force
            self.reaction[ci, : self.dim] = -force.sum(axis=0)
            if self.ring:  # the radial forces on a ring cancel round it: a body of revolution feels none net
                self.reaction[ci, 0] = 0.0
            self._active.append((act, blocks, force))
        self._revision = None  # a new state: revise() starts from this evaluation's contacts
        return self.W.T @ f

    def begin(self) -> None:
        """Start a Newton solve from the last accepted state: the active set it had (a failed attempt's additions
        are dropped)."""
        self.held = [h.copy() for h in self._held_accepted]

    def commit(self) -> None:
        """The last evaluation's touching nodes join the active set (after an accepted Newton iterate)."""
        self.held = [np.union1d(h, t) for h, t in zip(self.held, self.touching)]

    def release(self) -> bool:
        """At a converged state: nodes of the active set that pull (gap below -RELEASE cells) leave it.
        Returns whether any did (the state is then to be solved again)."""
        changed = False
        for ci, entry in enumerate(self._gaps):
            if entry is None:
                continue
            if self.colliders[ci].mode_code == ColliderMode.STICKY:
                continue  # a sticky collider's points cannot leave it
            act, gap = entry
            pulling = act[gap < -RELEASE * self.dx]
            # points of the active set only (a point still touching is in the evaluation whether held or not, and
            # would be "released" again at every call), and not a mirror plane's own points
            pulling = pulling[np.isin(pulling, self.held[ci]) & ~np.isin(pulling, self.bound[ci])]
            if len(pulling):
                self.held[ci] = np.setdiff1d(self.held[ci], pulling)
                changed = True
        return changed

    def step_limit(self, u_nodes: np.ndarray, step: np.ndarray) -> float:
        """The largest fraction (<= 1) of a Newton ``step`` from ``u_nodes`` after which no node lies deeper than
        :attr:`step_depth` cells past its level, or deeper than the deepest is now (:func:`step_fraction`): a step
        taken without the contacts it would make is cut before it drives nodes, and the particles next to them,
        deep into a collider. (Without the second bound the hexahedron's predictor at 1e-4 of the penalty halved
        its 27 mT increment ten times at 1/256 steps.)"""
        def depth(alpha):
            xt = self.positions(u_nodes + alpha * step)[self.touchable]
            return max(float(np.max(lvl - self.distance(c, xt))) for c, lvl in zip(self.colliders, self.level))

        return step_fraction(depth, self.step_depth * self.dx, rounds=12)

    def count(self) -> int:
        """How many points the active set holds, over all colliders."""
        return sum(len(h) for h in self.held)

    def signature(self) -> tuple:
        """Which nodes were in contact in the last :meth:`forces` evaluation (to tell a change of the set)."""
        return tuple(None if e is None else e[0].tobytes() for e in self._active)

    def tangent(self, free: np.ndarray) -> sparse.csc_matrix:
        """d(W^T f)/du on the free DOFs (n_free dim square), from the last :meth:`forces` evaluation:
        -W^T K_c W with K_c the contact springs' block-diagonal stiffness."""
        return self._springs([e[:2] for e in self._active if e is not None], free)

    def revise(self, u_nodes: np.ndarray, step: np.ndarray, free: np.ndarray):
        """One round of the active set on the linearised problem (a primal-dual active set step within a Newton
        iteration): ``step`` (n_nodes, dim) solves the Newton system with the contact springs of the last round
        (at first those of the last :meth:`forces` evaluation, at ``u_nodes``). Points of the set that the step
        would lift by more than RELEASE cells off their level leave it; points outside it that the step would
        take past their level join it, with their normal spring linearised at ``u_nodes`` (force k gap n, pulling
        while they are above the level; no tangential stiffness).
        Sticky colliders keep their set. The points that leave leave the held set too; the ones that join do not
        join it (they join where they touch after the step: held far off the collider, a point would pull on it).

        Returns None when no point changes, else (the change of the node forces W^T f (n_nodes, dim), the change of
        the tangent on the free DOFs, as :meth:`tangent`). Without it a body lifting off a collider loses one
        ring of contacts per Newton iteration, and the points released step back into the collider at the next
        iterate (measured on the pentahedron's first field level: 37 iterations, the held count swinging by 100
        to 300 points at each)."""
        if self._revision is None:
            self._revision = [None if e is None else {int(p): (fr, b) for p, b, fr in zip(*e)} for e in self._active]
        x_now = self.positions(u_nodes)
        x_new = x_now + self.W @ step
        df = np.zeros_like(x_now)
        changes = []
        for ci, c in enumerate(self.colliders):
            mode = c.mode_code
            if mode == ColliderMode.STICKY:
                continue
            current = self._revision[ci] if self._revision[ci] is not None else {}
            nodes = self.touchable
            predicted = self.level[ci] - self.distance(c, x_new[nodes])  # > 0: past the level after the step
            leaving = np.array([p for p in current if predicted[np.searchsorted(nodes, p)] < -RELEASE * self.dx],
                               dtype=np.int64)
            leaving = leaving[~np.isin(leaving, self.bound[ci])]
            joining = nodes[predicted > self.touch]
            joining = joining[~np.isin(joining, np.fromiter(current, np.int64, len(current)))]
            if len(leaving) == 0 and len(joining) == 0:
                continue
            points, blocks = [], []
            for p in leaving.tolist():
                fr, b = current.pop(p)
                df[p] -= fr
                points.append(p)
                blocks.append(-b)
            if len(joining):
                sel = np.searchsorted(nodes, joining)
                ph, n = self.signed_distance(c, x_now[joining])
                kc = self.k[joining]
                force = (kc * (self.level[ci][sel] - ph))[:, None] * n
                # the normal spring only: a point reaching its level carries next to no normal force, so its
                # friction, capped at mu f_n, has next to no tangential stiffness either (a tangential mu k here
                # pinned the joining points in the linear step that the law lets slide: the triangle of seed 002
                # on its friction plate took 20 Newton iterations a step, each shrunk 25-fold, and halved it)
                block = kc[:, None, None] * np.einsum("pi,pj->pij", n, n)
                for p, fr, b in zip(joining.tolist(), force, block):
                    current[p] = (fr, b)
                df[joining] += force
                points.extend(joining.tolist())
                blocks.extend(block)
            self._revision[ci] = current
            self.held[ci] = np.setdiff1d(self.held[ci], leaving)
            changes.append((np.asarray(points, dtype=np.int64), np.asarray(blocks)))
        if not changes:
            return None
        return self.W.T @ df, self._springs(changes, free)

    def round_state(self):
        """The active set of the current :meth:`revise` rounds (hashable; None before the first round), so that the
        rounds can tell a set they have had before."""
        if self._revision is None:
            return None
        return tuple(None if d is None else np.sort(np.fromiter(d, np.int64, len(d))).tobytes() for d in self._revision)

    def _springs(self, entries, free: np.ndarray) -> sparse.csc_matrix:
        """-W^T K W on the free DOFs of the springs ``entries``: (points, blocks (P, dim, dim)) pairs."""
        dim = self.dim
        n_nodes = self.W.shape[0]
        rows, cols, vals = [], [], []
        for act, blocks in entries:
            for a in range(dim):
                for b in range(dim):
                    rows.append(act * dim + a)
                    cols.append(act * dim + b)
                    vals.append(-blocks[:, a, b])
        n_full = n_nodes * dim
        if not rows:
            return sparse.csc_matrix((len(free) * dim, len(free) * dim))
        K = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_full, n_full))
        Wd = sparse.kron(self.W, sparse.identity(dim), format="csr")
        dofs = (free[:, None] * dim + np.arange(dim)[None, :]).ravel()
        Wf = Wd[:, dofs]
        return (Wf.T @ K @ Wf).tocsc()

    def accept(self, u_nodes: np.ndarray) -> None:
        """After a converged load increment: new contacts keep their anchors, sliding nodes' anchors follow them
        onto the Coulomb cone, nodes that left a friction or slip collider forget theirs."""
        xt = self.positions(u_nodes)
        for ci, c in enumerate(self.colliders):
            mode = c.mode_code
            if mode in (ColliderMode.SLIP, ColliderMode.SYMMETRY):
                continue
            origin = self._origin(c)
            phi = self.distance(c, xt[self.touchable])
            close = self.touchable[phi <= self.level[ci] + self.touch]
            touching = set(int(v) for v in close)
            normal = dict(zip(close.tolist(), self.signed_distance(c, xt[close])[1])) if len(close) else {}
            last = self._last_x
            new = {}
            for node in touching | set(self.anchor[ci]):
                j = int(np.searchsorted(self.touchable, node))
                a = self.anchor[ci].get(node)
                if a is None:
                    if node not in touching:
                        continue
                    phl, nl = self.signed_distance(c, last[node : node + 1])
                    a = last[node] - (phl[0] - self.level[ci][j]) * nl[0] - origin
                if mode == ColliderMode.FRICTION:
                    if node not in touching:
                        continue  # separated: free again
                    if not self.sticking[ci].get(node, True):  # slid: the anchor follows to the elastic slip
                        n = normal[node]
                        d = xt[node] - (a + origin)
                        dt = d - np.dot(d, n) * n
                        length = float(np.linalg.norm(dt))
                        if length > self.slip:
                            a = a + dt * (1.0 - self.slip / length)
                new[node] = a
            self.anchor[ci] = new
        self._last_x = xt
        self._held_accepted = [h.copy() for h in self.held]

    def adopt(self, other: "ColliderPenalty") -> None:
        """Take the active set of ``other``, the same colliders' penalty in another solver of the same scene
        (static.soft_penalty's predictor). The friction state (anchors, sticking points, the accepted positions new
        contacts anchor under) stays this part's own, so friction follows this solver's path of equilibria, as
        without the predictor: the predictor's soft floor lets points sink and slide where the full penalty
        would not, and its anchors moved the cross's arch 1.5 % at 1e-4 of the penalty (benchmarks/README.md,
        "Penalty continuation"). The penalty stays this part's own too."""
        self.held = [h.copy() for h in other.held]
        self._held_accepted = [h.copy() for h in other._held_accepted]
        self.touching = [t.copy() for t in other.touching]


class Contacts:
    """Several :class:`ColliderPenalty` sets (the scene's colliders at the particles, the modelled domain walls at
    the nodes) seen by the static solver as one: forces and tangents add, the active sets move together."""

    def __init__(self, parts):
        self.parts = list(parts)

    @property
    def penetration(self) -> float:
        return max((p.penetration for p in self.parts), default=0.0)

    def forces(self, u_nodes):
        return sum(p.forces(u_nodes) for p in self.parts)

    def tangent(self, free):
        return sum(p.tangent(free) for p in self.parts)

    def begin(self) -> None:
        for p in self.parts:
            p.begin()

    def commit(self) -> None:
        for p in self.parts:
            p.commit()

    def release(self) -> bool:
        return any([p.release() for p in self.parts])  # a list: every part releases, not only the first that does

    def step_limit(self, u_nodes, step) -> float:
        return min(p.step_limit(u_nodes, step) for p in self.parts)

    def revise(self, u_nodes, step, free, bodies: bool = True):
        """The parts' :meth:`ColliderPenalty.revise` rounds added up (None when none changes); ``bodies`` False
        leaves out the contact between bodies (a part with ``between_bodies``)."""
        parts = [p for p in self.parts if bodies or not getattr(p, "between_bodies", False)]
        changes = [c for c in (p.revise(u_nodes, step, free) for p in parts) if c is not None]
        if not changes:
            return None
        return sum(c[0] for c in changes), sum(c[1] for c in changes)

    def signature(self) -> tuple:
        return tuple(s for p in self.parts for s in p.signature())

    def count(self) -> int:
        """How many points the parts' active sets hold."""
        return sum(p.count() for p in self.parts)

    def round_state(self) -> tuple:
        """The parts' active sets in the current rounds of :meth:`revise` (hashable)."""
        return tuple(p.round_state() for p in self.parts)

    def accept(self, u_nodes) -> None:
        for p in self.parts:
            p.accept(u_nodes)

    def adopt(self, other: "Contacts") -> None:
        """The contact state of ``other``, another solver of the same scene: each part's from its counterpart
        (:meth:`ColliderPenalty.adopt`, :meth:`BodyContact.adopt <magsoro.mpm.newton.body_contact.BodyContact.adopt>`)."""
        for p, q in zip(self.parts, other.parts):
            if type(p) is type(q):
                p.adopt(q)
