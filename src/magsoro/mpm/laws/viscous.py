"""Finite-strain viscoelasticity: a generalised Maxwell (Prony series) relaxation of the isochoric stress.

Model (the convolution form of Simo's finite-strain viscoelasticity, as the Prony option of hyperelastic laws
in the FEM codes our users compare with). Write the second Piola stress of a particle's law as
S_0 = S_vol + S_iso, with S_iso = F^-1 P_iso(F) the isochoric part (the law's stress with its bulk modulus set
to 0, :mod:`magsoro.mpm.laws.elastic`). With the material key ``prony = [[g_1, tau_1], ..., [g_n, tau_n]]``
(n <= 3, g_i > 0 dimensionless fractions of the instantaneous shear modulus with sum g_i < 1, tau_i > 0 s):

    S = S_vol + g_inf S_iso + sum_i h_i,   g_inf = 1 - sum_i g_i,
    dh_i/dt + h_i / tau_i = g_i dS_iso/dt,  h_i(0) = 0,

so the response to a sudden strain is the law's own (instantaneous) stress, relaxing to the one with every
isochoric modulus scaled by g_inf; the bulk response is elastic. At small strain the shear relaxation modulus is
G(t) = G_0 (g_inf + sum g_i exp(-t/tau_i)), and under a sinusoidal strain of angular frequency w

    G'(w) = G_0 (g_inf + sum g_i w^2 tau_i^2 / (1 + w^2 tau_i^2)),  G''(w) = G_0 sum g_i w tau_i / (1 + w^2 tau_i^2).

Update over a step dt, exact when S_iso varies linearly in time across it (x_i = dt / tau_i):

    h_i <- exp(-x_i) h_i + g_i (1 - exp(-x_i)) / x_i (S_iso(F_new) - S_iso(F_old)).

Both coefficients lie in [0, 1] for every dt > 0, so the update is unconditionally stable: with dt << tau_i the
internal stress follows the law (h_i += g_i dS), with dt >> tau_i it vanishes at once (the relaxed law). The
decay is applied as h - (1 - exp(-x)) h with 1 - exp(-x) from its series for small x: at dt = 1e-6 s and
tau = 1 s, exp(-x) in float32 carries a relative error of 6 % in 1 - exp(-x), the series none.

State: per particle an array of 1 + n matrices (:class:`magsoro.mpm.model.State` ``H``): S_iso at the state's F,
then h_1 .. h_n. The solver updates it after each step's gather from the new F (:func:`make_viscous`
``viscous_update``, reading the step's input state and writing its output, so a check window can go back), and
p2g adds the overstress F (sum_i h_i - sum_i g_i S_iso) to the law's first Piola stress. The time step is set by
the instantaneous modulus (the stiffest response), so a Prony term never shortens it. The reported strain
energy is the law's (instantaneous) one; the dissipated work is not tracked.

The implicit integrator (:mod:`magsoro.mpm.newton.implicit`) uses the same update: each Newton iterate's residual takes
the overstress after the update to its own F (``trial_overstress``), its tangent the derivative of that
(``overstress_tangent``), and the state's H moves on when a step is accepted.

Plane stress (2D, ``plane = "stress"``): the internal stresses are 3 x 3 (the thickness direction included) and the
thickness stretch lambda_3 makes the normal stress of the law plus the overstress zero,
P_33 of P_law(F3) + F3 (sum_i h_i - sum_i g_i S_iso(F3)) = 0 with F3 = diag(F, lambda_3) and h_i the state's (the
stress) or updated to the trial F (the update, the implicit integrator's trial stress), solved by the secant method as for
the elastic laws (:func:`magsoro.mpm.laws.elastic.make_plane_stress_functions`). p2g takes the in-plane block of that
total stress (``plane_total``) for a Prony particle in place of the law's plane stress; ``overstress`` (the reported
stress, the implicit integrator's tangent) is that block minus the law's own plane stress.

Restrictions (the builder refuses them with one line): a Prony material cannot carry a stimulus eigenstrain; the
static solver (the relaxed equilibrium is the law with its isochoric moduli scaled by g_inf, which a user can
write as such) and the differentiable rollout refuse Prony materials.
"""

import functools

import warp as wp

