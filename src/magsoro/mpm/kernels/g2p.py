"""Grid-to-particle kernels: the gather of velocity and affine velocity, the position and F updates, the
velocity-gradient remap (docs/engine.md, "Why the remap"), and the host checks' reductions."""

import functools

import warp as wp

from magsoro.mpm.colliders import DeviceCollider
from magsoro.mpm.settings import FUpdate
from magsoro.mpm.kernels.stencil import make_stencil

# Unroll the 3^dim-node stencil loops (27 in 3D): constant offsets let the compiler fold the weight selection.
wp.set_module_options({"max_unroll": 32})

#: How g2p updates F (:class:`magsoro.mpm.settings.FUpdate`): from the gathered node velocities, left to the remap,
#: or on the reference grid
F_FROM_GRID = wp.constant(int(FUpdate.FROM_GRID))
F_FROM_REMAP = wp.constant(int(FUpdate.FROM_REMAP))
F_TOTAL = wp.constant(int(FUpdate.TOTAL))
F_REMAP_APART = wp.constant(int(FUpdate.REMAP_APART))  # F from the remap, whose scatter runs in remap_scatter (Solver.spread_scatter)


@functools.cache
def make_g2p(dim: int, scalar, two_fields: bool = False, differentiable: bool = False) -> dict:
    """Gather kernels for ``dim``, ``scalar``; ``two_fields``: the contact variant (:mod:`magsoro.mpm.kernels.contact`);
    ``differentiable``: with the adjoints of the kernels the differentiable rollout (:mod:`magsoro.diff`) records
    on its wp.Tape. Warp otherwise builds none (docs/engine.md, "Compile time")."""
    s = make_stencil(dim, scalar, two_fields)
    t = s.types
    vec, mat, v3, ivec = t.vec, t.mat, t.v3, t.ivec
    Block, Bodies, Particles, Checks, Step = t.Block, t.Bodies, t.Particles, t.Checks, t.Step
    ContactGrid = s.ContactGrid
    NS = s.NS
    slot_of, bspline_weights = s.slot_of, s.bspline_weights
    local_coords, outside_block, flat_index, stencil_node = s.local_coords, s.outside_block, s.flat_index, s.stencil_node
    node_of_flat, axis_mirror = s.node_of_flat, s.axis_mirror

    @wp.func
    def update_F(F_in: wp.array(dtype=mat), F_out: wp.array(dtype=mat), p: int, dtC: mat):
        """F_out = F + (dt C) F; False when the element inverts (det F <= 0) or F is not finite.
        F + (dt C) F rather than (I + dt C) F: in float32, 1 + dt C_ii rounds the small increments of a slowly
        creeping state away, which showed as a steady drift of loaded beams (docs/engine.md)."""
        Fp = F_in[p]
        Fn = Fp + dtC * Fp
        F_out[p] = Fn
        return wp.determinant(Fn) > scalar(0.0)

    @wp.func
    def report(checks: wp.array(dtype=Checks), ok: bool, xc: vec, new_v: vec):
        """Flag a non-finite or inverted particle and take part in the top-speed reduction."""
        for a in range(dim):
            if not wp.isfinite(xc[a]) or not wp.isfinite(new_v[a]):
                ok = False
        if not ok:
            wp.atomic_max(checks[0].error, 1, 1)
        wp.atomic_max(checks[0].max_speed, 0, wp.length(new_v))

    @wp.func
    def remap_node(grid_r: wp.array(dtype=vec), ct: wp.array(dtype=ContactGrid), p: int, q: int, w0: vec, w1: vec,
                   w2: vec, first: int, shape: ivec, mp: scalar, new_v: vec, Cd: mat, Cfx: vec):
        weight, of, idx = stencil_node(q, w0, w1, w2, first, shape)
        wp.atomic_add(grid_r, slot_of(ct, p, idx), (weight * mp) * (new_v + (Cd * of - Cfx)))  # new_v per node, as in p2g

    @wp.kernel(enable_backward=differentiable)
    def g2p(
        grid_v: wp.array(dtype=vec),
        bodies: wp.array(dtype=Bodies),
        block: Block,
        dt: scalar,
        x_in: wp.array(dtype=vec),
        x_cur: wp.array(dtype=vec),
        F_in: wp.array(dtype=mat),
        out: wp.array(dtype=Particles),
        checks: wp.array(dtype=Checks),
        f_update: int,
        grid_r: wp.array(dtype=vec),
        ct: wp.array(dtype=ContactGrid),
    ):
        """Grid-to-particle transfer: new x, v, C. With ``f_update`` = F_FROM_GRID F is updated from the same node
        velocities; with F_FROM_REMAP F is left to :func:`remap_F`, and the particle's new affine velocity field
        v + C (x_i - x_p) is scattered, mass-weighted, into ``grid_r`` (the first half of the velocity-gradient
        remap; it needs only this particle's new v and C, so it rides on the same stencil pass); with
        F_REMAP_APART that scatter is left to :func:`remap_scatter` (the GPU's scatter threads).

        ``x_in`` are the positions the grid weights are taken at and ``x_cur`` the particles' current positions,
        which move by dt v: the same array in the updated-Lagrangian form. In the total-Lagrangian form
        (F_TOTAL) ``x_in`` holds the reference positions, C is the velocity gradient with respect to them and F
        grows by dt C; the bounds reduction then covers the reference positions, which the grid block is
        fitted to. With ``bodies[0].stepped`` dt comes from ``bodies[0].step[0]`` (:class:`magsoro.mpm.kernels.stencil`
        Step) instead of ``dt``."""
        p = wp.tid()
        dts = dt
        if bodies[0].stepped != 0:
            dts = bodies[0].step[0].dt
        xp = x_in[p]
        xc = x_cur[p]
        o = out[0]
        code = bodies[0].clamped[p]
        if code != 0:
            # held particles keep their shape and move with their clamp (at rest unless it follows a path)
            vc = bodies[0].clamp_velocity[code]
            o.x[p] = xc + dts * vc
            o.v[p] = vc
            o.C[p] = mat()
            o.F[p] = F_in[p]
        else:
            dx = block.dx
            inv_dx = scalar(1.0) / dx
            base, fx = local_coords(xp, block.lo, inv_dx)
            if outside_block(base, block.shape):
                # only inside a check window, whose start is not checked on the host: p2g has flagged the
                # particle, the window runs again step by step; keep it as it was, read no node outside the block
                o.x[p] = xc
                o.v[p] = vec()
                o.C[p] = mat()
                o.F[p] = F_in[p]
                wp.atomic_max(checks[0].error, 0, 1)
                return
            w0, w1, w2 = bspline_weights(fx)
            new_v = vec()
            S = mat()
            first = flat_index(base, block.shape)
            for q in range(NS):
                weight, of, idx = stencil_node(q, w0, w1, w2, first, block.shape)
                wgv = weight * grid_v[slot_of(ct, p, idx)]
                new_v = new_v + wgv
                S = S + wp.outer(wgv, of)
            # C = (4/dx^2) sum w v_i (x_i - x_p)^T = (4/dx) (S - v fx^T)
            new_C = (scalar(4.0) * inv_dx) * (S - wp.outer(new_v, fx))
            xc = xc + dts * new_v
            o.x[p] = xc
            if f_update != F_TOTAL:
                xp = xc
            o.v[p] = new_v
            o.C[p] = new_C
            ok = True
            if f_update == F_TOTAL:
                Fn = F_in[p] + dts * new_C
                o.F[p] = Fn
                ok = wp.determinant(Fn) > scalar(0.0)
            elif f_update == F_FROM_GRID:
                ok = update_F(F_in, o.F, p, dts * new_C)
            elif f_update == F_FROM_REMAP:
                mp = bodies[0].mass[p]
                Cd = new_C * dx
                Cfx = Cd * fx
                for q in range(NS):
                    remap_node(grid_r, ct, p, q, w0, w1, w2, first, block.shape, mp, new_v, Cd, Cfx)
            report(checks, ok, xc, new_v)
        for a in range(dim):
            wp.atomic_min(checks[0].bounds, a, xp[a])
            wp.atomic_max(checks[0].bounds, dim + a, xp[a])

    @wp.kernel(enable_backward=False)
    def remap_scatter(
        x: wp.array(dtype=vec),
        bodies: wp.array(dtype=Bodies),
        block: Block,
        out: wp.array(dtype=Particles),
        grid_r: wp.array(dtype=vec),
        ct: wp.array(dtype=ContactGrid),
        spread: int,
    ):
        """First half of the velocity-gradient remap as a kernel of its own, after :func:`g2p` with F_REMAP_APART
        (the scatter threads of a GPU; g2p does it itself with F_FROM_REMAP): each particle's new affine velocity field
        v + C (x_i - x_p), mass-weighted, into ``grid_r`` over the stencil of its start-of-step position ``x`` (the
        one g2p gathered at). ``spread``: one thread per particle (0) or per (particle, node) (1), as in
        :func:`magsoro.mpm.kernels.p2g` p2g_scatter (docs/engine.md, "Scatter threads")."""
        tid = wp.tid()
        p = tid
        if spread != 0:
            p = tid // NS
        b = bodies[0]
        if b.clamped[p] != 0:
            return  # held particles scatter nothing: their nodes are held
        dx = block.dx
        base, fx = local_coords(x[p], block.lo, scalar(1.0) / dx)
        if outside_block(base, block.shape):
            return  # g2p has flagged it
        w0, w1, w2 = bspline_weights(fx)
        o = out[0]
        new_v = o.v[p]
        mp = b.mass[p]
        Cd = o.C[p] * dx
        Cfx = Cd * fx
        first = flat_index(base, block.shape)
        if spread != 0:
            remap_node(grid_r, ct, p, tid - p * NS, w0, w1, w2, first, block.shape, mp, new_v, Cd, Cfx)
        else:
            for q in range(NS):
                remap_node(grid_r, ct, p, q, w0, w1, w2, first, block.shape, mp, new_v, Cd, Cfx)

    @wp.kernel(enable_backward=False)
    def reset_reductions(bounds: wp.array(dtype=scalar), max_speed: wp.array(dtype=scalar), big: scalar):
        for a in range(dim):
            bounds[a] = big
            bounds[dim + a] = -big
        max_speed[0] = scalar(0.0)

    @wp.kernel(enable_backward=False)
    def load_step(
        table: wp.array(dtype=wp.float64),
        width: int,
        cursor: wp.array(dtype=wp.int32),
        step: wp.array(dtype=Step),
        colliders: wp.array(dtype=DeviceCollider),
        path: wp.array(dtype=DeviceCollider),
        n_moving: int,
    ):
        """A step of a check window takes its values from row ``cursor[0]`` of the window's drive table (``width``
        float64 per row: dt, the damping factor, the uniform field's 3 components) into ``step[0]``, and, where
        colliders move (``n_moving`` of them: all the scene's), their states at the step's time from row
        ``cursor[0]`` of ``path`` (``n_moving`` DeviceColliders per row) into ``colliders``; then moves the cursor
        on: every step of a window is the same launch sequence, which a CUDA graph can capture once (one thread)."""
        row = cursor[0]
        base = row * width
        sv = Step()
        sv.dt = scalar(table[base])
        sv.damping_factor = scalar(table[base + 1])
        sv.B_uniform = v3(scalar(table[base + 2]), scalar(table[base + 3]), scalar(table[base + 4]))
        step[0] = sv
        for i in range(n_moving):
            colliders[i] = path[row * n_moving + i]
        cursor[0] = row + 1

    @wp.kernel(enable_backward=False)
    def load_params(table: wp.array(dtype=wp.float64), width: int, cursor: wp.array(dtype=wp.int32), offset: int,
                    params: wp.array(dtype=wp.float64)):
        """After ``load_step``: a field source's parameters at the step's time, from the row ``load_step`` took
        (``cursor[0] - 1``), columns ``offset`` on, into the array its field kernel reads (one thread per value)."""
        i = wp.tid()
        params[i] = table[(cursor[0] - 1) * width + offset + i]

    @wp.kernel(enable_backward=differentiable)
    def remap_node_velocity(
        grid_r: wp.array(dtype=vec),
        grid_m: wp.array(dtype=scalar),
        grid_clamp: wp.array(dtype=wp.int32),
        grid_w: wp.array(dtype=vec),
        n_nodes: int,
        block: Block,
        axis: int,
    ):
        """Node velocities of the remap: the scattered momenta over the first transfer's node masses (same
        particles, same positions), at rest on held nodes. Once per slot (node and field) instead of once per
        stencil entry; slots from ``n_nodes`` on are the contact fields of the nodes. ``axis`` 1: an axisymmetric
        grid block (``block``) whose axis x = 0 is a node line; the nodes near it and their mirrors share mass and
        mirrored momentum, as in the grid update (:func:`magsoro.mpm.kernels.grid.make_grid`'s ``fold``)."""
        idx = wp.tid()
        m = grid_m[idx]
        r = grid_r[idx]
        node = idx
        if node >= n_nodes:
            node = idx - n_nodes
        if axis != 0 and idx < n_nodes:
            loc = node_of_flat(idx, block.shape)
            k = loc[0] + int(wp.round(block.lo[0] / block.dx))
            if k == 0:
                r[0] = scalar(0.0)
            elif k >= -2 and k <= 2:
                j = axis_mirror(loc, k, block.shape)
                if j >= 0:
                    q = grid_r[j]
                    q[0] = -q[0]
                    r = r + q
                    m = m + grid_m[j]
        if m > scalar(0.0) and grid_clamp[node] == 0:
            grid_w[idx] = r / m
        else:
            grid_w[idx] = vec()

    @wp.kernel(enable_backward=differentiable)
    def remap_F(
        x: wp.array(dtype=vec),
        bodies: wp.array(dtype=Bodies),
        block: Block,
        dt: scalar,
        grid_w: wp.array(dtype=vec),
        F_in: wp.array(dtype=mat),
        F_out: wp.array(dtype=mat),
        error: wp.array(dtype=wp.int32),
        ct: wp.array(dtype=ContactGrid),
    ):
        """F update from the remapped node velocities ``grid_w`` (:func:`remap_node_velocity`): F + dt (grad v) F
        at the particle's position at the start of the step, the same stencil as the first gather (held particles:
        ``bodies[0].clamped``; dt from ``bodies[0].step[0]`` when ``bodies[0].stepped``, as in :func:`g2p`)."""
        p = wp.tid()
        b = bodies[0]
        if b.clamped[p] != 0:
            F_out[p] = F_in[p]
            return
        dts = dt
        if b.stepped != 0:
            dts = b.step[0].dt
        inv_dx = scalar(1.0) / block.dx
        base, fx = local_coords(x[p], block.lo, inv_dx)
        if outside_block(base, block.shape):
            return  # outside the grid block: p2g has flagged it, the step is discarded
        w0, w1, w2 = bspline_weights(fx)
        S = mat()
        sv = vec()
        first = flat_index(base, block.shape)
        for q in range(NS):
            weight, of, idx = stencil_node(q, w0, w1, w2, first, block.shape)
            wv = weight * grid_w[slot_of(ct, p, idx)]
            sv = sv + wv
            S = S + wp.outer(wv, of)
        # as in g2p: (4/dx^2) sum w v_i (x_i - x_p)^T = (4/dx) (S - (sum w v_i) fx^T)
        if not update_F(F_in, F_out, p, (dts * scalar(4.0) * inv_dx) * (S - wp.outer(sv, fx))):
            wp.atomic_max(error, 1, 1)

    @wp.kernel(enable_backward=False)
    def contact_gather(
        x: wp.array(dtype=vec),
        clamped: wp.array(dtype=wp.int32),
        block: Block,
        dt: scalar,
        grid_dv: wp.array(dtype=vec),
        out: wp.array(dtype=Particles),
        ct: wp.array(dtype=ContactGrid),
    ):
        """Total Lagrangian with contact: each particle takes the contact corrections of its own field,
        dv = sum w dv_i, into its velocity, and moves by dt dv (``x`` the positions the contact grid's weights
        were taken at). C and F keep the reference grid's values."""
        p = wp.tid()
        if clamped[p] != 0:
            return
        base, fx = local_coords(x[p], block.lo, scalar(1.0) / block.dx)
        if outside_block(base, block.shape):
            return
        w0, w1, w2 = bspline_weights(fx)
        dv = vec()
        first = flat_index(base, block.shape)
        for q in range(NS):
            weight, of, idx = stencil_node(q, w0, w1, w2, first, block.shape)
            dv = dv + weight * grid_dv[slot_of(ct, p, idx)]
        o = out[0]
        o.v[p] = o.v[p] + dv
        o.x[p] = o.x[p] + dt * dv

    return dict(g2p=g2p, remap_scatter=remap_scatter, reset_reductions=reset_reductions, remap_node_velocity=remap_node_velocity, remap_F=remap_F,
                contact_gather=contact_gather, load_step=load_step,
                load_params=load_params)


