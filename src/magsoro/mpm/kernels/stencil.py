"""What every transfer shares: the types of a (dimension, precision), the structs that group kernel arguments,
and the quadratic B-spline stencil (seed 000 eq 2).

Grid: a dense block of nodes whose global index origin ``org`` and shape ``shape`` follow the bodies (see
:mod:`magsoro.mpm.solver`); arrays are flat, node (i, j[, k]) at ((i * ny) + j) * nz + k, and with contact
field f of node i at slot i + f n (:mod:`magsoro.mpm.kernels.contact`).

Structs with arrays are passed to the particle kernels as one-element arrays (``arg[0].field``): a struct
argument is copied for every task of a CPU launch, an array of it is not.
"""

import functools
from types import SimpleNamespace

import numpy as np
import warp as wp

from magsoro.constants import MU0
from magsoro.mpm.kernels.contact import make_contact
from magsoro.mpm.laws.elastic import LAW_PARAM_COUNT, make_material_functions, make_plane_stress_functions
from magsoro.mpm.settings import MagnetizationFollows


def host_bspline(X, lo, dx: float):
    """The quadratic B-spline stencil on the host (numpy, float64), as the kernels' ``local_coords`` and
    ``bspline_weights`` compute it: for points ``X`` (N, dim) on a grid of spacing ``dx`` whose node 0 is at
    ``lo``, the base node (N, dim) int64, the offset fx from it in cells, and the weights (3, N, dim) of the nodes
    base, base + 1, base + 2 along each axis."""
    xg = (np.asarray(X, dtype=np.float64) - lo) / dx
    base = np.floor(xg - 0.5).astype(np.int64)
    fx = xg - base
    return base, fx, np.stack([0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2])


