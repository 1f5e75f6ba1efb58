"""Grid kernels: node velocities from the scattered momenta (damping, gravity, domain walls, rigid colliders,
contact between velocity fields), and the sum of the CPU threads' private grids.

Colliders come as an array of :class:`magsoro.mpm.colliders.DeviceCollider` structs; the contact modes of colliders
and walls are :class:`magsoro.mpm.settings.ColliderMode`'s codes.
"""

import functools

import warp as wp

from magsoro.mpm.colliders import DeviceCollider, collider_sdf
from magsoro.mpm.kernels.contact import BODIES, SINGLE as SINGLE_FIELD, make_contact
from magsoro.mpm.settings import ColliderMode
from magsoro.mpm.kernels.stencil import make_stencil, make_types

# the contact modes as the kernels' ints
STICKY, FRICTION, SYMMETRY = (wp.constant(int(m)) for m in (ColliderMode.STICKY, ColliderMode.FRICTION, ColliderMode.SYMMETRY))


@functools.cache
def grid_settings_struct(dim: int, scalar):
    """The grid update's settings struct for ``dim`` and ``scalar`` (one class for both kernel variants)."""
    vec, Step = make_types(dim, scalar).vec, make_types(dim, scalar).Step

    @wp.struct
    class GridSettings:
        """What the grid update applies to a node's free velocity: the step dt (s), the damping factor
        exp(-c dt) of f = -c p, gravity (m/s^2), the domain walls (box lo .. hi, m; contact mode and friction of
        nodes within two cells of a wall), the grid spacing dx (m) and the rigid colliders (``n_colliders``
        DeviceCollider structs, :mod:`magsoro.mpm.colliders`; ``plane_z``: the z of a 2D scene's plane, m).
        ``node_shift`` = 1 (total Lagrangian): walls and colliders act at the nodes' current positions, the
        reference node plus the mass-weighted displacement of its particles (``node_displacement`` in
        :mod:`magsoro.mpm.kernels.p2g`), and a node is in contact with a collider from signed distance
        ``collider_skin`` (m) down. With ``record_impulse`` = 1 each collider adds the momentum it takes from
        the nodes it touches, -m dv (N s; three components per collider, 2D z = 0), to ``collider_impulse``: over
        an interval, the impulse the bodies give it (its force times the interval). ``axis`` = 1: the scene is
        axisymmetric about the node line x = ``axis_node``, and each node there and on either side takes its mirror
        node's mass and mirrored momentum (:func:`fold`)."""

        dt: scalar
        damping_factor: scalar
        gravity: vec
        dx: scalar
        domain_lo: vec
        domain_hi: vec
        wall_mode: int
        wall_friction: scalar
        colliders: wp.array(dtype=DeviceCollider)
        n_colliders: int
        plane_z: wp.float64
        node_shift: int
        collider_skin: wp.float64
        step: wp.array(dtype=Step)  # with stepped = 1, dt and the damping factor come from step[0] (stencil Step)
        stepped: int
        collider_impulse: wp.array(dtype=wp.float64)
        record_impulse: int
        clamp_velocity: wp.array(dtype=vec)  # velocity of held nodes per clamp code (Bodies.clamp_velocity)
        axis: int  # 1: an axisymmetric scene, its axis the node line x = axis_node (global node index)
        axis_node: int

    return GridSettings