# -- launchers: the one place each kernel's argument order is written (as in :mod:`magsoro.mpm.kernels.p2g`) -----------

def launch_g2p(kernels, n, *, grid_v, bodies, block, dt, x_in, x_cur, F_in, out, checks, f_update, grid_r, contact,
               device, record=False):
    """``g2p`` over ``n`` particles: node velocities ``grid_v``; ``x_in`` where the weights are taken, ``x_cur``
    the positions advected, ``F_in`` the input F; ``out`` the Particles struct array written, ``checks`` the Checks
    struct array; ``f_update`` an FUpdate code; ``grid_r`` the remap's scatter target."""
    return wp.launch(kernels["g2p"], dim=n, device=device, record_cmd=record,
                     inputs=[grid_v, bodies, block, dt, x_in, x_cur, F_in, out, checks, f_update, grid_r, contact])


def launch_remap_scatter(kernels, n, *, x, bodies, block, out, grid_r, contact, spread, device, record=False):
    """``remap_scatter``: ``n`` = particles (``spread`` 0) or particles x 3^dim (``spread`` 1)."""
    return wp.launch(kernels["remap_scatter"], dim=n, device=device, record_cmd=record,
                     inputs=[x, bodies, block, out, grid_r, contact, spread])


def launch_remap_node_velocity(kernels, n, *, grid_r, grid_m, grid_clamp, grid_w, n_nodes, block, axis, device,
                               record=False):
    """``remap_node_velocity`` over ``n`` slots (velocity fields x ``n_nodes``) of the grid block ``block``;
    ``axis`` 1: an axisymmetric scene's (the nodes near the axis mirrored)."""
    return wp.launch(kernels["remap_node_velocity"], dim=n, device=device, record_cmd=record,
                     inputs=[grid_r, grid_m, grid_clamp, grid_w, n_nodes, block, int(axis)])