@functools.cache
def make_types(dim: int, scalar) -> SimpleNamespace:
    """Vector and matrix types and the argument structs for ``dim`` in (2, 3) and ``scalar``."""
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    vec = wp.types.vector(length=dim, dtype=scalar)
    mat = wp.types.matrix(shape=(dim, dim), dtype=scalar)
    ivec = wp.types.vector(length=dim, dtype=wp.int32)
    v3 = wp.types.vector(length=3, dtype=scalar)
    m3 = wp.types.matrix(shape=(3, 3), dtype=scalar)
    vprm = wp.types.vector(length=LAW_PARAM_COUNT, dtype=scalar)  # a particle's law numbers

    @wp.struct
    class Block:
        """The active grid block: position of its first node ``lo`` (m), ``shape`` in nodes, spacing ``dx`` (m)."""

        lo: vec
        shape: ivec
        dx: scalar

    @wp.struct
    class Step:
        """What a step takes from the host: the time step dt (s), the damping factor exp(-c dt) and the uniform
        field B_uniform (T). The solver's kernels read it from a one-element device array (``Bodies.step``,
        ``GridSettings.step``), which the host writes before a plain step and a device kernel fills from a per-window
        table inside a check window (:meth:`magsoro.mpm.solver.Solver.run_window`), so that a window's launches
        do not change from one step to the next (CUDA graph capture)."""

        dt: scalar
        damping_factor: scalar
        B_uniform: v3

    @wp.struct
    class Bodies:
        """Per-particle constants of the model (:class:`magsoro.mpm.model.Model`): reference volume (m^3),
        mass (kg), shear and bulk moduli (Pa), material law code and its LAW_PARAM_COUNT numbers
        (:mod:`magsoro.mpm.laws.elastic`), remanence Br (T, reference frame; in 2D the in-plane part plus Br_z),
        clamp flag. Stimulus eigenstrain (:mod:`magsoro.mpm.laws.eigenstrain`): each particle's stimulus (a row of the
        two tables; -1: none), and per stimulus its current F_s^-1 and stress factor f det F_s, which the host
        updates when the stimulus changes; ``n_stimuli`` 0: no particle has one (the tables are never read).
        Pressure loads: each particle's reference face area vector (m^2, outward into the cavity) and its row
        of the pressure table (Pa, set by the host; -1: none); ``n_pressures`` 0: none (never read). For a load
        on a closed cavity, ``pressure_net[row]`` is the net force its faces give now (summed before each
        scatter) and ``pressure_share[p]`` the particle's part of it to take back (|dA| over the load's sum; 0 on
        open cavities), so that the load exerts no net force, as a pressure in a closed cavity does.
        ``stepped`` 1: the kernels take dt and the uniform field from ``step[0]`` (:class:`Step`) instead of their
        ``dt`` argument and ``Applied.B_uniform`` (the solver's launches); 0: from the arguments (other callers).
        ``radius0``: each particle's reference radius R (m, its x), read only by the axisymmetric kernels (the hoop
        stretch r / R and the hoop force); ``spacing``: the particle lattice's spacing h (m), where their pressure
        loads act (half of it from the particle)."""

        vol0: wp.array(dtype=scalar)
        radius0: wp.array(dtype=scalar)
        spacing: scalar
        mass: wp.array(dtype=scalar)
        shear: wp.array(dtype=scalar)
        bulk: wp.array(dtype=scalar)
        material_model: wp.array(dtype=wp.int32)
        material_params: wp.array(dtype=vprm)
        Br: wp.array(dtype=v3)
        follows: wp.array(dtype=wp.int32)
        clamped: wp.array(dtype=wp.int32)
        clamp_velocity: wp.array(dtype=vec)  # per clamp code (0 free, 1 held in place, 2 + path row): m/s this step
        stimulus: wp.array(dtype=wp.int32)
        stretch_inv: wp.array(dtype=mat)
        stretch_scale: wp.array(dtype=scalar)
        stretch_hoop_inv: wp.array(dtype=scalar)  # axisymmetric: 1 / F_s,tt per stimulus (1 elsewhere)
        n_stimuli: int
        pressure_area: wp.array(dtype=vec)
        pressure_row: wp.array(dtype=wp.int32)
        pressure_value: wp.array(dtype=scalar)
        pressure_share: wp.array(dtype=scalar)
        pressure_net: wp.array(dtype=vec)
        n_pressures: int
        step: wp.array(dtype=Step)
        stepped: int

    @wp.struct
    class Applied:
        """The applied field at the particles: the uniform part ``B_uniform`` (T) and, when ``has_gradient``,
        the non-uniform part ``B`` (T) and its gradient ``grad_B`` (T/m, grad_B[i, j] = dB_i/dx_j) per particle."""

        B_uniform: v3
        has_gradient: int
        B: wp.array(dtype=v3)
        grad_B: wp.array(dtype=m3)

    @wp.struct
    class GridArrays:
        """Node momenta (kg m/s), masses (kg) and held flags one transfer scatters into."""

        p: wp.array(dtype=vec)
        m: wp.array(dtype=scalar)
        clamp: wp.array(dtype=wp.int32)

    @wp.struct
    class Particles:
        """Particle state arrays a gather writes: positions (m), velocities (m/s), affine velocities C (1/s),
        deformation gradients F. ``x_now``: what p2g reads as the current positions where ``x`` holds the reference
        ones (the total form): the axisymmetric kernels' hoop stretch r / R."""

        x: wp.array(dtype=vec)
        v: wp.array(dtype=vec)
        C: wp.array(dtype=mat)
        F: wp.array(dtype=mat)
        x_now: wp.array(dtype=vec)

    @wp.struct
    class Checks:
        """What a gather reports to the host: particle bounds (min over axes, then max), the top speed (m/s) and
        the error flags ([0] outside the grid block, [1] invalid state)."""

        bounds: wp.array(dtype=scalar)
        max_speed: wp.array(dtype=scalar)
        error: wp.array(dtype=wp.int32)

    return SimpleNamespace(vec=vec, mat=mat, ivec=ivec, v3=v3, m3=m3, vprm=vprm, Block=Block, Bodies=Bodies, Applied=Applied,
                           GridArrays=GridArrays, Particles=Particles, Checks=Checks, Step=Step)


@functools.cache
def _make_stimulus_row(dim: int, scalar):
    """The row of particle ``p`` in the Bodies' stimulus table, -1 without a stimulus (shared by the plane and
    axisymmetric forms of :func:`make_body_elastic`)."""
    Bodies = make_types(dim, scalar).Bodies

    @wp.func
    def stimulus_row(b: Bodies, p: int):
        row = int(-1)
        if b.n_stimuli > 0:
            row = b.stimulus[p]
        return row

    return stimulus_row


