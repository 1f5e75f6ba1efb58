"""A differentiable MLS-MPM rollout on Warp's autodiff (``wp.Tape``) with checkpointed segments.

The physics is the engine's own: the kernels come from :func:`magsoro.mpm.kernels.make_kernels` and run through
the engine's launchers (:func:`magsoro.mpm.kernels.p2g.launch_p2g` and the others), as plain launches (the explicit
solver's recorded launches are not taped), over one fixed grid block chosen for the whole rollout. Inside a
segment of ``segment`` steps every step has its own State, field and grid arrays, so the tape can replay it
backwards; across segments only the segment start states are stored (checkpoints), and the
backward pass recomputes each segment under a tape and carries the adjoint of its end state into its start state.
Memory is then O(n_steps / segment + segment) states instead of O(n_steps).

Design variables enter through arrays with ``requires_grad=True``:

- ``model.Br`` (per-particle remanence), ``model.shear``, ``model.bulk``, ``model.material_params``;
- ``B_uniform`` (n_steps, 3): the uniform field of every step. The engine's p2g kernel takes the uniform field as a
  plain kernel argument (whose adjoint Warp does not return), so the rollout passes zero there and feeds the field
  per particle through ``B_particle`` (has_gradient = 1, grad B = 0 for uniform-only scenes), which gives the same
  forces bit for bit and makes dL/dB(t_k) the adjoint of ``B_uniform[k]``;
- ``source_params[s]`` (n_steps * L_s) float64: the device parameters (pose, moment ...) of every non-uniform
  source at every step, read by the accumulate kernel of :mod:`magsoro.fields.device`.

The error / bounds / max_speed outputs of the kernels are scratch arrays without gradients.
"""

from dataclasses import replace

import numpy as np
import warp as wp

from magsoro.errors import MagsoroError
from magsoro.fields.device import accumulate_kernel, launch_accumulate
from magsoro.mpm.colliders import MODES, DeviceCollider, collider_records
from magsoro.mpm.kernels.g2p import launch_g2p, launch_remap_F, launch_remap_node_velocity
from magsoro.mpm.kernels.grid import launch_grid_update
from magsoro.mpm.kernels import F_FROM_GRID, F_FROM_REMAP, make_kernels
from magsoro.mpm.kernels.p2g import launch_p2g
from magsoro.mpm.laws.elastic import LAWS
from magsoro.mpm.runtime import block_struct, bodies_array, contact_grid, grid_settings
from magsoro.mpm.laws.viscous import viscous_struct


class DiffError(MagsoroError):
    """A differentiable rollout cannot go on (particles left the fixed grid block, invalid state ...)."""


@wp.kernel
def _fill_uniform_f32(Bu: wp.array(dtype=wp.vec3f), k: int, B: wp.array(dtype=wp.vec3f)):
    i = wp.tid()
    B[i] = Bu[k]


@wp.kernel
def _fill_uniform_f64(Bu: wp.array(dtype=wp.vec3d), k: int, B: wp.array(dtype=wp.vec3d)):
    i = wp.tid()
    B[i] = Bu[k]


@wp.kernel
def _add_field_f32(
    B_a: wp.array(dtype=wp.vec3f), G_a: wp.array(dtype=wp.mat33f), B_b: wp.array(dtype=wp.vec3f), G_b: wp.array(dtype=wp.mat33f),
    B_out: wp.array(dtype=wp.vec3f), G_out: wp.array(dtype=wp.mat33f),
):
    i = wp.tid()
    B_out[i] = B_a[i] + B_b[i]
    G_out[i] = G_a[i] + G_b[i]


@wp.kernel
def _add_field_f64(
    B_a: wp.array(dtype=wp.vec3d), G_a: wp.array(dtype=wp.mat33d), B_b: wp.array(dtype=wp.vec3d), G_b: wp.array(dtype=wp.mat33d),
    B_out: wp.array(dtype=wp.vec3d), G_out: wp.array(dtype=wp.mat33d),
):
    i = wp.tid()
    B_out[i] = B_a[i] + B_b[i]
    G_out[i] = G_a[i] + G_b[i]


