"""Particle-to-grid kernels: the transfer of mass, momentum and stress impulse (seed 000 eqs 1-16), the
total-Lagrangian node displacements, and the contact scan."""

import functools

import warp as wp

from magsoro.constants import MU0
from magsoro.mpm.settings import P2GFlag
from magsoro.mpm.kernels.stencil import make_body_elastic, make_stencil
from magsoro.mpm.laws.viscous import make_viscous

#: bits of p2g's ``flags`` (:class:`magsoro.mpm.settings.P2GFlag`): the total-Lagrangian form; the affine matrix
#: and momentum stored for p2g_scatter
P2G_TOTAL = wp.constant(int(P2GFlag.TOTAL))
P2G_APART = wp.constant(int(P2GFlag.APART))

# Unroll the 3^dim-node stencil loops (27 in 3D): constant offsets let the compiler fold the weight selection.
wp.set_module_options({"max_unroll": 32})


@functools.cache
def make_p2g(dim: int, scalar, two_fields: bool = False, differentiable: bool = False, plane: str = "strain") -> dict:
    """Scatter kernels for ``dim``, ``scalar``; ``two_fields``: the contact variant (:mod:`magsoro.mpm.kernels.contact`);
    ``differentiable``: with the adjoints of the kernels the differentiable rollout (:mod:`magsoro.diff`) records
    on its wp.Tape. Warp otherwise builds none (docs/engine.md, "Compile time"). ``plane``: the 2D idealisation of
    the laws, "strain" or "stress" (:func:`magsoro.mpm.kernels.stencil.make_body_elastic`)."""
    s = make_stencil(dim, scalar, two_fields)
    t = s.types
    vec, mat, v3, m3, ivec = t.vec, t.mat, t.v3, t.m3, t.ivec
    Block, Bodies, Applied, GridArrays, Particles = t.Block, t.Bodies, t.Applied, t.GridArrays, t.Particles
    ContactGrid = s.ContactGrid
    NS = s.NS
    slot_of, inplane, bspline_weights = s.slot_of, s.inplane, s.bspline_weights
    local_coords, outside_block, flat_index, stencil_node = s.local_coords, s.outside_block, s.flat_index, s.stencil_node
    # Constants are computed here in double precision: literal arithmetic inside a kernel runs in float32.
    inv_mu0 = 1.0 / MU0
    body = make_body_elastic(dim, scalar, plane)
    body_elastic_stress = body.body_elastic_stress
    axisymmetric = plane == "axisymmetric"
    # the axisymmetric law (3 x 3 stress at diag(F, r / R)); plane strain's stands in elsewhere so the kernels compile
    body_elastic_stress3 = body.body_elastic_stress3 if axisymmetric else None
    if axisymmetric:
        body_elastic_stress = make_body_elastic(dim, scalar, "strain").body_elastic_stress
    moment_map, rotation_stress = s.moment_map, s.rotation_stress
    visc = make_viscous(dim, scalar, plane)
    Viscous, overstress, plane_total = visc["Viscous"], visc["overstress"], visc["plane_total"]
    plane_stress = plane == "stress"

    @wp.func
    def magnetic_stress(Fp: mat, b: Bodies, p: int, B: v3):
        """The magnetic part of :func:`particle_stress`."""
        br = b.Br[p]
        if b.follows[p] != 0:
            return rotation_stress(Fp, B, br)
        return -scalar(inv_mu0) * wp.outer(inplane(B), inplane(br))

    @wp.func
    def particle_stress(Fp: mat, b: Bodies, p: int, B: v3):
        """First Piola stress of particle ``p``: its elastic law (with its stimulus eigenstrain, if any) plus the
        magnetic stress of a hard-magnetic elastomer: P = -(1/mu0) B (x) Br when its moment follows F (seed 000
        eq 13), dW/dF of W = -(1/mu0) B . R Br when it follows R (:func:`magsoro.mpm.kernels.stencil.make_magnetization`)."""
        return body_elastic_stress(Fp, b, p) + magnetic_stress(Fp, b, p, B)

    @wp.func
    def gradient_force(Fp: mat, b: Bodies, p: int, grad_B: m3):
        """Gradient force (seed 000 eqs 15-16) on particle ``p``: f = (grad B)^T m with m = F Br V0 / mu0 its
        current moment (R Br V0 / mu0 when it follows R); summing w f over nodes gives the node form since the
        weights sum to one."""
        br = b.Br[p]
        Fbr = moment_map(Fp, b.follows[p]) * inplane(br)
        m3d = v3()
        for a in range(dim):
            m3d[a] = Fbr[a]
        if wp.static(dim == 2):
            m3d[2] = br[2]  # plane strain: F_zz = 1
        m3d = m3d * (b.vol0[p] * scalar(inv_mu0))
        return inplane(wp.transpose(grad_B) * m3d)

    @wp.func
    def pressure_force(Fp: mat, area: vec, pressure: scalar, hoop: scalar):
        """Force of a gauge ``pressure`` (Pa) on a particle's faces of reference area vector ``area`` (outward into
        the cavity): -p n da with n da = J F^-T N dA (Nanson's formula), so the load follows the surface as it
        turns and stretches. ``hoop``: the axisymmetric hoop stretch r / R (the ring's faces stretch with it; 1
        otherwise)."""
        return (-pressure * wp.determinant(Fp) * hoop) * (wp.transpose(wp.inverse(Fp)) * area)

    @wp.func
    def affine_momentum(sp: Particles, b: Bodies, applied: Applied, p: int, dts: scalar, B: v3, dx: scalar,
                        inv_dx: scalar, total: int, vs: Viscous):
        """What particle ``p`` brings to its nodes: the affine matrix A (stress impulse plus m C, times dx) and its
        momentum m v (with dt times the gradient force): node i receives w_i (m v + A o_i - A fx)."""
        Fp = sp.F[p]
        P = mat()
        hoop = scalar(1.0)
        hoop_force = vec()
        if wp.static(axisymmetric):
            # the ring's hoop stretch r / R, and the hoop stress's pull towards the axis: the r-row of
            # -dW/dx_i = -V0 P_tt w_i / R (docs/engine.md, "Axisymmetric bodies")
            R = b.radius0[p]
            hoop = sp.x_now[p][0] / R
            P3 = body_elastic_stress3(Fp, hoop, b, p)
            P = mat(P3[0, 0], P3[0, 1], P3[1, 0], P3[1, 1]) + magnetic_stress(Fp, b, p, B)
            hoop_force[0] = -b.vol0[p] * P3[2, 2] / R
        elif wp.static(plane_stress):
            # a Prony particle's law and overstress share their thickness stretch (magsoro.mpm.laws.viscous)
            if vs.n_rows > 0 and vs.row[p] >= 0:
                P = plane_total(Fp, b, vs, p, scalar(0.0), 0) + magnetic_stress(Fp, b, p, B)
            else:
                P = particle_stress(Fp, b, p, B)
        else:
            P = particle_stress(Fp, b, p, B)
            if vs.n_rows > 0:
                P = P + overstress(Fp, b, vs, p)
        # MLS-MPM: grid force -V0 P F^T grad w, with grad w = (4/dx^2) w (x_i - x_p) for quadratic B-splines
        stress = (-dts * b.vol0[p] * scalar(4.0) * inv_dx * inv_dx) * P
        if total == 0:
            stress = stress * wp.transpose(Fp)
        mp = b.mass[p]
        affine = stress + mp * sp.C[p]
        mv = mp * sp.v[p]
        if wp.static(axisymmetric):
            mv = mv + dts * hoop_force
        if applied.has_gradient != 0:
            mv = mv + dts * gradient_force(Fp, b, p, applied.grad_B[p])
        if b.n_pressures > 0:
            row = b.pressure_row[p]
            if row >= 0:
                f = pressure_force(Fp, b.pressure_area[p], b.pressure_value[row], hoop) - b.pressure_share[p] * b.pressure_net[row]
                mv = mv + dts * f
                if wp.static(axisymmetric):
                    # each face's force acts at the face, half a spacing from the particle: moved there to first
                    # order through the weights' gradient, w_i(x_p + d) ~ w_i (1 + (4/dx^2) (x_i - x_p) . d), i.e.
                    # an affine term (4/dx^2) f (x) d (on a linear field its work is the face's; docs/engine.md)
                    area = b.pressure_area[p]
                    moved = mat()
                    for a in range(dim):
                        if area[a] != scalar(0.0):
                            face = vec()
                            face[a] = area[a]
                            d = vec()
                            d[a] = wp.sign(area[a]) * scalar(0.5) * b.spacing
                            if total == 0:  # the weights follow the particles: the face's current offset
                                d = Fp * d
                            moved = moved + wp.outer(pressure_force(Fp, face, b.pressure_value[row], hoop), d)
                    affine = affine + (dts * scalar(4.0) * inv_dx * inv_dx) * moved
        return affine * dx, mv

    @wp.func
    def scatter_node(g: GridArrays, ct: wp.array(dtype=ContactGrid), p: int, q: int, w0: vec, w1: vec, w2: vec,
                     first: int, shape: ivec, fx: vec, mp: scalar, A: mat, Afx: vec, mv: vec, is_clamped: int,
                     inv_r: scalar):
        """Particle ``p``'s share of node q of its stencil: mass and mv + A (o - fx). mv is added per node, not
        folded into the constant part: the small momentum of a settling body would lose its low bits to the
        large stress term once for all 27 nodes alike, a bias that makes float32 bodies creep. ``inv_r``: dx / r
        of an axisymmetric scene's particle (:func:`contact_weight`), 0 otherwise."""
        weight, o, idx = stencil_node(q, w0, w1, w2, first, shape)
        slot = slot_of(ct, p, idx)
        wp.atomic_add(g.p, slot, weight * (mv + (A * o - Afx)))
        wp.atomic_add(g.m, slot, weight * mp)
        if wp.static(two_fields):
            wp.atomic_add(ct[0].grad_m, slot, (weight * mp * (scalar(1.0) + (o[0] - fx[0]) * inv_r)) * (o - fx))
        if is_clamped != 0:
            g.clamp[idx] = 1

    @wp.func
    def contact_weight(x: vec, dx: scalar):
        """dx / r of a particle at ``x`` in an axisymmetric scene (0 otherwise): its share of node i's mass gradient,
        which gives the contact normals, is weighted by r_i / r = 1 + (x_i - x)_r / r, so that the gradient is the
        section's own density's (a ring's mass grows with r, which would tilt every normal towards the axis by
        about dx / r) at the mass's own magnitude (the fields' centroids stay where they are)."""
        inv_r = scalar(0.0)
        if wp.static(axisymmetric):
            inv_r = dx / x[0]
        return inv_r

    @wp.func
    def step_values(b: Bodies, applied: Applied, dt: scalar):
        """dt and the uniform field of this step: the arguments', or ``bodies[0].step[0]``'s when stepped, plus the
        particle's own field added by the caller."""
        B = applied.B_uniform
        dts = dt
        if b.stepped != 0:
            sv = b.step[0]
            B = sv.B_uniform
            dts = sv.dt
        return dts, B

    @wp.kernel(enable_backward=differentiable)
    def p2g(
        src: wp.array(dtype=Particles),
        bodies: wp.array(dtype=Bodies),
        applied: Applied,
        block: Block,
        dt: scalar,
        grid: wp.array(dtype=GridArrays),
        error: wp.array(dtype=wp.int32),
        flags: int,
        ct: wp.array(dtype=ContactGrid),
        vs: Viscous,
        affine: wp.array(dtype=mat),
        momentum: wp.array(dtype=vec),
    ):
        """Particle-to-grid transfer of mass, momentum and the stress impulse from the particles ``src`` (x, v, C,
        F): each particle's affine matrix and momentum (:func:`affine_momentum`), scattered over its stencil. Its
        ``x`` are the positions the grid weights are taken at: the current ones (updated Lagrangian) or, with bit
        0 of ``flags`` (P2G_TOTAL), the reference ones (total Lagrangian: the grid is the reference
        configuration's, and the node force takes the first Piola stress P instead of the Kirchhoff stress P F^T).
        With bit 1 (P2G_APART) the affine matrix and momentum go to ``affine`` and ``momentum`` instead, for
        :func:`p2g_scatter` (the GPU's scatter threads, docs/engine.md "Scatter threads"). In the contact variant
        each node has two velocity fields (:mod:`magsoro.mpm.kernels.contact`): the particle scatters into its own, and
        adds its share of that field's mass gradient. ``vs``: the Prony materials' internal stresses
        (:mod:`magsoro.mpm.laws.viscous`), whose overstress adds to P. With ``bodies[0].stepped`` dt and the uniform
        field come from ``bodies[0].step[0]`` instead of ``dt`` and ``applied.B_uniform`` (:class:`magsoro.mpm.kernels.stencil`
        Step)."""
        p = wp.tid()
        dx = block.dx
        inv_dx = scalar(1.0) / dx
        sp = src[0]
        base, fx = local_coords(sp.x[p], block.lo, inv_dx)
        if outside_block(base, block.shape):
            error[0] = 1  # particle outside the active grid block: the solver refits and reports
            return
        b = bodies[0]
        dts, B = step_values(b, applied, dt)
        if applied.has_gradient != 0:
            B = B + applied.B[p]
        A, mv = affine_momentum(sp, b, applied, p, dts, B, dx, inv_dx, flags & P2G_TOTAL, vs)
        if (flags & P2G_APART) != 0:
            affine[p] = A
            momentum[p] = mv
            return
        mp = b.mass[p]
        is_clamped = b.clamped[p]
        w0, w1, w2 = bspline_weights(fx)
        Afx = A * fx
        first = flat_index(base, block.shape)
        g = grid[0]
        inv_r = contact_weight(sp.x[p], dx)
        for q in range(NS):
            scatter_node(g, ct, p, q, w0, w1, w2, first, block.shape, fx, mp, A, Afx, mv, is_clamped, inv_r)

    @wp.kernel(enable_backward=False)
    def p2g_scatter(
        x: wp.array(dtype=vec),
        bodies: wp.array(dtype=Bodies),
        block: Block,
        affine: wp.array(dtype=mat),
        momentum: wp.array(dtype=vec),
        grid: wp.array(dtype=GridArrays),
        ct: wp.array(dtype=ContactGrid),
        spread: int,
    ):
        """The scatter of :func:`p2g` as a kernel of its own, after p2g with P2G_APART: mass and the node values of
        the affine matrix and momentum it stored, over each particle's stencil at ``x`` (the positions p2g's
        particles had), into the same slots as p2g.

        ``spread`` = 0: one thread per particle, its 3^dim nodes in turn (launch n particles); 1: one thread per
        (particle, node), thread p 3^dim + q (launch n 3^dim): on a GPU the atomic adds of a particle no longer
        wait for each other, and a small scene fills the device (docs/engine.md, "Scatter threads"). Each node
        receives the same terms either way."""
        tid = wp.tid()
        p = tid
        if spread != 0:
            p = tid // NS
        inv_dx = scalar(1.0) / block.dx
        base, fx = local_coords(x[p], block.lo, inv_dx)
        if outside_block(base, block.shape):
            return  # p2g flags it
        b = bodies[0]
        mp = b.mass[p]
        A = affine[p]
        mv = momentum[p]
        is_clamped = b.clamped[p]
        w0, w1, w2 = bspline_weights(fx)
        Afx = A * fx
        first = flat_index(base, block.shape)
        g = grid[0]
        inv_r = contact_weight(x[p], block.dx)
        if spread != 0:
            scatter_node(g, ct, p, tid - p * NS, w0, w1, w2, first, block.shape, fx, mp, A, Afx, mv, is_clamped, inv_r)
        else:
            for q in range(NS):
                scatter_node(g, ct, p, q, w0, w1, w2, first, block.shape, fx, mp, A, Afx, mv, is_clamped, inv_r)

    @wp.kernel(enable_backward=False)
    def node_displacement(
        X: wp.array(dtype=vec),
        x: wp.array(dtype=vec),
        mass: wp.array(dtype=scalar),
        block: Block,
        grid_u: wp.array(dtype=vec),
        ct: wp.array(dtype=ContactGrid),
    ):
        """Total Lagrangian: scatter each particle's mass-weighted displacement m (x - X) to the reference grid
        (into its own velocity field's slot when bodies have fields of their own), so that node i sits at
        X_i + sum w m u / sum w m in the current configuration, where the walls and colliders act on it (exact for
        a rigid translation; first order in the displacement gradient)."""
        p = wp.tid()
        base, fx = local_coords(X[p], block.lo, scalar(1.0) / block.dx)
        if outside_block(base, block.shape):
            return  # p2g flags it
        w0, w1, w2 = bspline_weights(fx)
        mu = mass[p] * (x[p] - X[p])
        first = flat_index(base, block.shape)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, block.shape)
            wp.atomic_add(grid_u, slot_of(ct, p, idx), weight * mu)

    @wp.kernel(enable_backward=False)
    def contact_scan(
        x: wp.array(dtype=vec),
        X: wp.array(dtype=vec),
        mass: wp.array(dtype=scalar),
        group: wp.array(dtype=wp.int32),
        block: Block,
        fold: int,
        gmin: wp.array(dtype=wp.int32),
        gmax: wp.array(dtype=wp.int32),
        moments: wp.array(dtype=scalar),
    ):
        """Contact step 1 (:mod:`magsoro.mpm.kernels.contact`): the smallest and largest contact group reaching each node;
        with ``fold`` also the reference-position moments m, m X, m X X^T (1 + dim + dim^2 per node)."""
        p = wp.tid()
        base, fx = local_coords(x[p], block.lo, scalar(1.0) / block.dx)
        if outside_block(base, block.shape):
            return  # p2g flags it
        w0, w1, w2 = bspline_weights(fx)
        g = group[p]
        Xp = X[p]
        mp = mass[p]
        stride = 1 + dim + dim * dim
        first = flat_index(base, block.shape)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, block.shape)
            wp.atomic_min(gmin, idx, g)
            wp.atomic_max(gmax, idx, g)
            if fold != 0:
                wm = weight * mp
                row = idx * stride
                wp.atomic_add(moments, row, wm)
                for a in range(dim):
                    wp.atomic_add(moments, row + 1 + a, wm * Xp[a])
                    for c in range(dim):
                        wp.atomic_add(moments, row + 1 + dim + a * dim + c, wm * Xp[a] * Xp[c])

    @wp.kernel(enable_backward=False)
    def contact_scatter(
        x: wp.array(dtype=vec),
        v: wp.array(dtype=vec),
        mass: wp.array(dtype=scalar),
        block: Block,
        grid: wp.array(dtype=GridArrays),
        ct: wp.array(dtype=ContactGrid),
    ):
        """Total Lagrangian with contact: scatter the particles' trial velocities (after the reference-grid update)
        as momentum, with mass and mass gradient, into their velocity fields on a grid over the current
        configuration ``x`` (:mod:`magsoro.mpm.kernels.contact`), where :func:`contact_resolve` corrects them."""
        p = wp.tid()
        base, fx = local_coords(x[p], block.lo, scalar(1.0) / block.dx)
        if outside_block(base, block.shape):
            return  # the contact block is fitted to these positions every step
        w0, w1, w2 = bspline_weights(fx)
        mp = mass[p]
        mv = mp * v[p]
        g = grid[0]
        first = flat_index(base, block.shape)
        for q in range(NS):
            weight, o, idx = stencil_node(q, w0, w1, w2, first, block.shape)
            slot = slot_of(ct, p, idx)
            wp.atomic_add(g.p, slot, weight * mv)
            wp.atomic_add(g.m, slot, weight * mp)
            if wp.static(two_fields):
                wp.atomic_add(ct[0].grad_m, slot, (weight * mp) * (o - fx))

    @wp.kernel(enable_backward=False)
    def pressure_net(bodies: wp.array(dtype=Bodies), F: wp.array(dtype=mat), net: wp.array(dtype=vec)):
        """Sum each closed-cavity pressure load's force over its particles into ``net`` (zeroed before): the
        imbalance of the faces' Nanson-mapped areas, which p2g then takes back in proportion to each face's area.
        (Each particle's J F^-T N dA is its own face's current area vector; the particles' F differ by the
        method's noise, so round a closed cavity they sum to about 1e-4 of the load instead of zero, and a free
        pressurised body would drift.)"""
        p = wp.tid()
        b = bodies[0]
        row = b.pressure_row[p]
        if row >= 0:
            if b.pressure_share[p] > scalar(0.0):
                wp.atomic_add(net, row, pressure_force(F[p], b.pressure_area[p], b.pressure_value[row], scalar(1.0)))

    return dict(p2g=p2g, p2g_scatter=p2g_scatter, pressure_net=pressure_net, node_displacement=node_displacement, contact_scan=contact_scan, contact_scatter=contact_scatter)


