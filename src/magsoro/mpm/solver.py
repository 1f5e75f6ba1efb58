"""The explicit MLS-MPM solver: :class:`Solver` steps a :class:`~magsoro.mpm.model.Model`'s
:class:`~magsoro.mpm.model.State` under a :class:`~magsoro.mpm.model.Control`, ``step(state_in, state_out, control,
dt)``, and owns the grid and scratch memory.

The grid is a dense block of nodes over the particles' bounding box plus a margin, re-fitted when the bodies
move near its edge, so memory and per-step grid work follow the occupied region, not the domain.
"""

import itertools
import math
import time

import numpy as np
import warp as wp

from magsoro.errors import SimulationError
from magsoro.fields.device import FieldEvaluator
from magsoro.mpm.colliders import DeviceCollider, collider_records
from magsoro.mpm.interaction import MagneticInteraction
from magsoro.mpm.kernels import make_kernels
from magsoro.mpm.kernels.contact import launch_contact_classify
from magsoro.mpm.kernels.g2p import (launch_contact_gather, launch_g2p, launch_load_params, launch_load_step,
                                     launch_remap_F, launch_remap_node_velocity, launch_remap_scatter,
                                     launch_reset_reductions)
from magsoro.mpm.kernels.grid import launch_add_grid, launch_contact_resolve, launch_grid_update
from magsoro.mpm.kernels.p2g import (launch_contact_scan, launch_contact_scatter, launch_node_displacement, launch_p2g,
                                     launch_p2g_scatter, launch_pressure_net)
from magsoro.mpm.kernels.stencil import host_bspline
from magsoro.mpm.laws.viscous import launch_viscous_update, make_viscous, viscous_struct
from magsoro.mpm.model import Control, Model, SolverSettings, State
from magsoro.mpm.runtime import (Workers, block_struct, bodies_array, contact_grid, contact_node_arrays, grid_settings,
                                 resolve_threads, threads_from_env)
from magsoro.mpm.settings import COLLIDER_MODES, FORMULATIONS, INTERACTION_MODES, VELOCITY_GRADIENTS, FUpdate, P2GFlag
from magsoro.mpm.timestep import cfl_time_step


#: Capture check windows as graphs on CPU too (Warp's CPU graphs replay the recorded launches in C++). Off: on CPU
#: the window's steps are launched one by one (see Solver.capture_refusal and docs/engine.md, "CUDA graph windows").
CPU_GRAPHS = False

#: Resident threads per streaming multiprocessor (2048 on sm_70 to sm_90): below this many particles per SM, one
#: scatter thread per particle leaves the GPU partly empty, and one per (particle, stencil node) is faster; above,
#: the extra threads only add atomic traffic (H100: walker 9,600 particles 1.12x faster, block1m 10^6 particles
#: 0.61x; benchmarks/README.md, "Scatter threads")
SPREAD_THREADS_PER_SM = 2048

#: the grid block is fitted again when it holds more than this many times the nodes a fit to the particles needs
GRID_SHRINK = 2.0