class _Slot:
    """Arrays of one step inside a segment: its output state and its field / grid scratch."""

    def __init__(self, n, n_nodes, k, sc, dev, n_point):
        g = dict(dtype=k["vec"], device=dev, requires_grad=True)
        self.x = wp.zeros(n, **g)
        self.v = wp.zeros(n, **g)
        self.C = wp.zeros(n, dtype=k["mat"], device=dev, requires_grad=True)
        self.F = wp.zeros(n, dtype=k["mat"], device=dev, requires_grad=True)
        self.B = wp.zeros(n, dtype=k["v3"], device=dev, requires_grad=True)
        self.grad_B = wp.zeros(n, dtype=k["m3"], device=dev, requires_grad=True) if n_point else None
        self.Btot = wp.zeros(n, dtype=k["v3"], device=dev, requires_grad=True) if n_point else None
        # per point source: its own (B, grad_B) and the running sums
        self.Bs = [wp.zeros(n, dtype=k["v3"], device=dev, requires_grad=True) for _ in range(n_point)]
        self.grad_Bs = [wp.zeros(n, dtype=k["m3"], device=dev, requires_grad=True) for _ in range(n_point)]
        self.Bsum = [wp.zeros(n, dtype=k["v3"], device=dev, requires_grad=True) for _ in range(max(n_point - 1, 0))]
        self.grad_Bsum = [wp.zeros(n, dtype=k["m3"], device=dev, requires_grad=True) for _ in range(max(n_point - 1, 0))]
        self.grid_p = wp.zeros(n_nodes, dtype=k["vec"], device=dev, requires_grad=True)
        self.grid_m = wp.zeros(n_nodes, dtype=sc, device=dev, requires_grad=True)
        self.grid_v = wp.zeros(n_nodes, dtype=k["vec"], device=dev, requires_grad=True)
        self.grid_q = wp.zeros(n_nodes, dtype=k["vec"], device=dev, requires_grad=True)  # velocity-gradient remap
        self.grid_w = wp.zeros(n_nodes, dtype=k["vec"], device=dev, requires_grad=True)  # its node velocities
        self.grid_clamp = wp.zeros(n_nodes, dtype=wp.int32, device=dev)

    def state_arrays(self):
        return (self.x, self.v, self.C, self.F)

    def structs(self, k, rollout) -> dict:
        """The kernels' argument structs over this slot's arrays (one-element arrays, made once)."""
        if getattr(self, "_structs", None) is None:
            grid = k["GridArrays"]()
            grid.p, grid.m, grid.clamp = self.grid_p, self.grid_m, self.grid_clamp
            out = k["Particles"]()
            out.x, out.v, out.C, out.F = self.x, self.v, self.C, self.F
            dev = rollout.dev
            self._structs = {"grid": wp.array([grid], dtype=k["GridArrays"], device=dev),
                             "out": wp.array([out], dtype=k["Particles"], device=dev)}
        return self._structs

    def grad_arrays(self):
        out = [self.x, self.v, self.C, self.F, self.B, self.grid_p, self.grid_m, self.grid_v, self.grid_q]
        out += self.Bs + self.grad_Bs + self.Bsum + self.grad_Bsum
        if self.grad_B is not None:
            out += [self.grad_B, self.Btot]
        return out


