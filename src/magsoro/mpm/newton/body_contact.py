"""Contact between bodies, and within one, in the Newton solvers (:mod:`magsoro.mpm.newton.static`, :mod:`magsoro.mpm.newton.implicit`).

The static solver's reference grid is split by contact group (:meth:`magsoro.mpm.solver.Solver.reference_contact_grid`),
so bodies that may separate or slide never share an unknown; they meet only through this term, a penalty on the
bodies' surfaces with Coulomb friction, added to the energy the solvers minimise (its forces to the residual, its
springs to the tangent), as the rigid colliders' (:mod:`magsoro.mpm.newton.static_contact`).

Surfaces. A particle is on its body's surface when its neighbours of the same contact group within SURFACE_REACH
spacings, in the reference configuration, do not balance: their offsets sum to more than SURFACE_SPREAD spacings
(an interior particle of the builder's lattice has them symmetric, a sum of zero). Its outward reference normal N is
minus that sum's direction; at the current F the normal is F^-T N, normalised (Nanson). Each particle is a ball of
half its lattice spacing h (h^dim its volume; 2D: its area over the depth), the radius r = h / 2 that the collider
law gives it.

Gap. For a surface particle p and another group's surface particles q within MASTER_REACH spacings of it, facing it
(n_p . n_q < FACING), the other body's surface near p is the plane through their weighted centroid c with their
weighted mean normal n, weights w_q = (1 - (|x_p - x_q| / R)^2)^2 (a Shepard average, smooth in the positions):

    g = n . (x_p - c) - r_p - rbar - s,     c = sum w_q x_q / sum w_q,   rbar = sum w_q r_q / sum w_q,

with s = 0 between two contact groups, and s = SKIN_CELLS cells within one (self-contact): a skin around the balls
across which the contact already pushes (the margin d-hat of Li et al. 2020's barrier), so that the two layers of a
fold come to rest with their balls that far apart, less the penalty's give, and do not overlap where the arms' ends
meet corner to corner (a corner's normal is rounded between two faces, and its patch's plane is off by a fraction
of a spacing). Between groups the bodies are often drawn touching, where a skin would push them apart at the
start, and a corner contact that a slide uncovers later would push by the whole skin at once.

On a flat face every q lies at the same depth, so g is exact and does not jump as p slides from one q to the next;
on a curved face c lies inside it by about the sag of the patch, (MASTER_REACH h)^2 / (8 R_curvature). Particles
drawn touching (the builder puts them half a spacing inside each face) start at g = 0. The weights also carry
(-n_p . n_q)^FACING_POWER, so a body's corner particles, whose normals are rounded between two faces, barely tilt a
face's plane. The plane does not reach past the body's edge: the spring fades (smoothstep) from full where p's foot
lies within half a spacing of a master's tangential position to nothing a whole spacing from the nearest.

Normal law. A contact in the active set pushes p along n and the q's back with f_n = k (-g), k the colliders'
per-particle penalty (PENALTY (K + 4G/3) / dx h^(dim-1), 2D times the depth) halved: every face is both slave (its
particles pressed on the other's plane) and master (its plane pressed on by the other's particles), so a flat
contact carries the colliders' stiffness per unit area. K + 4G/3 is the softer group's of the two in contact (its
smallest over its particles): with the stiffest material's, a soft strip lying on a body 100 times stiffer could
not lift off (a held contact leaves once it pulls by RELEASE cells, and that gap cost the stiff spring a hundred
times the strip's weight). The penetration at equilibrium is p / (PENALTY (K + 4G/3)) cells of the softer body for
a contact pressure p. The active set is the colliders': a contact joins when it touches, stays through a Newton
solve even if it pulls, and leaves at a converged state where it pulls (RELEASE); so the law within a solve is a
fixed spring and the tangent is exact, n and the weights held (Gauss-Newton). Each Newton iteration of the static
solver first settles the set on its linearised problem (:meth:`BodyContact.revise`).

Friction. The colliders' regularised Coulomb law on the relative motion: d = e + (x_p - x_p') - sum w_q (x_q - x_q')
/ sum w_q, with x' the positions at the last accepted increment (or time step) and e the elastic slip carried from
it; f_t = -mu f_n t / max(|t|, slip) for t the tangential part of d, slip = SLIP_CELLS cells. The implicit
integrator lags f_n (``lag_normal``: the normal force of the last accepted state, Li et al. 2020's lagged
dissipative potential), so that within a step friction depends on the tangential motion alone. After a converged
increment a sticking contact keeps t as its e, a sliding one e = slip t / |t| (on the cone), one that separated
forgets it. mu is the pair's [contact] friction (the scene's table per pair of groups). With ``self_contact`` a
group's surface also meets itself where the particles were more than SELF_REACH_CELLS cells apart in the reference
(two layers of a folded strip, not neighbours on one face).

Limits: a Newton step or a load increment that carries a particle through the other body's surface patch in one go
(more than MASTER_REACH spacings) is not seen; the static solver's step cut (STEP_DEPTH cells of penetration) keeps
steps short where contacts are made.
"""

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from magsoro.mpm.newton.static_contact import (PENALTY, RELEASE, SLIP_CELLS, STEP_DEPTH, TOUCH_CELLS, particle_sections,
                                        regularised_coulomb, step_fraction)