@functools.cache
def make_body_elastic(dim: int, scalar, plane: str = "strain") -> SimpleNamespace:
    """The elastic stress and energy of a particle of the model, the one place where a particle's law, moduli and
    stimulus eigenstrain (:mod:`magsoro.mpm.laws.eigenstrain`) meet; every kernel that needs a particle's elastic
    response calls these:

    - ``body_elastic_stress(F, b, p)``: first Piola stress (Pa) of particle ``p`` of the Bodies ``b`` at ``F``,
      P = c P_e(F F_s^-1) F_s^-T with c = f det F_s of its stimulus now, P_e its law; without a stimulus
      (``b.n_stimuli`` = 0 or its row -1) exactly its law's stress at F, to the bit;
    - ``body_elastic_energy(F, b, p)``: the matching energy c W_e(F F_s^-1), J/m^3 of reference volume.

    ``plane`` (2D only): "strain" (F_zz = 1) or "stress" (the laws of
    :func:`magsoro.mpm.laws.elastic.make_plane_stress_functions`); a compile-time choice, so that plane-strain kernels
    carry no trace of the plane-stress solve."""
    t = make_types(dim, scalar)
    mat, Bodies = t.mat, t.Bodies
    if plane == "axisymmetric":
        return _make_body_elastic_axisymmetric(dim, scalar)
    if plane == "stress":
        if dim != 2:
            raise ValueError("plane stress is a 2D idealisation (dim = 2)")
        elastic = make_plane_stress_functions(scalar)
        elastic_stress, elastic_energy = elastic["plane_stress_stress"], elastic["plane_stress_energy"]
    elif plane == "strain":
        elastic = make_material_functions(dim, scalar)
        elastic_stress, elastic_energy = elastic["elastic_stress"], elastic["elastic_energy"]
    else:
        raise ValueError(f"plane must be 'strain', 'stress' or 'axisymmetric', got {plane!r}")

    stimulus_row = _make_stimulus_row(dim, scalar)

    @wp.func
    def body_elastic_stress(F: mat, b: Bodies, p: int):
        row = stimulus_row(b, p)
        Fe = F
        if row >= 0:
            Fe = F * b.stretch_inv[row]
        P = elastic_stress(Fe, b.material_model[p], b.shear[p], b.bulk[p], b.material_params[p])
        if row >= 0:
            P = b.stretch_scale[row] * (P * wp.transpose(b.stretch_inv[row]))
        return P

    @wp.func
    def body_elastic_energy(F: mat, b: Bodies, p: int):
        row = stimulus_row(b, p)
        Fe = F
        if row >= 0:
            Fe = F * b.stretch_inv[row]
        W = elastic_energy(Fe, b.material_model[p], b.shear[p], b.bulk[p], b.material_params[p])
        if row >= 0:
            W = b.stretch_scale[row] * W
        return W

    return SimpleNamespace(body_elastic_stress=body_elastic_stress, body_elastic_energy=body_elastic_energy)


@functools.cache
def _make_body_elastic_axisymmetric(dim: int, scalar) -> SimpleNamespace:
    """The axisymmetric form of :func:`make_body_elastic`: the law evaluated in 3D at F = diag(F_rz, r / R), with
    the hoop stretch r / R of the particle's ring (current over reference radius), and the particle's stimulus
    eigenstrain if any, F_s = diag(F_s,rz, F_s,tt) (:mod:`magsoro.mpm.laws.eigenstrain`: isotropic lambda I, or
    along a direction in the (r, z) plane with F_s,tt = 1), P = f det F_s P_e(F F_s^-1) F_s^-T:

    - ``body_elastic_stress(F, b, p)``: not given (the in-plane block alone would leave out the hoop stress);
    - ``body_elastic_stress3(F, hoop, b, p)``: the 3 x 3 first Piola stress, [2, 2] the hoop component P_tt;
    - ``body_elastic_energy3(F, hoop, b, p)``: W (J/m^3 of reference volume)."""
    if dim != 2:
        raise ValueError("an axisymmetric body is drawn in 2D (its (r, z) section)")
    import warp as wp

    t = make_types(dim, scalar)
    mat, m3, Bodies = t.mat, t.m3, t.Bodies
    f3 = make_material_functions(3, scalar)
    stress3, energy3 = f3["elastic_stress"], f3["elastic_energy"]

    @wp.func
    def ring(F: mat, hoop: scalar):
        z = scalar(0.0)
        return m3(F[0, 0], F[0, 1], z, F[1, 0], F[1, 1], z, z, z, hoop)

    stimulus_row = _make_stimulus_row(dim, scalar)

    @wp.func
    def body_elastic_stress3(F: mat, hoop: scalar, b: Bodies, p: int):
        row = stimulus_row(b, p)
        F3 = ring(F, hoop)
        if row >= 0:
            inv = ring(b.stretch_inv[row], b.stretch_hoop_inv[row])
            P = stress3(F3 * inv, b.material_model[p], b.shear[p], b.bulk[p], b.material_params[p])
            return b.stretch_scale[row] * (P * wp.transpose(inv))
        return stress3(F3, b.material_model[p], b.shear[p], b.bulk[p], b.material_params[p])

    @wp.func
    def body_elastic_energy3(F: mat, hoop: scalar, b: Bodies, p: int):
        row = stimulus_row(b, p)
        F3 = ring(F, hoop)
        if row >= 0:
            inv = ring(b.stretch_inv[row], b.stretch_hoop_inv[row])
            return b.stretch_scale[row] * energy3(F3 * inv, b.material_model[p], b.shear[p], b.bulk[p], b.material_params[p])
        return energy3(F3, b.material_model[p], b.shear[p], b.bulk[p], b.material_params[p])

    return SimpleNamespace(body_elastic_stress=None, body_elastic_energy=None,
                           body_elastic_stress3=body_elastic_stress3, body_elastic_energy3=body_elastic_energy3)