class Rollout:
    """Differentiable fixed-step rollout of a built scene (:class:`magsoro.scene.build.Built`).

    Parameters
    ----------
    built : the scene's Model, Control and settings (``magsoro.scene.build.build``).
    dt : time step, s (fixed for the whole rollout, so it does not depend on the design).
    n_steps : number of steps; the horizon is n_steps * dt.
    segment : steps per checkpoint segment (default: all steps in one segment, no recomputation).
    margin : free space around the reference bounding box covered by the fixed grid block, m (default: the
        largest extent of the bodies, enough for any rigid rotation about a point of the body).

    ``run(loss)`` returns the loss and, with ``grad=True``, the gradients as numpy arrays: ``Br`` (N, 3),
    ``shear`` (N,), ``bulk`` (N,), ``material_params`` (N, LAW_PARAM_COUNT = 6 of magsoro.mpm.laws.elastic),
    ``B_uniform`` (n_steps, 3), ``source_params`` (a list, one (n_steps, L_s) array per non-uniform source).
    """

    def __init__(self, built, dt: float, n_steps: int, segment: int | None = None, margin: float | None = None):
        self.built = built
        m = self.model = built.model
        self.control = built.control
        st = self.settings = built.settings
        if st.formulation == "total" and st.formulation_auto:
            # the scene did not ask for a form: the rollout's kernels are the updated-Lagrangian ones
            st = self.settings = replace(st, formulation="updated", formulation_auto=False)
        if st.formulation != "updated":
            raise ValueError(f"the differentiable rollout runs the updated-Lagrangian engine only; the scene asks for "
                             f"simulation.formulation = {st.formulation!r}")
        if st.magnetic_interaction != "none":
            raise ValueError("the differentiable rollout has no magnetic interaction between bodies; give the scene "
                             "simulation.magnetic_interaction = 'none'")
        if np.any(m.host["material_model"] == LAWS["ogden"].code):
            # its stress goes through wp.eig3, whose adjoint is NaN or wrong at repeated stretches, F = I included
            raise ValueError("the differentiable rollout cannot differentiate the Ogden law (its principal-stretch "
                             "stress has no reliable gradient at repeated stretches, the undeformed state included); "
                             "give the bodies another model (e.g. 'polynomial' or 'yeoh')")
        if np.any(m.host["magnetization_follows"] != 0):
            # the R law's stress goes through wp.svd3 (3D), whose adjoint is unreliable at repeated singular values
            raise ValueError("the differentiable rollout has no magnetization_follows = 'R' yet; give the materials "
                             "magnetization_follows = 'F' (or run the scene with magsoro run)")
        if getattr(m, "stimuli", ()):
            # the eigenstrain tables are set per step from the host; the rollout's tape has no per-step copy of them
            raise ValueError("the differentiable rollout has no stimulus-driven eigenstrain yet; remove material.stimulus "
                             "from the bodies (or run the scene with magsoro run)")
        if getattr(m, "pressure_ramps", False):
            # the pressure table is set per step from the host; the tape has no per-step copy of it (a constant
            # pressure is a fixed table and differentiates)
            raise ValueError("the differentiable rollout has no pressure ramp yet; give bodies' pressure ramp = 0 "
                             "(or run the scene with magsoro run)")
        if getattr(m, "viscous", False):
            # the internal stresses are updated in place of the state; the rollout's states do not carry them
            raise ValueError("the differentiable rollout has no viscoelastic (prony) materials yet; remove material.prony "
                             "from the bodies (or run the scene with magsoro run)")
        groups = int(m.host["contact_group"].max()) + 1
        if st.contact is not None and st.contact.active(groups):
            raise ValueError("the differentiable rollout has no contact between bodies or self-contact; give the scene "
                             "contact.friction = 'sticky' (one velocity field) or a single body")
        if getattr(m, "plane", "strain") == "axisymmetric":
            raise ValueError("the differentiable rollout has no axisymmetric scenes yet (simulation.dim = 'axisymmetric'); "
                             "run them with magsoro run")
        if getattr(m, "plane", "strain") == "stress":
            # the thickness stretch is solved by an inner Newton loop, which Warp's tape does not differentiate
            raise ValueError('the differentiable rollout has no plane stress yet; give the scene simulation.plane = '
                             '"strain" (or run it with magsoro run)')
        self.k = k = make_kernels(m.dim, m.scalar, differentiable=True)  # the engine's kernels, with their adjoints
        self._no_contact = contact_grid(m)  # one velocity field per node
        self._no_viscous = viscous_struct(m, None)
        # p2g's arrays for the scatter threads' split (unused here: the rollout runs p2g whole)
        self._no_affine = wp.zeros(0, dtype=m.kernels["mat"], device=m.device)
        self._no_momentum = wp.zeros(0, dtype=m.kernels["vec"], device=m.device)
        self._no_shift = wp.zeros(1, dtype=k["vec"], device=m.device)  # grid_update's node displacements (total form only)
        self.dim, self.dev, self.sc = m.dim, m.device, m.scalar
        self.dt = float(dt)
        self.n_steps = int(n_steps)
        if self.n_steps < 1:
            raise DiffError("a rollout needs at least one step")
        if not self.dt > 0:
            raise DiffError(f"dt must be > 0 s, got {dt}")
        self.segment = self.n_steps if segment is None else max(1, min(int(segment), self.n_steps))
        n, dim, sc, dev = m.n_particles, m.dim, m.scalar, m.device
        for a in (m.Br, m.shear, m.bulk, m.material_params):
            a.requires_grad = True
        # fixed grid block: reference bounding box + margin, clipped to the domain
        X = m.host["positions"]
        lo, hi = X.min(axis=0), X.max(axis=0)
        if margin is None:
            margin = float(np.max(hi - lo)) + 4 * m.dx
        self.margin = float(margin)
        blo = np.maximum(lo - margin, m.domain_lo)
        bhi = np.minimum(hi + margin, m.domain_hi)
        first = np.floor((blo - m.domain_lo) / m.dx - 0.5).astype(np.int64) - 1
        last = np.floor((bhi - m.domain_lo) / m.dx - 0.5).astype(np.int64) + 3
        self.org, self.shape = first, last - first + 1
        self.n_nodes = int(np.prod(self.shape))
        self.block_lo = m.domain_lo + first * m.dx
        self.block_hi = m.domain_lo + last * m.dx
        ivec, vec = k["ivec"], k["vec"]
        self._shape_v = ivec(*[int(s) for s in self.shape])
        self._org_v = ivec(*[int(o) for o in self.org])
        g = np.zeros(dim)
        gin = np.asarray(st.gravity, dtype=np.float64).ravel()
        g[: min(dim, len(gin))] = gin[:dim]
        self._gravity = vec(*[sc(v) for v in g])
        if st.walls not in MODES:
            raise DiffError(f"walls must be one of {sorted(MODES)}, got {st.walls!r}")
        # sources: uniform ones tabulated per step, the others as per-step device parameters
        flat = []
        for s in self.control.sources:
            flat.extend(s.sources())
        self.uniform_sources = [s for s in flat if s.uniform]
        self.point_sources = [s for s in flat if not s.uniform]
        times = self.dt * np.arange(self.n_steps)
        self.times = times
        Bu = np.zeros((self.n_steps, 3))
        for s in self.uniform_sources:
            Bu += np.array([s.uniform_value(t) for t in times])
        self.B_uniform = wp.array(Bu.astype(m.np_scalar), dtype=k["v3"], device=dev, requires_grad=True)
        self._point_kernels = [accumulate_kernel(s.device_func(), dim, sc, differentiable=True) for s in self.point_sources]
        self.source_params = []
        self._param_views = []
        for s in self.point_sources:
            rows = np.array([np.asarray(s.device_params(t), dtype=np.float64) for t in times])
            arr = wp.array(rows.ravel(), dtype=wp.float64, device=dev, requires_grad=True)
            L = rows.shape[1]
            self.source_params.append(arr)
            self._param_views.append([arr[i * L : (i + 1) * L] for i in range(self.n_steps)])
        # colliders: one table per step (moving colliders follow their paths)
        self.n_colliders = len(self.control.colliders)
        if self.n_colliders:
            records = np.concatenate([collider_records(self.control.colliders, t) for t in times])
            width = self.n_colliders
            self._collider_all = wp.array(records, dtype=DeviceCollider, device=dev)
            self._collider_views = [self._collider_all[i * width : (i + 1) * width] for i in range(self.n_steps)]
        else:
            empty = wp.zeros(1, dtype=DeviceCollider, device=dev)
            self._collider_views = [empty] * self.n_steps
        # the grid update's settings per step (they differ only in the colliders' states)
        if self.n_colliders:
            self._grid_settings = [grid_settings(m, st, self._gravity, v, self.n_colliders, self.dt) for v in self._collider_views]
        else:
            self._grid_settings = [grid_settings(m, st, self._gravity, self._collider_views[0], 0, self.dt)] * self.n_steps
        # scratch without gradients
        self.error = wp.zeros(2, dtype=wp.int32, device=dev)
        self.bounds = wp.zeros(2 * dim, dtype=sc, device=dev)
        self.max_speed = wp.zeros(1, dtype=sc, device=dev)
        checks = k["Checks"]()
        checks.bounds, checks.max_speed, checks.error = self.bounds, self.max_speed, self.error
        self._checks = wp.array([checks], dtype=k["Checks"], device=dev)
        self._bodies = bodies_array(m)
        self._block = block_struct(m, self.org, self.shape)
        self.grad_B_zero = wp.zeros(n, dtype=k["m3"], device=dev)
        f64 = sc == wp.float64
        self._fill = _fill_uniform_f64 if f64 else _fill_uniform_f32
        self._add = _add_field_f64 if f64 else _add_field_f32
        # segment pool: slot 0 holds the segment start state, slot j the state after j steps
        n_point = len(self.point_sources)
        self.slots = [_Slot(n, self.n_nodes, k, sc, dev, n_point) for _ in range(self.segment + 1)]
        self.n_segments = -(-self.n_steps // self.segment)
        self.checkpoints = []
        self.initial_velocity = np.zeros((n, dim)) if built.initial_velocity is None else np.asarray(built.initial_velocity, dtype=np.float64)

    # -- helpers ---------------------------------------------------------------------------------------------
    def _initial_state(self, slot):
        m, s = self.model, self.model.np_scalar
        n, dim = m.n_particles, m.dim
        slot.x.assign(m.host["positions"].astype(s))
        slot.v.assign(np.ascontiguousarray(np.broadcast_to(self.initial_velocity, (n, dim)), dtype=s))
        slot.C.zero_()
        slot.F.assign(np.ascontiguousarray(np.broadcast_to(np.eye(dim), (n, dim, dim)), dtype=s))

    def _step(self, step: int, src, dst) -> None:
        """Launch one step ``step`` from slot ``src`` into slot ``dst`` (recorded by an active tape)."""
        m, k, sc, dev, st = self.model, self.k, self.sc, self.dev, self.settings
        n = m.n_particles
        remap = st.velocity_gradient == "remap"
        dst.grid_p.zero_()
        dst.grid_m.zero_()
        dst.grid_q.zero_()
        dst.grid_clamp.zero_()
        dt = sc(self.dt)
        for i, (kern, views) in enumerate(zip(self._point_kernels, self._param_views)):
            launch_accumulate(kern, n, x=src.x, params=views[step], plane_z=wp.float64(st.plane_z), overwrite=1,
                              B=dst.Bs[i], grad_B=dst.grad_Bs[i], device=dev)
        wp.launch(self._fill, dim=n, inputs=[self.B_uniform, step, dst.B], device=dev)  # the uniform field per particle
        if self.point_sources:
            # B = uniform + sum of point sources; grad_B = sum of point sources (out of place for the tape)
            b_acc, g_acc = dst.B, self.grad_B_zero
            n_point = len(self.point_sources)
            for i in range(n_point):
                last = i == n_point - 1
                b_out = dst.Btot if last else dst.Bsum[i]
                g_out = dst.grad_B if last else dst.grad_Bsum[i]
                wp.launch(self._add, dim=n, inputs=[b_acc, g_acc, dst.Bs[i], dst.grad_Bs[i], b_out, g_out], device=dev)
                b_acc, g_acc = b_out, g_out
            B_particle, grad_B_particle = b_acc, g_acc
        else:
            B_particle, grad_B_particle = dst.B, self.grad_B_zero
        applied = k["Applied"]()
        applied.has_gradient = 1
        applied.B, applied.grad_B = B_particle, grad_B_particle
        structs = dst.structs(k, self)
        # the engine's phases through its launchers (plain launches: the tape records them)
        launch_p2g(k, n, src=src.structs(k, self)["out"], bodies=self._bodies, applied=applied, block=self._block, dt=dt,
                   grid=structs["grid"], error=self.error, flags=0, contact=self._no_contact, viscous=self._no_viscous,
                   affine=self._no_affine, momentum=self._no_momentum, device=dev)
        launch_grid_update(k, self.n_nodes, grid_p=dst.grid_p, grid_m=dst.grid_m, grid_clamp=dst.grid_clamp,
                           org=self._org_v, shape=self._shape_v, settings=self._grid_settings[step], grid_v=dst.grid_v,
                           contact=self._no_contact, grid_u=self._no_shift, device=dev)
        f_update = F_FROM_REMAP if remap else F_FROM_GRID
        launch_g2p(k, n, grid_v=dst.grid_v, bodies=self._bodies, block=self._block, dt=dt, x_in=src.x, x_cur=src.x,
                   F_in=src.F, out=structs["out"], checks=self._checks, f_update=f_update, grid_r=dst.grid_q,
                   contact=self._no_contact, device=dev)
        if remap:  # the engine's velocity-gradient remap (docs/engine.md), same kernels
            launch_remap_node_velocity(k, self.n_nodes, grid_r=dst.grid_q, grid_m=dst.grid_m, grid_clamp=dst.grid_clamp,
                                       grid_w=dst.grid_w, n_nodes=self.n_nodes, block=self._block, axis=0, device=dev)
            launch_remap_F(k, n, x=src.x, bodies=self._bodies, block=self._block, dt=dt, grid_w=dst.grid_w, F_in=src.F,
                           F_out=dst.F, error=self.error, contact=self._no_contact, device=dev)

    def _run_segment(self, seg: int) -> int:
        """Run segment ``seg`` from slot 0 (already holding its start state); returns its number of steps."""
        k0 = seg * self.segment
        k1 = min(k0 + self.segment, self.n_steps)
        for j in range(k1 - k0):
            self._step(k0 + j, self.slots[j], self.slots[j + 1])
        return k1 - k0

    def _check(self, seg: int) -> None:
        err = self.error.numpy()
        if err[0]:
            raise DiffError(
                f"a particle left the fixed grid block [{self.block_lo.tolist()}, {self.block_hi.tolist()}] m in segment {seg} "
                f"(steps {seg * self.segment} to {min((seg + 1) * self.segment, self.n_steps)}); give a larger margin "
                f"(now {self.margin:g} m) or a shorter horizon"
            )
        if err[1]:
            raise DiffError(
                f"the state became invalid (non-finite values or det F <= 0) in segment {seg}; lower dt or the field"
            )

    @staticmethod
    def _copy_state(dst, src) -> None:
        for a, b in zip(dst.state_arrays(), src.state_arrays()):
            wp.copy(a, b)

    def _load_checkpoint(self, seg: int) -> None:
        for a, b in zip(self.slots[0].state_arrays(), self.checkpoints[seg]):
            wp.copy(a, b)

    # -- public ----------------------------------------------------------------------------------------------
    def forward(self, observe=None, steps=None) -> dict:
        """Plain forward run storing the checkpoints. ``observe(step, slot)`` is called for every step in
        ``steps`` (indices 1..n_steps) with the slot holding that state; returns the final state as numpy."""
        steps = set(steps or ())
        self.error.zero_()
        self._initial_state(self.slots[0])
        self.checkpoints = []
        for seg in range(self.n_segments):
            self.checkpoints.append(tuple(wp.clone(a) for a in self.slots[0].state_arrays()))
            count = self._run_segment(seg)
            self._check(seg)
            k0 = seg * self.segment
            for j in range(1, count + 1):
                if k0 + j in steps and observe is not None:
                    observe(k0 + j, self.slots[j])
            if seg < self.n_segments - 1:
                self._copy_state(self.slots[0], self.slots[count])
        end = self.slots[self.n_steps - (self.n_segments - 1) * self.segment]
        return {"x": end.x.numpy().astype(np.float64), "F": end.F.numpy().astype(np.float64), "v": end.v.numpy().astype(np.float64)}

    def run(self, loss, grad: bool = True, loss_steps=None):
        """Loss (and gradients) of a rollout. ``loss(x, F)`` takes the state (numpy float64, (N, dim) and
        (N, dim, dim)) and returns ``(L, dL/dx, dL/dF)``; it is evaluated at ``loss_steps`` (default: the final
        step only) and averaged, so a list of steps gives a time-integrated loss. Returns ``(L, grads)``."""
        loss_steps = sorted(set(loss_steps or [self.n_steps]))
        if loss_steps[0] < 1 or loss_steps[-1] > self.n_steps:
            raise DiffError(f"loss steps must lie in 1..{self.n_steps}")
        w = 1.0 / len(loss_steps)
        seeds = {}
        total = [0.0]

        def observe(step, slot):
            L, gx, gF = loss(slot.x.numpy().astype(np.float64), slot.F.numpy().astype(np.float64))
            total[0] += w * float(L)
            seeds[step] = (w * np.asarray(gx), None if gF is None else w * np.asarray(gF))

        self.forward(observe, loss_steps)
        if not grad:
            return total[0], None
        return total[0], self.backward(seeds)

    def backward(self, seeds: dict) -> dict:
        """Gradients from ``seeds`` {step: (dL/dx, dL/dF)} after :meth:`forward` stored the checkpoints."""
        m, s = self.model, self.model.np_scalar
        for a in (m.Br, m.shear, m.bulk, m.material_params, self.B_uniform, *self.source_params):
            a.grad.zero_()
        carry = None
        for seg in reversed(range(self.n_segments)):
            k0 = seg * self.segment
            self._load_checkpoint(seg)
            for slot in self.slots:
                for a in slot.grad_arrays():
                    a.grad.zero_()
            tape = wp.Tape()
            with tape:
                count = self._run_segment(seg)
            end = self.slots[count]
            if carry is not None:
                for a, g in zip(end.state_arrays(), carry):
                    wp.copy(a.grad, g)
            for j in range(1, count + 1):
                if k0 + j in seeds:
                    gx, gF = seeds[k0 + j]
                    slot = self.slots[j]
                    slot.x.grad.assign(slot.x.grad.numpy() + gx.astype(s))
                    if gF is not None:
                        slot.F.grad.assign(slot.F.grad.numpy() + gF.astype(s))
            tape.backward()
            carry = tuple(wp.clone(a.grad) for a in self.slots[0].state_arrays())
            del tape  # not tape.reset(): it would zero the accumulated design gradients too
        return {
            "Br": m.Br.grad.numpy().astype(np.float64),
            "shear": m.shear.grad.numpy().astype(np.float64),
            "bulk": m.bulk.grad.numpy().astype(np.float64),
            "material_params": m.material_params.grad.numpy().astype(np.float64),
            "B_uniform": self.B_uniform.grad.numpy().astype(np.float64),
            "source_params": [a.grad.numpy().reshape(self.n_steps, -1) for a in self.source_params],
        }

    # -- design inputs ---------------------------------------------------------------------------------------
    def set_particle_arrays(self, Br=None, shear=None, bulk=None, material_params=None) -> None:
        """Replace per-particle inputs (SI numpy arrays)."""
        m, s = self.model, self.model.np_scalar
        for arr, val, key in ((m.Br, Br, "remanence"), (m.shear, shear, "shear_modulus"), (m.bulk, bulk, "bulk_modulus"), (m.material_params, material_params, "material_params")):
            if val is not None:
                val = np.asarray(val, dtype=np.float64)
                arr.assign(val.astype(s))
                m.host[key] = val.copy()

    def set_uniform_field(self, table) -> None:
        """Replace the uniform field of every step, (n_steps, 3) T."""
        self.B_uniform.assign(np.asarray(table, dtype=np.float64).astype(self.model.np_scalar))

    def set_source_params(self, index: int, rows) -> None:
        """Replace the device parameters of non-uniform source ``index`` for every step, (n_steps, L)."""
        rows = np.asarray(rows, dtype=np.float64)
        self.source_params[index].assign(rows.ravel())