@functools.cache
def make_grid(dim: int, scalar, two_fields: bool = False, differentiable: bool = False) -> dict:
    """Node kernels for ``dim``, ``scalar``; ``two_fields``: the contact variant (:mod:`magsoro.mpm.kernels.contact`);
    ``differentiable``: with the adjoints of the kernels the differentiable rollout (:mod:`magsoro.diff`) records
    on its wp.Tape. Warp otherwise builds none (docs/engine.md, "Compile time")."""
    s = make_stencil(dim, scalar, two_fields)
    t = s.types
    vec, ivec, v3 = t.vec, t.ivec, t.v3
    ContactGrid = s.ContactGrid
    inplane, node_of_flat, axis_mirror = s.inplane, s.node_of_flat, s.axis_mirror
    resolve_contact = make_contact(dim, scalar)["resolve"]
    GridSettings = grid_settings_struct(dim, scalar)

    @wp.func
    def project(vel: vec, cvel: vec, normal: vec, mode: int, mu: scalar):
        """Velocity projection against a rigid surface moving at ``cvel`` with outward unit ``normal``:
        sticky -> the node moves with the surface; slip -> the approaching normal component is removed;
        friction -> also the tangential part shrinks by mu |v_n| (Coulomb), stopping when it would reverse;
        symmetry -> the normal component is removed in both directions (a mirror plane: no separation)."""
        if mode == STICKY:
            return cvel
        vr = vel - cvel
        vn = wp.dot(vr, normal)
        if mode == SYMMETRY:
            return vr - vn * normal + cvel
        if vn >= scalar(0.0):
            return vel  # separating: no contact force
        vt = vr - vn * normal
        if mode == FRICTION:
            vt_norm = wp.length(vt)
            if vt_norm > scalar(0.0):
                vt = vt * (wp.max(vt_norm + mu * vn, scalar(0.0)) / vt_norm)
        return vt + cvel

    @wp.func
    def walls(vel: vec, pos: vec, gs: GridSettings):
        """Domain walls: nodes within two cells of a wall may not move into it."""
        for a in range(dim):
            normal = vec()
            if pos[a] < gs.domain_lo[a] + scalar(2.0) * gs.dx:
                normal[a] = scalar(1.0)
                vel = project(vel, vec(), normal, gs.wall_mode, gs.wall_friction)
            if pos[a] > gs.domain_hi[a] - scalar(2.0) * gs.dx:
                normal[a] = scalar(-1.0)
                vel = project(vel, vec(), normal, gs.wall_mode, gs.wall_friction)
        return vel

    @wp.func
    def colliders(vel: vec, pos: vec, m: scalar, gs: GridSettings, record: int):
        """Rigid colliders: a node with signed distance <= collider_skin is in contact (its momentum change
        recorded with ``gs.record_impulse``); symmetry planes take every node within half a cell."""
        p3 = wp.vec3d(wp.float64(pos[0]), wp.float64(pos[1]), gs.plane_z)
        if wp.static(dim == 3):
            p3 = wp.vec3d(wp.float64(pos[0]), wp.float64(pos[1]), wp.float64(pos[2]))
        for c in range(gs.n_colliders):
            col = gs.colliders[c]
            phi, nrm, cvel = collider_sdf(col, p3)
            mode = int(col.mode)
            skin = gs.collider_skin
            if mode == SYMMETRY:
                # a mirror plane holds the node layer on it: every node within half a cell of it (a plane through
                # a node layer is then safe from round-off in phi)
                skin = wp.max(skin, wp.float64(0.5) * wp.float64(gs.dx))
            if phi <= skin:
                mu = scalar(col.friction)
                before = vel
                vel = project(vel, inplane(v3(cvel)), inplane(v3(nrm)), mode, mu)
                if record != 0:
                    for a in range(dim):
                        wp.atomic_add(gs.collider_impulse, 3 * c + a, wp.float64(m * (before[a] - vel[a])))
        return vel

    @wp.func
    def node_velocity(momentum: vec, m: scalar, pos: vec, gs: GridSettings, record: int):
        """Velocity of one field of a node after damping, gravity, the domain walls and the rigid colliders (which
        add the momentum they take to their impulses when ``record``)."""
        # damping f = -c p (seed 000 eq 17), integrated exactly over the step so any c is stable
        dt = gs.dt
        damping_factor = gs.damping_factor
        if gs.stepped != 0:
            sv = gs.step[0]
            dt = sv.dt
            damping_factor = sv.damping_factor
        vel = momentum / m * damping_factor + dt * gs.gravity
        # colliders before the walls: a friction floor within two cells of the domain's edge takes its friction
        # from the approaching normal velocity, which a slip wall applied first would have removed (a block on
        # such a floor slid as if frictionless)
        if gs.n_colliders > 0:
            vel = colliders(vel, pos, m, gs, record)
        vel = walls(vel, pos, gs)
        return vel

    @wp.func
    def single(ct: wp.array(dtype=ContactGrid), idx: int):
        """Whether node ``idx`` carries one velocity field (always, without contact)."""
        one = True
        if wp.static(two_fields):
            one = ct[0].split[idx] == SINGLE_FIELD
        return one

    @wp.func
    def fold(grid_p: wp.array(dtype=vec), grid_m: wp.array(dtype=scalar), grid_u: wp.array(dtype=vec), idx: int,
             n: ivec, org: ivec, shape: ivec, gs: GridSettings, ct: wp.array(dtype=ContactGrid)):
        """An axisymmetric scene's nodes near the axis: the velocity field is mirror-symmetric about r = 0 (v_r odd,
        v_z even), so the node at r = k dx and its mirror at -k dx carry one unknown: both take the summed mass
        and the momentum p + M p' (M flips the radial component), and the node on the axis has no radial momentum.
        Returns (momentum, mass, mass-weighted displacement) of node ``idx`` at global node ``n``."""
        p = grid_p[idx]
        m = grid_m[idx]
        u = vec()
        if gs.node_shift != 0:
            u = grid_u[idx]
        k = n[0] - gs.axis_node
        if k == 0:
            p[0] = scalar(0.0)
            u[0] = scalar(0.0)
        elif k >= -2 and k <= 2:
            j = axis_mirror(n - org, k, shape)
            # with contact, only nodes of one field on both sides (the scene keeps contact off the axis)
            if j >= 0 and single(ct, idx) and single(ct, j):
                q = grid_p[j]
                q[0] = -q[0]
                p = p + q
                m = m + grid_m[j]
                if gs.node_shift != 0:
                    w = grid_u[j]
                    w[0] = -w[0]
                    u = u + w
        return p, m, u

    @wp.kernel(enable_backward=differentiable)
    def grid_update(
        grid_p: wp.array(dtype=vec),
        grid_m: wp.array(dtype=scalar),
        grid_clamp: wp.array(dtype=wp.int32),
        org: ivec,
        shape: ivec,
        gs: GridSettings,
        grid_v: wp.array(dtype=vec),
        ct: wp.array(dtype=ContactGrid),
        grid_u: wp.array(dtype=vec),
    ):
        """Node velocities. With contact, a node's second field (slot idx + n_nodes) gets its own velocity and the
        two are corrected for contact (:mod:`magsoro.mpm.kernels.contact`). With ``gs.node_shift`` the node sits at its
        reference position plus ``grid_u[idx] / m`` (mass-weighted particle displacement) for walls and
        colliders."""
        idx = wp.tid()
        m = grid_m[idx]
        momentum = grid_p[idx]
        shift = vec()
        if gs.node_shift != 0:
            shift = grid_u[idx]
        code = grid_clamp[idx]
        held = code != 0
        if gs.axis != 0:
            momentum, m, shift = fold(grid_p, grid_m, grid_u, idx, node_of_flat(idx, shape) + org, org, shape, gs, ct)
        if wp.static(not two_fields):
            if m <= scalar(0.0):
                grid_v[idx] = vec()  # empty node: most of the grid block
                return
            if held:  # a held node moves with its clamp (at rest unless the clamp follows a path)
                grid_v[idx] = gs.clamp_velocity[code]
                return
        n = node_of_flat(idx, shape) + org
        pos = vec()
        for a in range(dim):
            pos[a] = gs.domain_lo[a] + scalar(n[a]) * gs.dx
        pos0 = pos
        if gs.node_shift != 0 and m > scalar(0.0):
            pos0 = pos + shift / m
        vel = vec()
        if m > scalar(0.0) and not held:
            # an axisymmetric scene's mirror nodes (r < 0) repeat the nodes they mirror: not counted twice
            record = gs.record_impulse
            if gs.axis != 0 and n[0] < gs.axis_node:
                record = 0
            vel = node_velocity(momentum, m, pos0, gs, record)
            if gs.axis != 0 and n[0] == gs.axis_node:
                vel[0] = scalar(0.0)  # on the axis
        elif m > scalar(0.0):
            vel = gs.clamp_velocity[code]
        if wp.static(two_fields):
            slot = idx + ct[0].n_nodes
            m1 = grid_m[slot]
            vel1 = vec()
            if m1 > scalar(0.0) and not held:
                pos1 = pos
                if gs.node_shift != 0:
                    pos1 = pos + grid_u[slot] / m1
                vel1 = node_velocity(grid_p[slot], m1, pos1, gs, gs.record_impulse)
                if m > scalar(0.0):
                    vel, vel1 = resolve_contact(vel, vel1, m, m1, ct[0].grad_m[idx], ct[0].grad_m[slot], ct[0].mu[idx], ct[0].gap,
                                                 int(ct[0].split[idx] == BODIES))
            grid_v[slot] = vel1
        grid_v[idx] = vel

    @wp.kernel(enable_backward=False)
    def add_grid(dst_p: wp.array(dtype=vec), src_p: wp.array(dtype=vec), dst_m: wp.array(dtype=scalar), src_m: wp.array(dtype=scalar), with_mass: int):
        """Sum a worker thread's private grid into the shared one (CPU threads: Warp's CPU atomics are plain adds,
        so each thread scatters into its own copy)."""
        i = wp.tid()
        dst_p[i] = dst_p[i] + src_p[i]
        if with_mass != 0:
            dst_m[i] = dst_m[i] + src_m[i]

    @wp.kernel(enable_backward=False)
    def contact_resolve(
        grid_p: wp.array(dtype=vec),
        grid_m: wp.array(dtype=scalar),
        ct: wp.array(dtype=ContactGrid),
        grid_dv: wp.array(dtype=vec),
    ):
        """Total Lagrangian with contact: the correction dv of each field of a node (slots idx and idx + n_nodes)
        that the contact law (:mod:`magsoro.mpm.kernels.contact`) makes to the fields' velocities p / m; zero where a
        node has one field."""
        idx = wp.tid()
        slot = idx + ct[0].n_nodes
        m0 = grid_m[idx]
        m1 = grid_m[slot]
        dv0 = vec()
        dv1 = vec()
        if m0 > scalar(0.0) and m1 > scalar(0.0):
            v0 = grid_p[idx] / m0
            v1 = grid_p[slot] / m1
            n0, n1 = resolve_contact(v0, v1, m0, m1, ct[0].grad_m[idx], ct[0].grad_m[slot], ct[0].mu[idx], ct[0].gap,
                                      int(ct[0].split[idx] == BODIES))
            dv0 = n0 - v0
            dv1 = n1 - v1
        grid_dv[idx] = dv0
        grid_dv[slot] = dv1

    return dict(grid_update=grid_update, add_grid=add_grid, GridSettings=GridSettings, contact_resolve=contact_resolve)