#: codes of a material's magnetisation kinematics (scene key material.magnetization_follows)
MAGNETIZATION_FOLLOWS = {m.name: int(m) for m in MagnetizationFollows}
FOLLOWS_F = wp.constant(int(MagnetizationFollows.F))


@functools.cache
def make_magnetization(dim: int, scalar) -> SimpleNamespace:
    """How a particle's remanence Br (reference frame) is carried into the current one (docs/engine.md,
    "Magnetisation kinematics"): by F (``follows`` 0, Zhao's law: m = F Br V0 / mu0, W = -(1/mu0) B . F Br,
    P = -(1/mu0) B (x) Br) or by the rotation R of the polar decomposition F = R U (``follows`` 1: m = R Br V0 / mu0,
    W = -(1/mu0) B . R Br, P = dW/dF below). The two coincide (energy, moment, torque) for rigid rotations.

    - ``polar_rotation(F)``: R. 2D: R = rot(theta), theta = atan2(F21 - F12, F11 + F22) in closed form (the
      rotation that makes R^T F symmetric with the largest trace; R = I where F11 + F22 = F21 - F12 = 0). 3D: from
      wp.svd3 F = W S V^T, R = W V^T, the column of the smallest singular value flipped where det(W V^T) < 0
      (an inverted F: R stays a rotation and that singular value turns negative).
    - ``moment_map(F, follows)``: F or R, the map applied to the in-plane Br.
    - ``rotation_stress(F, B, Br)``: P of the R law (Pa). 3D: dR = R [omega]x with (tr U I - U) omega =
      axial(2 skew(R^T dF)), so dW = -(1/mu0) omega . (Br x R^T B) and P = -(1/mu0) R [d]x with
      d = (tr U I - U)^-1 (Br x R^T B), inverted in U's eigenbasis V (eigenvalues s_j + s_k); a sum
      s_j + s_k <= 0 (only an inverted F) drops that component. 2D (plane strain, Br_z B_z does not depend on F):
      d theta = (R^T dF) : J / tr U, J = [[0, -1], [1, 0]], so P = -(1/mu0) (B . R J Br) / tr U  R J.
    - ``magnetic_energy(F, follows, B, Br)``: -(1/mu0) B . (map Br), J/m^3 of reference volume (2D: with the
      out-of-plane term -(1/mu0) B_z Br_z)."""
    t = make_types(dim, scalar)
    vec, mat, v3 = t.vec, t.mat, t.v3
    inv_mu0 = 1.0 / MU0

    @wp.func
    def inplane_of(b: v3):
        if wp.static(dim == 2):
            return vec(b[0], b[1])
        else:
            return vec(b[0], b[1], b[2])

    if dim == 2:

        @wp.func
        def polar_cos_sin(F: mat):
            """cos theta, sin theta and tr U = |(F11 + F22, F21 - F12)| of F = R U."""
            a = F[0, 0] + F[1, 1]
            b = F[1, 0] - F[0, 1]
            r = wp.sqrt(a * a + b * b)
            c = scalar(1.0)
            s = scalar(0.0)
            if r > scalar(0.0):
                c = a / r
                s = b / r
            return c, s, r

        @wp.func
        def polar_rotation(F: mat):
            c, s, r = polar_cos_sin(F)
            return mat(c, -s, s, c)

        @wp.func
        def rotation_stress(F: mat, B: v3, Br: v3):
            c, s, r = polar_cos_sin(F)
            P = mat()
            if r > scalar(0.0):
                RJ = mat(-s, -c, c, -s)
                P = (-scalar(inv_mu0) * wp.dot(inplane_of(B), RJ * inplane_of(Br)) / r) * RJ
            return P

    else:

        @wp.func
        def polar_svd(F: mat):
            W = mat()
            S = vec()
            V = mat()
            wp.svd3(F, W, S, V)
            if wp.determinant(W * wp.transpose(V)) < scalar(0.0):
                for a in range(3):
                    W[a, 2] = -W[a, 2]
                S[2] = -S[2]
            return W, S, V

        @wp.func
        def polar_rotation(F: mat):
            W, S, V = polar_svd(F)
            return W * wp.transpose(V)

        @wp.func
        def rotation_stress(F: mat, B: v3, Br: v3):
            W, S, V = polar_svd(F)
            R = W * wp.transpose(V)
            c = wp.transpose(V) * wp.cross(Br, wp.transpose(R) * B)  # Br x R^T B in U's eigenbasis
            d = vec()
            for i in range(3):
                den = S[(i + 1) % 3] + S[(i + 2) % 3]
                if den > scalar(0.0):
                    d[i] = c[i] / den
            d = V * d
            Dx = mat(scalar(0.0), -d[2], d[1], d[2], scalar(0.0), -d[0], -d[1], d[0], scalar(0.0))
            return -scalar(inv_mu0) * (R * Dx)

    @wp.func
    def moment_map(F: mat, follows: int):
        M = F
        if follows != FOLLOWS_F:
            M = polar_rotation(F)
        return M

    @wp.func
    def magnetic_energy(F: mat, follows: int, B: v3, Br: v3):
        W = -wp.dot(inplane_of(B), moment_map(F, follows) * inplane_of(Br))
        if wp.static(dim == 2):
            W = W - B[2] * Br[2]
        return scalar(inv_mu0) * W

    return SimpleNamespace(polar_rotation=polar_rotation, moment_map=moment_map, rotation_stress=rotation_stress,
                           magnetic_energy=magnetic_energy)


