"""MLS-MPM kernels (seed 000 eqs 1-19), generated for a dimension (2 = plane strain, 3) and a precision.

One factory builds every kernel from the same source, so 2D/3D and float32/float64 never drift apart; Warp
compiles them for CPU and CUDA alike. Notation: dx grid spacing, inv_dx = 1/dx, particles carry reference
volume V0, mass, shear modulus G, bulk modulus K, remanence Br (reference frame, in-plane part in 2D).

Grid: a dense block of nodes whose global index origin ``org`` and shape ``shape`` follow the bodies (see
:mod:`magsoro.mpm.solver`); arrays are flat, node (i, j[, k]) at ((i * ny) + j) * nz + k.
Colliders come as a flat float64 table, one row of ``COLLIDER_STRIDE`` values each (see :mod:`colliders`).
"""

import functools

import warp as wp

from magsoro.constants import MU0
from magsoro.mpm.colliders import COLLIDER_STRIDE, collider_sdf
from magsoro.mpm.contact import make_contact
from magsoro.mpm.materials import make_material_functions

# Unroll the 3^dim-node stencil loops (27 in 3D): constant offsets let the compiler fold the weight selection.
wp.set_module_options({"max_unroll": 32})

# Collider boundary modes (also used by the scene schema)
STICKY = 0
SLIP = 1
FRICTION = 2


@functools.cache
def grid_settings_struct(dim: int, scalar):
    """The grid update's settings struct for ``dim`` and ``scalar`` (one class for both kernel variants)."""
    vec = wp.types.vector(length=dim, dtype=scalar)

    @wp.struct
    class GridSettings:
        """What the grid update applies to a node's free velocity: the step dt (s), the damping factor
        exp(-c dt) of f = -c p, gravity (m/s^2), the domain walls (box lo .. hi, m; contact mode and friction of
        nodes within two cells of a wall), the grid spacing dx (m) and the rigid colliders (flat float64 table of
        ``n_colliders`` rows, :mod:`magsoro.mpm.colliders`; ``plane_z``: the z of a 2D scene's plane, m).
        ``node_shift`` = 1 (total Lagrangian): walls and colliders act at the nodes' current positions, the
        reference node plus the mass-weighted displacement of its particles (:func:`node_displacement`), and a
        node is in contact with a collider from signed distance ``collider_skin`` (m) down."""

        dt: scalar
        damping_factor: scalar
        gravity: vec
        dx: scalar
        domain_lo: vec
        domain_hi: vec
        wall_mode: int
        wall_friction: scalar
        colliders: wp.array(dtype=wp.float64)
        n_colliders: int
        plane_z: wp.float64
        node_shift: int
        collider_skin: wp.float64

    return GridSettings