# -- launchers: the one place each kernel's argument order is written (as in :mod:`magsoro.mpm.kernels.p2g`) -----------

def launch_grid_update(kernels, n, *, grid_p, grid_m, grid_clamp, org, shape, settings, grid_v, contact, grid_u,
                       device, record=False):
    """``grid_update`` over ``n`` nodes of the block at node ``org`` of ``shape``: momenta ``grid_p`` and masses
    ``grid_m`` to velocities ``grid_v`` under the GridSettings struct ``settings`` (``grid_clamp`` the held nodes,
    ``grid_u`` the total form's node displacements)."""
    return wp.launch(kernels["grid_update"], dim=n, device=device, record_cmd=record,
                     inputs=[grid_p, grid_m, grid_clamp, org, shape, settings, grid_v, contact, grid_u])


def launch_add_grid(kernels, n, *, dst_p, src_p, dst_m, src_m, with_mass, device, record=False):
    """``add_grid`` over ``n`` nodes: a thread's private grid ``src_*`` added into ``dst_*`` (masses too when
    ``with_mass`` is 1)."""
    return wp.launch(kernels["add_grid"], dim=n, device=device, record_cmd=record,
                     inputs=[dst_p, src_p, dst_m, src_m, with_mass])


def launch_contact_resolve(kernels, n, *, grid_p, grid_m, contact, grid_dv, device, record=False):
    """``contact_resolve`` over ``n`` nodes: the contact law's velocity corrections into ``grid_dv``."""
    return wp.launch(kernels["contact_resolve"], dim=n, device=device, record_cmd=record,
                     inputs=[grid_p, grid_m, contact, grid_dv])