@functools.cache
def make_stencil(dim: int, scalar, two_fields: bool = False) -> SimpleNamespace:
    """Device functions of the quadratic B-spline stencil; ``two_fields``: particles scatter into and gather
    from the velocity field they belong to at each node (:mod:`magsoro.mpm.kernels.contact`)."""
    t = make_types(dim, scalar)
    vec, ivec, v3 = t.vec, t.ivec, t.v3
    ct_ns = make_contact(dim, scalar)
    ContactGrid = ct_ns["ContactGrid"]
    field_of = ct_ns["field_of"]

    @wp.func
    def slot_of(ct: wp.array(dtype=ContactGrid), p: int, idx: int):
        """Grid slot of particle ``p``'s velocity field at node ``idx``: the node itself without contact."""
        if wp.static(two_fields):
            return idx + field_of(ct, p, idx) * ct[0].n_nodes
        return idx

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
    def axis_mirror(loc: ivec, k: int, shape: ivec):
        """Flat index of the node mirrored across an axisymmetric scene's axis (the node line x = 0) from the node
        at block coordinates ``loc``, ``k`` nodes from the axis along x; -1 when the mirror lies outside the block."""
        mirror = loc
        mirror[0] = loc[0] - 2 * k
        j = int(-1)
        if mirror[0] >= 0 and mirror[0] < shape[0]:
            j = flat_index(mirror, shape)
        return j

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
        x_i - x_p = (o - fx) dx: the loops sum with o and subtract the fx part once, so that with q a
        constant (the loops are unrolled) each node costs a few additions instead of a product with (o - fx)."""
        o = stencil_offset(q)
        weight = scalar(1.0)
        of = vec()
        for a in range(dim):
            weight = weight * pick(w0, w1, w2, o[a])[a]
            of[a] = scalar(o[a])
        return weight, of, first + flat_index(o, shape)

    mag = make_magnetization(dim, scalar)
    return SimpleNamespace(moment_map=mag.moment_map, rotation_stress=mag.rotation_stress, types=t, NS=3**dim, ContactGrid=ContactGrid, slot_of=slot_of, inplane=inplane,
                           bspline_weights=bspline_weights, stencil_offset=stencil_offset, flat_index=flat_index,
                           node_of_flat=node_of_flat, axis_mirror=axis_mirror, local_coords=local_coords,
                           outside_block=outside_block,
                           stencil_node=stencil_node)