class Solver:
    """Steps a :class:`Model` forward. ``step(state_in, state_out, control, dt)`` never modifies ``state_in``."""

    def __init__(self, model: Model, settings: SolverSettings | None = None):
        self.model = model
        self.settings = settings or SolverSettings()
        st = self.settings
        if st.walls not in COLLIDER_MODES:
            raise ValueError(f"walls must be one of {sorted(COLLIDER_MODES)}, got {st.walls!r}")
        if st.velocity_gradient not in VELOCITY_GRADIENTS:
            raise ValueError(f"velocity_gradient must be 'remap' or 'grid', got {st.velocity_gradient!r}")
        if st.formulation not in FORMULATIONS:
            raise ValueError(f"formulation must be 'updated' or 'total', got {st.formulation!r}")
        if st.magnetic_interaction not in INTERACTION_MODES:
            raise ValueError(f"magnetic_interaction must be one of {INTERACTION_MODES}, got {st.magnetic_interaction!r}")
        if not isinstance(st.interaction_every, int) or st.interaction_every < 1:
            raise ValueError(f"interaction_every must be a positive integer, got {st.interaction_every!r}")
        self._total = st.formulation == "total"
        # the total-Lagrangian F update takes the velocity gradient on the reference grid directly: no remap
        self._remap = st.velocity_gradient == "remap" and not self._total
        self.k = model.kernels
        dim, dev, sc = model.dim, model.device, model.scalar
        self.dim, self.device, self.scalar = dim, dev, sc
        g = np.zeros(dim)
        gin = np.asarray(st.gravity, dtype=np.float64).ravel()
        g[: min(dim, len(gin))] = gin[:dim]
        self.gravity = self.k["vec"](*[sc(v) for v in g])
        self.org = np.zeros(dim, dtype=np.int64)
        self.shape = np.zeros(dim, dtype=np.int64)
        self.capacity = 0
        self.n_active = 0
        self.refits = 0
        self.error = wp.zeros(2, dtype=wp.int32, device=dev)
        if st.threads is not None and (not isinstance(st.threads, int) or st.threads < 1):
            raise ValueError(f"threads must be a positive integer or None (automatic), got {st.threads!r}")
        # CPU threads: each takes a contiguous range of particles, scatters into a grid of its own (thread 0 into
        # the shared one) and keeps its own bounds and top speed; the grids are summed node by node
        self.threads = resolve_threads(st.threads, dev, model.n_particles)
        #: why the threads are fewer than MAGSORO_THREADS asked for (a note for run.json), or None
        self.threads_note = threads_from_env()[1] if st.threads is None and dev.startswith("cpu") else None
        # contact: two velocity fields per node (magsoro.mpm.kernels.contact). Its scan and transfers index the particle
        # arrays globally, so a CPU step with contact runs on one thread. The updated form resolves contact in its
        # own grid update; the total form in a pass over a grid of the current configuration (_contact_pass).
        groups = int(model.host["contact_group"].max()) + 1
        contact_on = st.contact is not None and st.contact.active(groups)
        #: two velocity fields per node on the step's grid (contact between contact groups, or within one, is
        #: resolved). In the total form they only keep the contact groups apart on the reference grid (classified
        #: once, never resolved there); contact itself acts in _contact_pass
        self.contact_active = contact_on
        self._tcontact = contact_on and self._total
        if contact_on:
            fr = st.contact.friction
            if fr.shape[0] < groups:
                raise ValueError(f"contact friction table is {fr.shape[0]} x {fr.shape[0]}, the model has {groups} contact groups")
            self._contact_friction = wp.array(fr[:groups, :groups].ravel().astype(model.np_scalar), dtype=sc, device=dev)
            self._contact_groups = groups
        if self.contact_active:
            self.threads = 1
            self.k = make_kernels(dim, sc, contact=True, plane=model.plane)
        self._tc = None  # the total form's contact grid (allocated at the first pass)
        self._fields_per_node = 2 if self.contact_active else 1
        cuts = np.linspace(0, model.n_particles, self.threads + 1).round().astype(int)
        self._ranges = [(int(cuts[t]), int(cuts[t + 1])) for t in range(self.threads)]
        self._workers = Workers(self.threads - 1) if self.threads > 1 else None
        self._thread_bounds = [wp.zeros(2 * dim, dtype=sc, device=dev) for _ in range(self.threads)]
        self._thread_speed = [wp.zeros(1, dtype=sc, device=dev) for _ in range(self.threads)]
        # On CPU the host reads and resets the small per-step arrays (bounds, top speed, error flags) through numpy
        # views of the same memory, and zeroes the grid through views: a Warp call costs more than the work here.
        self._on_cpu = wp.get_device(dev).is_cpu
        #: the scatters (p2g, the remap's) with one thread per (particle, stencil node) instead of per particle: by
        #: default on a GPU that one thread per particle leaves part empty (docs/engine.md, "Scatter threads"); set
        #: before the first step
        self.spread_scatter = (not self._on_cpu and
                               model.n_particles < SPREAD_THREADS_PER_SM * wp.get_device(dev).sm_count)
        if self._on_cpu:
            self._bounds_np = [tb.numpy() for tb in self._thread_bounds]
            self._speed_np = [ts.numpy() for ts in self._thread_speed]
            self._error_np = self.error.numpy()
        self._grid_np = []  # CPU: numpy views of every grid array a step zeroes (set with the grid block)
        self._safe_lo = self._safe_hi = None  # box inside which every particle fits the grid block and the domain
        self._thread_grids = []  # (grid_p, grid_m) of threads 1.. (allocated with the grid block)
        self._thread_grid_views = []
        self._bounds_valid = False
        self._checked_bounds = None  # (lo, hi) of the particles at the last check
        self._checked_speed = 0.0  # top particle speed of the last check (m/s)
        self._window_open = False
        self._window_dt = 0.0  # largest dt of the open window
        self.host_reads = 0  # host reads of device results by the step loop (checks, bounds); see close_window
        self._evaluator = None
        self._evaluator_key = None
        n = model.n_particles
        self.B_particle = wp.zeros(n, dtype=self.k["v3"], device=dev)
        self.grad_B_particle = wp.zeros(n, dtype=self.k["m3"], device=dev)
        # p2g -> p2g_scatter with the scatter threads (allocated by the first launch set that spreads; else empty)
        self.particle_affine = wp.zeros(0, dtype=self.k["mat"], device=dev)
        self.particle_momentum = wp.zeros(0, dtype=self.k["vec"], device=dev)
        # the bodies' own field (None: off, or no magnetised particle), refreshed every interaction_every steps
        self.interaction = None
        if st.magnetic_interaction == "dipole":
            inter = MagneticInteraction(model, st.depth)
            self.interaction = inter if inter.active else None
        self._interaction_step = None  # the step the bodies' field was last refreshed at
        self._collider_array = None
        self._collider_host = None
        # the momentum each rigid collider took from the grid since the last read (N s, 3 per collider):
        # Simulation.collider_forces
        self.collider_impulse = wp.zeros(3, dtype=wp.float64, device=dev)
        self._launch_sets = {}
        self._grid_version = 0
        # what a step takes from the host (stencil Step: dt, damping factor, uniform field), one element on the
        # device that every recorded launch reads; written before a plain step when it changes (CPU: through a
        # numpy view) and by the load_step kernel inside a check window (run_window)
        self._step_values = wp.zeros(1, dtype=self.k["Step"], device=dev)
        self._step_np = self._step_values.numpy() if self._on_cpu else None
        self._step_written = None  # (uniform field, dt, damping) last written by a plain step
        # CPU: the small per-step host work (grid zeroing) goes through numpy views, except while a graph captures
        self._host_ops = self._on_cpu
        # check windows run from drive tables (run_window): the table, its cursor, the recorded load_step launch,
        # the captured graphs (cleared with the launch sets they replay) and counters
        self._drive = None
        self._graphs = {}
        self._launch_serials = itertools.count()
        self.graph_capture = None  # None: automatic (capture on CUDA; on CPU when CPU_GRAPHS); True / False: force
        self.graph_windows = 0  # windows run from drive tables
        self.graph_captures = 0  # graphs captured
        self.graph_replays = 0  # graph launches
        self.capture_failure = None  # why a capture failed (then graph_capture is False)
        self._grid_views = []
        self.phase_times = None
        # total Lagrangian: the reference positions the kernels take the grid weights at
        self._X0 = wp.array(model.host["positions"].astype(model.np_scalar), dtype=self.k["vec"], device=dev) if self._total else None
        #: total Lagrangian: the held-node mask of the (fixed) grid block (int32 per node, 1 held; set with the
        #: block, :meth:`_majority_held_nodes`); None in the updated form, whose clamps mark grid_clamp every step
        self.held_mask = None

    # -- states -------------------------------------------------------------------------------------------
    def new_state(self, velocity=None) -> State:
        """A state at the reference configuration (F = I), or at the model's initial displacement and its F, with
        optional initial velocities (N, dim) m/s."""
        m, k = self.model, self.k
        n, dim = m.n_particles, m.dim
        v = np.zeros((n, dim)) if velocity is None else np.broadcast_to(np.asarray(velocity, dtype=np.float64), (n, dim))
        eye = np.broadcast_to(np.eye(dim), (n, dim, dim))
        x0 = m.host["positions"]
        if "initial_displacement" in m.host:  # a body that starts displaced and strained (Model initial_displacement)
            x0 = x0 + m.host["initial_displacement"]
        eye = m.host.get("initial_deformation", eye)
        s = m.np_scalar
        return State(
            x=wp.array(x0.astype(s), dtype=k["vec"], device=m.device),
            v=wp.array(np.ascontiguousarray(v, dtype=s), dtype=k["vec"], device=m.device),
            C=wp.zeros(n, dtype=k["mat"], device=m.device),
            F=wp.array(np.ascontiguousarray(eye, dtype=s), dtype=k["mat"], device=m.device),
            H=wp.zeros((n, 1 + m.prony_terms), dtype=m.H_type, device=m.device) if m.viscous else None,
        )

    # -- grid block -----------------------------------------------------------------------------------------
    def _node_range(self, lo, hi):
        """Global node index range [first, last] touched by particles inside [lo, hi] (quadratic stencil)."""
        m = self.model
        glo = (np.asarray(lo) - m.domain_lo) / m.dx
        ghi = (np.asarray(hi) - m.domain_lo) / m.dx
        return np.floor(glo - 0.5).astype(np.int64), np.floor(ghi - 0.5).astype(np.int64) + 2

    def _fits(self, lo, hi) -> bool:
        if self.n_active == 0:
            return False
        first, last = self._node_range(lo, hi)
        # one spare node on each side: the kernels locate particles in the run's precision (float32 by default),
        # which can round a particle on the block edge one node further out than this float64 test
        return bool(np.all(first >= self.org + 1) and np.all(last < self.org + self.shape - 1))

    def _oversized(self, lo, hi) -> bool:
        """Whether the grid block holds more than GRID_SHRINK times the nodes a fit to the particle box ``lo``-``hi``
        would: a robot that folded up and flattened again, or the room a fast phase's check windows asked for,
        kept while the particles stay inside, and every grid phase pays for its nodes. Then the block is fitted
        again (the nodes keep their global positions, so the particles see the same grid)."""
        if self.n_active == 0:
            return False
        first, last = self._node_range(lo, hi)
        need = int(np.prod(last - first + 1 + 2 * self.settings.grid_margin))
        return self.n_active > GRID_SHRINK * need

    def _refit(self, lo, hi) -> None:
        first, last = self._node_range(lo, hi)
        margin = self.settings.grid_margin
        self.org = first - margin
        self.shape = last - first + 1 + 2 * margin
        need = int(np.prod(self.shape))
        if need > self.capacity:
            cap = int(need * 1.3) + 64  # slack so a slowly growing body does not reallocate every refit
            k, dev, sc = self.k, self.device, self.scalar
            nf = self._fields_per_node  # slots per node: one per velocity field
            self.grid_p = wp.zeros(nf * cap, dtype=k["vec"], device=dev)
            self.grid_v = wp.zeros(nf * cap, dtype=k["vec"], device=dev)
            self.grid_m = wp.zeros(nf * cap, dtype=sc, device=dev)
            self.grid_clamp = wp.zeros(cap, dtype=wp.int32, device=dev)
            # total Lagrangian: mass-weighted node displacements (where walls and colliders act), per field
            self.grid_u = wp.zeros(nf * cap if self._total else 1, dtype=k["vec"], device=dev)
            if self.contact_active:
                self._ct = contact_node_arrays(self.model, cap, self.settings.contact.self_contact)
            self._thread_grids = [
                (wp.zeros(cap, dtype=k["vec"], device=dev), wp.zeros(cap, dtype=sc, device=dev)) for _ in range(self.threads - 1)
            ]
            self.capacity = cap
        self.n_active = need
        self.refits += 1
        self._grid_version += 1
        self._drop_launches()
        slots = self._fields_per_node * need
        self._grid_views = [self.grid_p[:slots], self.grid_m[:slots], self.grid_clamp[:need]]
        if self._total:
            self._grid_views += [self.grid_u[:slots]]
        if self.contact_active:
            # zeroed each step (the views after the first three); the group bounds are reset apart
            self._grid_views += [self._ct["grad"][: 2 * need]]
            if self.settings.contact.self_contact:
                self._grid_views += [self._ct["moments"][: need * (1 + self.dim + self.dim * self.dim)]]
            self._ct_group_views = [self._ct["gmin"][:need], self._ct["gmax"][:need]]
        self._thread_grid_views = [(gp[:need], gm[:need]) for gp, gm in self._thread_grids]
        if self._on_cpu:
            self._grid_np = [v.numpy() for v in self._grid_views] + [a.numpy() for pair in self._thread_grid_views for a in pair]
        if self._total:
            self.held_mask = wp.array(self._majority_held_nodes(), dtype=wp.int32, device=self.device)
        # The box in which a particle needs neither a refit nor a domain check: the inverse of _fits (first node
        # >= org + 1, last node < org + shape - 1) intersected with the domain. Particle bounds inside it skip
        # the checks of the next step.
        m = self.model
        fit_lo = m.domain_lo + (self.org + 1.5) * m.dx
        fit_hi = m.domain_lo + (self.org + self.shape - 2.5) * m.dx
        eps = 1e-9 * m.dx  # round-off of the two forms of the same test
        self._safe_lo = np.maximum(fit_lo, m.domain_lo) + eps
        self._safe_hi = np.minimum(fit_hi, m.domain_hi) - eps
        if self._tcontact:
            self._classify_reference()

    def _classify_reference(self) -> None:
        """Total form with contact: split the reference grid's nodes where two contact groups meet, once per grid
        block, so that the groups' velocity fields stay apart there (bodies near each other in the reference
        configuration would otherwise move as one)."""
        m, dev = self.model, self.device
        for v, fill in zip(self._ct_group_views, (2**31 - 1, -1)):
            v.fill_(fill)
        scan, classify = self._classify_inputs(self._X0, block_struct(self.model, self.org, self.shape), 0, self._ct)
        launch_contact_scan(self.k, m.n_particles, device=dev, **scan)
        launch_contact_classify(self.k, self.n_active, device=dev, **classify)

    def _classify_inputs(self, x, block, fold: int, arrays: dict):
        """Arguments of the contact scan's launcher (particles at ``x`` on ``block``) and of the node
        classification's, over the node arrays ``arrays`` (:func:`contact_node_arrays`)."""
        m, c = self.model, self.settings.contact
        scan = dict(x=x, X=m.X0, mass=m.mass, group=m.contact_group, block=block, fold=fold, gmin=arrays["gmin"],
                    gmax=arrays["gmax"], moments=arrays["moments"])
        classify = dict(gmin=arrays["gmin"], gmax=arrays["gmax"], moments=arrays["moments"], fold=fold,
                        spread2=self.scalar((c.fold_spread * m.dx) ** 2), friction=self._contact_friction,
                        n_groups=self._contact_groups, split=arrays["split"], xbar=arrays["xbar"], axis=arrays["axis"],
                        mu=arrays["mu"])
        return scan, classify

    def _contact_grid(self, arrays: dict, n_nodes: int, gap: float) -> wp.array:
        """The kernels' ContactGrid over the node arrays ``arrays`` of a grid of ``n_nodes`` nodes."""
        return contact_grid(self.model, active=1, n_nodes=n_nodes, gap=self.scalar(gap), group=self.model.contact_group,
                            X=self.model.X0, split=arrays["split"], gmin=arrays["gmin"], xbar=arrays["xbar"],
                            axis=arrays["axis"], mu=arrays["mu"], grad_m=arrays["grad"])

    def _majority_held_nodes(self) -> np.ndarray:
        """Held-node mask of the grid block for the total-Lagrangian form (flat, int32): a node is held when at
        least half of the mass the reference particles give it comes from clamped particles. For a clamped region
        whose face lies on a lattice line this holds the nodes up to and including the face, where the
        updated-Lagrangian rule (every node a clamped particle touches) holds one more layer. A held node's value
        is the clamp code (Model ``clamped``) that gives it the most mass: 1 held in place, 2 + row on a path."""
        m, dim = self.model, self.dim
        X = m.host["positions"]
        mass = m.host["mass"]
        held_p = m.host["clamped"]
        codes = m.host["clamp_code"]
        n_codes = int(codes.max()) + 1
        by_code = np.zeros((max(n_codes - 1, 0), int(np.prod(self.shape)))) if n_codes > 2 else None
        base, _, w = host_bspline(X, m.domain_lo, m.dx)
        n_nodes = int(np.prod(self.shape))
        total = np.zeros(n_nodes)
        clamped = np.zeros(n_nodes)
        local = base - self.org
        for q in range(3**dim):
            o = [(q // 3 ** (dim - 1 - a)) % 3 for a in range(dim)]
            weight = mass.copy()
            flat = np.zeros(len(X), dtype=np.int64)
            for a in range(dim):
                weight = weight * w[o[a]][:, a]
                flat = flat * int(self.shape[a]) + (local[:, a] + o[a])
            total += np.bincount(flat, weights=weight, minlength=n_nodes)
            clamped += np.bincount(flat[held_p], weights=weight[held_p], minlength=n_nodes)
            if by_code is not None:
                for c in range(1, n_codes):
                    mine = codes == c
                    by_code[c - 1] += np.bincount(flat[mine], weights=weight[mine], minlength=n_nodes)
        held = ((total > 0) & (clamped >= (0.5 - 1e-9) * total)).astype(np.int32)
        if by_code is not None:  # moving clamps: each held node follows the clamp that gives it the most mass
            held = np.where(held != 0, 1 + np.argmax(by_code, axis=0), 0).astype(np.int32)
        return held

    def enable_phase_timing(self, on: bool = True) -> None:
        """Time the phases of each step (p2g, grid, g2p, other) into ``phase_times`` (seconds, summed).
        Synchronises the device between phases, so use it for profiling only."""
        self.phase_times = {"p2g": 0.0, "grid": 0.0, "g2p": 0.0, "other": 0.0} if on else None

    def _phase(self, name: str, since: float) -> float:
        if self.phase_times is None:
            return since
        wp.synchronize_device(self.device)
        now = time.perf_counter()
        self.phase_times[name] += now - since
        return now

    def _record_launches(self, state_in: State, state_out: State, control: Control, has_gradient: bool) -> dict:
        """Pack every kernel's arguments once (Warp's recorded launches) for this pair of states; a step then only
        updates the values that change. Packing all arguments on each launch costs more than the kernels
        themselves for small robots. Particle kernels get one launch per thread, over that thread's slice, with
        argument structs of the thread's slices (:mod:`magsoro.mpm.kernels.stencil`)."""
        m, k, st, dev, sc = self.model, self.k, self.settings, self.device, self.scalar
        n_act = self.n_active
        block = block_struct(self.model, self.org, self.shape)
        org = k["ivec"](*[int(o) for o in self.org])
        grid_p = [self.grid_p] + [gp for gp, _ in self._thread_grids]
        grid_m = [self.grid_m] + [gm for _, gm in self._thread_grids]
        x_grid = self._X0 if self._total else state_in.x  # the positions the grid weights are taken at
        if self.collider_impulse.shape[0] < 3 * len(control.colliders):
            self.collider_impulse = wp.zeros(3 * len(control.colliders), dtype=wp.float64, device=dev)
        gs = grid_settings(m, st, self.gravity, self._collider_array, len(control.colliders), 0.0, step=self._step_values,
                           impulse=self.collider_impulse)
        ct = contact_grid(m)
        if self.contact_active:  # the total form's reference grid keeps the fields apart but never resolves (gap 0)
            ct = self._contact_grid(self._ct, n_act, 0.0 if self._total else st.contact.gap)
        threads = []  # per thread: its slice of the particle arrays and its argument structs
        for t, (a, b) in enumerate(self._ranges):
            cut = (lambda arr, a=a, b=b: arr[a:b]) if self.threads > 1 else (lambda arr: arr)
            applied = k["Applied"]()
            applied.has_gradient = 1 if has_gradient else 0
            applied.B, applied.grad_B = cut(self.B_particle), cut(self.grad_B_particle)
            grid = k["GridArrays"]()
            grid.p, grid.m, grid.clamp = grid_p[t], grid_m[t], self.grid_clamp
            out = k["Particles"]()
            out.x, out.v, out.C, out.F = cut(state_out.x), cut(state_out.v), cut(state_out.C), cut(state_out.F)
            src = k["Particles"]()  # what p2g reads: positions where the weights are taken, v, C and F of state_in
            src.x, src.v, src.C, src.F = cut(x_grid), cut(state_in.v), cut(state_in.C), cut(state_in.F)
            src.x_now = cut(state_in.x)  # the current positions (the axisymmetric hoop stretch)
            checks = k["Checks"]()
            checks.bounds, checks.max_speed, checks.error = self._thread_bounds[t], self._thread_speed[t], self.error
            threads.append(dict(
                t=t, cut=cut, n=b - a, applied=applied, bodies=bodies_array(m, cut, step=self._step_values),
                grid=wp.array([grid], dtype=k["GridArrays"], device=dev),
                out=wp.array([out], dtype=k["Particles"], device=dev),
                src=wp.array([src], dtype=k["Particles"], device=dev),
                checks=wp.array([checks], dtype=k["Checks"], device=dev),
            ))

        def particles(launcher, args_of, per_thread=1):
            """One recorded launch per thread, over its slice; ``args_of(thread, cut)`` gives the launcher's arguments."""
            return [launcher(k, th["n"] * per_thread, device=dev, record=True, **args_of(th, th["cut"])) for th in threads]

        spread = 1 if self.spread_scatter else 0
        f_update = FUpdate.TOTAL if self._total else (FUpdate.FROM_REMAP if self._remap else FUpdate.FROM_GRID)
        if spread and f_update == FUpdate.FROM_REMAP:
            f_update = FUpdate.REMAP_APART  # the remap's scatter in remap_scatter
        p2g_flags = (P2GFlag.TOTAL if self._total else 0) | (P2GFlag.APART if spread else 0)
        if spread and self.particle_affine.shape[0] != m.n_particles:
            self.particle_affine = wp.zeros(m.n_particles, dtype=k["mat"], device=dev)
            self.particle_momentum = wp.zeros(m.n_particles, dtype=k["vec"], device=dev)
        spread_threads = 3**self.dim if spread else 1

        rec = dict(device=dev, record=True)
        L = {
            # with the scatter threads (docs/engine.md, "Scatter threads") p2g stores each particle's affine matrix
            # and momentum, and p2g_scatter spreads them with one thread per (particle, node)
            "p2g": particles(launch_p2g, lambda th, cut: dict(
                src=th["src"], bodies=th["bodies"], applied=th["applied"], block=block, dt=sc(0.0), grid=th["grid"],
                error=self.error, flags=int(p2g_flags), contact=ct, viscous=viscous_struct(m, state_in.H, cut),
                # read only when spread; otherwise empty, and not sliced per thread
                affine=cut(self.particle_affine) if spread else self.particle_affine,
                momentum=cut(self.particle_momentum) if spread else self.particle_momentum)),
            "p2g_scatter": particles(launch_p2g_scatter, lambda th, cut: dict(
                x=cut(x_grid), bodies=th["bodies"], block=block, affine=cut(self.particle_affine),
                momentum=cut(self.particle_momentum), grid=th["grid"], contact=ct, spread=spread),
                spread_threads) if spread else [],
            "grid_update": launch_grid_update(
                k, n_act, grid_p=self.grid_p, grid_m=self.grid_m,
                grid_clamp=self.held_mask if self._total else self.grid_clamp, org=org, shape=block.shape, settings=gs,
                grid_v=self.grid_v, contact=ct, grid_u=self.grid_u, **rec),
            "g2p": particles(launch_g2p, lambda th, cut: dict(
                grid_v=self.grid_v, bodies=th["bodies"], block=block, dt=sc(0.0), x_in=cut(x_grid), x_cur=cut(state_in.x),
                F_in=cut(state_in.F), out=th["out"], checks=th["checks"], f_update=int(f_update), grid_r=grid_p[th["t"]],
                contact=ct)),
            "sum_mass": [launch_add_grid(k, n_act, dst_p=self.grid_p, src_p=grid_p[t], dst_m=self.grid_m, src_m=grid_m[t],
                                         with_mass=1, **rec) for t in range(1, self.threads)],
            "sum_momentum": [launch_add_grid(k, n_act, dst_p=self.grid_p, src_p=grid_p[t], dst_m=self.grid_m,
                                             src_m=grid_m[t], with_mass=0, **rec) for t in range(1, self.threads)],
            # keep the states' arrays and the argument structs alive: the set is found again by the arrays' ids
            "_arrays": (state_in.x, state_in.v, state_in.C, state_in.F, state_out.x, state_out.v, state_out.C, state_out.F,
                        state_in.H, state_out.H),
            "_threads": threads,
            "_grid_settings": gs,  # keeps the collider array it points to alive
            "_serial": next(self._launch_serials),  # names the set in the graph cache (ids can be reused)
            "_contact_grid": ct,  # referenced by pointer from the recorded launches
        }
        if m.viscous:  # the Prony internal stresses of state_out from its new F (magsoro.mpm.laws.viscous)
            L["viscous"] = [launch_viscous_update(
                make_viscous(m.dim, m.scalar, m.plane), m.n_particles, F=state_out.F, bodies=bodies_array(m, step=self._step_values),
                viscous=viscous_struct(m, state_in.H), H_out=state_out.H, dt=sc(0.0), **rec)]
        if m.closed_pressures:  # the closed cavities' net pressure force, taken back in p2g
            L["pressure_net"] = launch_pressure_net(k, m.n_particles, bodies=bodies_array(m, step=self._step_values),
                                                    F=state_in.F, net=m.pressure_net, **rec)
        if self._total:
            L["node_displacement"] = launch_node_displacement(k, m.n_particles, X=self._X0, x=state_in.x, mass=m.mass,
                                                              block=block, grid_u=self.grid_u, contact=ct, **rec)
        if self.contact_active and not self._total:
            scan, classify = self._classify_inputs(state_in.x, block, 1 if st.contact.self_contact else 0, self._ct)
            L["contact"] = [launch_contact_scan(k, m.n_particles, **scan, **rec),
                            launch_contact_classify(k, n_act, **classify, **rec)]
        if self._remap:
            # second half of the remap: g2p has scattered the new affine velocities into grid_p (free after the
            # grid update); node velocities go to grid_v (free after g2p), and F is gathered from them
            L["remap_scatter"] = particles(launch_remap_scatter, lambda th, cut: dict(
                x=cut(state_in.x), bodies=th["bodies"], block=block, out=th["out"], grid_r=grid_p[th["t"]], contact=ct,
                spread=spread), spread_threads) if spread else []
            L["remap_nodes"] = launch_remap_node_velocity(
                k, self._fields_per_node * n_act, grid_r=self.grid_p, grid_m=self.grid_m, grid_clamp=self.grid_clamp,
                grid_w=self.grid_v, n_nodes=n_act, block=block, axis=int(m.plane == "axisymmetric"), **rec)
            L["remap_F"] = particles(launch_remap_F, lambda th, cut: dict(
                x=cut(state_in.x), bodies=th["bodies"], block=block, dt=sc(0.0), grid_w=self.grid_v, F_in=cut(state_in.F),
                F_out=cut(state_out.F), error=self.error, contact=ct))
        return L

    def _launch_set(self, state_in: State, state_out: State, control: Control, has_gradient: bool) -> dict:
        arrays = (state_in.x, state_in.v, state_in.C, state_in.F, state_out.x, state_out.v, state_out.C, state_out.F,
                  state_in.H, state_out.H)
        key = (len(control.colliders), has_gradient) + tuple(id(a) for a in arrays)
        L = self._launch_sets.get(key)
        if L is None:
            if len(self._launch_sets) >= 8:  # states made afresh each call: do not keep their launches forever
                self._drop_launches()
            L = self._record_launches(state_in, state_out, control, has_gradient)
            self._launch_sets[key] = L
        return L

    def _parallel(self, launches) -> None:
        """Run one launch per thread: the calling thread takes the first (Warp releases the GIL in CPU kernels)."""
        if len(launches) == 1:
            launches[0].launch()
        else:
            self._workers.run(launches)

    def forget_bounds(self) -> None:
        """Drop the particle bounds of the last check (the caller went back to an earlier state)."""
        self._bounds_valid = False
        self._window_open = False

    def grid_info(self) -> dict:
        return {"origin": self.org.tolist(), "shape": self.shape.tolist(), "nodes": self.n_active, "capacity": self.capacity, "refits": self.refits}

    def _particle_bounds(self, state: State):
        """Bounds of the particles the next step starts from: those of the last check (no read), or, after a
        rollback or at the start, read from the state (the reference positions in the total form)."""
        if self._bounds_valid:
            return self._checked_bounds
        if not self._total:
            self.host_reads += 1
        x = self.model.host["positions"] if self._total else state.x.numpy()  # what the grid block is fitted to
        return x.min(axis=0).astype(np.float64), x.max(axis=0).astype(np.float64)

    # -- control --------------------------------------------------------------------------------------------
    @property
    def step_kernels(self) -> dict:
        """The kernel table the steps launch (:func:`magsoro.mpm.kernels.make_kernels`): the contact variant, with
        two velocity fields per node, when contact between groups (or within one) is on."""
        return self.k

    def reference_contact_grid(self):
        """The total form's reference grid split by contact group (after :meth:`check_and_fit`): the kernels'
        ContactGrid argument (two fields at a node where two groups that may separate meet, never resolved), and on
        the host the node classes and each node's smallest group, over the grid block's nodes. None without contact
        between groups or in the updated form."""
        if not self._tcontact:
            return None
        n_act = self.n_active
        ct = self._contact_grid(self._ct, n_act, 0.0)
        return ct, self._ct["split"].numpy()[:n_act].copy(), self._ct["gmin"].numpy()[:n_act].copy()

    def field_evaluator(self, control: Control) -> FieldEvaluator:
        """The device evaluator of ``control``'s field sources (made again when the control or its sources change)."""
        key = id(control), tuple(id(s) for s in control.sources)
        if self._evaluator_key != key:
            self._evaluator = FieldEvaluator(control.sources, self.dim, self.scalar, self.device, self.settings.plane_z)
            self._evaluator_key = key
        return self._evaluator

    def stable_dt(self, control: Control | None = None, max_speed: float = 0.0, field_magnitude: float | None = None) -> float:
        """CFL bound dt = cfl dx / (c + |v|max), with c the elastic (and magnetic) wave speed."""
        if field_magnitude is None:
            field_magnitude = self.field_magnitude(control) if control is not None else 0.0
        c = self.model.wave_speed(field_magnitude)
        return cfl_time_step(self.settings.cfl, self.model.dx, c, max_speed)

    def field_magnitude(self, control: Control, t: float = 0.0) -> float:
        """Largest |B| (T) the sources give at the reference particle positions (uniform profiles: their peak)."""
        pts = np.zeros((self.model.n_particles, 3))
        pts[:, : self.dim] = self.model.host["positions"]
        if self.dim == 2:
            pts[:, 2] = self.settings.plane_z
        total = 0.0
        for s in control.sources:
            for e in s.sources():
                total += e.max_magnitude(pts, t)
        if self.interaction is not None:
            # the bodies' own field: about mu0 M = |Br| inside a magnet, up to twice that between two in contact
            total += 2.0 * float(np.max(np.linalg.norm(self.model.host["remanence"], axis=1)))
        return total

    def last_max_speed(self) -> float:
        """Top particle speed (m/s) of the last check (the last checked step, or the whole last window)."""
        return self._checked_speed

    # -- stepping -------------------------------------------------------------------------------------------
    def step(self, state_in: State, state_out: State, control: Control, dt: float, check: bool = True,
             reach: float = 0.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out``. Raises SimulationError on a bad state.

        Phases (docs/engine.md, "Per step"): check the particles against the grid block and the domain; evaluate
        the drives (fields, colliders, the stimuli of eigenstrain materials) at t; scatter (contact scan, p2g, node
        displacements); node velocities; gather (g2p and the remap); read the error flags.

        ``check=False``: a step inside a check window (:meth:`open_window`, :meth:`close_window`), no host read;
        flags, bounds and top speed accumulate on the device. A window's first step fits the grid block to the
        particles grown by ``reach`` (m, their travel in the window; updated form). Checked: a window of one."""
        t = state_in.time
        tick = time.perf_counter() if self.phase_times is not None else 0.0
        if check or not self._window_open:
            self.check_and_fit(state_in, 0.0 if check or self._total else reach)
            self.open_window()
        b0, has_gradient = self._particle_fields(control, state_in)
        self._update_colliders(control, t)
        self._update_drives(t, dt)
        L = self._launch_set(state_in, state_out, control, has_gradient)
        self._set_step_values(b0, dt, t)
        self._clear_grid()
        tick = self._phase("other", tick)
        self._scatter(L)
        tick = self._phase("p2g", tick)
        self._update_grid(L)
        tick = self._phase("grid", tick)
        self._gather(L)
        if self._tcontact:
            self._contact_pass(state_in, state_out, dt)
        tick = self._phase("g2p", tick)
        state_out.time = t + dt
        state_out.step = state_in.step + 1
        self._window_dt = max(self._window_dt, dt)
        if check:
            err = self._read_checks()
            self._phase("other", tick)
            self._raise_on_error(err, state_in)
            self._check_motion(state_in, dt)

    def _update_drives(self, t: float, dt: float) -> None:
        """The model's drives over the step from ``t``: the stimuli of eigenstrain materials and the pressures at
        t, the moving clamps' velocities over [t, t + dt]."""
        if self.model.stimuli:
            self.model.update_stimuli(t)
        if self.model.pressures:
            self.model.update_pressures(t)
        if self.model.clamp_paths:
            self.model.update_clamps(t, dt)

    # -- check windows ----------------------------------------------------------------------------------------
    def open_window(self) -> None:
        """Start a check window: zero the error flags and the particle-bound and top-speed reductions, which the
        window's steps then accumulate on the device (bounds over every state of the window, the top speed of
        all its steps)."""
        if self._on_cpu:
            self._error_np.fill(0)
            for b in self._bounds_np:
                b[: self.dim] = 1e30
                b[self.dim :] = -1e30
            for ts in self._speed_np:
                ts[0] = 0.0
        else:
            self.error.zero_()
            for t in range(self.threads):
                launch_reset_reductions(self.k, bounds=self._thread_bounds[t], max_speed=self._thread_speed[t],
                                        big=self.scalar(1e30), device=self.device)
        self._window_open = True
        self._window_dt = 0.0

    def close_window(self) -> str | None:
        """End a check window with one host read of its flags, bounds and top speed. None when every step of it
        passed every check a checked step makes: no flag (every particle inside the grid block, finite, det F >
        0), every particle inside the domain at every state and none faster than a cell per step; the next step
        then refits the block if the particles came near its edge. Otherwise the reason, and the caller goes back
        to the window's first state and runs the window again with checked steps, which refit where a particle
        would leave the block, or stop at the exact step with the error."""
        err = self._read_checks()
        self._window_open = False
        if err[0] or err[1]:
            self._bounds_valid = False
            return "a particle left the grid block" if err[0] and not err[1] else "the state became invalid"
        lo, hi = self._checked_bounds
        m = self.model
        if np.any(lo < m.domain_lo) or np.any(hi > m.domain_hi):
            self._bounds_valid = False
            return "a particle left the domain"
        if self._moved_cells(self._window_dt) > 1.0:
            self._bounds_valid = False
            return "a particle moved more than a cell in one step"
        return None

    # -- check windows from drive tables (CUDA graphs) ----------------------------------------------------------
    def _drop_launches(self) -> None:
        """Forget the recorded launches (grid block refitted, collider array reallocated, too many state pairs) and
        the graphs that replay them."""
        self._launch_sets.clear()
        self._graphs.clear()

    def start_window(self, state: State, reach: float = 0.0) -> None:
        """Start a check window at ``state`` for :meth:`run_window`: the checks and the refit a window's first step
        makes (:meth:`step`; ``reach`` as there), then :meth:`open_window`."""
        self.check_and_fit(state, 0.0 if self._total else reach)
        self.open_window()

    def graph_refusal(self, control: Control) -> str | None:
        """Why the steps of this run cannot go through :meth:`run_window` (a window's values prepared on the host
        once, the steps launched, or replayed as a graph, without the host), so not into a CUDA graph either;
        None when they can. Each reason is a part of a step that needs the host at every step."""
        if self.interaction is not None:
            return "the magnetic interaction refreshes the bodies' field on the host (an FFT) every interaction_every steps"
        if self.model.stimuli:
            return "stimulus eigenstrain: the stimulus tables are set on the host at every step"
        if self.model.pressure_ramps:
            return "a pressure ramp: the pressures are set on the host at every step"
        if self.model.clamp_paths:
            return "a moving clamp: its velocity over the step is set on the host at every step"
        if self._tcontact:
            return "the total form with contact fits its contact grid to the positions on the host at every step"
        if self.phase_times is not None:
            return "phase timing synchronises the device between the phases of every step"
        return None

    def capture_refusal(self) -> str | None:
        """Why :meth:`run_window` launches the steps one by one instead of capturing them as a graph (None: it
        captures). Automatic (``graph_capture`` None): capture on CUDA; on CPU the launches run one by one (a CPU
        graph replays them no faster here, see CPU_GRAPHS)."""
        if self.capture_failure is not None:
            return self.capture_failure
        if self.graph_capture is False:
            return "turned off (Solver.graph_capture = False)"
        if self.threads > 1:
            return f"{self.threads} CPU threads: a step hands work to helper threads, which a graph does not record"
        if self._on_cpu and self.graph_capture is None and not CPU_GRAPHS:
            return "on CPU the window's steps are launched one by one"
        return None

    def run_window(self, state_a: State, state_b: State, control: Control, dts, tick=None) -> State:
        """Run steps of ``dts`` (s each) from ``state_a`` inside a window opened by :meth:`start_window`, alternating
        between the two states, and return the one holding the last step's result (``state_b`` for an odd count;
        the other holds the step before, as after plain steps). Needs :meth:`graph_refusal` None.

        The host fills the window's drive table once (per step k: dt_k, exp(-c dt_k), the uniform field at t_k and,
        when a collider moves, the colliders' states at t_k in the drive's collider path) and copies it to the
        device; every step then runs the same launches: ``load_step`` takes the next row into the Step and the
        collider array the kernels read,
        then the step's phases. Captured (:meth:`capture_refusal` None), the steps become graphs of 2^j steps,
        captured once per size, pair of states, grid block and drive table, and replayed; else they are launched
        one by one. Same kernels, same values: the trajectory of :meth:`step` to the bit. ``tick()`` (optional) after
        each step launched one by one and each graph replayed: a heartbeat (the states are not readable then)."""
        n = len(dts)
        if n == 0:
            return state_a
        times = [state_a.time]
        for dt in dts:
            times.append(times[-1] + dt)
        step0 = state_a.step
        self._update_colliders(control, times[0])
        gradient = self.field_evaluator(control).has_gradient
        L = (self._launch_set(state_a, state_b, control, gradient), self._launch_set(state_b, state_a, control, gradient))
        moving = self._fill_drive(control, dts, times)
        F = (self._window_fields(state_a), self._window_fields(state_b))
        # from here the device's Step and collider array hold window rows: a plain step writes its own again
        self._step_written = None
        if moving:
            self._collider_host = None
        load = self._drive["launch"]
        if self.capture_refusal() is None:
            self._replay(L, load, n, tick, F)
        else:
            for k in range(n):
                self._window_step(L[k % 2], load, F[k % 2])
                if tick is not None:
                    tick()
        self.graph_windows += 1
        if moving:  # the collider array now holds the last step's
            self._collider_host = collider_records(control.colliders, times[n - 1])
        self._window_dt = max(self._window_dt, max(dts))
        states = (state_a, state_b)
        for k in (n - 1, n):
            states[k % 2].time, states[k % 2].step = times[k], step0 + k
        return states[n % 2]

    def _fill_drive(self, control: Control, dts, times) -> bool:
        """Write the window's drive table (:meth:`run_window`) and copy it to the device; reset its cursor. Returns
        whether a collider moves (the colliders' states at each step are then in the drive's collider path). A
        row: dt, damping factor, uniform field, then the non-uniform field sources' parameters (``load_params``
        copies them into the arrays their kernels read)."""
        n, dev, st = len(dts), self.device, self.settings
        moving = any(c.path is not None for c in control.colliders)
        n_moving = len(control.colliders) if moving else 0
        fields = self.field_evaluator(control)
        prm = fields.param_arrays
        width = 5 + sum(int(a.shape[0]) for a in prm)
        d = self._drive
        if (d is None or d["width"] != width or d["rows"] < n or d["colliders"] is not self._collider_array
                or d["n_moving"] != n_moving or d["fields"] is not fields):
            old = d["rows"] if d is not None else 0
            rows = old if old >= n else max(n, 2 * old, 64)  # grows by doubling: few reallocations, few re-captures
            table = wp.zeros(rows * width, dtype=wp.float64, device=dev)
            host = table if self._on_cpu else wp.zeros(rows * width, dtype=wp.float64, device="cpu", pinned=True)
            path = wp.zeros(max(rows * n_moving, 1), dtype=DeviceCollider, device=dev)
            path_host = path if self._on_cpu else wp.zeros(path.shape[0], dtype=DeviceCollider, device="cpu", pinned=True)
            cursor = wp.zeros(1, dtype=wp.int32, device=dev)
            launch = launch_load_step(self.k, table=table, width=width, cursor=cursor, step=self._step_values,
                                      colliders=self._collider_array, path=path, n_moving=n_moving, device=dev, record=True)
            param_loads, offset = [], 5
            for a in prm:
                param_loads.append(launch_load_params(self.k, int(a.shape[0]), table=table, width=width, cursor=cursor,
                                                      offset=offset, params=a, device=dev, record=True))
                offset += int(a.shape[0])
            d = self._drive = {"width": width, "rows": rows, "table": table, "host": host, "host_np": host.numpy(),
                               "path": path, "path_host": path_host, "path_np": path_host.numpy(), "n_moving": n_moving,
                               "cursor": cursor, "cursor_np": cursor.numpy() if self._on_cpu else None, "launch": launch,
                               "colliders": self._collider_array, "fields": fields, "param_loads": param_loads,
                               "field_launches": {}}
            self._graphs.clear()  # they read the table, the collider arrays and the parameters through these launches
        if not self._on_cpu:  # the pinned buffers are rewritten: their last copies must be done (the device is idle here)
            wp.synchronize_device(dev)
        rows = d["host_np"][: n * width].reshape(n, width)
        for k in range(n):
            row = rows[k]
            row[0] = dts[k]
            row[1] = math.exp(-st.damping_at(times[k]) * dts[k])
            row[2:5] = fields.uniform_value(times[k])
            if prm:
                row[5:] = fields.params_at(times[k])
        if n_moving:
            d["path_np"][: n * n_moving] = np.concatenate([collider_records(control.colliders, times[k]) for k in range(n)])
        if self._on_cpu:
            d["cursor_np"][0] = 0
        else:
            wp.copy(d["table"], d["host"], count=n * width)
            if n_moving:
                wp.copy(d["path"], d["path_host"], count=n * n_moving)
            d["cursor"].zero_()
        return moving

    def _window_fields(self, state: State) -> list:
        """The recorded launches of a window step from ``state``: the non-uniform sources' parameters from the
        step's row of the drive table, then their kernels at the state's positions (none without such sources)."""
        d = self._drive
        if not d["param_loads"]:
            return []
        cache = d["field_launches"]
        launches = cache.get(id(state.x))
        if launches is None:
            if len(cache) >= 8:  # states made afresh each call
                cache.clear()
                self._graphs.clear()
            launches = cache[id(state.x)] = d["param_loads"] + d["fields"].record_launches(
                state.x, self.B_particle, self.grad_B_particle)
        return launches

    def _window_step(self, L: dict, load, fields=()) -> None:
        """One step of a window: its values from the next row of the drive table (``load``, then ``fields``: the
        non-uniform field at the particles), then the phases of :meth:`step`."""
        load.launch()
        for launch in fields:
            launch.launch()
        self._clear_grid()
        self._scatter(L)
        self._update_grid(L)
        self._gather(L)

    def _replay(self, L: tuple, load, n: int, tick=None, F: tuple = ((), ())) -> None:
        """``n`` steps as graphs of 2^j steps (binary digits of n, largest first), each captured at its first use
        per (size, first state); ``L`` the launch sets from state a to b and back."""
        start, size = 0, 1 << max(n.bit_length() - 1, 0)
        while size:
            if n & size:
                key = (size, L[start]["_serial"], L[1 - start]["_serial"])
                graph = self._graphs.get(key)
                if graph is None and self.graph_capture is not False:
                    if len(self._graphs) >= 64:  # launch sets dropped without a refit (many state pairs)
                        self._graphs.clear()
                    try:
                        graph = self._graphs[key] = self._capture(L, load, size, start, F)
                    except Exception as exc:  # nothing of the piece ran: launch it, and capture no more
                        self.graph_capture = False
                        self.capture_failure = f"the capture failed ({type(exc).__name__}: {exc})"
                if graph is None:
                    for j in range(size):
                        self._window_step(L[(start + j) % 2], load, F[(start + j) % 2])
                else:
                    wp.capture_launch(graph)
                    self.graph_replays += 1
                if tick is not None:
                    tick()
                start = (start + size) % 2
            size >>= 1

    def _capture(self, L: tuple, load, size: int, start: int, F: tuple = ((), ())):
        """Capture ``size`` window steps from launch set ``L[start]`` on (nothing runs while capturing)."""
        self._host_ops = False  # zero the grids with device operations, which the graph records
        try:
            with wp.ScopedCapture(device=self.device, force_module_load=False) as capture:
                for j in range(size):
                    self._window_step(L[(start + j) % 2], load, F[(start + j) % 2])
        finally:
            self._host_ops = self._on_cpu
        self.graph_captures += 1
        return capture.graph

    def _read_checks(self) -> np.ndarray:
        """The one host read of a check: error flags, particle bounds and top speed (counted in host_reads). It
        closes the window it checks (a checked step is a window of one): the next unchecked step opens a new one,
        with its fit of the grid block."""
        self.host_reads += 1
        self._window_open = False
        if self._on_cpu:
            err = self._error_np.copy()
            bounds = np.array(self._bounds_np, dtype=np.float64)
            speed = max(float(ts[0]) for ts in self._speed_np)
        else:
            err = self.error.numpy()
            bounds = np.array([tb.numpy() for tb in self._thread_bounds], dtype=np.float64)
            speed = max(float(ts.numpy()[0]) for ts in self._thread_speed)
        self._checked_bounds = (bounds[:, : self.dim].min(axis=0), bounds[:, self.dim :].max(axis=0))
        self._checked_speed = speed
        self._bounds_valid = True
        return err

    # -- the phases of a step -------------------------------------------------------------------------------
    def check_and_fit(self, state_in: State, reach: float = 0.0) -> None:
        """The first phase of a step, also the static solver's start (the grid block, its held nodes). Particles inside the safe box of the current grid block (NaN compares false) need no refit and no
        domain check; otherwise check them and refit the block when they do not fit it. ``reach`` (m) grows the
        particles' box (within the domain) for the fit: room for the motion of a check window."""
        m, t = self.model, state_in.time
        lo0, hi0 = self._particle_bounds(state_in)
        lo, hi = lo0, hi0
        if reach > 0.0:
            lo, hi = np.maximum(lo0 - reach, m.domain_lo), np.minimum(hi0 + reach, m.domain_hi)
        inside = self._safe_lo is not None and (lo >= self._safe_lo).all() and (hi < self._safe_hi).all()
        if inside and not self._oversized(lo, hi):
            return
        if not (np.all(np.isfinite(lo0)) and np.all(np.isfinite(hi0))):
            raise SimulationError("particle positions are not finite", state_in.step, t, input_rejected=True)
        if np.any(lo0 < m.domain_lo) or np.any(hi0 > m.domain_hi):
            raise SimulationError(
                f"a particle left the domain [{m.domain_lo.tolist()}, {m.domain_hi.tolist()}] m "
                f"(particles span {lo0.tolist()} to {hi0.tolist()}); enlarge simulation.domain or check the drives",
                state_in.step,
                t,
                input_rejected=True,
            )
        if not self._fits(lo, hi) or self._oversized(lo, hi):
            self._refit(lo, hi)

    def _particle_fields(self, control: Control, state_in: State):
        """The field at the particles at the state's time: the uniform part (returned, T) and, when there is a
        non-uniform one (field sources with a gradient, the bodies' own field), B and grad B per particle in
        B_particle and grad_B_particle. Returns (uniform B, whether there is a non-uniform part)."""
        fields = self.field_evaluator(control)
        if fields.has_gradient:
            fields.evaluate(state_in.x, self.B_particle, self.grad_B_particle, state_in.time)
        if self.interaction is not None:
            self._interact(state_in, keep=fields.has_gradient)
        return fields.uniform_value(state_in.time), fields.has_gradient or self.interaction is not None

    def _interact(self, state_in: State, keep: bool) -> None:
        """Add the bodies' own field to the per-particle field (``keep`` False: it is the only non-uniform
        part), refreshed at every interaction_every-th step and after a return to an earlier state."""
        step, every = state_in.step, self.settings.interaction_every
        last = self._interaction_step
        fresh = last is None or step < last or step - last >= every
        if fresh:
            self.interaction.refresh(state_in.x, state_in.F)
            self._interaction_step = step
        if fresh or keep:  # without other non-uniform fields the particle arrays keep it between refreshes
            self.interaction.add_to(self.B_particle, self.grad_B_particle, keep)

    def _update_colliders(self, control: Control, t: float) -> None:
        """The colliders' DeviceCollider array at time t, copied to the device only when it changed (resting
        colliders: no copy)."""
        if control.colliders:
            records = collider_records(control.colliders, t)
            if self._collider_array is None or self._collider_array.shape[0] != len(records):
                self._collider_array = wp.array(records, dtype=DeviceCollider, device=self.device)
                self._collider_host = records
                self._drop_launches()
            elif self._collider_host is None or records.tobytes() != self._collider_host.tobytes():
                self._collider_array.assign(records)
                self._collider_host = records
        elif self._collider_array is None:
            self._collider_array = wp.zeros(1, dtype=DeviceCollider, device=self.device)

    def _set_step_values(self, b0, dt: float, t: float = 0.0) -> None:
        """Uniform field, time step and damping factor (the damping at the step's start time ``t``) of a plain step
        into the device's Step, written only when they change (CPU: through a numpy view of the same memory)."""
        values = (tuple(float(b) for b in b0), float(dt), self.settings.damping_at(t))
        if values == self._step_written:
            return
        damping = math.exp(-values[2] * dt)
        if self._step_np is not None:
            v = self._step_np
            v["dt"][0], v["damping_factor"][0], v["B_uniform"][0] = dt, damping, values[0]
        else:
            sc, k = self.scalar, self.k
            one = k["Step"]()
            one.dt, one.damping_factor, one.B_uniform = sc(dt), sc(damping), k["v3"](*[sc(b) for b in values[0]])
            wp.copy(self._step_values, wp.array([one], dtype=k["Step"], device="cpu"))
        self._step_written = values

    def _clear_grid(self) -> None:
        """Zero the grid arrays a step scatters into (CPU: through numpy views, a Warp call costs more than the
        work here; not while a graph captures the step). The error flags are zeroed when a check window opens."""
        if self._host_ops:
            for view in self._grid_np:
                view.fill(0)
        else:
            for view in self._grid_views:
                view.zero_()

    def _scatter(self, L: dict) -> None:
        """Contact scan (with contact), p2g on every thread, the threads' grids summed, node displacements (total
        Lagrangian)."""
        if "pressure_net" in L:
            self.model.pressure_net.zero_()
            L["pressure_net"].launch()
        if self.contact_active and not self._total:
            for v, fill in zip(self._ct_group_views, (2**31 - 1, -1)):
                v.fill_(fill)
            for one in L["contact"]:
                one.launch()
        self._parallel(L["p2g"])
        if L["p2g_scatter"]:
            self._parallel(L["p2g_scatter"])
        for one in L["sum_mass"]:
            one.launch()
        if self._total:
            L["node_displacement"].launch()

    def _update_grid(self, L: dict) -> None:
        """Node velocities; then, for the remap, zero the grids the gather scatters into."""
        L["grid_update"].launch()
        if self._remap:
            # grid_p (and the threads' copies) receive the remap's momenta in g2p
            if self._host_ops:
                self._grid_np[0].fill(0)
                for i in range(len(self._thread_grid_views)):
                    self._grid_np[len(self._grid_views) + 2 * i].fill(0)
            else:
                self._grid_views[0].zero_()
                for gp, _ in self._thread_grid_views:
                    gp.zero_()

    def _gather(self, L: dict) -> None:
        """g2p on every thread; with the remap (counted in the g2p phase) the node momenta rebuilt from the
        particles' new affine velocities over the first transfer's node masses and held-node flags, then F; then
        the Prony materials' internal stresses at the new F."""
        self._parallel(L["g2p"])
        if self._remap:
            if L["remap_scatter"]:
                self._parallel(L["remap_scatter"])
            for one in L["sum_momentum"]:
                one.launch()
            L["remap_nodes"].launch()
            self._parallel(L["remap_F"])
        for one in L.get("viscous", []):
            one.launch()

    def _contact_pass(self, state_in: State, state_out: State, dt: float) -> None:
        """Total Lagrangian with contact (between bodies, self-contact): the reference grid cannot see bodies meet,
        so after its update the particles' trial velocities go to a grid over the current configuration (the
        start-of-step positions, as the updated form's weights), with two velocity fields per node classified as
        in the updated form; the contact law corrects the fields there, and each particle takes the correction of
        its own field into v and x (not into C or F). Counted in the g2p phase."""
        m, k, dev, dim = self.model, self.k, self.device, self.dim
        x = state_in.x
        xs = x.numpy()  # a host read every step (counted): the total form with contact is not windowed yet
        self.host_reads += 1
        lo, hi = xs.min(axis=0).astype(np.float64), xs.max(axis=0).astype(np.float64)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise SimulationError("particle positions are not finite", state_in.step, state_in.time, input_rejected=True)
        first, last = self._node_range(lo, hi)
        first, last = first - 1, last + 1
        shape = last - first + 1
        n = int(np.prod(shape))
        c = self.settings.contact
        fold = 1 if c.self_contact else 0
        tc = self._tc
        if tc is None or n > tc["cap"]:
            cap = int(n * 1.3) + 64
            tc = self._tc = contact_node_arrays(m, cap, c.self_contact)
            tc.update(cap=cap, p=wp.zeros(2 * cap, dtype=k["vec"], device=dev), m=wp.zeros(2 * cap, dtype=self.scalar, device=dev),
                      dv=wp.zeros(2 * cap, dtype=k["vec"], device=dev), clamp=wp.zeros(1, dtype=wp.int32, device=dev), key=None)
        tc["gmin"][:n].fill_(2**31 - 1)
        tc["gmax"][:n].fill_(-1)
        for name, size in (("moments", n * (1 + dim + dim * dim) if fold else 0), ("grad", 2 * n), ("p", 2 * n), ("m", 2 * n)):
            if size:
                tc[name][:size].zero_()
        block = block_struct(self.model, first, shape)
        key = (n, id(tc["gmin"]), id(state_out.x))
        if tc["key"] != key:  # the argument structs, made again when the block size or the output state changes
            tc["ct"] = self._contact_grid(tc, n, c.gap)
            grid = k["GridArrays"]()
            grid.p, grid.m, grid.clamp = tc["p"], tc["m"], tc["clamp"]
            tc["grid"] = wp.array([grid], dtype=k["GridArrays"], device=dev)
            out = k["Particles"]()
            out.x, out.v, out.C, out.F = state_out.x, state_out.v, state_out.C, state_out.F
            tc["out"] = wp.array([out], dtype=k["Particles"], device=dev)
            tc["key"] = key
        ct, N = tc["ct"], m.n_particles
        scan, classify = self._classify_inputs(x, block, fold, tc)
        launch_contact_scan(k, N, device=dev, **scan)
        launch_contact_classify(k, n, device=dev, **classify)
        launch_contact_scatter(k, N, x=x, v=state_out.v, mass=m.mass, block=block, grid=tc["grid"], contact=ct, device=dev)
        launch_contact_resolve(k, n, grid_p=tc["p"], grid_m=tc["m"], contact=ct, grid_dv=tc["dv"], device=dev)
        launch_contact_gather(k, N, x=x, clamped=m.clamped, block=block, dt=self.scalar(dt), grid_dv=tc["dv"],
                              out=tc["out"], contact=ct, device=dev)

    def _check_motion(self, state_in: State, dt: float) -> None:
        """A particle that moves more than a cell in a step was not resolved by the time step (a fixed dt too
        large for the motion, or a force that grew within one step: the start of a blow-up); the transfers would
        smear it over the grid and the run would go on, so stop instead. Uses the top-speed reduction that the
        automatic time step reads anyway."""
        cells = self._moved_cells(dt)
        if cells > 1.0:
            self._bounds_valid = False
            raise SimulationError(
                f"a particle moved {cells:.3g} cells in one step (speed {self._checked_speed:.3g} m/s, "
                f"dt {dt:.3g} s); the time step does not resolve the motion: lower simulation.dt or simulation.cfl, "
                f"or the loads grew too fast (a field too strong for the grid: refine simulation.dx or raise damping)",
                state_in.step,
                state_in.time,
            )

    def _moved_cells(self, dt: float) -> float:
        """Cells the fastest particle of the last check moves in a step of ``dt``."""
        return self._checked_speed * dt / self.model.dx

    def _raise_on_error(self, err, state_in: State) -> None:
        if err[0]:
            # cannot happen while the margin exceeds the per-step motion; a refit at the next step would hide
            # lost mass, so stop instead
            raise SimulationError(
                "a particle moved outside the active grid block within one step; the time step is too large "
                "for the particle speed (lower simulation.dt or simulation.cfl)",
                state_in.step,
                state_in.time,
            )
        if err[1]:
            self._bounds_valid = False
            raise SimulationError(
                "the state became invalid (non-finite values or an inverted element, det F <= 0); likely causes: "
                "time step too large for the material stiffness (lower simulation.dt or simulation.cfl), or a "
                "field too strong for the grid spacing (refine simulation.dx or raise damping)",
                state_in.step,
                state_in.time,
            )