from magsoro.mpm.laws.elastic import PLANE_STRESS_ITERATIONS, make_material_functions, make_plane_stress_functions
from magsoro.mpm.kernels.stencil import make_types

# No kernel here runs under wp.Tape (only magsoro.diff's rollout does): Warp need not build their adjoints.
wp.set_module_options({"enable_backward": False})


@functools.cache
def make_viscous(dim: int, scalar, plane: str = "strain"):
    """The Warp side for ``dim``, ``scalar`` and the 2D ``plane`` idealisation: the ``Viscous`` argument struct
    (each particle's Prony row, -1 none; per row g and tau; the state's ``H`` (N, 1 + terms), dim x dim or, in
    plane stress, 3 x 3; ``n_rows`` 0: no Prony material, nothing is read), the function
    ``overstress(F, b, vs, p)``, and the kernels ``viscous_update`` (after a step's gather), ``add_overstress``
    (the reported stress) and ``overstress_tangent`` (the implicit integrator's)."""
    t = make_types(dim, scalar)
    mat, v3, m3, Bodies = t.mat, t.v3, t.m3, t.Bodies
    stress = plane == "stress"
    if stress and dim != 2:
        raise ValueError("plane stress is a 2D idealisation (dim = 2)")
    Hmat = m3 if stress else mat  # the internal stresses' type
    elastic_stress = make_material_functions(dim, scalar)["elastic_stress"]
    stress3 = make_material_functions(3, scalar)["elastic_stress"]
    law_plane_stress = make_plane_stress_functions(scalar)["plane_stress_stress"] if stress else None
    # series of 1 - exp(-x) below x = 1e-2 (relative error x^5 / 720 < 1.4e-13); constants in double
    sixth, twenty_fourth = 1.0 / 6.0, 1.0 / 24.0
    # plane stress: lambda_3 by the secant method, as materials.make_plane_stress_functions solves it
    tol = 1.0e-15 if scalar == wp.float64 else 2.0e-6
    iterations = PLANE_STRESS_ITERATIONS
    four_thirds = 4.0 / 3.0

    @wp.struct
    class Viscous:
        row: wp.array(dtype=wp.int32)
        g: wp.array(dtype=v3)
        tau: wp.array(dtype=v3)
        H: wp.array2d(dtype=Hmat)
        n_rows: int
        terms: int

    @wp.func
    def one_minus_exp(x: scalar):
        r = scalar(1.0) - wp.exp(-x)
        if x < scalar(1.0e-2):
            r = x * (scalar(1.0) - x * (scalar(0.5) - x * (scalar(sixth) - x * scalar(twenty_fourth))))
        return r

    @wp.func
    def updated_term(h: Hmat, g: scalar, tau: scalar, dS: Hmat, dt: scalar):
        """Internal stress h_i after a step of ``dt`` in which S_iso changed by ``dS`` (module docstring)."""
        x = dt / tau
        decay = one_minus_exp(x)
        return h - decay * h + (g * decay / x) * dS

    @wp.func
    def internal(S: Hmat, vs: Viscous, p: int, dt: scalar, trial: int):
        """sum_i h_i - sum_i g_i S_iso of particle ``p`` with S_iso = ``S``: h_i the state's (``trial`` 0) or
        updated over ``dt`` to S (``trial`` 1)."""
        row = vs.row[p]
        g = vs.g[row]
        tau = vs.tau[row]
        Q = -(g[0] + g[1] + g[2]) * S
        if trial != 0:
            dS = S - vs.H[p, 0]
            for i in range(vs.terms):
                Q = Q + updated_term(vs.H[p, i + 1], g[i], tau[i], dS, dt)
        else:
            for i in range(vs.terms):
                Q = Q + vs.H[p, i + 1]
        return Q

    if not stress:

        @wp.func
        def iso_pk2(F: mat, b: Bodies, p: int):
            """Isochoric second Piola stress S_iso = F^-1 P_iso of particle ``p``'s law at ``F`` (bulk modulus 0)."""
            P_iso = elastic_stress(F, b.material_model[p], b.shear[p], scalar(0.0), b.material_params[p])
            return wp.inverse(F) * P_iso

        @wp.func
        def viscous_stress(F: mat, b: Bodies, vs: Viscous, p: int, dt: scalar, trial: int):
            """Overstress of particle ``p`` at ``F``: F (sum_i h_i - sum_i g_i S_iso), the state's h_i (``trial``
            0) or updated over ``dt`` to F (1)."""
            return F * internal(iso_pk2(F, b, p), vs, p, dt, trial)

        @wp.func
        def state_pk2(F: mat, b: Bodies, vs: Viscous, p: int, dt: scalar):
            """S_iso of particle ``p`` at the state's new ``F`` (viscous_update)."""
            return iso_pk2(F, b, p)

    else:

        @wp.func
        def thick(F: mat, l3: scalar):
            """diag(F, l3) as a 3 x 3 deformation gradient."""
            z = scalar(0.0)
            return m3(F[0, 0], F[0, 1], z, F[1, 0], F[1, 1], z, z, z, l3)

        @wp.func
        def total_stress(F3: m3, b: Bodies, vs: Viscous, p: int, dt: scalar, trial: int):
            """First Piola stress (3 x 3) of the law plus the overstress at ``F3``, and S_iso there: the law's
            isochoric part evaluated once (bulk modulus 0) and its volumetric part K (J - 1) J F^-T written out
            (every law's W_vol = K/2 (J - 1)^2), so that each evaluation inlines the laws once."""
            P_iso = stress3(F3, b.material_model[p], b.shear[p], scalar(0.0), b.material_params[p])
            Finv = wp.inverse(F3)
            S = Finv * P_iso
            J = wp.determinant(F3)
            P = P_iso + (b.bulk[p] * (J - scalar(1.0)) * J) * wp.transpose(Finv) + F3 * internal(S, vs, p, dt, trial)
            return P, S

        @wp.func
        def normal(F: mat, l3: scalar, b: Bodies, vs: Viscous, p: int, dt: scalar, trial: int):
            P, S = total_stress(thick(F, l3), b, vs, p, dt, trial)
            return P[2, 2]

        @wp.func
        def thickness_stretch(F: mat, b: Bodies, vs: Viscous, p: int, dt: scalar, trial: int):
            """lambda_3 with a zero normal stress of the law plus the overstress (module docstring), by the secant
            method as materials.make_plane_stress_functions solves the law's."""
            G = b.shear[p]
            K = b.bulk[p]
            J = wp.determinant(F)
            l0 = scalar(1.0)
            if J > scalar(0.0):
                l0 = scalar(1.0) / wp.sqrt(J)
            r0 = normal(F, l0, b, vs, p, dt, trial)
            slope0 = K + scalar(four_thirds) * G
            l1 = wp.clamp(l0 - r0 / slope0, scalar(0.5) * l0, scalar(2.0) * l0)
            it = int(0)
            while it < iterations:
                r1 = normal(F, l1, b, vs, p, dt, trial)
                if wp.abs(r1) <= scalar(tol) * (K + G) or l1 == l0:
                    break
                slope = (r1 - r0) / (l1 - l0)
                if slope <= scalar(0.0):  # not expected of a stable law: step by the small-strain slope
                    slope = slope0
                l0 = l1
                r0 = r1
                l1 = wp.clamp(l1 - r1 / slope, scalar(0.5) * l1, scalar(2.0) * l1)
                it += 1
            return l1

        @wp.func
        def plane_total(F: mat, b: Bodies, vs: Viscous, p: int, dt: scalar, trial: int):
            """In-plane first Piola stress of the law plus the overstress at the thickness stretch that makes their
            normal stress zero (plane stress)."""
            l3 = thickness_stretch(F, b, vs, p, dt, trial)
            P3, S = total_stress(thick(F, l3), b, vs, p, dt, trial)
            return mat(P3[0, 0], P3[0, 1], P3[1, 0], P3[1, 1])

        @wp.func
        def viscous_stress(F: mat, b: Bodies, vs: Viscous, p: int, dt: scalar, trial: int):
            """Overstress of particle ``p`` at ``F`` in plane stress: :func:`plane_total` minus the law's own plane
            stress (the reported stress and the implicit integrator's tangent add it to the law's)."""
            law = law_plane_stress(F, b.material_model[p], b.shear[p], b.bulk[p], b.material_params[p])
            return plane_total(F, b, vs, p, dt, trial) - law

        @wp.func
        def state_pk2(F: mat, b: Bodies, vs: Viscous, p: int, dt: scalar):
            """S_iso (3 x 3) of particle ``p`` at the state's new ``F`` and the thickness stretch its updated
            internal stresses give (viscous_update)."""
            l3 = thickness_stretch(F, b, vs, p, dt, 1)
            P3, S = total_stress(thick(F, l3), b, vs, p, dt, 1)
            return S

    @wp.func
    def overstress(F: mat, b: Bodies, vs: Viscous, p: int):
        """First Piola overstress of particle ``p`` at ``F`` from the state's H (zero without a Prony material)."""
        P = mat()
        if vs.n_rows > 0:
            if vs.row[p] >= 0:
                P = viscous_stress(F, b, vs, p, scalar(0.0), 0)
        return P

    @wp.kernel
    def viscous_update(F: wp.array(dtype=mat), bodies: wp.array(dtype=Bodies), vs: Viscous,
                       H_out: wp.array2d(dtype=Hmat), dt: scalar):
        """H_out of particle p from the step's input H (in ``vs``) and its new deformation gradient F (module
        docstring); dt from ``bodies[0].step[0]`` when ``bodies[0].stepped`` (:class:`magsoro.mpm.kernels.stencil` Step)."""
        p = wp.tid()
        row = vs.row[p]
        if row < 0:
            return
        dts = dt
        if bodies[0].stepped != 0:
            dts = bodies[0].step[0].dt
        S = state_pk2(F[p], bodies[0], vs, p, dts)
        dS = S - vs.H[p, 0]
        H_out[p, 0] = S
        g = vs.g[row]
        tau = vs.tau[row]
        for i in range(vs.terms):
            H_out[p, i + 1] = updated_term(vs.H[p, i + 1], g[i], tau[i], dS, dts)

    @wp.func
    def trial_overstress(F: mat, b: Bodies, vs: Viscous, p: int, dt: scalar):
        """Overstress of particle ``p`` at ``F`` after a step of ``dt`` from the internal state in ``vs.H``: the
        stress ``overstress`` gives after ``viscous_update`` to ``F``, as a function of F alone (the implicit
        integrator's residual and, by central differences, its tangent)."""
        P = mat()
        if vs.row[p] >= 0:
            P = viscous_stress(F, b, vs, p, dt, 1)
        return P

    @wp.kernel
    def overstress_tangent(F: wp.array(dtype=mat), bodies: wp.array(dtype=Bodies), vs: Viscous, dt: scalar,
                           h: scalar, A: wp.array(dtype=mat)):
        """Add d(trial_overstress)/dF of every Prony particle at its F to ``A`` (laid out as the static solver's
        material_tangent: A[p dim^2 + b dim + d] holds dP_ac/dF_bd over (a, c)), by central differences of step
        ``h``; clamped particles and those without a Prony row add nothing."""
        p = wp.tid()
        if vs.row[p] < 0 or bodies[0].clamped[p] != 0:
            return
        F0 = F[p]
        # a dynamic loop over the dim^2 components (not unrolled: each trial_overstress inlines the laws, and in
        # plane stress two thickness solves)
        q = int(0)
        while q < dim * dim:
            E = mat()
            E[q / dim, q % dim] = h
            dP = (trial_overstress(F0 + E, bodies[0], vs, p, dt) - trial_overstress(F0 - E, bodies[0], vs, p, dt)) / (scalar(2.0) * h)
            k = p * dim * dim + q
            A[k] = A[k] + dP
            q += 1

    @wp.kernel
    def add_overstress(F: wp.array(dtype=mat), bodies: wp.array(dtype=Bodies), vs: Viscous, P: wp.array(dtype=mat)):
        """Add each particle's overstress to its first Piola stress ``P`` (the reported stress)."""
        p = wp.tid()
        P[p] = P[p] + overstress(F[p], bodies[0], vs, p)

    return dict(Viscous=Viscous, overstress=overstress, viscous_update=viscous_update, add_overstress=add_overstress,
                trial_overstress=trial_overstress, overstress_tangent=overstress_tangent, H_type=Hmat,
                plane_total=plane_total if stress else None)