#: a particle's same-group neighbours within this many of its spacings (reference) tell whether it is on a surface
SURFACE_REACH = 1.8
#: on the surface when the neighbours' offsets sum to more than this many spacings (a lattice's interior: zero)
SURFACE_SPREAD = 0.5
#: the other body's surface particles within this many spacings of a particle make its contact plane
MASTER_REACH = 2.5
#: a particle and a surface particle of another body face each other when their normals' dot product is below this
FACING = -0.2
#: the power of the facing cosine -n_slave . n_master in a master's weight
FACING_POWER = 8
#: a contact keeps its patch until its slave has slid this many of its spacings (tangentially) over it
REFRESH_SPACINGS = 0.75
#: self-contact: particles of one group closer than this many cells in the reference do not touch (one face)
SELF_REACH_CELLS = 3.0
#: self-contact: the skin (cells) between the particle balls across which the contact pushes (module docstring). The
#: strip of magsoro validate self_contact, folded by its field with the implicit integrator: reference-far particles
#: at least 0.448 cells apart without a skin (its arm tips meet corner to corner and their balls overlap), 0.546 with
#: 0.1 cells (two rows of particles at 2 per cell touching face to face are 0.5 cells apart)
SKIN_CELLS = 0.1


def surface_normals(X: np.ndarray, group: np.ndarray, spacing: np.ndarray):
    """Surface particles and their outward unit normals in the reference configuration (module docstring).
    Returns (indices, normals (S, dim))."""
    reach = SURFACE_REACH * float(np.max(spacing))
    tree = cKDTree(X)
    pairs = tree.query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros(0, np.int64), np.zeros((0, X.shape[1]))
    i, j = pairs[:, 0], pairs[:, 1]
    d = np.linalg.norm(X[i] - X[j], axis=1)
    keep = (group[i] == group[j]) & (d <= SURFACE_REACH * np.minimum(spacing[i], spacing[j]))
    i, j = i[keep], j[keep]
    s = np.zeros_like(X)
    off = X[j] - X[i]
    for a in range(X.shape[1]):
        s[:, a] = np.bincount(i, weights=off[:, a], minlength=len(X)) - np.bincount(j, weights=off[:, a], minlength=len(X))
    length = np.linalg.norm(s, axis=1)
    on = np.flatnonzero(length > SURFACE_SPREAD * spacing)
    return on, -s[on] / length[on, None]