@functools.cache
def make_kernels(dim: int, scalar, contact: bool = False):
    """Return a namespace of kernels and functions for ``dim`` in (2, 3) and ``scalar`` in (wp.float32, wp.float64).

    ``contact``: the variant with two velocity fields per node (:mod:`magsoro.mpm.contact`). Without it the
    kernels never read their contact argument, which on CPU doubled the grid update of a single body (a few
    nanoseconds per node against about 4 ns for the whole update)."""
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    two_fields = bool(contact)  # the name ``contact`` is taken below by the collider velocity projection
    vec = wp.types.vector(length=dim, dtype=scalar)
    mat = wp.types.matrix(shape=(dim, dim), dtype=scalar)
    ivec = wp.types.vector(length=dim, dtype=wp.int32)
    v3 = wp.types.vector(length=3, dtype=scalar)
    m3 = wp.types.matrix(shape=(3, 3), dtype=scalar)
    NS = 3**dim
    ct_ns = make_contact(dim, scalar)
    ContactGrid = ct_ns["ContactGrid"]
    field_of = ct_ns["field_of"]
    resolve_contact = ct_ns["resolve"]

    @wp.func
    def slot_of(ct: wp.array(dtype=ContactGrid), p: int, idx: int):
        """Grid slot of particle ``p``'s velocity field at node ``idx``: the node itself without contact."""
        if wp.static(two_fields):
            return idx + field_of(ct, p, idx) * ct[0].n_nodes
        return idx
    # Constants are computed here in double precision: literal arithmetic inside a kernel runs in float32.
    inv_mu0 = 1.0 / MU0

    # Constitutive laws (stress and energy of each registered law): see magsoro.mpm.materials
    elastic = make_material_functions(dim, scalar)
    elastic_stress = elastic["elastic_stress"]
    elastic_energy = elastic["elastic_energy"]

    @wp.func
    def inplane(b: v3):
        if wp.static(dim == 2):
            return vec(b[0], b[1])
        else:
            return vec(b[0], b[1], b[2])

    @wp.func
    def bspline_weights(fx: vec):
        """Quadratic B-spline weights (seed 000 eq 2) of the three nodes base, base+1, base+2 along each axis."""
        one = vec()
        for a in range(dim):
            one[a] = scalar(1.0)
        half = scalar(0.5) * one
        w0 = scalar(0.5) * wp.cw_mul(scalar(1.5) * one - fx, scalar(1.5) * one - fx)
        w1 = scalar(0.75) * one - wp.cw_mul(fx - one, fx - one)
        w2 = scalar(0.5) * wp.cw_mul(fx - half, fx - half)
        return w0, w1, w2

    @wp.func
    def pick(w0: vec, w1: vec, w2: vec, o: int):
        """The weights of offset ``o`` (a constant once the stencil loop is unrolled) along every axis."""
        if o == 0:
            return w0
        if o == 1:
            return w1
        return w2

    @wp.func
    def stencil_offset(q: int):
        o = ivec()
        if wp.static(dim == 2):
            o = ivec(q // 3, q % 3)
        else:
            o = ivec(q // 9, (q // 3) % 3, q % 3)
        return o

    @wp.func
    def flat_index(n: ivec, shape: ivec):
        if wp.static(dim == 2):
            return n[0] * shape[1] + n[1]
        else:
            return (n[0] * shape[1] + n[1]) * shape[2] + n[2]

    @wp.func
    def node_of_flat(idx: int, shape: ivec):
        n = ivec()
        if wp.static(dim == 2):
            n = ivec(idx // shape[1], idx % shape[1])
        else:
            n = ivec(idx // (shape[1] * shape[2]), (idx // shape[2]) % shape[1], idx % shape[2])
        return n

    @wp.func
    def local_coords(xp: vec, grid_lo: vec, inv_dx: scalar):
        xg = (xp - grid_lo) * inv_dx
        base = ivec()
        fx = vec()
        for a in range(dim):
            b = int(wp.floor(xg[a] - scalar(0.5)))
            base[a] = b
            fx[a] = xg[a] - scalar(b)
        return base, fx

    @wp.func
    def outside_block(base: ivec, shape: ivec):
        """True when a particle's 3^dim stencil (nodes base .. base + 2) leaves the active grid block."""
        out = False
        for a in range(dim):
            if base[a] < 0 or base[a] + 2 >= shape[a]:
                out = True
        return out

    @wp.func
    def stencil_node(q: int, w0: vec, w1: vec, w2: vec, first: int, shape: ivec):
        """Weight, integer offset o (as a vector) and flat grid index of the q-th node of a particle's 3^dim
        stencil; ``first`` is the flat index of its base node. The node's offset from the particle is
        x_i - x_p = (o - fx) dx: the loops below sum with o and subtract the fx part once, so that with q a
        constant (the loops are unrolled) each node costs a few additions instead of a product with (o - fx)."""
        o = stencil_offset(q)
        weight = scalar(1.0)
        of = vec()
        for a in range(dim):
            weight = weight * pick(w0, w1, w2, o[a])[a]
            of[a] = scalar(o[a])
        return weight, of, first + flat_index(o, shape)

    @wp.func
    def update_F(F_in: wp.array(dtype=mat), F_out: wp.array(dtype=mat), p: int, dtC: mat):
        """F_out = F + (dt C) F; False when the element inverts (det F <= 0) or F is not finite.
        F + (dt C) F rather than (I + dt C) F: in float32, 1 + dt C_ii rounds the small increments of a slowly
        creeping state away, which showed as a steady drift of loaded beams (docs/engine.md)."""
        Fp = F_in[p]
        Fn = Fp + dtC * Fp
        F_out[p] = Fn
        return wp.determinant(Fn) > scalar(0.0)

    @wp.kernel
    def p2g(
        x: wp.array(dtype=vec),
        v: wp.array(dtype=vec),
        C: wp.array(dtype=mat),
        F: wp.array(dtype=mat),
        vol0: wp.array(dtype=scalar),
        mass: wp.array(dtype=scalar),
        shear: wp.array(dtype=scalar),
        bulk: wp.array(dtype=scalar),
        material_model: wp.array(dtype=wp.int32),
        material_params: wp.array(dtype=v3),
        Br: wp.array(dtype=v3),
        clamped: wp.array(dtype=wp.int32),
        B_uniform: v3,
        has_gradient: int,
        B_particle: wp.array(dtype=v3),
        G_particle: wp.array(dtype=m3),
        grid_lo: vec,
        shape: ivec,
        dx: scalar,
        dt: scalar,
        grid_p: wp.array(dtype=vec),
        grid_m: wp.array(dtype=scalar),
        grid_clamp: wp.array(dtype=wp.int32),
        error: wp.array(dtype=wp.int32),
        total: int,
        ct: wp.array(dtype=ContactGrid),
    ):
        """Particle-to-grid transfer of mass, momentum and the stress impulse. ``x`` are the positions the grid
        weights are taken at: the current ones (updated Lagrangian, ``total`` = 0) or the reference ones (total
        Lagrangian, ``total`` = 1: the grid is the reference configuration's, and the node force takes the first
        Piola stress P instead of the Kirchhoff stress P F^T). In the contact variant each node has two
        velocity fields (:mod:`magsoro.mpm.contact`): the particle scatters into its own, and adds its share of
        that field's mass gradient."""
        p = wp.tid()
        inv_dx = scalar(1.0) / dx
        base, fx = local_coords(x[p], grid_lo, inv_dx)
        if outside_block(base, shape):
            error[0] = 1  # particle outside the active grid block: the solver refits and reports
            return
        w0, w1, w2 = bspline_weights(fx)
        Fp = F[p]
        B = B_uniform
        if has_gradient != 0:
            B = B + B_particle[p]
        br = Br[p]
        # Magnetic stress of a hard-magnetic elastomer (seed 000 eq 13): P = -(1/mu0) B (x) Br
        P = elastic_stress(Fp, material_model[p], shear[p], bulk[p], material_params[p]) - scalar(inv_mu0) * wp.outer(inplane(B), inplane(br))
        # MLS-MPM: grid force -V0 P F^T grad w, with grad w = (4/dx^2) w (x_i - x_p) for quadratic B-splines
        stress = (-dt * vol0[p] * scalar(4.0) * inv_dx * inv_dx) * P
        if total == 0:
            stress = stress * wp.transpose(Fp)
        mp = mass[p]
        affine = stress + mp * C[p]
        mv = mp * v[p]
        if has_gradient != 0:
            # Gradient force (seed 000 eqs 15-16) per particle: f = (grad B)^T m, m = F Br V0 / mu0 the current
            # moment; summing w f over nodes gives the node form since the weights sum to one.
            Fbr = inplane(br)
            Fbr = Fp * Fbr
            m3d = v3()
            for a in range(dim):
                m3d[a] = Fbr[a]
            if wp.static(dim == 2):
                m3d[2] = br[2]  # plane strain: F_zz = 1
            m3d = m3d * (vol0[p] * scalar(inv_mu0))
            f3 = wp.transpose(G_particle[p]) * m3d
            mv = mv + dt * inplane(f3)
        is_clamped = clamped[p]
        # node value mv + affine (x_i - x_p) = mv + ((affine dx) o - affine fx dx). mv is added per node, not
        # folded into the constant part: the small momentum of a settling body would lose its low bits to the
        # large stress term once for all 27 nodes alike, a bias that makes float32 bodies creep
        A = affine * dx
        Afx = A * fx
        first = flat_index(base, shape)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
            slot = slot_of(ct, p, idx)
            wp.atomic_add(grid_p, slot, weight * (mv + (A * o - Afx)))
            wp.atomic_add(grid_m, slot, weight * mp)
            if wp.static(two_fields):
                wp.atomic_add(ct[0].grad_m, slot, (weight * mp) * (o - fx))
            if is_clamped != 0:
                grid_clamp[idx] = 1

    @wp.func
    def contact(vel: vec, cvel: vec, normal: vec, mode: int, mu: scalar):
        """Velocity projection against a rigid surface moving at ``cvel`` with outward unit ``normal``:
        sticky -> the node moves with the surface; slip -> the approaching normal component is removed;
        friction -> also the tangential part shrinks by mu |v_n| (Coulomb), stopping when it would reverse."""
        if mode == 0:
            return cvel
        vr = vel - cvel
        vn = wp.dot(vr, normal)
        if vn >= scalar(0.0):
            return vel  # separating: no contact force
        vt = vr - vn * normal
        if mode == 2:
            vt_norm = wp.length(vt)
            if vt_norm > scalar(0.0):
                vt = vt * (wp.max(vt_norm + mu * vn, scalar(0.0)) / vt_norm)
        return vt + cvel

    GridSettings = grid_settings_struct(dim, scalar)

    @wp.func
    def node_velocity(momentum: vec, m: scalar, pos: vec, gs: GridSettings):
        """Velocity of one field of a node after damping, gravity, the domain walls and the rigid colliders."""
        # damping f = -c p (seed 000 eq 17), integrated exactly over the step so any c is stable
        vel = momentum / m * gs.damping_factor + gs.dt * gs.gravity
        # domain walls: nodes within two cells of a wall may not move into it
        for a in range(dim):
            normal = vec()
            if pos[a] < gs.domain_lo[a] + scalar(2.0) * gs.dx:
                normal[a] = scalar(1.0)
                vel = contact(vel, vec(), normal, gs.wall_mode, gs.wall_friction)
            if pos[a] > gs.domain_hi[a] - scalar(2.0) * gs.dx:
                normal[a] = scalar(-1.0)
                vel = contact(vel, vec(), normal, gs.wall_mode, gs.wall_friction)
        # rigid colliders: a node with signed distance <= collider_skin is in contact
        if gs.n_colliders > 0:
            p3 = wp.vec3d(wp.float64(pos[0]), wp.float64(pos[1]), gs.plane_z)
            if wp.static(dim == 3):
                p3 = wp.vec3d(wp.float64(pos[0]), wp.float64(pos[1]), wp.float64(pos[2]))
            for c in range(gs.n_colliders):
                phi, nrm, cvel = collider_sdf(gs.colliders, c, p3)
                if phi <= gs.collider_skin:
                    row = c * COLLIDER_STRIDE
                    mode = int(gs.colliders[row + 1])
                    mu = scalar(gs.colliders[row + 2])
                    vel = contact(vel, inplane(v3(cvel)), inplane(v3(nrm)), mode, mu)
        return vel

    @wp.kernel
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
        two are corrected for contact (:mod:`magsoro.mpm.contact`). With ``gs.node_shift`` the node sits at its
        reference position plus ``grid_u[idx] / m`` (mass-weighted particle displacement) for walls and
        colliders."""
        idx = wp.tid()
        m = grid_m[idx]
        held = grid_clamp[idx] != 0
        if wp.static(not two_fields):
            if m <= scalar(0.0) or held:
                grid_v[idx] = vec()  # empty or held node: most of the grid block
                return
        n = node_of_flat(idx, shape) + org
        pos = vec()
        for a in range(dim):
            pos[a] = gs.domain_lo[a] + scalar(n[a]) * gs.dx
        if gs.node_shift != 0 and m > scalar(0.0):
            pos = pos + grid_u[idx] / m
        vel = vec()
        if m > scalar(0.0) and not held:
            vel = node_velocity(grid_p[idx], m, pos, gs)
        if wp.static(two_fields):
            slot = idx + ct[0].n_nodes
            m1 = grid_m[slot]
            vel1 = vec()
            if m1 > scalar(0.0) and not held:
                vel1 = node_velocity(grid_p[slot], m1, pos, gs)
                if m > scalar(0.0):
                    vel, vel1 = resolve_contact(vel, vel1, m, m1, ct[0].grad_m[idx], ct[0].grad_m[slot], ct[0].mu[idx], ct[0].gap)
            grid_v[slot] = vel1
        grid_v[idx] = vel

    @wp.kernel
    def g2p(
        grid_v: wp.array(dtype=vec),
        clamped: wp.array(dtype=wp.int32),
        grid_lo: vec,
        shape: ivec,
        dx: scalar,
        dt: scalar,
        x_in: wp.array(dtype=vec),
        F_in: wp.array(dtype=mat),
        x_out: wp.array(dtype=vec),
        v_out: wp.array(dtype=vec),
        C_out: wp.array(dtype=mat),
        F_out: wp.array(dtype=mat),
        bounds: wp.array(dtype=scalar),
        max_speed: wp.array(dtype=scalar),
        error: wp.array(dtype=wp.int32),
        remap: int,
        mass: wp.array(dtype=scalar),
        grid_r: wp.array(dtype=vec),
        x_cur: wp.array(dtype=vec),
        total: int,
        ct: wp.array(dtype=ContactGrid),
    ):
        """Grid-to-particle transfer: new x, v, C. With ``remap`` = 0 F is updated from the same node velocities
        ("grid"); otherwise F_out is left to :func:`remap_F`, and the particle's new affine velocity field
        v + C (x_i - x_p) is scattered, mass-weighted, into ``grid_r`` (the first half of the velocity-gradient
        remap; it needs only this particle's new v and C, so it rides on the same stencil pass).

        ``x_in`` are the positions the grid weights are taken at and ``x_cur`` the particles' current positions,
        which move by dt v: the same array in the updated-Lagrangian form (``total`` = 0). In the
        total-Lagrangian form ``x_in`` holds the reference positions, C is the velocity gradient with respect to
        them and F grows by dt C (``remap`` must be 0); the bounds reduction then covers the reference positions,
        which the grid block is fitted to."""
        p = wp.tid()
        xp = x_in[p]
        xc = x_cur[p]
        if clamped[p] != 0:
            # held particles keep their place and shape
            x_out[p] = xc
            v_out[p] = vec()
            C_out[p] = mat()
            F_out[p] = F_in[p]
        else:
            inv_dx = scalar(1.0) / dx
            base, fx = local_coords(xp, grid_lo, inv_dx)
            w0, w1, w2 = bspline_weights(fx)
            new_v = vec()
            S = mat()
            first = flat_index(base, shape)
            for q in range(NS):
                weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
                wgv = weight * grid_v[slot_of(ct, p, idx)]
                new_v = new_v + wgv
                S = S + wp.outer(wgv, o)
            # C = (4/dx^2) sum w v_i (x_i - x_p)^T = (4/dx) (sum w v_i o^T - v fx^T)
            new_C = (scalar(4.0) * inv_dx) * (S - wp.outer(new_v, fx))
            xc = xc + dt * new_v
            x_out[p] = xc
            if total == 0:
                xp = xc
            v_out[p] = new_v
            C_out[p] = new_C
            ok = True
            if total != 0:
                Fn = F_in[p] + dt * new_C
                F_out[p] = Fn
                ok = wp.determinant(Fn) > scalar(0.0)
            elif remap == 0:
                ok = update_F(F_in, F_out, p, dt * new_C)
            else:
                mp = mass[p]
                Cd = new_C * dx
                Cfx = Cd * fx
                for q in range(NS):  # new_v added per node, as in p2g
                    weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
                    slot = slot_of(ct, p, idx)
                    wp.atomic_add(grid_r, slot, (weight * mp) * (new_v + (Cd * o - Cfx)))
            for a in range(dim):
                if not wp.isfinite(xc[a]) or not wp.isfinite(new_v[a]):
                    ok = False
            if not ok:
                wp.atomic_max(error, 1, 1)
            wp.atomic_max(max_speed, 0, wp.length(new_v))
        for a in range(dim):
            wp.atomic_min(bounds, a, xp[a])
            wp.atomic_max(bounds, dim + a, xp[a])

    @wp.kernel
    def node_displacement(
        X: wp.array(dtype=vec),
        x: wp.array(dtype=vec),
        mass: wp.array(dtype=scalar),
        grid_lo: vec,
        shape: ivec,
        dx: scalar,
        grid_u: wp.array(dtype=vec),
    ):
        """Total Lagrangian: scatter each particle's mass-weighted displacement m (x - X) to the reference grid,
        so that node i sits at X_i + sum w m u / sum w m in the current configuration, where the walls and
        colliders act on it (exact for a rigid translation; first order in the displacement gradient)."""
        p = wp.tid()
        base, fx = local_coords(X[p], grid_lo, scalar(1.0) / dx)
        if outside_block(base, shape):
            return  # p2g flags it
        w0, w1, w2 = bspline_weights(fx)
        mu = mass[p] * (x[p] - X[p])
        first = flat_index(base, shape)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
            wp.atomic_add(grid_u, idx, weight * mu)

    @wp.kernel
    def contact_scan(
        x: wp.array(dtype=vec),
        X: wp.array(dtype=vec),
        mass: wp.array(dtype=scalar),
        group: wp.array(dtype=wp.int32),
        grid_lo: vec,
        shape: ivec,
        dx: scalar,
        fold: int,
        gmin: wp.array(dtype=wp.int32),
        gmax: wp.array(dtype=wp.int32),
        moments: wp.array(dtype=scalar),
    ):
        """Contact step 1 (:mod:`magsoro.mpm.contact`): the smallest and largest contact group reaching each node;
        with ``fold`` also the reference-position moments m, m X, m X X^T (1 + dim + dim^2 per node)."""
        p = wp.tid()
        base, fx = local_coords(x[p], grid_lo, scalar(1.0) / dx)
        if outside_block(base, shape):
            return  # p2g flags it
        w0, w1, w2 = bspline_weights(fx)
        g = group[p]
        Xp = X[p]
        mp = mass[p]
        stride = 1 + dim + dim * dim
        first = flat_index(base, shape)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
            wp.atomic_min(gmin, idx, g)
            wp.atomic_max(gmax, idx, g)
            if fold != 0:
                wm = weight * mp
                row = idx * stride
                wp.atomic_add(moments, row, wm)
                for a in range(dim):
                    wp.atomic_add(moments, row + 1 + a, wm * Xp[a])
                    for b in range(dim):
                        wp.atomic_add(moments, row + 1 + dim + a * dim + b, wm * Xp[a] * Xp[b])

    @wp.kernel
    def reset_reductions(bounds: wp.array(dtype=scalar), max_speed: wp.array(dtype=scalar), big: scalar):
        for a in range(dim):
            bounds[a] = big
            bounds[dim + a] = -big
        max_speed[0] = scalar(0.0)

    @wp.kernel
    def stress_kernel(
        F: wp.array(dtype=mat), model: int, G: scalar, K: scalar, prm: v3, P: wp.array(dtype=mat), psi: wp.array(dtype=scalar)
    ):
        i = wp.tid()
        P[i] = elastic_stress(F[i], model, G, K, prm)
        psi[i] = elastic_energy(F[i], model, G, K, prm)

    @wp.kernel
    def remap_node_velocity(
        grid_r: wp.array(dtype=vec),
        grid_m: wp.array(dtype=scalar),
        grid_clamp: wp.array(dtype=wp.int32),
        grid_w: wp.array(dtype=vec),
        n_nodes: int,
    ):
        """Node velocities of the remap: the scattered momenta over the first transfer's node masses (same
        particles, same positions), at rest on held nodes. Once per slot (node and field) instead of once per
        stencil entry; slots from ``n_nodes`` on are the contact fields of the nodes."""
        idx = wp.tid()
        m = grid_m[idx]
        node = idx
        if node >= n_nodes:
            node = idx - n_nodes
        if m > scalar(0.0) and grid_clamp[node] == 0:
            grid_w[idx] = grid_r[idx] / m
        else:
            grid_w[idx] = vec()

    @wp.kernel
    def remap_F(
        x: wp.array(dtype=vec),
        clamped: wp.array(dtype=wp.int32),
        grid_lo: vec,
        shape: ivec,
        dx: scalar,
        dt: scalar,
        grid_w: wp.array(dtype=vec),
        F_in: wp.array(dtype=mat),
        F_out: wp.array(dtype=mat),
        error: wp.array(dtype=wp.int32),
        ct: wp.array(dtype=ContactGrid),
    ):
        """F update from the remapped node velocities ``grid_w`` (:func:`remap_node_velocity`): F + dt (grad v) F
        at the particle's position at the start of the step, the same stencil as the first gather."""
        p = wp.tid()
        if clamped[p] != 0:
            F_out[p] = F_in[p]
            return
        inv_dx = scalar(1.0) / dx
        base, fx = local_coords(x[p], grid_lo, inv_dx)
        if outside_block(base, shape):
            return  # outside the grid block: p2g has flagged it, the step is discarded
        w0, w1, w2 = bspline_weights(fx)
        S = mat()
        sv = vec()
        first = flat_index(base, shape)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
            wv = weight * grid_w[slot_of(ct, p, idx)]
            sv = sv + wv
            S = S + wp.outer(wv, o)
        # as in g2p: (4/dx^2) sum w v_i (x_i - x_p)^T = (4/dx) (S - (sum w v_i) fx^T)
        if not update_F(F_in, F_out, p, (dt * scalar(4.0) * inv_dx) * (S - wp.outer(sv, fx))):
            wp.atomic_max(error, 1, 1)

    @wp.kernel
    def add_grid(dst_p: wp.array(dtype=vec), src_p: wp.array(dtype=vec), dst_m: wp.array(dtype=scalar), src_m: wp.array(dtype=scalar), with_mass: int):
        """Sum a worker thread's private grid into the shared one (CPU threads: Warp's CPU atomics are plain adds,
        so each thread scatters into its own copy)."""
        i = wp.tid()
        dst_p[i] = dst_p[i] + src_p[i]
        if with_mass != 0:
            dst_m[i] = dst_m[i] + src_m[i]

    return dict(
        add_grid=add_grid,
        remap_node_velocity=remap_node_velocity,
        remap_F=remap_F,
        p2g=p2g,
        grid_update=grid_update,
        g2p=g2p,
        reset_reductions=reset_reductions,
        stress_kernel=stress_kernel,
        ContactGrid=ContactGrid,
        GridSettings=GridSettings,
        contact_scan=contact_scan,
        node_displacement=node_displacement,
        contact_classify=ct_ns["contact_classify"],
        vec=vec,
        mat=mat,
        ivec=ivec,
        v3=v3,
        m3=m3,
    )