# -- launchers: the one place each kernel's argument order is written ------------------------------------------
# Each takes the kernel table of :func:`magsoro.mpm.kernels.make_kernels` (or of :func:`make_p2g`), the launch
# size ``n`` and the arguments by name; ``record=True`` returns Warp's recorded launch (the explicit solver's
# recorded launches and CUDA graphs), else the kernel runs at once.

def launch_p2g(kernels, n, *, src, bodies, applied, block, dt, grid, error, flags, contact, viscous, affine, momentum,
               device, record=False):
    """:func:`make_p2g`'s ``p2g`` over ``n`` particles: ``src`` the Particles struct array read (x where the weights
    are taken, v, C, F), ``grid`` the GridArrays struct array written, ``flags`` P2GFlag bits, ``contact`` the
    ContactGrid array, ``viscous`` the Viscous struct, ``affine``/``momentum`` the P2GFlag.APART outputs."""
    return wp.launch(kernels["p2g"], dim=n, device=device, record_cmd=record,
                     inputs=[src, bodies, applied, block, dt, grid, error, flags, contact, viscous, affine, momentum])


def launch_p2g_scatter(kernels, n, *, x, bodies, block, affine, momentum, grid, contact, spread, device, record=False):
    """``p2g_scatter``: ``n`` = particles (``spread`` 0) or particles x 3^dim (``spread`` 1)."""
    return wp.launch(kernels["p2g_scatter"], dim=n, device=device, record_cmd=record,
                     inputs=[x, bodies, block, affine, momentum, grid, contact, spread])