class BodyContact:
    """Contact between the contact groups of a :class:`~magsoro.mpm.newton.static.StaticSolver` (and within one, with
    self-contact): forces on its slots, their tangent, the active set and friction's slip (module docstring). The
    interface is :class:`~magsoro.mpm.newton.static_contact.ColliderPenalty`'s, so :class:`~magsoro.mpm.newton.static_contact.Contacts`
    takes it as one more part."""

    between_bodies = True  # Contacts.revise(bodies=False) leaves it out

    def __init__(self, static, friction: np.ndarray, self_contact: bool, depth: float = 1.0):
        model = static.model
        h = model.host
        self.static = static
        self.dim, self.dx = model.dim, float(model.dx)
        self.t = 0.0  # the colliders' time (Contacts sets it on every part); no use here
        self.group = np.asarray(h["contact_group"], dtype=np.int64)
        self.n_groups = int(self.group.max()) + 1
        fr = np.asarray(friction, dtype=np.float64)[: self.n_groups, : self.n_groups]
        self.mu_table = np.maximum(fr, 0.0)
        allowed = fr >= 0.0
        if not self_contact:
            np.fill_diagonal(allowed, False)
        self.allowed = allowed
        # an axisymmetric scene's particles are rings: the section's spacing, and a penalty per unit length of the
        # ring times its length 2 pi R (the colliders' rule)
        self.ring = model.plane == "axisymmetric"
        spacing, length = particle_sections(model, depth)
        self.X = np.asarray(h["positions"], dtype=np.float64)
        free = np.asarray(h["clamped"]) == 0
        surf, normals = surface_normals(self.X, self.group, spacing)
        keep = free[surf] & np.isin(self.group[surf], np.flatnonzero(allowed.any(axis=1)))
        self.surface, self.N = surf[keep], normals[keep]
        self.radius = 0.5 * spacing
        self.reach = MASTER_REACH * float(np.max(spacing))
        # the penalty per unit P-wave modulus; a contact's modulus is the softer of its two groups' (pair_wave)
        self.k = 0.5 * PENALTY / self.dx * spacing ** (self.dim - 1) * length
        wave = static.model.p_wave_modulus()
        softest = np.array([wave[self.group == g].min() for g in range(self.n_groups)])
        self.pair_wave = np.minimum(softest[:, None], softest[None, :])
        self.slip = SLIP_CELLS * self.dx
        self.touch = TOUCH_CELLS * self.dx
        self.skin = SKIN_CELLS * self.dx
        #: a step's cut: no contact deeper than this (cells); scaled by 1/f with the penalty (static.soft_penalty)
        self.step_depth = STEP_DEPTH
        self.P = static.interpolation()
        self._x_last = self.X.copy()
        #: per contact key, how far it starts inside the other body's plane (m, <= 0; the colliders' rule: a
        #: contact that starts closer is held where it starts, not pushed out): a corner's rounded normal tilts the
        #: plane under a face that touches it by up to about 1 % of a cell
        self.start_gap = {}
        #: friction takes the normal force of the last accepted state instead of the current one (the implicit
        #: integrator: Li et al. 2020's lagged dissipative potential; its steps are short), so that within a step
        #: friction is a potential of the tangential motion alone
        self.lag_normal = False
        self._fn_lag = {}
        self.elastic = {}  # contact key (slave particle * groups + master group) -> elastic slip e (dim)
        self.held = np.zeros(0, np.int64)  # the active set's keys during a Newton solve
        self._revision = None  # revise(): the linearised contacts of this Newton iteration
        self._held_accepted = self.held.copy()
        self.touching = np.zeros(0, np.int64)
        self._last = None  # the last evaluation's contacts (a dict of arrays)
        self.penetration = 0.0
        #: (groups, groups, 3) N: the force group a exerts on group b, at the last evaluation
        self.pair_force = np.zeros((self.n_groups, self.n_groups, 3))
        self.patches = None  # the contacts' patches in the current Newton solve (_contacts)
        self._lever0 = {}  # per contact key: the slave's tangential offset from its patch's centroid when it was taken
        self._patches_accepted = None
        start = self._contacts(np.zeros((self.P.shape[1], self.dim)), record=False)
        if start is not None:
            inside = start["gap"] < 0.0
            self.start_gap = dict(zip(start["keys"][inside].tolist(), start["gap"][inside].tolist()))

    # -- geometry ---------------------------------------------------------------------------------------------
    def _surface_state(self, u_nodes: np.ndarray):
        """Current positions of every particle (X + P u); per surface particle its F and F^-T N (not normalised:
        the patches' normals are their weighted sums, normalised)."""
        x = self.X + self.P @ u_nodes
        nodes, _, grad = self.static.particle_stencil()
        s = self.surface
        F = np.eye(self.dim)[None] + np.einsum("psa,psb->pab", u_nodes[nodes[s]], grad[s])
        m = np.linalg.solve(np.transpose(F, (0, 2, 1)), self.N[:, :, None])[:, :, 0]
        return x, F, m

    def _fresh_planes(self, x: np.ndarray, m: np.ndarray):
        """Every (surface particle, other group) with facing surface particles of that group in reach at the
        positions ``x`` (``m``: the surface particles' F^-T N): its patch of masters and their weights (module
        docstring), keys sorted, masters listed by row (as surface indices); None when there is none."""
        s = self.surface
        if len(s) < 2:
            return None
        xs = x[s]
        n_s = m / np.maximum(np.linalg.norm(m, axis=1), 1e-300)[:, None]
        pairs = cKDTree(xs).query_pairs(self.reach, output_type="ndarray")
        if len(pairs) == 0:
            return None
        a = np.concatenate([pairs[:, 0], pairs[:, 1]])  # slave (surface index)
        b = np.concatenate([pairs[:, 1], pairs[:, 0]])  # master
        ga, gb = self.group[s[a]], self.group[s[b]]
        ok = self.allowed[ga, gb] & (np.einsum("pi,pi->p", n_s[a], n_s[b]) < FACING)
        same = ok & (ga == gb)
        if same.any():
            far = np.linalg.norm(self.X[s[a[same]]] - self.X[s[b[same]]], axis=1) > SELF_REACH_CELLS * self.dx
            ok[np.flatnonzero(same)[~far]] = False
        a, b, gb = a[ok], b[ok], gb[ok]
        if len(a) == 0:
            return None
        d = np.linalg.norm(xs[a] - xs[b], axis=1)
        # a master's weight falls with its distance and with how far its normal turns from facing the slave's:
        # a body's corner particles (their normals rounded between two faces) barely tilt the plane of a face
        facing = np.maximum(-np.einsum("pi,pi->p", n_s[a], n_s[b]), 0.0)
        w = (1.0 - (d / self.reach) ** 2) ** 2 * facing ** FACING_POWER
        key = s[a] * self.n_groups + gb
        order = np.argsort(key, kind="stable")
        a, b, w, key = a[order], b[order], w[order], key[order]
        keys, start, counts = np.unique(key, return_index=True, return_counts=True)
        row = np.repeat(np.arange(len(keys)), counts)
        W = np.bincount(row, weights=w)
        return dict(keys=keys, slave=s[a[start]], master=b, row=row, weight=w / W[row])

    def _coverage(self, planes: dict, x: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Per contact, how far its slave lies over the other body's surface: 1 while its foot on the plane falls
        within half a spacing of a master (on a master's tile), down to 0 (smoothstep) where it lies a whole
        spacing from the nearest: a patch's plane does not reach past the body's edge."""
        v = x[planes["slave"]][planes["row"]] - x[self.surface[planes["master"]]]
        nr = n[planes["row"]]
        t = np.linalg.norm(v - np.einsum("ji,ji->j", v, nr)[:, None] * nr, axis=1)
        t = t / (2.0 * self.radius[self.surface[planes["master"]]])
        z = np.clip((1.0 - t) / 0.5, 0.0, 1.0)  # 1 at t <= 1/2, 0 at t >= 1
        phi = z * z * (3.0 - 2.0 * z)
        out = np.zeros(len(planes["keys"]))
        np.maximum.at(out, planes["row"], phi)
        return out

    def _geometry(self, planes: dict, x: np.ndarray, m: np.ndarray):
        """Per contact of ``planes`` at the positions ``x``: the gap (m; less its start gap), the unit normal n,
        the patch's centroid c and |sum w m_q| (the normal's length before normalising); the slaves' coverage
        (:meth:`_coverage`) is left in ``_cover``."""
        keys, row, wh, dim = planes["keys"], planes["row"], planes["weight"], self.dim
        mp = self.surface[planes["master"]]
        c = np.stack([np.bincount(row, weights=wh * x[mp, k], minlength=len(keys)) for k in range(dim)], axis=1)
        S = np.stack([np.bincount(row, weights=wh * m[planes["master"], k], minlength=len(keys)) for k in range(dim)], axis=1)
        size = np.maximum(np.linalg.norm(S, axis=1), 1e-300)
        n = S / size[:, None]
        rbar = np.bincount(row, weights=wh * self.radius[mp], minlength=len(keys))
        gap = np.einsum("ki,ki->k", n, x[planes["slave"]] - c) - self.radius[planes["slave"]] - rbar
        own = self.group[planes["slave"]] == keys % self.n_groups
        if own.any():  # self-contact: the skin (SKIN_CELLS)
            gap = gap - self.skin * own
        if self.start_gap:
            gap = gap - np.array([self.start_gap.get(int(kk), 0.0) for kk in keys])
        self._cover = self._coverage(planes, x, n)
        return gap, n, c, size

    @staticmethod
    def _select(planes: dict, keep: np.ndarray) -> dict:
        """The patches of the contacts ``keep`` (a boolean mask over planes["keys"]), masters renumbered."""
        sel = np.flatnonzero(keep)
        remap = np.full(len(planes["keys"]), -1)
        remap[sel] = np.arange(len(sel))
        on = remap[planes["row"]] >= 0
        return dict(keys=planes["keys"][sel], slave=planes["slave"][sel], master=planes["master"][on],
                    row=remap[planes["row"][on]], weight=planes["weight"][on])

    @staticmethod
    def _join(p: dict, q: dict) -> dict:
        """Two sets of patches with distinct keys as one, sorted by key."""
        keys = np.concatenate([p["keys"], q["keys"]])
        order = np.argsort(keys, kind="stable")
        rank = np.empty(len(keys), np.int64)
        rank[order] = np.arange(len(keys))
        new_row = rank[np.concatenate([p["row"], q["row"] + len(p["keys"])])]
        by = np.argsort(new_row, kind="stable")
        return dict(keys=keys[order], slave=np.concatenate([p["slave"], q["slave"]])[order], row=new_row[by],
                    master=np.concatenate([p["master"], q["master"]])[by],
                    weight=np.concatenate([p["weight"], q["weight"]])[by])

    def _contacts(self, u_nodes: np.ndarray, keys_wanted: np.ndarray | None = None, record: bool = True):
        """The contacts at ``u_nodes``: the patches kept in this Newton solve (masters and weights taken when the
        contact was first seen since the last accepted state, so that the gap is one smooth function of u within
        the solve), plus every touching contact found anew, kept from here on (``record``). Keys in ``keys_wanted``
        are kept whatever their gap, the others only when they touch. None when there are none."""
        x, F, m = self._surface_state(u_nodes)
        fresh = self._fresh_planes(x, m)
        kept = self.patches
        if fresh is not None:
            near = (self._geometry(fresh, x, m)[0] <= self.touch) & (self._cover > 0.0)
            if keys_wanted is not None:
                near |= np.isin(fresh["keys"], keys_wanted)
            fresh = self._select(fresh, near)
            if kept is not None:
                fresh = self._select(fresh, ~np.isin(fresh["keys"], kept["keys"]))
            if len(fresh["keys"]):
                kept = fresh if kept is None else self._join(kept, fresh)
                if record:  # where each new patch's slave lies from its centroid (accept: has it slid off?)
                    _, n_f, c_f, _ = self._geometry(fresh, x, m)
                    lever = x[fresh["slave"]] - c_f
                    lever -= np.einsum("ki,ki->k", lever, n_f)[:, None] * n_f
                    self._lever0.update(zip(fresh["keys"].tolist(), lever))
        if record:
            self.patches = kept
        if kept is None or len(kept["keys"]) == 0:
            return None
        gap, n, c, size = self._geometry(kept, x, m)
        cover = self._cover
        touching = (gap <= self.touch) & (cover > 0.0)
        keep = touching if keys_wanted is None else (touching | np.isin(kept["keys"], keys_wanted))
        if not keep.any():
            return None
        cs = self._select(kept, keep)
        cs.update(gap=gap[keep], cover=cover[keep], normal=n[keep], centroid=c[keep], size=size[keep], touching=touching[keep],
                  x=x, F=F, m=m)
        return cs

    def _stiffness(self, cs: dict) -> np.ndarray:
        """Each contact's normal spring (N/m): the penalty per unit modulus of its slave, times the P-wave modulus
        of the softer of the two groups it joins, times its coverage."""
        slave = cs["slave"]
        return self.k[slave] * self.pair_wave[self.group[slave], cs["keys"] % self.n_groups] * cs["cover"]

    def _gap_gradient(self, cs: dict) -> sparse.csr_matrix:
        """d gap / du for each contact of ``cs`` (n_contacts x n_nodes dim, sparse): the slave's and the patch's
        motion along n, and the turn of n with the masters' F (n = S / |S|, S = sum w F_q^-T N_q:
        d(F^-T N) = -F^-T dF^T F^-T N, dF_q = sum_s du_s (x) grad_qs)."""
        dim, n_c = self.dim, len(cs["keys"])
        n_slots = self.P.shape[1]
        nodes, _, grad = self.static.particle_stencil()
        Pd = self.P
        # translation: n_d (P_slave - sum w P_master)
        C = sparse.csr_matrix((np.concatenate([np.ones(n_c), -cs["weight"]]),
                               (np.concatenate([np.arange(n_c), cs["row"]]),
                                np.concatenate([cs["slave"], self.surface[cs["master"]]]))), shape=(n_c, len(self.X)))
        B = (C @ Pd).tocoo()
        rows = [np.repeat(B.row, dim)]
        cols = [(B.col[:, None] * dim + np.arange(dim)[None]).ravel()]
        vals = [(B.data[:, None] * cs["normal"][B.row]).ravel()]
        # rotation: (x_p - c) . dn = l . dS / |S|, l = (I - n n^T)(x_p - c)
        n = cs["normal"]
        lever = cs["x"][cs["slave"]] - cs["centroid"]
        lever = lever - np.einsum("ki,ki->k", lever, n)[:, None] * n
        q = cs["master"]  # surface indices
        Fq, mq = cs["F"][q], cs["m"][q]
        r = cs["row"]
        a = np.linalg.solve(Fq, lever[r][:, :, None])[:, :, 0]  # F_q^-1 l
        coef = -(cs["weight"] / cs["size"][r])  # per master entry
        qp = self.surface[q]
        ag = np.einsum("ja,jsa->js", a, grad[qp])  # (J, S): a . grad_qs
        slot = nodes[qp]  # (J, S)
        val = (coef[:, None, None] * ag[:, :, None]) * mq[:, None, :]  # (J, S, dim)
        rows.append(np.repeat(r, slot.shape[1] * dim))
        cols.append((slot[:, :, None] * dim + np.arange(dim)[None, None]).ravel())
        vals.append(val.ravel())
        G = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_c, n_slots * dim))
        return G, C

    # -- forces and tangent -----------------------------------------------------------------------------------
    def forces(self, u_nodes: np.ndarray) -> np.ndarray:
        """Node (slot) forces (n_nodes, dim) at ``u_nodes``: the normal springs' -k g dg/du and P^T of the
        friction forces on the particles."""
        dim = self.dim
        n_slots = self.P.shape[1]
        cs = self._contacts(u_nodes, self.held)
        self._revision = None  # a new state: revise() starts from this evaluation's contacts
        self.pair_force = np.zeros((self.n_groups, self.n_groups, 3))
        self._last = cs
        self.penetration = 0.0
        if cs is None:
            self.touching = np.zeros(0, np.int64)
            return np.zeros((n_slots, dim))
        self.touching = cs["keys"][cs["touching"]]
        keys, slave, gap, n = cs["keys"], cs["slave"], cs["gap"], cs["normal"]
        m_row, m_idx, m_w, x = cs["row"], self.surface[cs["master"]], cs["weight"], cs["x"]
        self.penetration = float(np.max(-gap[cs["cover"] > 0.0], initial=0.0))
        kc = self._stiffness(cs)  # a slave near the other body's edge: a spring that fades off it
        fn_signed = kc * (-gap)  # > 0 pressing; < 0 on a held contact that pulls until released
        G, C = self._gap_gradient(cs)
        f_nodes = (G.T @ fn_signed).reshape(n_slots, dim)
        force = np.zeros((len(keys), dim))  # friction, on the slave (its patch takes minus it)
        blocks = np.zeros((len(keys), dim, dim))
        fn = np.maximum(fn_signed, 0.0)
        lagged = self.lag_normal
        if lagged:  # friction's normal force as it was at the last accepted state (Li et al. 2020)
            fn = np.array([self._fn_lag.get(int(kk), 0.0) for kk in keys])
        mu = self.mu_table[self.group[slave], keys % self.n_groups]
        rough = mu > 0.0
        stuck = np.ones(len(keys), bool)
        dt = np.zeros((len(keys), dim))
        if rough.any():
            # the relative motion since the last accepted state, plus the elastic slip carried from it
            moved = x - self._x_last
            rel = moved[slave].copy()
            for k in range(dim):
                rel[:, k] -= np.bincount(m_row, weights=m_w * moved[m_idx, k], minlength=len(keys))
            e = np.array([self.elastic.get(int(kk), np.zeros(dim)) for kk in keys]).reshape(len(keys), dim)
            Pt = np.eye(dim)[None] - np.einsum("pi,pj->pij", n, n)
            dt = np.einsum("pij,pj->pi", Pt, e + rel)
            dfn = np.where((gap < 0.0)[:, None], kc[:, None] * n, 0.0)  # -d f_n / d(relative position), n held
            if lagged:
                dfn = np.zeros_like(dfn)
            _, sliding = regularised_coulomb(force, blocks, dt, Pt, fn, dfn, mu, kc, self.slip, rough,
                                             cs["touching"] & (not lagged))
            stuck = ~sliding
        self._slip_state = (keys, dt, stuck)
        fp = np.zeros((len(self.X), dim))
        for k in range(dim):
            fp[:, k] += np.bincount(slave, weights=force[:, k], minlength=len(self.X))
            fp[:, k] -= np.bincount(m_idx, weights=m_w * force[m_row, k], minlength=len(self.X))
        # the force each group exerts on each other: on the slaves, the normal and friction forces; the patches
        # take the reactions
        total = force + fn_signed[:, None] * n
        gs, gm = self.group[slave], keys % self.n_groups
        for k in range(dim):
            if k == 0 and self.ring:  # the radial forces on a ring cancel round it (net force along the axis only)
                continue
            np.add.at(self.pair_force[:, :, k], (gm, gs), total[:, k])
            np.add.at(self.pair_force[:, :, k], (gs, gm), -total[:, k])
        self._tangent_parts = (G, kc, (C @ self.P).tocsr(), blocks)
        self._friction_force = force
        return f_nodes + self.P.T @ fp

    def tangent(self, free: np.ndarray) -> sparse.csc_matrix:
        """d(forces)/du on the free slots' DOFs (n_free dim square), from the last :meth:`forces` evaluation:
        -sum_c k_c g_c' g_c'^T (the normal springs, Gauss-Newton: the gap's curvature times the force left out)
        and friction's -B_c^T K_c B_c, B_c the slots' combination of contact c's relative position."""
        dim = self.dim
        n_free = len(free) * dim
        if self._last is None:
            return sparse.csc_matrix((n_free, n_free))
        return self._springs(*self._tangent_parts, free)

    def _springs(self, G, kc, B, blocks, free: np.ndarray) -> sparse.csc_matrix:
        """-sum_c k_c g_c' g_c'^T - B_c^T K_c B_c on the free slots' DOFs: the normal springs ``kc`` on the gap
        gradients ``G`` and the friction blocks ``blocks`` (C, dim, dim) on the relative positions ``B``."""
        dim = self.dim
        dofs = (free[:, None] * dim + np.arange(dim)[None, :]).ravel()
        Gf = G[:, dofs]
        out = -(Gf.T @ sparse.diags(kc) @ Gf)
        if np.any(blocks):
            Bf = B[:, free]
            for a in range(dim):
                for b in range(dim):
                    part = -(Bf.T @ sparse.diags(blocks[:, a, b]) @ Bf)
                    unit = sparse.csr_matrix(([1.0], ([a], [b])), shape=(dim, dim))
                    out = out + sparse.kron(part, unit, format="csc")
        return out.tocsc()

    # -- the active set ----------------------------------------------------------------------------------------
    def begin(self) -> None:
        """Start a Newton solve from the last accepted state: its active set and patches."""
        self.held = self._held_accepted.copy()
        self.patches = self._patches_accepted

    def commit(self) -> None:
        """The last evaluation's touching contacts join the active set (after an accepted Newton iterate)."""
        self.held = np.union1d(self.held, self.touching)

    def release(self) -> bool:
        """At a converged state: contacts of the active set that pull (gap above RELEASE cells) leave it. Returns
        whether any did (the state is then to be solved again)."""
        if self._last is None:
            return False
        pulling = self._last["keys"][(self._last["gap"] > RELEASE * self.dx) | (self._last["cover"] <= 0.0)]
        pulling = np.intersect1d(pulling, self.held)
        if len(pulling):
            self.held = np.setdiff1d(self.held, pulling)
            return True
        return False

    def revise(self, u_nodes: np.ndarray, step: np.ndarray, free: np.ndarray):
        """One round of the active set on the linearised problem, as :meth:`ColliderPenalty.revise
        <magsoro.mpm.newton.static_contact.ColliderPenalty.revise>` does for the colliders: with the gaps linear in the
        step, g + G step (:meth:`_gap_gradient` at ``u_nodes``, the last :meth:`forces` evaluation), contacts of the
        set that ``step`` (n_slots, dim) would open by more than RELEASE cells leave it, and contacts of this
        solve's patches that it would close join it (their spring linearised at ``u_nodes``, friction's tangent
        that of a contact reaching its level). Contacts whose patch is not yet known (a particle that has never
        come near the other body in this solve) join at accepted iterates, as before.

        Returns None when no contact changes, else (the change of the slots' forces (n_slots, dim), the change
        of the tangent on the free slots' DOFs)."""
        if self._revision is None:
            if self.patches is None or len(self.patches["keys"]) == 0:
                return None
            cs = self._contacts(u_nodes, self.patches["keys"], record=False)
            if cs is None:
                return None
            keys, slave = cs["keys"], cs["slave"]
            kc = self._stiffness(cs)
            G, C = self._gap_gradient(cs)
            n = cs["normal"]
            force = np.zeros((len(keys), self.dim))
            blocks = np.zeros((len(keys), self.dim, self.dim))
            mu = self.mu_table[self.group[slave], keys % self.n_groups]
            blocks += (mu * kc)[:, None, None] * (np.eye(self.dim)[None] - np.einsum("pi,pj->pij", n, n))
            last = self._last
            current = np.zeros(len(keys), bool)
            if last is not None:  # the evaluated contacts keep their friction force and stiffness
                where = np.searchsorted(keys, last["keys"])
                current[where] = True
                _, _, _, last_blocks = self._tangent_parts
                blocks[where] = last_blocks
                force[where] = self._friction_force
            self._revision = dict(keys=keys, gap=cs["gap"], cover=cs["cover"], kc=kc, G=G.tocsr(),
                                  B=(C @ self.P).tocsr(), force=force, blocks=blocks, current=current)
        rev = self._revision
        predicted = rev["gap"] + rev["G"] @ np.asarray(step).ravel()
        leaving = rev["current"] & (predicted > RELEASE * self.dx)
        joining = ~rev["current"] & (predicted < -self.touch) & (rev["cover"] > 0.0)
        if not leaving.any() and not joining.any():
            return None
        sign = np.where(joining, 1.0, 0.0) - np.where(leaving, 1.0, 0.0)
        dim, n_slots = self.dim, self.P.shape[1]
        G, B = rev["G"], rev["B"]
        fn = rev["kc"] * (-rev["gap"]) * sign
        df = (G.T @ fn).reshape(n_slots, dim) + (B.T @ (rev["force"] * sign[:, None]))
        dJ = self._springs(G, rev["kc"] * sign, B, rev["blocks"] * sign[:, None, None], free)
        rev["current"] = (rev["current"] & ~leaving) | joining
        self.held = np.setdiff1d(self.held, rev["keys"][leaving])  # joining ones join where they touch
        return df, dJ

    def step_limit(self, u_nodes: np.ndarray, step: np.ndarray) -> float:
        """The largest fraction (<= 1) of ``step`` after which no contact is deeper than :attr:`step_depth` cells (or
        than the deepest one at ``u_nodes``, if that is deeper)."""
        def depth(alpha):
            cs = self._contacts(u_nodes + alpha * step, record=False)
            return 0.0 if cs is None else float(np.max(-cs["gap"][cs["cover"] > 0.0], initial=0.0))

        return step_fraction(depth, self.step_depth * self.dx, rounds=10)

    def round_state(self):
        """The active set of the current :meth:`revise` rounds (hashable; None before the first round)."""
        if self._revision is None:
            return None
        return self._revision["current"].tobytes()

    def count(self) -> int:
        """How many contacts the active set holds."""
        return len(self.held)

    def signature(self) -> tuple:
        """Which contacts the last evaluation had (to tell a change of the set)."""
        return (None if self._last is None else self._last["keys"].tobytes(),)

    def accept(self, u_nodes: np.ndarray) -> None:
        """After a converged increment or step: sticking contacts keep their elastic slip, sliding ones put it on
        the cone, separated ones forget it; the positions become the next increment's start, and the next solve
        takes its patches anew, centred on the slaves where they are now."""
        self.forces(u_nodes)
        new = {}
        if self._last is not None:
            keys, dt, stuck = self._slip_state
            for j in np.flatnonzero(self._last["touching"]):
                t = dt[j]
                if not stuck[j]:
                    t = t * (self.slip / max(float(np.linalg.norm(t)), 1e-300))
                new[int(keys[j])] = t
        self.elastic = new
        self._fn_lag = {}
        if self._last is not None:
            fn_now = np.maximum(self._stiffness(self._last) * (-self._last["gap"]), 0.0)
            self._fn_lag = dict(zip(self._last["keys"][self._last["touching"]].tolist(), fn_now[self._last["touching"]].tolist()))
        self._x_last = self.X + self.P @ u_nodes
        self._held_accepted = self.held.copy()
        # the patches stay while their contacts last and their slaves stay over them: a patch taken anew changes
        # the gap by what the two patches' geometry differs (a rounded corner's normal, a curved face's sag), which
        # next to the penetrations of a stiff penalty (1e-6 cells for a body's weight) is no small change. A slave
        # that slid more than REFRESH_SPACINGS of its spacing over its patch takes a new one, centred on it
        cs = self._last
        kept = None
        if cs is not None:
            lever = cs["x"][cs["slave"]] - cs["centroid"]
            lever -= np.einsum("ki,ki->k", lever, cs["normal"])[:, None] * cs["normal"]
            lever0 = np.array([self._lever0.get(int(kk), np.zeros(self.dim)) for kk in cs["keys"]]).reshape(lever.shape)
            stays = np.linalg.norm(lever - lever0, axis=1) <= REFRESH_SPACINGS * 2.0 * self.radius[cs["slave"]]
            stays &= np.isin(cs["keys"], np.union1d(self.held, self.touching))
            kept = self._select(cs, stays)
        self.patches = kept
        cs = self._contacts(u_nodes, self.held, record=True)
        self._patches_accepted = self.patches

    def adopt(self, other: "BodyContact") -> None:
        """Take the active set of ``other``, the same scene's body contact in another solver (static.soft_penalty's
        predictor), with the patches its contacts use. The friction state (elastic slips, lagged normal forces,
        the accepted positions) stays this part's own, so friction follows this solver's path of equilibria
        (:meth:`ColliderPenalty.adopt <magsoro.mpm.newton.static_contact.ColliderPenalty.adopt>`); so does the
        penalty."""
        def patches(p):
            return None if p is None else {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in p.items()}

        self.held = other.held.copy()
        self._held_accepted = other._held_accepted.copy()
        self.touching = other.touching.copy()
        self.patches, self._patches_accepted = patches(other.patches), patches(other._patches_accepted)
        self._lever0 = {k: np.array(v, copy=True) for k, v in other._lever0.items()}
        self._last = None
        self._revision = None

    def last_contacts(self) -> dict | None:
        """The contacts of the last :meth:`forces` evaluation (keys, slave particles, gaps, normals, ...), or None."""
        return self._last

    def touching_particles(self, u_nodes: np.ndarray):
        """(slave particles, master particles) of the contacts touching at ``u_nodes``: pairs of particles of
        bodies that rest on each other (the static solver's check for free bodies)."""
        cs = self._contacts(u_nodes, record=False)
        if cs is None:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return cs["slave"][cs["row"]], self.surface[cs["master"]]