# -- launchers: the one place each kernel's argument order is written (as in :mod:`magsoro.mpm.kernels.p2g`); ``kernels``
# is :func:`make_viscous`'s table, ``record=True`` returns Warp's recorded launch ---------------------------------

def launch_viscous_update(kernels, n, *, F, bodies, viscous, H_out, dt, device, record=False):
    """``viscous_update`` over ``n`` particles: the internal stresses ``H_out`` at the new ``F`` from the Viscous
    struct ``viscous`` (the step's input H) over ``dt``."""
    return wp.launch(kernels["viscous_update"], dim=n, device=device, record_cmd=record,
                     inputs=[F, bodies, viscous, H_out, dt])


def launch_overstress_tangent(kernels, n, *, F, bodies, viscous, dt, h, A, device, record=False):
    """``overstress_tangent`` over ``n`` particles: d(trial overstress)/dF by central differences of step ``h``,
    added to ``A``."""
    return wp.launch(kernels["overstress_tangent"], dim=n, device=device, record_cmd=record,
                     inputs=[F, bodies, viscous, dt, h, A])


def launch_add_overstress(kernels, n, *, F, bodies, viscous, P, device, record=False):
    """``add_overstress`` over ``n`` particles: each particle's overstress added to ``P``."""
    return wp.launch(kernels["add_overstress"], dim=n, device=device, record_cmd=record,
                     inputs=[F, bodies, viscous, P])