def launch_node_displacement(kernels, n, *, X, x, mass, block, grid_u, contact, device, record=False):
    """``node_displacement`` over ``n`` particles: reference positions ``X``, current ``x``, into ``grid_u``."""
    return wp.launch(kernels["node_displacement"], dim=n, device=device, record_cmd=record,
                     inputs=[X, x, mass, block, grid_u, contact])


def launch_contact_scan(kernels, n, *, x, X, mass, group, block, fold, gmin, gmax, moments, device, record=False):
    """``contact_scan`` over ``n`` particles at ``x`` (reference positions ``X``, contact ``group`` per particle)."""
    return wp.launch(kernels["contact_scan"], dim=n, device=device, record_cmd=record,
                     inputs=[x, X, mass, group, block, fold, gmin, gmax, moments])


def launch_contact_scatter(kernels, n, *, x, v, mass, block, grid, contact, device, record=False):
    """``contact_scatter`` over ``n`` particles: velocities ``v`` at ``x`` into the GridArrays ``grid``."""
    return wp.launch(kernels["contact_scatter"], dim=n, device=device, record_cmd=record,
                     inputs=[x, v, mass, block, grid, contact])


def launch_pressure_net(kernels, n, *, bodies, F, net, device, record=False):
    """``pressure_net`` over ``n`` particles: the closed cavities' net pressure force at ``F`` summed into ``net``."""
    return wp.launch(kernels["pressure_net"], dim=n, device=device, record_cmd=record, inputs=[bodies, F, net])