def launch_remap_F(kernels, n, *, x, bodies, block, dt, grid_w, F_in, F_out, error, contact, device, record=False):
    """``remap_F`` over ``n`` particles: F_out from F_in and the remapped node velocities ``grid_w``."""
    return wp.launch(kernels["remap_F"], dim=n, device=device, record_cmd=record,
                     inputs=[x, bodies, block, dt, grid_w, F_in, F_out, error, contact])


def launch_contact_gather(kernels, n, *, x, clamped, block, dt, grid_dv, out, contact, device, record=False):
    """``contact_gather`` over ``n`` particles: the contact corrections ``grid_dv`` into ``out``'s v and x."""
    return wp.launch(kernels["contact_gather"], dim=n, device=device, record_cmd=record,
                     inputs=[x, clamped, block, dt, grid_dv, out, contact])


def launch_reset_reductions(kernels, *, bounds, max_speed, big, device, record=False):
    """``reset_reductions`` (one thread): particle bounds to +-``big``, top speed to 0."""
    return wp.launch(kernels["reset_reductions"], dim=1, device=device, record_cmd=record,
                     inputs=[bounds, max_speed, big])


def launch_load_step(kernels, *, table, width, cursor, step, colliders, path, n_moving, device, record=False):
    """``load_step`` (one thread): the drive table's next row into the Step, and the moving colliders' states at
    that step from ``path`` into ``colliders``."""
    return wp.launch(kernels["load_step"], dim=1, device=device, record_cmd=record,
                     inputs=[table, width, cursor, step, colliders, path, n_moving])


def launch_load_params(kernels, n, *, table, width, cursor, offset, params, device, record=False):
    """``load_params`` over the ``n`` values of a field source's parameter array ``params``."""
    return wp.launch(kernels["load_params"], dim=n, device=device, record_cmd=record,
                     inputs=[table, width, cursor, offset, params])