def viscous_struct(model, H, cut=lambda arr: arr):
    """The ``Viscous`` struct of ``model`` with the state array ``H`` (None: a model without Prony materials),
    over the particle slice ``cut``."""
    V = make_viscous(model.dim, model.scalar, model.plane)["Viscous"]
    vs = V()
    vs.row, vs.g, vs.tau = cut(model.prony_row), model.prony_g, model.prony_tau
    vs.n_rows = len(model.prony)
    vs.terms = model.prony_terms
    vs.H = cut(H) if H is not None else model.empty_H
    return vs


def prescribed_history(model, F_path, times):
    """First Piola stress of every particle of ``model`` driven through the deformation gradients ``F_path``
    (T, N, dim, dim) at ``times`` (T,) s, from the reference state (F = I, H = 0) at times[0] with F_path[0]: the
    engine's own update and stress functions, without the transfers (a material point test). Returns (T, N, dim,
    dim) float64: the law's stress (with its stimulus, if any) plus the Prony overstress."""
    import numpy as np

    from magsoro.mpm.kernels import launch_body_stress  # kernels imports this module (through p2g)
    from magsoro.mpm.runtime import bodies_array

    k, dev, s = model.kernels, model.device, model.np_scalar
    kv = make_viscous(model.dim, model.scalar, model.plane)
    n, dim = model.n_particles, model.dim
    F_path = np.asarray(F_path, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64)
    H = [wp.zeros((n, 1 + model.prony_terms), dtype=kv["H_type"], device=dev) for _ in range(2)]
    F = wp.zeros(n, dtype=k["mat"], device=dev)
    P = wp.zeros(n, dtype=k["mat"], device=dev)
    W = wp.zeros(n, dtype=model.scalar, device=dev)
    bodies = bodies_array(model)
    out = np.empty((len(times), n, dim, dim))
    for i in range(len(times)):
        F.assign(np.ascontiguousarray(F_path[i], dtype=s))
        if model.viscous:
            dt = times[i] - times[i - 1] if i > 0 else 0.0
            if dt > 0:
                launch_viscous_update(kv, n, F=F, bodies=bodies, viscous=viscous_struct(model, H[0]), H_out=H[1],
                                      dt=model.scalar(dt), device=dev)
                H.reverse()
            elif i > 0 or not np.allclose(F_path[0], np.eye(dim)):
                raise ValueError("times must increase, and the path start at F = I")
        launch_body_stress(k, n, F=F, bodies=bodies, P=P, psi=W, device=dev)
        if model.viscous:
            launch_add_overstress(kv, n, F=F, bodies=bodies, viscous=viscous_struct(model, H[0]), P=P, device=dev)
        out[i] = P.numpy()
    return out
