"""Quasi-static solver: equilibrium shapes by Newton's method on the engine's own total-Lagrangian discretisation.

The unknowns are the displacements u of the free nodes of the reference grid block (the total-Lagrangian form's
grid: nodes carrying particle mass that are not held by a clamp). A displacement field puts every particle at
x_p = X_p + sum_i w_ip u_i with F_p = I + sum_i u_i (x) grad w_ip (the engine's MLS gradient, as its total-form
gather computes them), and the residual is the node force of the engine's own scatter (p2g with zero velocity and
a unit step: the stress divergence of every elastic law, the magnetic stress, the gradient force) plus gravity.
Equilibrium is R(u) = 0.

Newton-Raphson with a backtracking line search on |R|; the tangent dR/du is assembled from the particles as a
finite-element stiffness is, -V0 g_i . A . g_j with A = dP/dF of each particle's law (central differences of the
law at the particle's F: a local derivative, accurate to about 1e-10), plus the terms of a non-uniform field
(:meth:`StaticSolver.tangent`). Finite differences of the whole residual are not accurate enough: a slender beam's
bending stiffness is about (t/L)^2 of the entries, and the tangent's error along the bending mode stalled Newton
to linear convergence. The linear systems are solved by a sparse direct solver (SuperLU). Loads are applied in adaptive increments from the
last converged state (halved when Newton fails, grown when it converges quickly). float64 is recommended: the
tolerance is relative to the out-of-balance force of the undeformed body under the full load, 1e-8 by default.

Stability: after each load increment the eigenvalue nearest zero of the symmetric stiffness -(J + J^T)/2 is
computed (shift-invert about zero; as the load passes a bifurcation the eigenvalue that turns negative is the one
nearest zero). A negative one means the equilibrium is unstable (a symmetric beam past its buckling load, which
Newton keeps straight, as it converges to saddles as readily as to minima): the solver adds an imperfection force
along that mode (sized to move the level's stable start by BRANCH_KICKS cells, larger in turn until the result is stable), follows it up and takes it away again, which
leaves the body on the stable branch, and reports the level as buckled.

Rigid colliders meet the bodies' surface (static.collider_contact = "surface": the particles as balls of half their
spacing) or the nodes as the engine's total-Lagrangian form has them ("nodes"), by a penalty with stick and Coulomb
slip (:mod:`magsoro.mpm.newton.static_contact`; each level reports the penetration left). Not handled yet:
contact between bodies (refused). The engine's walls act on nodes within two cells of the domain's edge: a
wall whose band holds a node at the start acts here as a half-space collider at the band's edge with the walls'
contact law (:meth:`StaticSolver._starting_walls`); for the others, a level whose equilibrium reaches the band is
reported as not converged (:meth:`StaticSolver.wall_crossing`): the dynamics would have stopped the body there.

The bodies' own field (simulation.magnetic_interaction = "dipole") enters the residual and ramps with gravity_level;
its dense part of the Jacobian is not assembled: Newton's steps come from GMRES on finite-difference products of
the residual, preconditioned by the assembled tangent (:meth:`StaticSolver._solve_linear`); no stability check or
arc length with it.

Limit points: with ``[static] arc_length = true`` (scenes without colliders), and wherever load increments fail,
the path from one level to the next is followed by arc length (:meth:`StaticSolver._arc_length`): a snap-through
is passed and the field levels where the path turned back are reported. The stability check above also reads
the sign of the stiffness's determinant (its LU): an odd number of negative eigenvalues sends it on to the
negative one nearest zero, which an increment that went well past a bifurcation can leave behind a positive one.
"""

import functools
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from magsoro.errors import SimulationError
from magsoro.constants import MU0
from magsoro.mpm.colliders import WALL_CELLS, Collider
from magsoro.mpm.newton.linear import (FACTOR_CHECK, DirectSolver, IterativeSolver, Ordering, factor, forcing_term,  # noqa: F401 (re-exported)
                                make_linear_solver, rigid_body_modes)
from magsoro.mpm.newton import linear as _linear
from magsoro.mpm.kernels.p2g import P2G_TOTAL, launch_p2g, launch_pressure_net
from magsoro.mpm.settings import NodeClass
from magsoro.mpm.runtime import block_struct, bodies_array, contact_grid
from magsoro.mpm.kernels.stencil import host_bspline, make_body_elastic, make_stencil
from magsoro.mpm.laws.viscous import viscous_struct

#: per Newton iteration: |R|, the step taken, the contacts' set (logging.DEBUG)
log = logging.getLogger("magsoro.static")

# No kernel here runs under wp.Tape (only magsoro.diff's rollout does): Warp need not build their adjoints.
wp.set_module_options({"enable_backward": False})

#: central-difference step of the material tangent dP/dF (dimensionless) and of the field's gradient (cells)
F_STEP = 1e-6
X_STEP = 1e-4
#: the imperfection forces along a mode of negative stiffness that switch to the buckled branch, tried in turn until
#: the equilibrium left when the force is taken away is stable: the force that would move the level's (stable)
#: starting state this many cells along the mode at its largest node
BRANCH_KICKS = (0.1, 1.0, 10.0)
#: branch switches within one level before the solver gives up
MAX_SWITCHES = 4
#: a Newton step is taken while |R| stays below this many times the lowest residual of the solve
GROWTH = 1.0e3
#: the energy line search (StaticSolver._slope_search), tried on a load increment where Newton with the
#: residual-norm search failed, before the increment is halved (scenes without colliders): it accepts a step where
#: the energy's slope along it has fallen to SLOPE_RATIO of its start, within SLOPE_TRIALS trials
SLOPE_RATIO = 0.5
SLOPE_TRIALS = 8
#: the largest move of a node in one Newton step, cells
MAX_STEP = 10.0
#: with colliders, a Newton solve whose lowest |R| has not fallen to STALL_FACTOR of what it was STALL_ITERATIONS
#: iterations before gives up (its load increment is then halved): at a contact's onset such solves went on to the
#: iteration limit at a level |R| (the obstacle beam from straight to 3 mT: six attempts of 40 iterations)
STALL_ITERATIONS = 10
STALL_FACTOR = 0.5
#: once a converged state has released points that pull (a body lifting off a collider), points that pull leave the
#: active set after every accepted Newton iterate of that solve, not only at converged states
PEEL = True
#: the contacts' active set is settled on each Newton iteration's linearised problem in at most this many rounds
#: (StaticSolver._settle_contacts; 0: the set changes at accepted iterates only)
ACTIVE_SET_ROUNDS = 30
#: an iterative linear solver's relative tolerance in those rounds (they decide the set; the step that is taken is
#: solved to the Newton iteration's own tolerance)
ROUND_RTOL = 1.0e-2
#: and a step whose contact set those rounds changed moves no node more than this many cells (MAX_STEP otherwise): the
#: linearised step of a flap that has just let go of a collider (the hexahedron's walls, held by their hinges only)
#: was 14.7 cells long, and its |R| rose from 0.03 to 7 N
ROUND_STEP = 2.0
#: arc-length continuation (StaticSolver._arc_length), taken where load increments fail (a limit point): at most
#: ARC_STEPS steps along the equilibrium path; the first step's load change is ARC_FIRST of the way left; a step
#: grows by ARC_GROW (up to ARC_LONGEST times the first) after a corrector that converged within 4 iterations
#: and is halved after one that failed, down to ARC_MIN of the first. A limit point's load is the vertex of the
#: parabola through the three steps around it.
ARC_STEPS = 400
ARC_FIRST = 0.05
ARC_GROW = 1.5
ARC_LONGEST = 4.0
ARC_MIN = 1e-4
#: per dimension: free nodes lighter than this fraction of the heaviest node are extrapolated from the nodes inward
#: of them, not solved for (StaticSolver._slaving); 2D tangents have no null modes to remove, so none is
LIGHT = {2: 0.0, 3: 1.0e-2}
#: the tangent's diagonal shift (relative to its median diagonal) that regularises any null mode left
NULL_SHIFT = 1.0e-12
#: a level's force scale takes a moving clamp's linear response: the clamps moved this many cells (_reference_force)
CLAMP_PROBE_CELLS = 0.1
#: fit_nodes' least squares is shifted by this fraction of its median diagonal (regular where a node moves nothing)
PROJECT_SHIFT = 1.0e-16
#: and refined this many times on the fit's own residual (the normal equations square the light nodes' condition: the
#: settled strip's lightest nodes came back 4e-7 cells off unrefined, 6e-10 after three refinements)
PROJECT_REFINEMENTS = 3
#: with the bodies' own field: the finite-difference step of the Jacobian's products (cells: the largest node
#: displacement of the probe), the Krylov solver's relative tolerance and its restarts (_solve_linear)
FD_CELLS = 1.0e-6
KRYLOV_RTOL = 1.0e-4
KRYLOV_RESTARTS = 4
#: the stability check without a factorisation (StaticSolver._lowest_mode_iterative): LOBPCG's block size, its
#: relative tolerance and iterations
LOBPCG_BLOCK = 3
LOBPCG_TOL = 1.0e-6
LOBPCG_ITERATIONS = 200
#: with colliders and the iterative linear solver, the stability check factorises the (unsymmetric) stiffness up to
#: this many unknowns and is skipped above: the factorisation's memory (24 GB resident, killed, at about 70,000
#: unknowns of the 3D cantilever on this 23 GB machine; benchmarks/linear_scaling.py)
STABILITY_DIRECT_MAX = 50_000


def _odd_negative_count(K, lu=None) -> bool:
    """Whether the symmetric sparse matrix ``K`` has an odd number of negative eigenvalues: the sign of its
    determinant from an LU factorisation (Pr K Pc = L U, L with a unit diagonal: sign det K = sign prod diag U times
    the signs of the two permutations; ``lu``: :func:`factor` of K when the caller has it). Sylvester's law of
    inertia makes the determinant's sign the parity of the negative eigenvalues; an even number of them (two modes
    crossing zero together) is not seen."""
    lu = factor(K) if lu is None else lu
    negative = int(np.count_nonzero(lu.U.diagonal() < 0.0))
    return (negative + _permutation_parity(lu.perm_r) + _permutation_parity(lu.perm_c)) % 2 == 1


def _permutation_parity(perm) -> int:
    """0 for an even permutation, 1 for an odd one (n minus the number of cycles, mod 2)."""
    perm = np.asarray(perm)
    seen = np.zeros(len(perm), dtype=bool)
    cycles = 0
    for start in range(len(perm)):
        if not seen[start]:
            cycles += 1
            j = start
            while not seen[j]:
                seen[j] = True
                j = perm[j]
    return (len(perm) - cycles) % 2


def _vertex(points) -> float:
    """The extreme value of the parabola through three (path length, load fraction) points: a limit point's load
    between arc-length steps (the middle point's load where the parabola's extreme lies outside the three points,
    as for points nearly on a line)."""
    (s0, a0), (s1, a1), (s2, a2) = points
    d01, d12 = (a1 - a0) / (s1 - s0), (a2 - a1) / (s2 - s1)
    curv = (d12 - d01) / (s2 - s0)  # half the second derivative
    if curv == 0.0:
        return a1
    slope1 = d01 + curv * (s1 - s0)  # the parabola's slope at s1
    shift = -slope1 / (2.0 * curv)  # where the extreme lies, from s1
    if not s0 <= s1 + shift <= s2:
        return a1
    return a1 + 0.5 * slope1 * shift


@functools.cache
def make_static_kernels(dim: int, scalar, plane: str = "strain", two_fields: bool = False) -> dict:
    """The static solver's kernels for ``dim``, ``scalar`` and, in 2D, the laws' ``plane`` idealisation ("strain" or
    "stress", :func:`magsoro.mpm.kernels.stencil.make_body_elastic`); ``two_fields``: the reference grid is split by contact
    group (:meth:`magsoro.mpm.solver.Solver.reference_contact_grid`), each particle gathering from and assembling
    into its own group's slot of a node, as the contact variant of p2g scatters."""
    s = make_stencil(dim, scalar, two_fields)
    t = s.types
    vec, mat, Block = t.vec, t.mat, t.Block
    NS = s.NS
    bspline_weights, local_coords, flat_index, stencil_node = s.bspline_weights, s.local_coords, s.flat_index, s.stencil_node
    ContactGrid, slot_of = s.ContactGrid, s.slot_of

    @wp.kernel
    def place_particles(X: wp.array(dtype=vec), u: wp.array(dtype=vec), block: Block, clamped: wp.array(dtype=wp.int32),
                        clamp_shift: wp.array(dtype=vec), ct: wp.array(dtype=ContactGrid), x: wp.array(dtype=vec),
                        F: wp.array(dtype=mat)):
        """Positions X + sum w u_i and deformation gradients I + sum u_i (x) grad w of the node displacements
        ``u`` (the total-Lagrangian gather with v = u and a unit step); clamped particles keep F = I and sit at X
        plus their clamp's displacement ``clamp_shift[code]`` (zero for code 1, held in place), as the engine's
        gather moves them."""
        p = wp.tid()
        code = clamped[p]
        if code != 0:
            x[p] = X[p] + clamp_shift[code]
            F[p] = wp.identity(n=dim, dtype=scalar)
            return
        inv_dx = scalar(1.0) / block.dx
        base, fx = local_coords(X[p], block.lo, inv_dx)
        w0, w1, w2 = bspline_weights(fx)
        first = flat_index(base, block.shape)
        disp = vec()
        S = mat()
        for q in range(NS):
            weight, of, idx = stencil_node(q, w0, w1, w2, first, block.shape)
            wu = weight * u[slot_of(ct, p, idx)]
            disp = disp + wu
            S = S + wp.outer(wu, of)
        x[p] = X[p] + disp
        F[p] = wp.identity(n=dim, dtype=scalar) + (scalar(4.0) * inv_dx) * (S - wp.outer(disp, fx))

    axisymmetric = plane == "axisymmetric"
    body = make_body_elastic(dim, scalar, plane)
    # an axisymmetric particle's law is evaluated at diag(F, r / R) (body_elastic_stress3); plane strain's in-plane
    # law stands in for the 2D one so that the kernels below compile in every mode
    body_elastic_stress = make_body_elastic(dim, scalar, "strain").body_elastic_stress if axisymmetric else body.body_elastic_stress
    body_elastic_stress3 = body.body_elastic_stress3 if axisymmetric else None
    Bodies = t.Bodies

    @wp.kernel
    def particle_stress(F: wp.array(dtype=mat), bodies: wp.array(dtype=Bodies), P: wp.array(dtype=mat)):
        """Elastic first Piola stress of every particle at ``F`` (its own law and moduli, and its eigenstrain when
        its material has a stimulus): the function the engine's scatter uses."""
        p = wp.tid()
        P[p] = body_elastic_stress(F[p], bodies[0], p)

    @wp.kernel
    def material_tangent(F: wp.array(dtype=mat), x: wp.array(dtype=vec), bodies: wp.array(dtype=Bodies), h: scalar,
                         A: wp.array(dtype=mat), hoop_A: wp.array(dtype=mat), hoop_c: wp.array(dtype=scalar)):
        """dP/dF of every particle's own law at its F by central differences of step ``h``: A[p dim^2 + b dim + d]
        holds dP_ac/dF_bd over (a, c); zero for clamped particles (they keep F = I whatever the nodes do).

        Axisymmetric: the law at diag(F, r / R) (r the current radius x[p][0], R the reference one), and its
        derivatives along the hoop stretch too: hoop_A[2 p] = dP_ac/d(r/R), hoop_A[2 p + 1] = dP_tt/dF_bd (the
        hoop stress's change with the in-plane F), hoop_c[p] = dP_tt/d(r/R). Not read otherwise."""
        p = wp.tid()
        F0 = F[p]
        held = bodies[0].clamped[p] != 0
        if wp.static(axisymmetric):
            R = bodies[0].radius0[p]
            h0 = x[p][0] / R
            Et = mat()
            for b in range(dim):
                for d in range(dim):
                    E = mat()
                    E[b, d] = h
                    dP = mat()
                    if not held:
                        d3 = (body_elastic_stress3(F0 + E, h0, bodies[0], p)
                              - body_elastic_stress3(F0 - E, h0, bodies[0], p)) / (scalar(2.0) * h)
                        dP = mat(d3[0, 0], d3[0, 1], d3[1, 0], d3[1, 1])
                        Et[b, d] = d3[2, 2]
                    A[p * dim * dim + b * dim + d] = dP
            Dh = mat()
            ch = scalar(0.0)
            if not held:
                d3 = (body_elastic_stress3(F0, h0 + h, bodies[0], p)
                      - body_elastic_stress3(F0, h0 - h, bodies[0], p)) / (scalar(2.0) * h)
                Dh = mat(d3[0, 0], d3[0, 1], d3[1, 0], d3[1, 1])
                ch = d3[2, 2]
            hoop_A[2 * p] = Dh
            hoop_A[2 * p + 1] = Et
            hoop_c[p] = ch
        else:
            for b in range(dim):
                for d in range(dim):
                    E = mat()
                    E[b, d] = h
                    dP = mat()
                    if not held:
                        dP = (body_elastic_stress(F0 + E, bodies[0], p) - body_elastic_stress(F0 - E, bodies[0], p)) / (scalar(2.0) * h)
                    A[p * dim * dim + b * dim + d] = dP

    @wp.struct
    class FieldTerms:
        """Per particle, what a non-uniform field adds to the tangent (StaticSolver.tangent): V0 / mu0, the field's
        gradient grad_B (G below, T/m), the in-plane remanence Br (T), and H_ae = sum_b dG_ba/dx_e m_b (m the moment,
        A m^2); ``active`` 0: no non-uniform field (the arrays are not read)."""

        active: int
        coef: wp.array(dtype=scalar)
        grad_B: wp.array(dtype=mat)
        br: wp.array(dtype=vec)
        H: wp.array(dtype=mat)

    @wp.kernel
    def assemble_tangent(X: wp.array(dtype=vec), block: Block, bodies: wp.array(dtype=Bodies), A: wp.array(dtype=mat),
                         hoop_A: wp.array(dtype=mat), hoop_c: wp.array(dtype=scalar),
                         fterms: FieldTerms, ct: wp.array(dtype=ContactGrid), dof: wp.array(dtype=wp.int32),
                         indptr: wp.array(dtype=wp.int32), slots: wp.array(dtype=wp.int32), data: wp.array(dtype=scalar)):
        """Adds the dim x dim blocks of one particle's stencil node s (thread p 3^dim + s) against every node t of
        its stencil to the CSC values ``data`` (column pointers ``indptr``; ``slots[(p 3^dim + s) 3^dim + t]``: where
        the rows of node s start in the columns of node t, counted from each column's start, -1 where either node
        is not free). Block (s a, t b): -V0 A_acbd g_s^c g_t^d, and with a field G_ab (Br . g_s) w_t V0/mu0 + w_s
        G_ba (Br . g_t) V0/mu0 + w_s w_t H_ab (g the reference weight gradients, w the weights).

        Axisymmetric (the hoop stretch r / R = 1 + sum_t w_t u_t,r / R): the hoop terms of -dW/du too,
        -V0 [e_b,r (w_t / R) dP_ac/d(r/R) g_s^c + e_a,r (w_s / R) dP_tt/dF_bd g_t^d + e_a,r e_b,r (w_s w_t / R^2)
        dP_tt/d(r/R)] (material_tangent's hoop_A and hoop_c)."""
        tid = wp.tid()
        p = tid // NS
        s = tid - p * NS
        inv_dx = scalar(1.0) / block.dx
        base, fx = local_coords(X[p], block.lo, inv_dx)
        w0, w1, w2 = bspline_weights(fx)
        first = flat_index(base, block.shape)
        ws, ofs, ids = stencil_node(s, w0, w1, w2, first, block.shape)
        rs = dof[slot_of(ct, p, ids)]
        if rs < 0:
            return
        gs = (scalar(4.0) * inv_dx * ws) * (ofs - fx)
        V0 = bodies[0].vol0[p]
        brs = scalar(0.0)
        if fterms.active != 0:
            brs = wp.dot(fterms.br[p], gs)
        # column b of every block (s, t) is -V0 Y_b g_t, Y_b's column d = A_.cbd g_s^c: the three Y_b formed once
        Y0 = mat()
        Y1 = mat()
        Y2 = mat()
        for b in range(dim):
            Yb = mat()
            for d in range(dim):
                unit_d = vec()
                unit_d[d] = scalar(1.0)
                Yb = Yb + wp.outer(A[p * dim * dim + b * dim + d] * gs, unit_d)
            if b == 0:
                Y0 = Yb
            elif b == 1:
                Y1 = Yb
            else:
                Y2 = Yb
        Dgs = vec()  # axisymmetric: (dP/d(r/R)) g_s, the hoop stretch's column, and the ring's terms
        Et = mat()
        ring_c = scalar(0.0)
        inv_R = scalar(0.0)
        if wp.static(axisymmetric):
            inv_R = scalar(1.0) / bodies[0].radius0[p]
            Dgs = hoop_A[2 * p] * gs
            Et = hoop_A[2 * p + 1]
            ring_c = hoop_c[p]
        G = mat()
        H = mat()
        c = scalar(0.0)
        if fterms.active != 0:
            G = fterms.grad_B[p]
            H = fterms.H[p]
            c = fterms.coef[p]
        for t in range(NS):
            slot = slots[tid * NS + t]
            if slot < 0:
                continue
            wt, oft, idt = stencil_node(t, w0, w1, w2, first, block.shape)
            col = dof[slot_of(ct, p, idt)]
            gt = (scalar(4.0) * inv_dx * wt) * (oft - fx)
            # the field's block, whole: (c brs wt) G + (c ws (Br . g_t)) G^T + ws wt H
            Kf = mat()
            if fterms.active != 0:
                Kf = (c * brs * wt) * G + (c * ws * wp.dot(fterms.br[p], gt)) * wp.transpose(G) + (ws * wt) * H
            for b in range(dim):
                Yb = Y0
                if b == 1:
                    Yb = Y1
                elif b == 2:
                    Yb = Y2
                unit_b = vec()
                unit_b[b] = scalar(1.0)
                kb = (-V0) * (Yb * gt) + Kf * unit_b
                if wp.static(axisymmetric):
                    kb[0] = kb[0] - V0 * ws * inv_R * (wp.dot(Et[b], gt) + wt * inv_R * ring_c * unit_b[0])
                    kb = kb - (V0 * wt * inv_R * unit_b[0]) * Dgs
                lo = indptr[col * dim + b] + slot  # the rows of node s in column (t, b); rows rs dim + a follow
                for a in range(dim):
                    wp.atomic_add(data, lo + a, kb[a])

    return {"place_particles": place_particles, "particle_stress": particle_stress,
            "material_tangent": material_tangent, "assemble_tangent": assemble_tangent, "FieldTerms": FieldTerms}


# -- launchers: the one place each kernel's argument order is written (as in :mod:`magsoro.mpm.kernels.p2g`); ``kernels``
# is :func:`make_static_kernels`' table ------------------------------------------------------------------------

def launch_place_particles(kernels, n, *, X, u, block, clamped, clamp_shift, contact, x, F, device, record=False):
    """``place_particles`` over ``n`` particles: positions ``x`` and ``F`` from the node displacements ``u`` (per
    slot of the ``contact`` grid's split)."""
    return wp.launch(kernels["place_particles"], dim=n, device=device, record_cmd=record,
                     inputs=[X, u, block, clamped, clamp_shift, contact, x, F])


def launch_material_tangent(kernels, n, *, F, x, bodies, h, A, hoop_A, hoop_c, device, record=False):
    """``material_tangent`` over ``n`` particles: dP/dF by central differences of step ``h`` into ``A`` (and an
    axisymmetric scene's hoop derivatives into ``hoop_A``, ``hoop_c``, at the current positions ``x``)."""
    return wp.launch(kernels["material_tangent"], dim=n, device=device, record_cmd=record,
                     inputs=[F, x, bodies, h, A, hoop_A, hoop_c])


def launch_assemble_tangent(kernels, n, *, X, block, bodies, A, hoop_A, hoop_c, field_terms, contact, dof, indptr, slots,
                            data, device, record=False):
    """``assemble_tangent`` over ``n`` = particles x 3^dim: the tangent's entries into ``data`` (CSC pattern of
    ``indptr`` and ``slots``)."""
    return wp.launch(kernels["assemble_tangent"], dim=n, device=device, record_cmd=record,
                     inputs=[X, block, bodies, A, hoop_A, hoop_c, field_terms, contact, dof, indptr, slots, data])


@dataclass
class LevelResult:
    """One solved load level: field scale ``level``, converged or not, Newton iterations and load increments."""

    level: float
    converged: bool
    iterations: int
    increments: int
    residual: float  # |R|_inf at the end, N (2D: per the scene's depth)
    residual_relative: float
    wall_time: float
    message: str = ""
    lowest_eigenvalue: float | None = None  # of the stiffness -J at the equilibrium (lowest_mode), N/m
    buckled: bool = False  # the equilibrium reached first was unstable; the branch was switched (docstring)
    penetration: float | None = None  # m: the largest overlap of a node with a collider at the end (static_contact)
    # arc-length continuation (taken where load increments failed): the field levels where the path turned back
    # (limit points, a snap-through starting at the first one) and its steps
    limit_levels: list = field(default_factory=list)
    arc_length_steps: int = 0
    # where the equilibrium reached the band of the domain walls (StaticSolver.wall_crossing); the level is then
    # not converged and the state stays at the previous level's
    wall_crossing: str | None = None
    # the loads pull free bodies along the friction collider that carries them harder than friction holds
    # (StaticSolver._sliding): no equilibrium near the state, smaller load increments cannot help
    no_equilibrium: bool = False
    # the time of the loads (s): simulation.duration, or the time of a sweep along the paths ([static] times)
    time: float | None = None
    # the Newton steps' linear solves (magsoro.mpm.newton.linear; static.linear_solver): the kind used ('direct',
    # 'iterative', or both joined by '+'), the solves, their Krylov iterations (0 for a direct solve), the
    # factorisations or multigrid hierarchies made, and the iterative solves that missed their tolerance and were
    # done by the direct solver instead
    linear_solver: str = ""
    linear_solves: int = 0
    linear_iterations: int = 0
    linear_setups: int = 0
    linear_fallbacks: int = 0
    # the predictor's solve of the level (static.soft_penalty; Simulation.solve_static): its Newton iterations and
    # linear solves, and whether it converged (the level starts from its equilibrium only then)
    predictor_iterations: int = 0
    predictor_linear_solves: int = 0
    predictor_converged: bool | None = None


@dataclass
class StaticResult:
    """Outcome of :meth:`magsoro.simulation.Simulation.solve_static`: one LevelResult per level solved."""

    converged: bool
    levels: list = field(default_factory=list)
    wall_time: float = 0.0
    message: str = ""
    residual_evaluations: int = 0


def check_supported(sim, who: str = "the static solver", viscous: bool = False) -> None:
    """Raise SimulationError naming what the static solver cannot take in ``sim`` (form, contact, colliders, the
    bodies' own field, moments that follow R); ``who`` names the solver in the messages."""
    solver = sim.solver
    if solver.settings.formulation != "total":
        raise SimulationError(f"{who} works on the total-Lagrangian form (simulation.formulation = 'total' or 'auto')")
    if np.any(sim.model.host["magnetization_follows"] != 0):
        # its tangent takes the magnetic stress and the moment as Zhao's law has them (F Br); the R law's dP/dF is not in it
        raise SimulationError(f"{who} has no magnetization_follows = 'R' yet (its tangent carries the moment "
                              "with F); give the materials magnetization_follows = 'F', or use --equilibrium (relax)")
    if sim.model.viscous and not viscous:
        # the equilibrium under held loads is the relaxed one: the law with its isochoric moduli scaled by g_inf
        raise SimulationError(f"{who} has no viscoelastic (prony) materials; the equilibrium under held loads "
                              "is the relaxed one: give the material its long-term moduli (every isochoric modulus times "
                              "1 - sum g) without prony, or use --equilibrium (relax)")


class StaticSolver:
    """Newton solver for the equilibria of a :class:`magsoro.simulation.Simulation` built in the total-Lagrangian
    form (rigid colliders and the domain walls a body starts at: penalty, see :mod:`magsoro.mpm.newton.static_contact`;
    contact between bodies on a reference grid split by contact group: :mod:`magsoro.mpm.newton.body_contact`). Loads: the fields at time ``t`` scaled by a level, gravity in full, the
    colliders where their paths have them at ``t`` (reached with the first level's load increments)."""

    #: whether Prony materials are taken (the implicit integrator's steps; an equilibrium has none to give)
    takes_prony = False

    def __init__(self, sim, t: float, tolerance: float = 1e-8, max_iterations: int = 40, arc_length: bool = False,
                 collider_contact: str | None = None, linear_solver: str | None = None, penalty_scale: float = 1.0,
                 check_stability: bool = True):
        self.sim, self.t = sim, float(t)
        # the contacts' penalty stiffness times this (static.soft_penalty's predictor: a soft penalty lets a peeling
        # front move several cells per Newton iteration); check_stability False skips lowest_mode (a predictor's
        # states are not the answer)
        self.penalty_scale = float(penalty_scale)
        self.check_stability = bool(check_stability)
        # how the Newton steps' linear systems are solved (static.linear_solver; magsoro.mpm.newton.linear): 'direct',
        # 'iterative' (multigrid-preconditioned Krylov) or 'auto' (direct up to linear.DIRECT_MAX_UNKNOWNS unknowns)
        self.linear_solver = getattr(sim.scene.static, "linear_solver", "auto") if linear_solver is None else linear_solver
        if self.linear_solver not in _linear.KINDS:
            raise SimulationError(f"static.linear_solver must be one of {', '.join(map(repr, _linear.KINDS))}, "
                                  f"not {self.linear_solver!r}")
        self._linear = None  # the last tangent's LinearSolver (an iterative one's hierarchy serves the next tangents)
        self.linear_iterations = 0  # Krylov iterations of every Newton step so far (0 per direct solve)
        self.linear_solves = 0
        self.linear_setups = 0  # factorisations or multigrid hierarchies made
        self.linear_fallbacks = 0  # iterative solves that missed their tolerance and were done directly
        self.round_cycles = 0  # settled contact rounds that came back to a set of an earlier round (ended there)
        self.linear_kinds = set()  # the kinds used ('direct', 'iterative')
        # where the scene's colliders meet the bodies (static.collider_contact): 'surface' (the particles) or 'nodes'
        self.collider_contact = sim.scene.static.collider_contact if collider_contact is None else collider_contact
        self.tolerance, self.max_iterations = float(tolerance), int(max_iterations)
        self.arc_length = bool(arc_length)
        if self.arc_length and sim.control.colliders:
            raise SimulationError("static.arc_length = true follows the equilibrium path of scenes without colliders; "
                                  "remove the colliders or set static.arc_length = false")
        if self.arc_length and sim.solver.interaction is not None:
            raise SimulationError("static.arc_length = true follows the equilibrium path of scenes without the bodies' "
                                  "own field; set simulation.magnetic_interaction = 'none' or static.arc_length = false")
        solver, model = sim.solver, sim.model
        st = solver.settings
        check_supported(sim, viscous=self.takes_prony)
        self.solver, self.model = solver, model
        self.dim, self.dev, self.sc = model.dim, model.device, model.scalar
        k = solver.step_kernels  # the contact variant of p2g where the reference grid is split by contact group
        self.k = k
        # the moving clamps' displacements per clamp code (Model clamp_code: 0 free, 1 held in place, 2 + path row)
        # at the clamps' time (_set_collider_time), which the held particles and nodes take
        self.clamp_shift = wp.zeros(2 + len(model.clamp_paths), dtype=k["vec"], device=self.dev)
        self.held_code = None  # per node its clamp code, read below
        self._shift = np.zeros((2 + len(model.clamp_paths), self.dim))  # what clamp_shift holds, on the host
        state = sim.state
        model.update_stimuli(self.t)  # eigenstrains (material.stimulus) at the solve's time
        model.update_pressures(self.t)  # pressure loads at the solve's time
        solver.check_and_fit(state, 0.0)  # the reference grid block, its held nodes
        self.block = block_struct(model, solver.org, solver.shape)
        #: the grid block's nodes; the unknowns live on its slots: one per node, or two where the reference grid is
        #: split by contact group (slot i + n_block holds the groups other than node i's smallest), so that bodies
        #: that may separate or slide never share a node and meet only through the body contact's springs
        self.n_block = int(solver.n_active)
        split = solver.reference_contact_grid()
        self.split = split is not None
        if self.split:
            self.ct, self.node_class, self.node_gmin = split
        else:
            self.ct = contact_grid(model)
        self.kk = make_static_kernels(self.dim, self.sc, model.plane, self.split)
        self.n_nodes = self.n_block * (2 if self.split else 1)
        n = model.n_particles
        self.x = wp.zeros(n, dtype=k["vec"], device=self.dev)
        self.F = wp.zeros(n, dtype=k["mat"], device=self.dev)
        self.zero_v = wp.zeros(n, dtype=k["vec"], device=self.dev)
        self.zero_C = wp.zeros(n, dtype=k["mat"], device=self.dev)
        self.u = wp.zeros(self.n_nodes, dtype=k["vec"], device=self.dev)
        self.bodies = bodies_array(model)
        self.no_viscous = viscous_struct(model, None)
        grid = k["GridArrays"]()
        grid.p, grid.m, grid.clamp = solver.grid_p, solver.grid_m, solver.grid_clamp
        self.grid = wp.array([grid], dtype=k["GridArrays"], device=self.dev)
        src = k["Particles"]()  # p2g reads the reference positions, no motion, and the trial F
        src.x, src.v, src.C, src.F = model.X0, self.zero_v, self.zero_C, self.F
        src.x_now = self.x  # the placed particles' positions: an axisymmetric ring's hoop stretch r / R
        self.src = wp.array([src], dtype=k["Particles"], device=self.dev)
        g = np.zeros(self.dim)
        g[:] = np.asarray(st.gravity, dtype=np.float64).ravel()[: self.dim]
        self.gravity = g
        self.fields = solver.field_evaluator(sim.control)
        self.residual_evaluations = 0
        self.extra_force = None  # (n_nodes, dim) N: the imperfection force of a branch switch
        self.contact = None  # the colliders' penalty (magsoro.mpm.newton.static_contact), set up below
        self.collider_time = self.t  # the time the colliders stand at (their paths), s: ramped from 0 to t
        self.field_time = self.t  # the time the fields are evaluated at, s: moved with the loads after move_to()
        self._scene_contact = None  # its part for the scene's colliders (the rest: the domain walls)
        self._last_tangent = None
        # free nodes: carrying mass, not held
        self._scatter(np.zeros((self.n_nodes, self.dim)), 0.0, 0.0)
        mass = solver.grid_m.numpy()[: self.n_nodes].astype(np.float64)
        self.held_code = np.tile(solver.held_mask.numpy()[: self.n_block].astype(np.int64), self.n_nodes // self.n_block)
        held = self.held_code != 0
        self.node_mass = mass
        self.held_nodes = held  # nodes the clamps hold (read once: which nodes they hold does not change)
        self.free = np.flatnonzero((mass > 0) & ~held)
        shape = np.asarray(solver.shape, dtype=np.int64)
        self.shape = shape
        self.coords = np.stack(np.unravel_index(np.arange(self.n_nodes) % self.n_block, tuple(shape)), axis=1)
        self.dof_of_node = np.full(self.n_nodes, -1, dtype=np.int64)
        self.dof_of_node[self.free] = np.arange(len(self.free))
        if self.split:
            self._check_split()
        self.E = self._slaving(mass, held)
        self.u_nodes = np.zeros((self.n_nodes, self.dim))
        self.field_level = 0.0
        self.gravity_level = 0.0
        # the domain walls a body starts within reach of act as half-space colliders (the engine's walls stop nodes
        # two cells inside the domain's edge); the others are watched (wall_crossing)
        self.walls = self._starting_walls()
        if list(sim.control.colliders) or self.walls:
            from magsoro.mpm.newton.static_contact import ColliderPenalty, Contacts

            # the scene's colliders meet the bodies' surface (the particles) unless static.collider_contact = 'nodes';
            # the walls act where the engine's do (the nodes)
            points = {"surface": "particles", "nodes": "nodes"}[self.collider_contact]
            sets = [(list(sim.control.colliders), points), (self.walls, "nodes")]
            parts = [ColliderPenalty(self, cs, self.t, st.plane_z, st.depth, points=kind) for cs, kind in sets if cs]
            self.contact = Contacts(parts)
            self._scene_contact = parts[0] if sim.control.colliders else None
            # the colliders start where they are at the scene's start; the first level's load increments move them
            # along their paths to the solve's time with the loads (a plate pressed into a body: a crushing test)
            self._set_collider_time(0.0)
        #: contact between the bodies' contact groups, and within one (magsoro.mpm.newton.body_contact); None without
        self.body_contact = None
        if solver.contact_active:
            from magsoro.mpm.newton.body_contact import BodyContact
            from magsoro.mpm.newton.static_contact import Contacts

            self.body_contact = BodyContact(self, st.contact.friction, st.contact.self_contact, st.depth)
            self.contact = Contacts(([] if self.contact is None else self.contact.parts) + [self.body_contact])
        if self.contact is not None and self.penalty_scale != 1.0:
            for part in self.contact.parts:  # the colliders' and the bodies' penalties, and their step cuts
                part.k = part.k * self.penalty_scale
                part.step_depth = part.step_depth / self.penalty_scale
        if model.clamp_paths:  # so do the moving clamps, from where they stand at the start
            self._set_collider_time(0.0)
        self._check_held()
        if self.arc_length and self.walls:
            raise SimulationError("static.arc_length = true follows the equilibrium path of scenes without colliders, "
                                  "and a body starts within two cells of a domain wall (which then acts as one); "
                                  "enlarge simulation.domain_lo / domain_hi or set static.arc_length = false")

    def _check_held(self) -> None:
        """Refuse a scene with a free, loaded part: particles joined through shared grid nodes (bodies without
        contact between them share the grid, so they act as one) or resting on each other (body contact at the
        start), that no clamp holds and no collider or modelled domain wall touches at the start, on which the loads at the solve's time (fields at level 1, gravity) leave
        a net force or couple: it has no equilibrium where it is (a body 1 mm above its floor under gravity failed
        its load increments after minutes). A free part whose loads balance (a ring under internal pressure) is
        solved."""
        from scipy.sparse.csgraph import connected_components

        P = self.interpolation()
        mass = self.node_mass
        carrying = mass > 0
        _, label = connected_components((P.T @ P).tocsr(), directed=False)
        particle_label = label[np.asarray(P.argmax(axis=1)).ravel()]  # each particle's part: that of its largest weight's node
        supported = set(np.unique(label[self.held_nodes & carrying]).tolist())
        supported |= set(np.unique(label[P[np.flatnonzero(self.model.host["clamped"] != 0)].indices]).tolist())
        gaps = {}  # part label -> (smallest clearance above a collider's touching level, m; the collider's index)
        if self.body_contact is not None:
            # bodies resting on each other at the start are one part here: a stack on a floor is held by the floor
            a, b = self.body_contact.touching_particles(np.zeros((self.n_nodes, self.dim)))
            if len(a):
                from scipy import sparse as _sparse

                pa, pb = particle_label[a], particle_label[b]
                n_lab = int(label.max()) + 1
                links = _sparse.coo_matrix((np.ones(len(pa)), (pa, pb)), shape=(n_lab, n_lab)).tocsr()
                _, merged = connected_components(links + _sparse.identity(n_lab, format="csr"), directed=False)
                label, particle_label = merged[label], merged[particle_label]
        if self.contact is not None:
            for part in self.contact.parts:
                if part is self.body_contact:
                    continue
                pts = part.X[part.touchable]
                point_labels = label[part.touchable] if part.W is not P else particle_label[part.touchable]
                for ci, (c, lvl) in enumerate(zip(part.colliders, part.level)):
                    clearance = part.distance(c, pts, 0.0) - lvl - part.touch
                    supported |= set(np.unique(point_labels[clearance <= 0.0]).tolist())
                    if part is self._scene_contact:
                        for lab in np.unique(point_labels):
                            gap = float(np.min(clearance[point_labels == lab]))
                            if lab not in gaps or gap < gaps[lab][0]:
                                gaps[lab] = (gap, ci)
        free = [lab for lab in np.unique(particle_label) if lab not in supported]
        if not free:
            return
        # the loads' net force and couple (about the part's centroid) on each free part: the stresses' node forces
        # sum to zero, with their moments (at u = 0: no stress anyway, as the body starts unstressed)
        f = self._scatter(np.zeros((self.n_nodes, self.dim)), 1.0, 1.0)
        if self.contact is not None:
            f = f - self.contact.forces(np.zeros((self.n_nodes, self.dim)))
        X = self.node_positions()[2]  # the nodes' reference positions
        loaded = []
        for lab in free:
            nodes = np.flatnonzero((label == lab) & carrying)
            fn, xn = f[nodes], X[nodes]
            centre = np.average(xn, axis=0, weights=mass[nodes])
            net = fn.sum(axis=0)
            arm = xn - centre
            couple = (arm[:, 0] * fn[:, 1] - arm[:, 1] * fn[:, 0]).sum() if self.dim == 2 else np.cross(arm, fn).sum(axis=0)
            if self.model.plane == "axisymmetric":  # a ring body's only rigid motion: along the axis
                net, couple = net[1:], 0.0
            size = float(np.max(np.linalg.norm(arm, axis=1))) + float(self.model.dx)
            gross = float(np.abs(fn).sum()) + 1e-300
            if np.linalg.norm(net) > 1e-6 * gross or np.linalg.norm(couple) > 1e-6 * gross * size:
                loaded.append(lab)
        self._scatter(np.zeros((self.n_nodes, self.dim)), 0.0, 0.0)  # the unloaded state's evaluation again
        free = loaded
        if not free:
            return
        names = self.sim.built.body_names
        body = np.asarray(self.model.host["body"])
        lab = free[0]
        parts = [names[int(b)] for b in np.unique(body[particle_label == lab])]
        what = f"body '{parts[0]}'" if len(parts) == 1 else "bodies " + ", ".join(f"'{n}'" for n in parts)
        where = "no collider in the scene"
        if lab in gaps:
            gap, ci = gaps[lab]
            where = (f"it lies {gap * 1e3:.3g} mm ({gap / float(self.model.dx):.2g} cells) clear of colliders[{ci}] "
                     f"({self.sim.control.colliders[ci].kind}), the nearest")
        touching = "its surface on the collider" if self.collider_contact == "surface" else "within 0.1 cells of a node"
        raise SimulationError(
            f"{what} is free at the start: no clamp holds it and no collider touches it ({where}), and its loads "
            f"(fields, gravity) do not balance, so it has no equilibrium there. Place it on the collider meant to "
            f"carry it (static.collider_contact = '{self.collider_contact}': {touching}), add a clamp, or run the "
            f"dynamics (magsoro run without --static, or --equilibrium)")

    # -- residual -----------------------------------------------------------------------------------------
    def _place(self, u_nodes: np.ndarray) -> None:
        self.u.assign(u_nodes.astype(self.model.np_scalar))
        launch_place_particles(self.kk, self.model.n_particles, X=self.model.X0, u=self.u, block=self.block,
                               clamped=self.model.clamped, clamp_shift=self.clamp_shift, contact=self.ct, x=self.x,
                               F=self.F, device=self.dev)

    def _scatter(self, u_nodes: np.ndarray, field_level: float, gravity_level: float) -> np.ndarray:
        """Node forces (n_nodes, dim) at the displacement ``u_nodes`` under the given load levels."""
        solver, model, k, sc = self.solver, self.model, self.k, self.sc
        self._place(u_nodes)
        applied = k["Applied"]()
        b0 = self.fields.uniform_value(self.field_time) * field_level
        applied.B_uniform = k["v3"](*[sc(b) for b in b0])
        has_gradient = self.fields.has_gradient or solver.interaction is not None
        applied.has_gradient = 1 if has_gradient else 0
        if has_gradient:
            B, grad_B = solver.B_particle, solver.grad_B_particle
            B.zero_()
            grad_B.zero_()
            if self.fields.has_gradient:
                self.fields.evaluate(self.x, B, grad_B, self.field_time)
                if field_level != 1.0:
                    Bn, Gn = B.numpy(), grad_B.numpy()
                    B.assign(Bn * field_level)
                    grad_B.assign(Gn * field_level)
            if solver.interaction is not None:
                # the bodies' own field is not scaled by the field level: it is on at every level, like gravity,
                # and ramps with gravity_level from the unloaded state (so load increments can take it in steps)
                inter = solver.interaction
                inter.refresh(self.x, self.F)
                if gravity_level != 1.0:
                    inter.B.assign(inter.B.numpy() * gravity_level)
                    inter.grad_B.assign(inter.grad_B.numpy() * gravity_level)
                inter.add_to(B, grad_B, keep=True)
        applied.B, applied.grad_B = solver.B_particle, solver.grad_B_particle
        solver.grid_p.zero_()
        solver.grid_m.zero_()
        solver.error.zero_()
        if model.closed_pressures:
            # a closed cavity's net pressure force at the trial F, taken back in p2g as in a step (the tangent
            # leaves this correction out, as it leaves out the load's own stiffness)
            model.pressure_net.zero_()
            launch_pressure_net(k, model.n_particles, bodies=self.bodies, F=self.F, net=model.pressure_net, device=self.dev)
        launch_p2g(k, model.n_particles, src=self.src, bodies=self.bodies, applied=applied, block=self.block, dt=sc(1.0),
                   grid=self.grid, error=solver.error, flags=P2G_TOTAL, contact=self.ct, viscous=self._viscous_argument(),
                   affine=solver.particle_affine, momentum=solver.particle_momentum, device=self.dev)
        self.residual_evaluations += 1
        f = solver.grid_p.numpy()[: self.n_nodes].astype(np.float64)
        m = solver.grid_m.numpy()[: self.n_nodes].astype(np.float64)
        f = f + m[:, None] * (gravity_level * self.gravity)[None, :]
        if self.contact is not None:
            f = f + self.contact.forces(u_nodes)
        return f if self.extra_force is None else f + self.extra_force

    def _viscous_argument(self):
        """The p2g kernel's Viscous argument at the placed particles (no Prony overstress: the static solver refuses
        Prony materials; the implicit integrator gives its step's)."""
        return self.no_viscous

    def _add_material_tangent(self, A) -> None:
        """Add to the particles' dP/dF ``A`` (material_tangent's layout) what the stress of :meth:`_scatter` has
        beyond each law's own (nothing here; the implicit integrator's Prony overstress)."""

    def residual(self, u_nodes, field_level, gravity_level) -> np.ndarray:
        """Out-of-balance force on the unknowns (the free nodes' forces gathered by the slaving), flat."""
        return self._reduce(self._scatter(u_nodes, field_level, gravity_level))

    def node_forces(self, u_nodes, field_level, gravity_level) -> np.ndarray:
        """Node forces (n_nodes, dim), N, at the node displacements ``u_nodes`` under the given load levels; the
        solver's particle positions x and deformation gradients F are left at ``u_nodes``."""
        return self._scatter(u_nodes, field_level, gravity_level)

    def forces_on_unknowns(self, node_forces: np.ndarray) -> np.ndarray:
        """The node forces (n_nodes, dim) gathered onto the unknowns (E^T f over the free nodes: virtual work), flat."""
        return self._reduce(node_forces)

    def particle_stencil(self):
        """Per particle: flat node indices (N, 3^dim), weights (N, 3^dim) and reference weight gradients (N, 3^dim,
        dim, 1/m) of the engine's quadratic B-splines on the reference grid block (computed once)."""
        return self._stencil()

    def fit_nodes(self, values: np.ndarray, gradients: np.ndarray) -> np.ndarray:
        """Node values (n_nodes, dim) on the unknowns (held nodes zero) whose interpolation best fits the particles'
        ``values`` (n_particles, dim) and their reference gradients ``gradients`` (n_particles, dim, dim: d value_a /
        dX_b), in the mass-weighted least-squares sense with the gradients weighted by dx^2 (clamped particles left
        out: they do not follow their nodes). The gradients matter:
        combinations of light nodes at a body's faces move no particle but change the particles' F, so a fit of the
        positions alone leaves them free, and a state at rest came back out of balance (the 3D strip of
        benchmarks/implicit_vs_explicit.py, settled: its light nodes 4 cells, its face nodes 0.13 cells from where
        they were, |R| from 6e-9 to 1e-2 N; with the gradients it came back to 1e-10 cells). Where the solver slaves
        nodes (the light nodes in 3D, an axisymmetric scene's mirror and axis nodes) they follow the unknowns
        through the map E (:meth:`_slaving`): the fit is one least-squares problem per component on E's block of
        that component."""
        from scipy import sparse

        if self.E.shape[0] != self.E.shape[1]:
            return self._fit_nodes_mapped(values, gradients)
        if self._projector is None:
            # without slaved nodes the unknowns are the free nodes' components and the fit splits into one scalar
            # least-squares problem per component, with the same matrix
            P = self.interpolation()[:, self.free]
            nodes, _, grad = self._stencil()
            rows = np.repeat(np.arange(self.model.n_particles), nodes.shape[1])
            column = np.full(self.n_nodes, -1)
            column[self.free] = np.arange(len(self.free))
            cols, keep = column[nodes.ravel()], column[nodes.ravel()] >= 0
            dx = float(self.model.dx)
            blocks = [P] + [sparse.csr_matrix((dx * grad[:, :, b].ravel()[keep], (rows[keep], cols[keep])),
                                              shape=P.shape) for b in range(self.dim)]
            Q = sparse.vstack(blocks, format="csr")
            # clamped particles stay where they are whatever their nodes do (the static solver's placement)
            mass = np.where(self.model.host["clamped"] != 0, 0.0, self.model.host["mass"].astype(np.float64))
            QtW = (Q.T @ sparse.diags(np.tile(mass, self.dim + 1))).tocsr()
            A = (QtW @ Q).tocsc()
            shift = PROJECT_SHIFT * float(np.median(np.abs(A.diagonal()))) if A.shape[0] else 0.0
            self._projector = (Q, QtW, factor(A + shift * sparse.identity(A.shape[0], format="csc")))
        Q, QtW, lu = self._projector
        dx = float(self.model.dx)
        gradients = np.asarray(gradients, dtype=np.float64)
        data = np.concatenate([np.asarray(values, dtype=np.float64)] + [dx * gradients[:, :, b] for b in range(self.dim)])
        # the normal equations square Q's condition (the light nodes'): refined on the residual of the fit itself
        x = np.zeros((Q.shape[1], self.dim))
        for _ in range(PROJECT_REFINEMENTS + 1):
            x = x + lu.solve(QtW @ (data - Q @ x))
        out = np.zeros((self.n_nodes, self.dim))
        out[self.free] = x
        return out

    def _fit_nodes_mapped(self, values: np.ndarray, gradients: np.ndarray) -> np.ndarray:
        """:meth:`fit_nodes` through the map E from the unknowns to the free nodes, whose components do not mix (the
        light nodes of the 3D solver, extrapolated component by component; the mirror nodes of an axisymmetric
        scene): per component a, the free nodes' values are E_a y_a."""
        from scipy import sparse

        dim, dx = self.dim, float(self.model.dx)
        if self._projector is None:
            P = self.interpolation()[:, self.free]
            nodes, _, grad = self._stencil()
            rows = np.repeat(np.arange(self.model.n_particles), nodes.shape[1])
            column = np.full(self.n_nodes, -1)
            column[self.free] = np.arange(len(self.free))
            cols, keep = column[nodes.ravel()], column[nodes.ravel()] >= 0
            Q = sparse.vstack([P] + [sparse.csr_matrix((dx * grad[:, :, b].ravel()[keep], (rows[keep], cols[keep])),
                                                       shape=P.shape) for b in range(dim)], format="csr")
            mass = np.where(self.model.host["clamped"] != 0, 0.0, self.model.host["mass"].astype(np.float64))
            weights = sparse.diags(np.tile(mass, dim + 1))
            E = self.E.tocsr()
            parts = []
            for a in range(dim):
                Ea = E[a::dim, a::dim]
                Qa = (Q @ Ea).tocsr()
                QtWa = (Qa.T @ weights).tocsr()
                Aa = (QtWa @ Qa).tocsc()
                diag = np.abs(Aa.diagonal())
                shift = PROJECT_SHIFT * float(np.median(diag[diag > 0])) if np.any(diag > 0) else 1.0
                # an unknown that moves no node (an axis node's radial one) has an empty column: the shift keeps it 0
                parts.append((Ea, Qa, QtWa, factor((Aa + shift * sparse.identity(Aa.shape[0], format="csc")).tocsc())))
            self._projector = parts
        gradients = np.asarray(gradients, dtype=np.float64)
        out = np.zeros((self.n_nodes, dim))
        for a, (Ea, Qa, QtWa, lu) in enumerate(self._projector):
            data = np.concatenate([np.asarray(values, dtype=np.float64)[:, a]] + [dx * gradients[:, a, b] for b in range(dim)])
            y = np.zeros(Qa.shape[1])
            for _ in range(PROJECT_REFINEMENTS + 1):
                y = y + lu.solve(QtWa @ (data - Qa @ y))
            out[self.free, a] = Ea @ y
        return out

    def displacement_at(self, X: np.ndarray, groups: np.ndarray | None = None):
        """The displacement field of the nodes' displacements ``u_nodes`` at reference points ``X`` (N, dim, m),
        as the engine interpolates it (quadratic B-splines on the reference grid block): (u (N, dim) m, its
        reference gradient (N, dim, dim), du_a/dX_b). Points must lie where the block's nodes carry mass. A block
        split by contact groups needs each point's group (``groups``, as the model's contact_group). Used to start
        a solve on a finer grid from this one's equilibrium (grid sequencing)."""
        X = np.asarray(X, dtype=np.float64)[:, : self.dim]
        nodes, w, grad = self._bspline_stencil(X)
        if self.split:
            if groups is None:
                raise ValueError("displacement_at: the block is split by contact groups; give each point's group")
            nodes = self._slot_of(np.asarray(groups)[:, None], nodes)
        u_at = self.u_nodes[nodes]  # (N, S, dim)
        return np.einsum("ps,psa->pa", w, u_at), np.einsum("psb,psa->pab", grad, u_at)

    def interpolation(self):
        """P (n_particles x n_nodes, sparse CSR): the particles' B-spline weights on the reference grid block, so
        that the particles sit at X + P u (computed once)."""
        if getattr(self, "_interpolation_cache", None) is None:
            from scipy import sparse

            nodes, w, _ = self._stencil()
            n = self.model.n_particles
            rows = np.repeat(np.arange(n), nodes.shape[1])
            self._interpolation_cache = sparse.csr_matrix((w.ravel(), (rows, nodes.ravel())), shape=(n, self.n_nodes))
        return self._interpolation_cache

    def node_positions(self):
        """(nodes carrying mass, W, X) of :func:`~magsoro.mpm.newton.static_contact.node_positions_map` (computed once):
        where the engine puts the grid nodes, X + W u, for the node contact law and the walls' check."""
        if getattr(self, "_node_map", None) is None:
            from magsoro.mpm.newton.static_contact import node_positions_map

            self._node_map = node_positions_map(self)
        return self._node_map

    def _wall_positions(self, u_nodes: np.ndarray) -> np.ndarray:
        """Where the engine's walls see the free nodes carrying mass at ``u_nodes``: reference position plus the
        mass-weighted displacement of their particles, clamped ones held (:meth:`node_positions`, the map the node
        law of the colliders uses), (n_free_with_mass, dim)."""
        carrying, W, X = self.node_positions()
        free = np.setdiff1d(carrying, np.flatnonzero(self.held_nodes))
        return X[free] + W[free] @ np.asarray(u_nodes)

    def _walls_reached(self, u_nodes: np.ndarray) -> list:
        """The domain walls whose band (WALL_CELLS from the domain's edge, where the engine's walls stop a node)
        holds a free node carrying mass at ``u_nodes``: (axis, side 'lo'/'hi', the band's inner edge, the domain's
        face) each."""
        dim, dx = self.dim, float(self.model.dx)
        pos = self._wall_positions(u_nodes)
        lo = np.asarray(self.model.domain_lo, dtype=np.float64)[:dim]
        hi = np.asarray(self.model.domain_hi, dtype=np.float64)[:dim]
        out = []
        for a in range(dim):
            if np.any(pos[:, a] < lo[a] + WALL_CELLS * dx):
                out.append((a, "lo", lo[a] + WALL_CELLS * dx, lo[a]))
            if np.any(pos[:, a] > hi[a] - WALL_CELLS * dx):
                out.append((a, "hi", hi[a] - WALL_CELLS * dx, hi[a]))
        return out

    def _starting_walls(self) -> list:
        """Half-space colliders for the domain walls whose band holds a free node at the start: the plane at the
        band's inner edge less the penalty's skin (so a node touches where the engine's wall stops it), with the
        walls' contact law (simulation.walls, wall_friction); a node that starts deeper is held where it starts."""
        from magsoro.mpm.newton.static_contact import SKIN_CELLS

        st = self.solver.settings
        out = []
        for a, side, edge, _ in self._walls_reached(self.u_nodes):
            normal = np.zeros(3)
            normal[a] = 1.0 if side == "lo" else -1.0
            point = np.zeros(3)
            point[a] = edge - normal[a] * SKIN_CELLS * float(self.model.dx)
            out.append(Collider.half_space(point, normal, mode=st.walls, friction=float(st.wall_friction)))
            out[-1].wall = (a, side)
        return out

    def wall_crossing(self, u_nodes: np.ndarray) -> str | None:
        """Where the displacement ``u_nodes`` puts a free node carrying mass into the band of a domain wall that the
        solver does not model (the engine's walls stop a node within two cells of the domain's edge; walls a body
        starts in are modelled, :meth:`_starting_walls`), as a phrase naming the wall and its scene key; None
        when no node is there."""
        modelled = {c.wall for c in self.walls}
        for a, side, _, face in self._walls_reached(u_nodes):
            if (a, side) not in modelled:
                return (f"within two cells of the domain wall at {'xyz'[a]} = {face:.6g} m (simulation.domain_{side}[{a}]), "
                        f"where the engine's walls act")
        return None

    # -- the unknowns -------------------------------------------------------------------------------------
    def _slaving(self, mass: np.ndarray, held: np.ndarray):
        """The map E from the unknowns to the free nodes' displacements (sparse, n_free dim x n_unknown dim).

        A free node whose mass is below LIGHT of the heaviest node's (the outer layer of nodes a body's particles
        reach only with the tail of the B-spline, its edges and corners) is not an unknown: its displacement is
        extrapolated linearly from the two nodes inward of it, u = 2 u_a - u_b, a and b one and two cells towards
        its particles' centroid (exact for any affine displacement: rigid motions and uniform strains). Left as
        unknowns, such nodes reach only one or two particles and have more unknowns than those particles have
        strains: combinations of them that move no particle are null modes of the tangent (in 3D with two cells
        across a section, 168 of 3150 unknowns), and those that barely move one stall Newton.

        Axisymmetric: the displacement field is mirror-symmetric about the axis (u_r odd, u_z even), as the
        engine's grid update makes the velocities. A node at r = -k dx (the stencils of particles next to the axis
        reach it) takes its mirror's displacement with u_r reversed, and a node on the axis moves along it only:
        its radial column of E is zero (the tangent's null shift keeps that unknown at zero)."""
        from scipy import sparse

        dim = self.dim
        nodes, w, _ = self._stencil()
        h = self.model.host
        wm = w * h["mass"][:, None]
        centroid = np.stack([np.bincount(nodes.ravel(), weights=(wm * h["positions"][:, a][:, None]).ravel(),
                                         minlength=self.n_nodes) for a in range(dim)], axis=1)
        X = (self.model.domain_lo + self.solver.org * self.model.dx) + self.coords * self.model.dx
        light = np.zeros(self.n_nodes, bool)
        light[self.free] = mass[self.free] < self.light_fraction() * mass.max()
        self.n_light = int(light.sum())
        ones = np.ones(dim)
        axis = None  # an axisymmetric scene's axis: its column of nodes in the block
        if self.model.plane == "axisymmetric":
            axis = int(round(-(self.model.domain_lo[0] + self.solver.org[0] * self.model.dx) / self.model.dx))
            light[self.coords[:, 0] < axis] = True  # mirror nodes: never unknowns
        mirror_sign = np.where(np.arange(dim) == 0, -1.0, 1.0)
        along_axis = np.where(np.arange(dim) == 0, 0.0, 1.0)
        unknown = self.free[~light[self.free]]
        column = np.full(self.n_nodes, -1, dtype=np.int64)
        column[unknown] = np.arange(len(unknown))
        shape = tuple(int(v) for v in self.shape)
        memo = {}
        # a split block: the neighbours a light node extrapolates from are its group's slots of the nodes inward
        slot_group = self._slot_groups()

        def combination(node: int, depth: int = 0) -> dict:
            """The node's displacement as {unknown: per-component coefficients}."""
            if axis is None:
                return extrapolated(node, depth)
            c = self.coords[node]
            if c[0] < axis:  # a mirror node: its mirror's displacement, u_r reversed
                q = c.copy()
                q[0] = 2 * axis - c[0]
                if q[0] >= shape[0]:
                    return {}
                partner = int(self._slot_of(slot_group[node], np.ravel_multi_index(tuple(q), shape)))
                return {k: v * mirror_sign for k, v in combination(partner, depth + 1).items()}
            out = extrapolated(node, depth)
            if c[0] == axis:  # on the axis: along it only
                out = {k: v * along_axis for k, v in out.items()}
            return out

        def extrapolated(node: int, depth: int = 0) -> dict:
            if column[node] >= 0:
                return {int(column[node]): ones}
            if held[node] or mass[node] <= 0.0 or depth > 8:
                return {}  # a held node does not move; an empty one is not reached
            if node not in memo:
                c = self.coords[node]
                d = np.clip(np.round((centroid[node] / mass[node] - X[node]) / self.model.dx), -1, 1).astype(np.int64)
                out = {}
                inner = [c + d, c + 2 * d]
                ok = [bool(np.all(q >= 0) and np.all(q < self.shape)) for q in inner]
                ids = [int(self._slot_of(slot_group[node], np.ravel_multi_index(tuple(q), shape))) if k else -1
                       for q, k in zip(inner, ok)]
                if not ok[0] or not d.any():
                    memo[node] = {}
                    return {}
                linear = ok[1] and (mass[ids[1]] > 0.0 or held[ids[1]])
                for coef, q in ((2.0, ids[0]), (-1.0, ids[1])) if linear else ((1.0, ids[0]),):
                    for k, v in combination(q, depth + 1).items():
                        out[k] = out.get(k, 0.0) + coef * v
                memo[node] = out
            return memo[node]

        rows, cols, vals = [], [], []
        for k, node in enumerate(self.free):
            for col, v in combination(int(node)).items():
                for a in range(dim):
                    if v[a] != 0.0:
                        rows.append(k * dim + a)
                        cols.append(col * dim + a)
                        vals.append(v[a])
        self.unknown_nodes = unknown  # the node of each unknown's dim components, in their order
        return sparse.csr_matrix((vals, (rows, cols)), shape=(len(self.free) * dim, len(unknown) * dim))

    def light_fraction(self) -> float:
        """Free nodes lighter than this fraction of the heaviest node are slaved (:meth:`_slaving`): LIGHT[dim]."""
        return LIGHT[self.dim]

    def _reduce(self, node_forces: np.ndarray) -> np.ndarray:
        """Forces on the unknowns, E^T f over the free nodes (virtual work), flat."""
        return self.E.T @ node_forces[self.free].ravel()

    def _expand(self, values: np.ndarray) -> np.ndarray:
        """Node displacements (n_nodes, dim) of the unknowns' ``values`` (flat): E values on the free nodes."""
        out = np.zeros((self.n_nodes, self.dim))
        out[self.free] = (self.E @ values).reshape(-1, self.dim)
        return out

    def _valid(self) -> bool:
        F = self.F.numpy().astype(np.float64)
        return bool(np.all(np.isfinite(F)) and np.all(np.linalg.det(F) > 0.0))

    def _check_split(self) -> None:
        """Refuse a scene where three contact groups that may separate reach one grid node at the start: the split
        grid keeps two apart per node (the node's smallest group and the rest), so the other two would be glued."""
        nodes, _, _ = self._stencil()
        g = np.repeat(self.model.host["contact_group"].astype(np.int64), nodes.shape[1])
        lo = np.full(self.n_nodes, np.iinfo(np.int64).max)
        hi = np.full(self.n_nodes, -1)
        np.minimum.at(lo, nodes.ravel(), g)
        np.maximum.at(hi, nodes.ravel(), g)
        friction = self.solver.settings.contact.friction
        mixed = np.flatnonzero(hi > lo)
        mixed = mixed[friction[lo[mixed], hi[mixed]] >= 0.0]
        if len(mixed) == 0:
            return
        node = int(mixed[0]) % self.n_block
        body = self.model.host["body"]
        groups = np.unique(self.model.host["contact_group"][np.any(nodes % self.n_block == node, axis=1)])
        names = self.sim.built.body_names
        what = ", ".join(f"'{names[int(b)]}'" for b in np.unique(body[np.isin(self.model.host["contact_group"], groups)]))
        raise SimulationError(
            f"bodies {what} come within about three cells of one another at one grid node at the start; the Newton "
            f"solvers keep two bodies apart per node, so these would act as one: draw them further apart, bond the "
            f"ones meant to stick ([contact] bonded or a [[contact.pairs]] entry with bonded = true), or run the "
            f"explicit engine")

    def _slot_groups(self) -> np.ndarray:
        """The contact group each slot holds (-1 for a slot no particle reaches), computed once."""
        if getattr(self, "_slot_group_cache", None) is None:
            nodes, _, _ = self._stencil()
            out = np.full(self.n_nodes, -1, dtype=np.int64)
            out[nodes.ravel()] = np.repeat(self.model.host["contact_group"], nodes.shape[1])
            self._slot_group_cache = out
        return self._slot_group_cache

    def _slot_of(self, group, node):
        """The slot holding contact group ``group`` at grid-block node ``node`` (arrays, broadcast): the node's second
        where the reference grid is split there and the group is not its smallest (:mod:`magsoro.mpm.kernels.contact`'s
        field_of); the node itself otherwise."""
        node = np.asarray(node)
        if not self.split:
            return node
        second = (self.node_class[node] == int(NodeClass.BODIES)) & (np.asarray(group) != self.node_gmin[node])
        return node + second * self.n_block

    # -- tangent --------------------------------------------------------------------------------------------
    def _stencil(self):
        """Per particle: flat node indices (N, 3^dim), weights (N, 3^dim) and reference weight gradients
        (N, 3^dim, dim) of the engine's quadratic B-splines on the reference grid block (MLS: grad w =
        (4/dx^2) w (x_i - x_p))."""
        if getattr(self, "_stencil_cache", None) is None:
            m = self.model
            nodes, w, grad = self._bspline_stencil(m.host["positions"])
            if self.split:  # each particle's own group's slot (the kernels' slot_of)
                nodes = self._slot_of(m.host["contact_group"][:, None], nodes)
            self._stencil_cache = (nodes, w, grad)
        return self._stencil_cache

    def _bspline_stencil(self, X: np.ndarray):
        """Flat node indices in the unsplit block (N, 3^dim), weights and reference weight gradients of points
        ``X`` (N, dim) on the reference grid block."""
        m, dim = self.model, self.dim
        base, fx, w1d = host_bspline(X[:, :dim], m.domain_lo + self.solver.org * m.dx, m.dx)  # w1d: (3, N, dim)
        if np.any(base < 0) or np.any(base + 2 >= np.asarray(self.shape)[None, :]):
            raise ValueError("points outside the solver's grid block")
        offs = np.stack(np.meshgrid(*[np.arange(3)] * dim, indexing="ij"), axis=-1).reshape(-1, dim)  # (S, dim)
        w = np.ones((len(X), len(offs)))
        for a in range(dim):
            w *= w1d[offs[:, a], :, a].T
        nodes = np.ravel_multi_index(tuple((base[:, None, :] + offs[None]).transpose(2, 0, 1)), tuple(self.shape))
        grad = (4.0 / m.dx) * w[:, :, None] * (offs[None, :, :] - fx[:, None, :])
        return nodes, w, grad

    def _field_terms(self, field_level: float):
        """B, grad B (T, T/m; the model's in-plane part) at the particles' current positions and the gradient's
        derivative along each axis (central differences of the sources), all scaled by ``field_level``; None
        without a non-uniform source."""
        if not self.fields.has_gradient:
            return None
        dim, n, k = self.dim, self.model.n_particles, self.model.kernels
        B = wp.zeros(n, dtype=k["v3"], device=self.dev)
        G = wp.zeros(n, dtype=k["m3"], device=self.dev)
        x0 = self.x.numpy().astype(np.float64)
        xs = wp.zeros(n, dtype=k["vec"], device=self.dev)
        self.fields.evaluate(self.x, B, G, self.field_time)
        G0 = G.numpy().astype(np.float64)[:, :dim, :dim] * field_level
        h = X_STEP * self.model.dx
        dG = np.zeros((n, dim, dim, dim))  # dG[p, a, b, e] = d(dB_a/dx_b)/dx_e
        for e in range(dim):
            Gs = []
            for sign in (1.0, -1.0):
                xx = x0.copy()
                xx[:, e] += sign * h
                xs.assign(xx.astype(self.model.np_scalar))
                self.fields.evaluate(xs, B, G, self.field_time)
                Gs.append(G.numpy().astype(np.float64)[:, :dim, :dim])
            dG[:, :, :, e] = (Gs[0] - Gs[1]) / (2.0 * h) * field_level
        return G0, dG

    def tangent(self, u_nodes, field_level, gravity_level):
        """dR/du on the free DOFs, assembled from the particles (sparse, CSC) by the kernels ``material_tangent``
        and ``assemble_tangent``:

        - elastic: -V0 A_acbd g_i^c g_j^d with A = dP/dF of each particle's law (central differences) and g the
          reference weight gradients (F = I + sum_j u_j g_j^T);
        - with a non-uniform field, the magnetic stress's change with position, V0 / mu0 G_ab Br_c g_i^c w_j,
          and the gradient force f = G^T m (m = F Br V0 / mu0)'s change with F and with position, w_i (G_ba
          Br_c V0 / mu0 g_j^c + d(G_ba)/dx_e m_b w_j).
        The bodies' own field is left out of the tangent (it enters the residual; :meth:`_solve_linear`)."""
        from scipy import sparse

        self._scatter(u_nodes, field_level, gravity_level)  # x and F at u
        dim, n, k, dev = self.dim, self.model.n_particles, self.model.kernels, self.dev
        indices, indptr, d_slots, d_indptr = self._pattern()
        if getattr(self, "_tangent_arrays", None) is None:
            ring = self.model.plane == "axisymmetric"  # the hoop derivatives: read in that mode only
            self._tangent_arrays = (wp.zeros(n * dim * dim, dtype=k["mat"], device=dev),
                                    wp.array(self.dof_of_node.astype(np.int32), dtype=wp.int32, device=dev),
                                    wp.zeros(len(indices), dtype=self.sc, device=dev),
                                    wp.zeros(2 * n if ring else 1, dtype=k["mat"], device=dev),
                                    wp.zeros(n if ring else 1, dtype=self.sc, device=dev))
        A, dof, data, hoop_A, hoop_c = self._tangent_arrays
        launch_material_tangent(self.kk, n, F=self.F, x=self.x, bodies=self.bodies, h=self.sc(F_STEP), A=A,
                                hoop_A=hoop_A, hoop_c=hoop_c, device=dev)
        self._add_material_tangent(A)
        fterms = self.kk["FieldTerms"]()
        terms = self._field_terms(field_level)
        if terms is not None:  # (a 2D scene's out-of-plane moment, Br_z, is left out of the tangent)
            G0, dG = terms
            V0 = self.model.host["volumes"]
            br = self.model.host["remanence"][:, :dim]
            m = np.einsum("pbc,pc->pb", self.F.numpy().astype(np.float64), br) * (V0 / MU0)[:, None]
            npsc = self.model.np_scalar
            fterms.active = 1
            fterms.coef = wp.array((V0 / MU0).astype(npsc), dtype=self.sc, device=dev)
            fterms.grad_B = wp.array(G0.astype(npsc), dtype=k["mat"], device=dev)
            fterms.br = wp.array(br.astype(npsc), dtype=k["vec"], device=dev)
            fterms.H = wp.array(np.einsum("pbae,pb->pae", dG, m).astype(npsc), dtype=k["mat"], device=dev)
        data.zero_()
        launch_assemble_tangent(self.kk, n * 3 ** dim, X=self.model.X0, block=self.block, bodies=self.bodies, A=A,
                                hoop_A=hoop_A, hoop_c=hoop_c, field_terms=fterms, contact=self.ct, dof=dof, indptr=d_indptr, slots=d_slots, data=data, device=dev)
        n_dof = len(self.free) * dim
        J = sparse.csc_matrix((data.numpy().astype(np.float64), indices, indptr), shape=(n_dof, n_dof))
        if self.contact is not None:  # the colliders' springs at u (the scatter above evaluated them)
            J = J + self.contact.tangent(self.free)
        J = (self.E.T @ J @ self.E).tocsc()  # on the unknowns (_slaving)
        # what null modes the slaving leaves (a body thinner than its stencil): a shift of NULL_SHIFT of the
        # median diagonal keeps the factorisation regular; the residual has no part along them
        n = J.shape[0]
        shift = NULL_SHIFT * float(np.median(np.abs(J.diagonal()))) if n else 0.0
        return (J - shift * sparse.identity(n, format="csc")).tocsc()

    def _pattern(self):
        """The tangent's CSC pattern on the free DOFs, computed once (the stencils and free nodes do not change):
        every pair of free nodes that share a particle's stencil couples all their components. Returns the row
        indices (sorted within each column) and column pointers, on the host and on the device."""
        if getattr(self, "_pattern_cache", None) is None:
            from scipy import sparse

            dim = self.dim
            nodes, _, _ = self._stencil()
            nf = len(self.free)
            rows = self.dof_of_node[nodes]  # (N, S): the free node's index, -1 for a held or empty node
            ok = (rows[:, :, None] >= 0) & (rows[:, None, :] >= 0)
            pair = rows[:, None, :] * nf + rows[:, :, None]  # (N, s, t): column node t, row node s
            # the coupled node pairs, sorted by column node j and row node i (key j nf + i): the pattern of S^T S,
            # S the particles' incidence on the free nodes (a sort of all N S^2 pairs took 5 times as long)
            on = rows.ravel() >= 0
            incidence = sparse.csr_matrix((np.ones(int(on.sum())), (np.repeat(np.arange(len(rows)), rows.shape[1])[on],
                                                                     rows.ravel()[on])), shape=(len(rows), nf))
            coupled = (incidence.T @ incidence).tocsc()
            coupled.sort_indices()
            col_node = np.repeat(np.arange(nf, dtype=np.int64), np.diff(coupled.indptr))
            row_node = coupled.indices.astype(np.int64)
            key = col_node * nf + row_node
            glen = np.bincount(col_node, minlength=nf) * dim  # entries of each column of node j
            gstart = np.concatenate([[0], np.cumsum(glen)[:-1]])
            expanded = (row_node[:, None] * dim + np.arange(dim)[None, :]).ravel()  # by j, then i, then a
            lens, starts = np.repeat(glen, dim), np.repeat(gstart, dim)  # column j dim + b: node j's rows again
            indptr = np.concatenate([[0], np.cumsum(lens)])
            pick = np.arange(indptr[-1]) - np.repeat(indptr[:-1], lens) + np.repeat(starts, lens)
            indices = expanded[pick].astype(np.int32)
            indptr = indptr.astype(np.int32)
            # where the rows of each particle's stencil node s start in the columns of its node t, from the column's
            # start (the same in the dim columns of node t): the assembly kernel adds there without a search (a
            # binary search per block took about half of the assembly's time on the CPU)
            # (node j's first key sits at gstart[j] / dim in ``key``)
            slots = np.where(ok, np.searchsorted(key, pair) * dim - gstart[np.maximum(rows, 0)][:, None, :], -1)
            self._pattern_cache = (indices, indptr, wp.array(slots.astype(np.int32).ravel(), dtype=wp.int32, device=self.dev),
                                   wp.array(indptr, dtype=wp.int32, device=self.dev))
        return self._pattern_cache

    # -- Newton ---------------------------------------------------------------------------------------------
    def _newton(self, u_nodes, field_level, gravity_level, scale, slope: bool = False):
        """Newton with line search from ``u_nodes`` (``slope``: the energy line search, else the residual-norm
        one). Returns (u, converged, iterations, |R|_inf, message)."""
        u_nodes = self.hold(u_nodes)  # the moving clamps' nodes where the clamps are now
        if self.contact is not None:
            self.contact.begin()
        r_full = self._scatter(u_nodes, field_level, gravity_level)
        if self.contact is not None:
            self.contact.commit()
        r = self._reduce(r_full)
        norm = float(np.abs(r).max()) if r.size else 0.0
        best = norm
        bests = []  # the lowest |R| so far, after each iteration (STALL_ITERATIONS)
        peeling = False  # PEEL: after a release at a converged state, pulling points also leave after each iterate
        forcing = (None, None)  # the last step's |r|_2 and linear tolerance (iterative solves: linear.forcing_term)
        for it in range(self.max_iterations + 1):
            if norm <= self.tolerance * scale:
                if self.contact is None or not self.contact.release():
                    return u_nodes, True, it, norm, ""
                # nodes that pull left the colliders' active set: solve again without them
                log.debug("newton %d: converged, pulling points released: contacts %d", it, self.contact.count())
                peeling = PEEL
                forcing = (None, None)
                r_full = self._scatter(u_nodes, field_level, gravity_level)
                r = self._reduce(r_full)
                norm = best = float(np.abs(r).max())
                bests = []
                continue
            if it == self.max_iterations:
                break
            bests.append(best)
            if self.contact is not None and len(bests) > STALL_ITERATIONS and best > STALL_FACTOR * bests[-1 - STALL_ITERATIONS]:
                return u_nodes, False, it, norm, f"|R| stalled over {STALL_ITERATIONS} Newton iterations"
            J = self.tangent(u_nodes, field_level, gravity_level)
            self._last_tangent = J  # the stability check after convergence reuses it (one step from the solution)
            try:
                lin = self._linear_solver(J, u_nodes)
            except RuntimeError as exc:  # singular tangent
                return u_nodes, False, it, norm, f"singular tangent ({exc})"
            # an iterative solve's tolerance: Eisenstat-Walker forcing (linear.forcing_term), never tighter than what
            # lets this step reach the Newton tolerance (a tenth of it left in the linear residual)
            norm2 = float(np.linalg.norm(r))
            rtol = forcing_term(norm2, *forcing, floor=0.1 * self.tolerance * scale / max(norm2, 1e-300))
            forcing = (norm2, rtol)
            before = (lin.total_iterations, lin.solves, lin.fallbacks)
            if self.solver.interaction is None:
                du = lin.solve(-r, rtol=rtol)
            else:
                du = self._solve_linear(lin, u_nodes, r, field_level, gravity_level)
            self._count_linear(lin, before)
            settled = False
            if self.contact is not None and ACTIVE_SET_ROUNDS and self.solver.interaction is None:
                du, r, lin, settled = self._settle_contacts(u_nodes, J, r, du, lin, rtol)
            step = self._expand(du)
            # Non-monotone line search: the full step may raise |R| for an iteration (the nodes at the bodies'
            # edges carry little stiffness, and their forces answer the first step nonlinearly), after which
            # Newton converges quadratically; a step is taken when F stays invertible and |R| stays within
            # GROWTH times the lowest residual of this solve, else halved.
            # A step that changes which nodes touch a collider is taken whatever its residual: the tangent it
            # came from did not know the new contacts, and the next one will (an active-set iteration).
            contacts = self.contact.signature() if self.contact is not None else None
            # a trust region: no node moves more than MAX_STEP cells in one step (a slender body's linearised
            # step from the straight state can be many times its length)
            biggest = float(np.abs(step).max()) if step.size else 0.0
            longest = ROUND_STEP if settled else MAX_STEP
            alpha = min(1.0, longest * self.model.dx / biggest) if biggest > 0.0 else 1.0
            capped = alpha < 1.0  # the trust region cut the step: it moves a node `longest` cells, whatever |R| does
            if self.contact is not None:
                alpha = min(alpha, self.contact.step_limit(u_nodes, alpha * step) * alpha)
            first = alpha
            g0 = float(r @ du)  # the energy's slope along du is -g0: > 0 where du goes downhill
            if slope and contacts is None and g0 > 0.0:
                found = self._slope_search(u_nodes, step, du, g0, first, field_level, gravity_level)
                if found is not None:
                    u_nodes, r_full, r, norm = found
                    best = min(best, norm)
                    continue
                alpha = first
            while alpha >= 1.0 / 256:
                trial = u_nodes + alpha * step
                r_try_full = self._scatter(trial, field_level, gravity_level)
                if self._valid():
                    r_try = self._reduce(r_try_full)
                    n_try = float(np.abs(r_try).max())
                    changed = contacts is not None and alpha == first and self.contact.signature() != contacts
                    if math.isfinite(n_try) and (n_try < GROWTH * best or changed):
                        u_nodes, r_full, r, norm = trial, r_try_full, r_try, n_try
                        best = norm if changed else min(best, norm)  # new contacts: a new problem, a new reference
                        if capped and alpha == first:
                            # a full trust-region step is progress though |R| may rise (a wall folding a long way
                            # in 2-cell steps, each followed by a short correction): the stall check starts again
                            bests = []
                        if self.contact is not None:
                            self.contact.commit()
                            if peeling and self.contact.release():
                                # a peeling front: the points it lifts leave at once, not one ring per converged
                                # round (a new problem: a new reference for the line search and the stall check)
                                r_full = self._scatter(u_nodes, field_level, gravity_level)
                                r = self._reduce(r_full)
                                norm = best = float(np.abs(r).max())
                                bests = []
                        if log.isEnabledFor(logging.DEBUG):
                            log.debug("newton %d: |R| %.3e, step %.3g of %.3g cells (first %.3g)%s%s", it + 1, norm,
                                      alpha, biggest / self.model.dx, first,
                                      ", rounds changed the set" if settled else "",
                                      f", contacts {self.contact.count()}" if self.contact is not None else "")
                        break
                alpha *= 0.5
            else:
                return u_nodes, False, it + 1, norm, "the line search found no step that lowers the residual"
        return u_nodes, False, self.max_iterations, norm, f"no convergence in {self.max_iterations} Newton iterations"

    def _settle_contacts(self, u_nodes, J, r, du, lin, rtol, bodies: bool = True):
        """The contacts' active set settled on the linearised problem before a Newton step is taken (rounds of
        :meth:`Contacts.revise <magsoro.mpm.newton.static_contact.Contacts.revise>`, at most ACTIVE_SET_ROUNDS): points
        the step ``du`` would lift leave, points it would push into a collider join, and the step is solved again
        with the tangent ``J`` and residual ``r`` changed by their springs, until the set stays. An iterative
        solver solves the rounds to ROUND_RTOL (they only decide the set), on a new hierarchy where the last one
        no longer serves (never the direct fallback); the last step is then solved to ``rtol``. Returns the step,
        the residual, the linear solver of the last round and whether the set changed (the step is then held to
        ROUND_STEP cells). A round that brings back a set of an earlier round ends them (the rounds cycle: the
        gripper of scenes/gripper.toml pulled off its bead, 7 to 9 contacts between the bodies flipping through
        the same four sets for all 30 rounds of every Newton iteration). ``bodies`` False: the colliders' set
        only (the implicit integrator; contacts between bodies change at the iterates)."""
        changed = False
        seen = set()
        for _ in range(ACTIVE_SET_ROUNDS):
            change = self.contact.revise(u_nodes, self._expand(du), self.free, bodies=bodies)
            if change is None:
                break
            changed = True
            df, dJ = change
            r = r + self._reduce(df)
            J = (J + self.E.T @ dJ @ self.E).tocsc()
            self._last_tangent = J
            try:
                lin = self._linear_solver(J, u_nodes)
            except RuntimeError:  # singular with the new set: keep the last round's step
                break
            before = (lin.total_iterations, lin.solves, lin.fallbacks)
            if isinstance(lin, IterativeSolver):
                trial = lin.solve(-r, rtol=max(rtol, ROUND_RTOL), x0=du, fallback=False)
                if lin.failed:  # the set changed the tangent too much for the hierarchy: a new one, not the LU
                    self._count_linear(lin, before)
                    lin = self._linear_solver(J, u_nodes, reuse=False)
                    before = (lin.total_iterations, lin.solves, lin.fallbacks)
                    trial = lin.solve(-r, rtol=max(rtol, ROUND_RTOL), x0=du)
                du = trial
            else:
                du = lin.solve(-r)
            self._count_linear(lin, before)
            state = self.contact.round_state()
            if state in seen:
                self.round_cycles += 1
                break
            seen.add(state)
        if changed and isinstance(lin, IterativeSolver) and rtol < ROUND_RTOL:
            before = (lin.total_iterations, lin.solves, lin.fallbacks)
            du = lin.solve(-r, rtol=rtol, x0=du)
            self._count_linear(lin, before)
        return du, r, lin, changed

    def _linear_solver(self, J, u_nodes=None, reuse: bool = True):
        """The LinearSolver (magsoro.mpm.newton.linear) of the tangent ``J`` at ``u_nodes`` (node displacements; default
        the current state) of the kind static.linear_solver asks for ('auto': direct up to
        linear.DIRECT_MAX_UNKNOWNS unknowns). An iterative one keeps the last tangent's multigrid hierarchy as its
        preconditioner (``reuse``) until its iterations grow (IterativeSolver.stale); a new hierarchy takes the
        rigid-body modes of the unknowns' nodes where they stand (reference positions plus ``u_nodes``: a body
        turned by 90 degrees keeps its near-null space) and aggregates them on the grid's lattice. Raises
        RuntimeError for a singular tangent (direct)."""
        kind = self._linear_kind(J.shape[0])
        last = self._linear
        symmetric = None  # tested (linear.is_symmetric): friction makes J unsymmetric where points slide
        if kind == "direct":
            if self._ordering is None:
                self._ordering = Ordering()  # one pattern for every tangent of this solver
            lin = DirectSolver(J, self._ordering)
        elif reuse and isinstance(last, IterativeSolver) and last.shape == J.shape and not last.stale():
            lin = last.update(J, symmetric=symmetric)
        else:
            nodes = self.unknown_nodes
            u = self.u_nodes if u_nodes is None else u_nodes
            ref = (self.model.domain_lo + self.solver.org * self.model.dx)[: self.dim] + self.coords[nodes] * self.model.dx
            lin = IterativeSolver(J, near_null=rigid_body_modes(ref + np.asarray(u)[nodes]), grid=self.coords[nodes],
                                  symmetric=symmetric, dim=self.dim)
        if lin is not last:
            self.linear_setups += 1
        self._linear = lin
        self.linear_kinds.add(lin.kind)
        return lin

    #: 'auto' solves directly up to this many unknowns (None: linear.DIRECT_MAX_UNKNOWNS, read when used)
    direct_max_unknowns = None
    _ordering = None  # the direct solver's fill-reducing ordering of the tangents' pattern (linear.Ordering)
    _projector = None  # (Q, Q^T W, factorisation) of fit_nodes' least squares, made once
    _checked = None  # (u_nodes, lowest eigenvalue) of the last increment's stability check in this level

    def _linear_kind(self, unknowns: int) -> str:
        """'direct' or 'iterative': the scene's linear_solver, 'auto' decided by the number of unknowns."""
        if self.linear_solver != "auto":
            return self.linear_solver
        limit = _linear.DIRECT_MAX_UNKNOWNS if self.direct_max_unknowns is None else self.direct_max_unknowns
        return "direct" if unknowns <= limit else "iterative"

    def _count_linear(self, lin, before) -> None:
        """Add what ``lin`` did since its counts were ``before`` (Krylov iterations, solves, fallbacks) to the
        solver's."""
        self.linear_iterations += lin.total_iterations - before[0]
        self.linear_solves += lin.solves - before[1]
        self.linear_fallbacks += lin.fallbacks - before[2]

    def _solve_linear(self, lin, u_nodes, r, field_level, gravity_level):
        """The Newton step du with the bodies' own field: J du = -r for the whole Jacobian J, whose part from the
        field of every particle on every other is dense and left out of the assembled tangent. GMRES on the
        products J v = (R(u + h v) - R(u)) / h (a residual evaluation each, the interaction refreshed; h moves the
        farthest node FD_CELLS cells), preconditioned by the assembled tangent's solver ``lin`` (a LinearSolver: its
        LU, or an iterative solve to linear.ITERATIVE_RTOL, nearly as exact) and started from its
        step. Where the bodies' field is weak the preconditioned system is near the identity and GMRES takes a few
        products."""
        from scipy.sparse.linalg import LinearOperator, gmres

        n = r.size

        def product(v):
            step = self._expand(v)
            biggest = float(np.abs(step).max())
            if biggest == 0.0:
                return np.zeros(n)
            h = FD_CELLS * self.model.dx / biggest
            return (self._reduce(self._scatter(u_nodes + h * step, field_level, gravity_level)) - r) / h

        A = LinearOperator((n, n), matvec=product, dtype=np.float64)
        M = LinearOperator((n, n), matvec=lin.solve, dtype=np.float64)
        du, _ = gmres(A, -r, x0=lin.solve(-r), M=M, rtol=KRYLOV_RTOL, atol=0.0, restart=20, maxiter=KRYLOV_RESTARTS)
        self._scatter(u_nodes, field_level, gravity_level)  # the state at u again (the products moved it)
        return du

    def _slope_search(self, u_nodes, step, du, g0, first, field_level, gravity_level):
        """Line search on the energy along a downhill Newton step (the loads are conservative, so R = -dPi/du):
        the step length alpha where the slope g(alpha) = R(u + alpha step) . du has fallen to SLOPE_RATIO of
        g(0) = g0 in magnitude, found by secants on g from alpha = ``first`` (the trust region's limit), at most
        SLOPE_TRIALS trials; a trial where F is not invertible is halved. Returns (u, R full, R, |R|_inf) or None
        when no trial is acceptable (the caller falls back to the residual-norm search)."""
        alpha, lo, g_lo = first, 0.0, g0
        hi, g_hi = None, None  # the bracket [lo, hi]: g(lo) > 0, g(hi) < 0 (past the minimum along the line)
        best = None
        for _ in range(SLOPE_TRIALS):
            trial = u_nodes + alpha * step
            r_full = self._scatter(trial, field_level, gravity_level)
            if not self._valid():
                hi, g_hi, alpha = alpha, None, 0.5 * (lo + alpha)
                continue
            r = self._reduce(r_full)
            norm = float(np.abs(r).max())
            if not math.isfinite(norm):
                hi, g_hi, alpha = alpha, None, 0.5 * (lo + alpha)
                continue
            g = float(r @ du)
            if best is None or abs(g) < best[0]:
                best = (abs(g), (trial, r_full, r, norm))
            if abs(g) <= SLOPE_RATIO * g0 or (g > 0.0 and alpha >= first):
                return trial, r_full, r, norm  # near the line's minimum, or still downhill at the trust limit
            if g > 0.0:
                lo, g_lo = alpha, g
            else:
                hi, g_hi = alpha, g
            # here g < 0 at alpha = first, or alpha lies inside a bracket: hi is set
            if g_hi is None:  # the top of the bracket had no valid F: bisect
                alpha = 0.5 * (lo + hi)
            else:  # the secant's zero inside the bracket, kept off its ends
                x = lo + (hi - lo) * g_lo / (g_lo - g_hi)
                alpha = min(max(x, lo + 0.1 * (hi - lo)), hi - 0.1 * (hi - lo))
        if best is not None and best[0] < g0:
            return best[1]
        return None

    def _set_collider_time(self, tau: float) -> None:
        """Put the colliders and the moving clamps where their paths have them at time ``tau`` (s)."""
        self.collider_time = float(tau)
        if self.contact is not None:
            for part in self.contact.parts:
                part.t = float(tau)
        if self.model.clamp_paths:
            self._set_clamps(self._clamp_displacements(tau))

    def _clamp_displacements(self, tau: float) -> np.ndarray:
        """(2 + clamp paths, dim) m: the displacement of each clamp code at time ``tau`` (codes 0 and 1: zero)."""
        paths = self.model.clamp_paths
        shift = np.zeros((2 + len(paths), self.dim))
        for row in range(len(paths)):
            shift[2 + row] = self.model.clamp_displacement(row, tau)
        return shift

    def _set_clamps(self, shift: np.ndarray) -> None:
        """The moving clamps' displacements per clamp code (:meth:`_clamp_displacements`) for the placements and
        :meth:`hold`."""
        self._shift = shift
        self.clamp_shift.assign(shift.astype(self.model.np_scalar))

    def hold(self, u_nodes: np.ndarray, tau: float | None = None) -> np.ndarray:
        """``u_nodes`` with the nodes of moving clamps at their clamp's displacement at time ``tau`` (s; default
        where the clamps stand now): the Dirichlet values of the unknowns' solve (nodes held in place stay zero). A
        copy when there are moving clamps, ``u_nodes`` itself otherwise."""
        if not self.model.clamp_paths or self.held_code is None:
            return u_nodes
        shift = self._shift if tau is None else self._clamp_displacements(tau)
        out = np.array(u_nodes, dtype=np.float64, copy=True)
        moving = self.held_code >= 2
        out[moving] = shift[self.held_code[moving]]
        return out

    def _reference_force(self, target) -> float:
        """The force scale of a level's tolerance: the largest out-of-balance node force of the undeformed body
        under the ``target`` loads, the colliders and clamps at the solve's time. A moving clamp's share is its
        linear response: the clamps moved a tenth of a cell along the way to their place at the solve's time, the
        force scaled up by the ratio (a clamp moved cells away from the undeformed body beside it would invert the
        particles between)."""
        tau, tf = self.collider_time, self.field_time
        self._set_collider_time(self.t)
        self.field_time = self.t
        zeros = np.zeros_like(self.u_nodes)
        try:
            if not self.model.clamp_paths:
                return float(np.abs(self._reduce(self._scatter(zeros, *target))).max(initial=0.0))
            full = self._shift
            travel = float(np.abs(full).max(initial=0.0))
            probe = min(1.0, CLAMP_PROBE_CELLS * float(self.model.dx) / travel) if travel > 0.0 else 1.0
            self._set_clamps(0.0 * full)
            r0 = self._reduce(self._scatter(zeros, *target))
            self._set_clamps(probe * full)
            r1 = self._reduce(self._scatter(self.hold(zeros), *target))
            return max(float(np.abs(r0).max(initial=0.0)), float(np.abs(r1 - r0).max(initial=0.0)) / probe)
        finally:
            self._set_collider_time(tau)
            self.field_time = tf

    def _load_times(self, times0, s: float) -> None:
        """The colliders and the fields at fraction ``s`` of their way from ``times0`` (collider time, field time)
        to the solve's time."""
        tau0, tf0 = times0
        self._set_collider_time(tau0 + s * (self.t - tau0))
        self.field_time = tf0 + s * (self.t - tf0)

    def _colliders_move(self) -> bool:
        """Whether a scene collider has a path (it moves with the first level's load increments)."""
        return any(c.path is not None for c in self.sim.control.colliders)

    def _sliding_on_bodies(self, f: np.ndarray) -> str:
        """The body-contact form of :meth:`_sliding`: a phrase when a body that no clamp holds and no collider
        touches rests on one other body alone, and the applied node forces ``f`` (fields, gravity, stresses: the
        contacts' part out, at the last converged state) pull it along their contact harder than friction holds
        (|F_t| > mu F_n over the mean normal of their contacts); '' otherwise."""
        bc = self.body_contact
        cs = bc.last_contacts()
        if cs is None:
            return ""
        h = self.model.host
        group = h["contact_group"]
        slot_group = self._slot_groups()
        touched = set()
        if self._scene_contact is not None:
            P = self.interpolation()
            for pts in self._scene_contact.touching:
                if len(pts):
                    touched |= set(np.unique(group[pts] if self._scene_contact.W is P else slot_group[pts]).tolist())
        names = self.sim.built.body_names
        slave_group = group[cs["slave"]]
        master_group = cs["keys"] % bc.n_groups
        for g in np.unique(np.concatenate([slave_group, master_group])):
            mine = group == g
            if g in touched or np.any(h["clamped"][mine] != 0):
                continue
            as_slave, as_master = slave_group == g, master_group == g
            others = set(master_group[as_slave].tolist()) | set(slave_group[as_master].tolist())
            if len(others) != 1:
                continue
            other = others.pop()
            n = cs["normal"][as_slave].sum(axis=0) - cs["normal"][as_master].sum(axis=0)  # into g
            if not np.linalg.norm(n) > 0.0:
                continue
            n = n / np.linalg.norm(n)
            net = f[slot_group == g].sum(axis=0)
            f_n = -float(net @ n)
            f_t = float(np.linalg.norm(net + f_n * n))
            mu = float(bc.mu_table[g, other])
            if f_t <= mu * max(f_n, 0.0):
                continue
            body = lambda grp: ", ".join(f"'{names[int(b)]}'" for b in np.unique(h["body"][group == grp]))
            return (f"at the level's load the fields and gravity pull {body(g)} along {body(other)} with {f_t:.3g} N "
                    f"against a friction limit of {mu * max(f_n, 0.0):.3g} N (mu {mu:g} times the {f_n:.3g} N pressing "
                    f"it on): no equilibrium lies near this state, it slides until something stops it; run the "
                    f"dynamics to see where it comes to rest (simulation.integrator = 'implicit', or magsoro run "
                    f"without --static)")
        return ""

    def _sliding(self, load, flat_only: bool = False) -> str:
        """After a failed load increment towards ``load`` (field, gravity levels: the level's), in a scene whose bodies
        no clamp holds and which rest on one friction collider: a phrase saying so when the net applied force (fields
        and gravity at ``load``, at the last converged state) pulls along that collider's surface harder than friction
        holds (|F_t| > mu F_n): a rigid body cannot rest there, there is no equilibrium near the state, and the
        bodies move until something stops them. '' otherwise. ``flat_only``: only for a half-space collider, whose
        one normal makes this a strict bound (the sum of the points' Coulomb cones)."""
        part = self._scene_contact
        if self.body_contact is None and (part is None or np.any(self.model.host["clamped"] != 0)
                                          or np.any(self.held_nodes)):
            return ""
        u = self.u_nodes
        f = self._scatter(u, *load) - self.contact.forces(u)  # the contacts' part out: fields, gravity, stresses
        if self.body_contact is not None:
            on_bodies = self._sliding_on_bodies(f)
            if on_bodies or part is None or np.any(self.model.host["clamped"] != 0) or np.any(self.held_nodes):
                return on_bodies
        net = f.sum(axis=0)  # the stresses' node forces sum to zero
        touched = [(ci, c) for ci, c in enumerate(part.colliders) if len(part.touching[ci])]
        if len(touched) != 1 or touched[0][1].mode != "friction":
            return ""
        if flat_only and touched[0][1].kind != "half_space":
            return ""
        ci, c = touched[0]
        pts = part.positions(u)[part.touching[ci]]
        n = part.signed_distance(c, pts)[1].mean(axis=0)
        n /= np.linalg.norm(n)
        f_n = -float(net @ n)  # pressing the bodies onto the collider
        f_t = float(np.linalg.norm(net + f_n * n))
        if f_t <= c.friction * max(f_n, 0.0):
            return ""
        return (f"at the level's load the fields and gravity pull the bodies along colliders[{ci}] ({c.kind}, friction "
                f"{c.friction:g}) with {f_t:.3g} N against a friction limit of {c.friction * max(f_n, 0.0):.3g} N (mu "
                f"times the {f_n:.3g} N pressing them on it): no equilibrium lies near this state, the bodies slide "
                f"until something stops them; run the dynamics to see where they come to rest (magsoro run without "
                f"--static, or --equilibrium)")

    def _increments(self, start, target, scale, watch: bool = False):
        """Load increments from the current state at load ``start`` to ``target`` (field, gravity levels):
        halved when Newton fails, doubled after a quick convergence. With ``watch``, the lowest stiffness is
        checked after every increment and the walk stops at the first unstable one, the solver keeping the
        stable state before it. Returns (status, iterations, increments, |R|, fraction reached, message,
        unstable load, its eigenvalue, its mode) with status 'done', 'failed', 'sliding' (failed, and the loads pull
        the free bodies off their friction collider: :meth:`_sliding`, in the message) or 'unstable'."""
        s, ds = 0.0, 1.0
        iterations = increments = 0
        u = self.u_nodes.copy()
        norm, message = 0.0, ""
        # the colliders move along their paths to the solve's time with the loads, and the fields from where
        # move_to() left them
        times0 = (self.collider_time, self.field_time)
        while s < 1.0 - 1e-12:
            ds = min(ds, 1.0 - s)
            s_try = s + ds
            load = tuple(a + s_try * (b - a) for a, b in zip(start, target))
            self._load_times(times0, s_try)
            log.debug("increment to %.4g of the level (ds %.3g)", s_try, ds)
            u_new, ok, its, norm, message = self._newton(u.copy(), load[0], load[1], scale)
            iterations += its
            if not ok and self.contact is None and self.dim == 3:
                # Measured on continuum_soft's preview (3D, a 37 mm rod turned about 50 degrees by one 4 mT
                # level): the residual-norm search failed at the full level and at half of it (30 iterations) and
                # reached it in 96 iterations over 7 increments; the energy search reached the full level in 21.
                # Alone, the energy search is slower where the norm search converges (3D beam 48 -> 168
                # iterations): so it is the second try, not the first. Not in 2D, where the light edge nodes are
                # unknowns (no slaving): their forces keep |R| up while the energy falls (2D cantilever: 61 -> 279
                # iterations alone, and as a second try it failed too, adding 25).
                u_new, ok, its, norm, message = self._newton(u.copy(), load[0], load[1], scale, slope=True)
                iterations += its
            if ok:
                if watch and self.check_stability:
                    before = (self.u_nodes, self.field_level, self.gravity_level)
                    self.u_nodes, (self.field_level, self.gravity_level) = u_new, load
                    lam, mode = self.lowest_mode(self._last_tangent if its > 0 else None)
                    self._checked = (u_new, lam)  # the level's end takes it if the state is still this one
                    if lam is not None and lam < 0.0:
                        self.u_nodes, self.field_level, self.gravity_level = before
                        return "unstable", iterations, increments, norm, s, "", load, lam, mode
                u, s = u_new, s_try
                increments += 1
                self.u_nodes = u
                self.field_level, self.gravity_level = load
                if self.contact is not None:  # anchors of new contacts; sliding ones follow (static_contact)
                    self._scatter(u, *load)
                    self.contact.accept(u)
                if its <= 4:
                    ds *= 2.0
            else:
                self._load_times(times0, s)
                ds *= 0.5
                # From the unloaded state with the colliders still, the loads grow in proportion: where they pull
                # the free bodies along the one flat friction collider that carries them harder than friction
                # holds at the level, they do so at every fraction of it, and smaller increments cannot help
                # (scenes/cube_dipole_3d.toml halved its first increment 14 times, 6.5 minutes, before this).
                proportional = s == 0.0 and not any(start) and not self._colliders_move()
                if ds < 1e-4 or proportional:
                    sliding = self._sliding(target, flat_only=proportional and ds >= 1e-4)
                    if sliding:
                        return "sliding", iterations, increments, norm, s, f"{message}; {sliding}", None, None, None
                    if ds < 1e-4:
                        return "failed", iterations, increments, norm, s, message, None, None, None
        return "done", iterations, increments, norm, 1.0, "", None, None, None

    def _arc_length(self, start, target, scale):
        """Follow the equilibrium path from the current state (at load ``start``) towards ``target`` with the load
        factor a as an unknown, load = start + a (target - start): Crisfield's cylindrical arc length, |D| = dl for
        the unknowns' change D within a step. Predictor along the path's tangent dU/da = -J^-1 dR/da (its sign
        keeps the direction of the last step, so the path turns back at a limit point); corrector: Newton on R = 0
        with the constraint, the root of its quadratic in the load change nearer the last step's direction. dR/da
        by central differences over half the load change (exact, the loads enter R linearly). Stops where a reaches
        1 again: the level is then solved at a = 1 from the state interpolated between the two steps around it
        (a stable equilibrium is required, else the path goes on). Returns (ok, iterations, steps, |R|, the field
        levels where a turned back, message)."""
        def load(a):
            return tuple(x + a * (y - x) for x, y in zip(start, target))

        def residual(u, a):
            return self._reduce(self._scatter(u, *load(a)))

        def slope(u, a):  # dR/da
            return residual(u, a + 0.5) - residual(u, a - 0.5)

        def solve(u, a, rhs_list):
            lin = self._linear_solver(self.tangent(u, *load(a)), u, reuse=False)
            before = (lin.total_iterations, lin.solves, lin.fallbacks)
            out = [lin.solve(rhs) for rhs in rhs_list]
            self._count_linear(lin, before)
            return out

        u, a = self.u_nodes.copy(), 0.0
        limit_cells = MAX_STEP * self.model.dx
        (tan,) = solve(u, a, [-slope(u, a)])
        dl0 = ARC_FIRST * float(np.linalg.norm(tan))
        if not (dl0 > 0.0 and math.isfinite(dl0)):
            return False, 0, 0, 0.0, [], "no path tangent (the load does not move the unknowns)"
        dl, last, history = dl0, None, [(0.0, 0.0)]  # (path length, load fraction) of the accepted steps
        iterations = steps = 0
        norm, turns = 0.0, []
        while steps < ARC_STEPS:  # tan: the path's tangent at the last accepted state (u, a)
            size = float(np.linalg.norm(tan))
            sign = 1.0 if last is None or float(tan @ last) >= 0.0 else -1.0
            D = sign * dl / size * tan
            biggest = float(np.abs(self._expand(D)).max())
            if biggest > limit_cells:  # the trust region of Newton's steps
                dl *= limit_cells / biggest
                D *= limit_cells / biggest
            A = a + sign * dl / size
            converged = False
            for it in range(self.max_iterations):
                U = u + self._expand(D)
                r = residual(U, A)
                if not self._valid() or not np.all(np.isfinite(r)):
                    break
                norm = float(np.abs(r).max()) if r.size else 0.0
                if norm <= self.tolerance * scale:
                    converged = True
                    break
                da, db = solve(U, A, [-r, -slope(U, A)])
                base = D + da
                qa, qb, qc = float(db @ db), 2.0 * float(db @ base), float(base @ base) - dl * dl
                disc = qb * qb - 4.0 * qa * qc
                if qa <= 0.0 or disc < 0.0:
                    break
                roots = [(-qb + sq) / (2.0 * qa) for sq in (math.sqrt(disc), -math.sqrt(disc))]
                x = max(roots, key=lambda x: float((base + x * db) @ D))
                D, A = base + x * db, A + x
            iterations += it
            if not converged:
                dl *= 0.5
                if dl < ARC_MIN * dl0:
                    return False, iterations, steps, norm, turns, f"the arc-length step fell below {ARC_MIN:g} of the first at load fraction {a:.4g}"
                continue
            steps += 1
            history.append((history[-1][0] + dl, A))
            if len(history) >= 3 and (history[-2][1] - history[-3][1]) * (history[-1][1] - history[-2][1]) < 0.0:
                turns.append(load(_vertex(history[-3:]))[0])  # the load factor turned back: a limit point
            if a < 1.0 <= A or (A < 1.0 <= a):  # the path reaches the level: solve it there
                f = (1.0 - a) / (A - a)
                guess = u + f * self._expand(D)
                u_new, ok, its, norm_new, _ = self._newton(guess, *load(1.0), scale)
                iterations += its
                if ok:
                    keep = (self.u_nodes, self.field_level, self.gravity_level)
                    self.u_nodes, (self.field_level, self.gravity_level) = u_new, load(1.0)
                    lam, _ = self.lowest_mode(self._last_tangent if its > 0 else None)
                    if lam is None or lam >= 0.0:
                        return True, iterations, steps, norm_new, turns, ""
                    self.u_nodes, self.field_level, self.gravity_level = keep
            u, a, last = U, A, D
            (tan,) = solve(u, a, [-slope(u, a)])
            if it <= 4:
                dl = min(dl * ARC_GROW, ARC_LONGEST * dl0)
        return False, iterations, steps, norm, turns, f"{ARC_STEPS} arc-length steps did not reach the level (load fraction {a:.4g})"

    def _switch_branch(self, load, lam, mode, scale):
        """From the current stable state, reach ``load`` where the path's equilibrium is unstable (lowest
        stiffness ``lam`` along ``mode``) on the stable branch: an imperfection force along the mode, sized by
        BRANCH_KICKS, followed up to the load and taken away in steps. Returns (ok, iterations, increments,
        |R|, message)."""
        u0, start = self.u_nodes.copy(), (self.field_level, self.gravity_level)
        lam_start, _ = self.lowest_mode()
        direction = self._expand(mode)
        direction /= max(float(np.abs(direction).max()), 1e-300)
        iterations = increments = 0
        norm, message = 0.0, ""
        for kick in BRANCH_KICKS:
            self.u_nodes, (self.field_level, self.gravity_level) = u0.copy(), start
            force = direction * abs(lam_start or lam) * kick * self.model.dx
            self.extra_force = force
            try:
                status, its, inc, norm, _, message, *_ = self._increments(start, load, scale)
                iterations, increments = iterations + its, increments + inc
                ok = status == "done"
                for amount in (0.5, 0.25, 0.125, 0.0625, 0.0):  # take the force away in steps
                    if not ok:
                        break
                    self.extra_force = amount * force
                    u_new, ok, its, norm, message = self._newton(self.u_nodes.copy(), load[0], load[1], scale)
                    iterations += its
                    if ok:
                        self.u_nodes = u_new
            finally:
                self.extra_force = None
            if not ok:
                break
            lam_now, _ = self.lowest_mode()
            if lam_now is None or lam_now >= 0.0:
                return True, iterations, increments, norm, ""
        self.u_nodes, (self.field_level, self.gravity_level) = u0, start
        return False, iterations, increments, norm, message or "the equilibrium stayed unstable after the largest imperfection"

    def start_from(self, other: "StaticSolver") -> None:
        """Start the next solve from the equilibrium of ``other``, a solver of the same simulation (static.soft_penalty's
        predictor), with its contacts' active set (:meth:`Contacts.adopt <magsoro.mpm.newton.static_contact.Contacts.adopt>`;
        the friction state stays this solver's)."""
        self.u_nodes = self.hold(other.u_nodes.copy())
        if self.contact is not None and other.contact is not None:
            self.contact.adopt(other.contact)

    def move_to(self, t: float) -> None:
        """Continue to the loads at time ``t`` (s): the next :meth:`solve_level` moves the fields and the colliders
        along their paths from where they stand to ``t`` with its load increments, from the last equilibrium (a
        sweep along a magnet's path, each position from the last). Eigenstrains and pressure loads stay at the
        solver's first time."""
        self.t = float(t)

    def solve_level(self, level: float, gravity_level: float = 1.0) -> LevelResult:
        """Equilibrium under the fields scaled by ``level`` and gravity scaled by ``gravity_level``, reached in
        load increments from the last converged state, each checked for stability; at the first unstable one
        the solver switches to the stable branch and goes on (module docstring). The result counts the level's
        linear solves (LevelResult.linear_*)."""
        counts = (self.linear_solves, self.linear_iterations, self.linear_setups, self.linear_fallbacks)
        self.linear_kinds = set()
        res = self._solve_level(level, gravity_level)
        res.linear_solver = "+".join(sorted(self.linear_kinds))
        res.linear_solves = self.linear_solves - counts[0]
        res.linear_iterations = self.linear_iterations - counts[1]
        res.linear_setups = self.linear_setups - counts[2]
        res.linear_fallbacks = self.linear_fallbacks - counts[3]
        return res

    def _solve_level(self, level: float, gravity_level: float = 1.0) -> LevelResult:
        t0 = time.perf_counter()
        self._checked = None
        target = (float(level), float(gravity_level))
        before = (self.u_nodes.copy(), self.field_level, self.gravity_level)
        # the force scale of the tolerance: the out-of-balance force of the undeformed body under the target load,
        # the colliders and the moving clamps at the solve's time (a plate moved into the body loads it through the
        # penalty, a clamp moved along its path through the nodes it holds)
        scale = max(self._reference_force(target), 1e-30)
        iterations = increments = arc_steps = 0
        buckled, lam, limits = False, None, []
        if self.arc_length:  # the whole way along the path, limit points reported
            here = (self.field_level, self.gravity_level)
            ok, its, arc_steps, norm, limits, message = self._arc_length(here, target, scale)
            if not ok:
                self._scatter(self.u_nodes, self.field_level, self.gravity_level)
                return LevelResult(level, False, its, 0, norm, norm / scale, time.perf_counter() - t0,
                                   f"arc length: {message}", None, False, limit_levels=limits, arc_length_steps=arc_steps)
            iterations = its
        # after move_to: the fields move along their paths to the solve's time (arc length follows a field level only)
        moved_from = self.field_time if self.field_time != self.t else None
        for _ in range(0 if self.arc_length else MAX_SWITCHES + 1):
            here = (self.field_level, self.gravity_level)
            status, its, inc, norm, reached, message, load, lam, mode = self._increments(here, target, scale, watch=True)
            iterations, increments = iterations + its, increments + inc
            if status == "done":
                break
            if status == "failed" and self.contact is None and self.solver.interaction is None and moved_from is None:
                # a limit point: no equilibrium near the path past it under load control; follow the path by arc
                # length until it reaches the level again (beyond a snap-through)
                here = (self.field_level, self.gravity_level)
                ok, its, steps, norm, turns, arc_message = self._arc_length(here, target, scale)
                iterations, arc_steps = iterations + its, arc_steps + steps
                limits += turns
                if ok:
                    break
                message = f"{message}; arc length: {arc_message}"
            if status in ("failed", "sliding"):
                self._scatter(self.u_nodes, self.field_level, self.gravity_level)
                why = (f"no equilibrium from {reached:.4g} of the way" if status == "sliding"
                       else f"load increment below 1e-4 of the level at {reached:.4g} of the way")
                if moved_from is not None:
                    why += (f" (the fields moving along their paths from t = {moved_from:.6g} s to {self.t:.6g} s: "
                            "move_to intermediate times)")
                return LevelResult(level, False, iterations, increments, norm, norm / scale, time.perf_counter() - t0,
                                   f"{why}: {message}", lam, buckled, limit_levels=limits, arc_length_steps=arc_steps,
                                   no_equilibrium=status == "sliding")
            buckled = True
            ok, its, inc, norm, message = self._switch_branch(load, lam, mode, scale)
            iterations, increments = iterations + its, increments + inc
            if not ok:
                self._scatter(self.u_nodes, self.field_level, self.gravity_level)
                return LevelResult(level, False, iterations, increments, norm, norm / scale, time.perf_counter() - t0,
                                   f"unstable equilibrium at field level {load[0]:.4g} (lowest stiffness {lam:.3g} N/m); the "
                                   f"switch to a stable branch did not converge: {message}", lam, True)
        if not self.check_stability:
            lam = None
        elif self._checked is not None and self._checked[0] is self.u_nodes:
            lam = self._checked[1]  # checked at the last increment (its last Newton tangent), not again
        else:
            lam, _ = self.lowest_mode()
        self._checked = None
        r = self._reduce(self._scatter(self.u_nodes, *target))
        norm = float(np.abs(r).max()) if r.size else 0.0
        crossing = self.wall_crossing(self.u_nodes)
        if crossing is not None:
            self.u_nodes, self.field_level, self.gravity_level = before
            self._scatter(self.u_nodes, self.field_level, self.gravity_level)
            return LevelResult(level, False, iterations, increments, norm, norm / scale, time.perf_counter() - t0,
                               f"its equilibrium puts the body {crossing}; the static solver has no domain walls, "
                               f"so the dynamics would stop the body there: enlarge simulation.domain_lo / domain_hi "
                               f"(or give the wall as a collider)", lam, buckled,
                               limit_levels=limits, arc_length_steps=arc_steps, wall_crossing=crossing)
        return LevelResult(level, True, iterations, increments, norm, norm / scale, time.perf_counter() - t0,
                           "", lam, buckled, None if self.contact is None else self.contact.penetration,
                           limit_levels=limits, arc_length_steps=arc_steps)

    def lowest_mode(self, tangent=None):
        """Eigenvalue nearest zero (N/m) and its mode of the stiffness -J at the current equilibrium (shift-invert
        about zero), from ``tangent`` when given (the last Newton iteration's, one converged step away); (None,
        None) when the eigensolver does not converge.

        Without colliders the loads are conservative and J symmetric: the eigenvalue is its symmetric part's.
        With colliders, friction makes J unsymmetric, and the symmetric part can be indefinite where the bodies
        are at rest (a block on a friction floor: -0.21 N/m in tests/test_static_contact.py; the triangle robot
        on its plate at 2 mT: -3.8e-4 N/m while every eigenvalue of J near zero was +0.0107 N/m, and the branch
        switch that followed cost 45 Newton iterations to return to the same state). There the eigenvalue is
        J's own nearest zero: a real one crossing zero is the divergence (a limit or bifurcation point) that a
        load-controlled path meets.

        With the iterative linear solver (static.linear_solver, or 'auto' above linear.DIRECT_MAX_UNKNOWNS
        unknowns): without colliders by LOBPCG on the multigrid hierarchy (:meth:`_lowest_mode_iterative`); with
        colliders by the factorisation below up to STABILITY_DIRECT_MAX unknowns, not at all above."""
        from scipy.sparse.linalg import ArpackNoConvergence, ArpackError, LinearOperator, eigs, eigsh

        if self.solver.interaction is not None:
            return None, None  # the bodies' own field's stiffness is not in the assembled tangent: not checked
        J = tangent if tangent is not None else self.tangent(self.u_nodes, self.field_level, self.gravity_level)
        K = -J
        unsymmetric = self.contact is not None
        K = (K if unsymmetric else 0.5 * (K + K.T)).tocsc()
        kind = self._linear_kind(K.shape[0])
        if kind == "iterative" and not unsymmetric:
            return self._lowest_mode_iterative(J, K)
        if kind == "iterative" and K.shape[0] > STABILITY_DIRECT_MAX:
            return None, None  # unsymmetric and too large to factorise: not checked (STABILITY_DIRECT_MAX)
        try:
            # one factorisation of K for the shift-invert about zero (the one eigsh makes itself) and for the
            # determinant's sign below
            lu = factor(K)
            inverse = LinearOperator(K.shape, matvec=lu.solve, dtype=K.dtype)
            v0 = np.ones(K.shape[0])
            if unsymmetric:
                vals, vecs = eigs(K, k=1, sigma=0.0, which="LM", v0=v0, OPinv=inverse)
                vals, vecs = vals.real, vecs.real  # a complex pair nearest zero: its real part (no divergence)
                vecs = vecs / max(float(np.linalg.norm(vecs[:, 0])), 1e-300)
            else:
                vals, vecs = eigsh(K, k=1, sigma=0.0, which="LM", v0=v0, OPinv=inverse)
                if vals[0] > 0.0 and _odd_negative_count(K, lu):
                    # a negative eigenvalue farther from zero than the positive one found (a load increment that
                    # went well past a bifurcation): in shift-invert mode 'SA' picks the most negative 1/lambda,
                    # the negative eigenvalue nearest zero
                    vals, vecs = eigsh(K, k=1, sigma=0.0, which="SA", v0=v0, OPinv=inverse)
        except (ArpackNoConvergence, ArpackError, RuntimeError):
            return None, None
        mode = vecs[:, 0]
        return float(vals[0]), mode if mode[np.argmax(np.abs(mode))] > 0 else -mode  # a reproducible sign

    def _lowest_mode_iterative(self, J, K):
        """:meth:`lowest_mode` of a symmetric K = -(J + J^T)/2 without a factorisation (static.linear_solver
        'iterative', or 'auto' above linear.DIRECT_MAX_UNKNOWNS unknowns): its smallest eigenvalue by LOBPCG
        (Knyazev 2001; a block of LOBPCG_BLOCK vectors) preconditioned by the multigrid hierarchy of the Newton
        solve (kept for the tangent ``J``). At a stable state that is the eigenvalue nearest zero; past a
        bifurcation the most negative one, whose mode the branch switch follows as well. (None, None) where LOBPCG
        leaves the eigenvalue's sign in doubt (its residual above a tenth of |lambda|, and above LOBPCG_TOL of the
        stiffness's scale).

        With colliders K is J's own (unsymmetric) spectrum, for which no such cheap eigensolver serves: ARPACK's
        shift-invert about zero needs tens of solves, and with GMRES for each it took minutes per check on the
        pentahedron (22,458 unknowns; 97 % of a 60 s profile). There the check factorises K directly up to
        STABILITY_DIRECT_MAX unknowns and is skipped above (:meth:`lowest_mode`)."""
        import warnings

        from scipy.sparse.linalg import lobpcg

        lin = self._linear_solver(J)  # the Newton solve's hierarchy, the Krylov method on this tangent
        n = K.shape[0]
        X = np.random.default_rng(0).standard_normal((n, LOBPCG_BLOCK))
        X[:, 0] = 1.0
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # non-convergence is judged below, by the residual
                vals, vecs = lobpcg(K, X, M=lin.preconditioner(), largest=False, tol=LOBPCG_TOL,
                                    maxiter=LOBPCG_ITERATIONS)
        except (RuntimeError, np.linalg.LinAlgError, ValueError):
            return None, None
        k = int(np.argmin(vals))
        lam, mode = float(vals[k]), vecs[:, k] / max(float(np.linalg.norm(vecs[:, k])), 1e-300)
        resid = float(np.linalg.norm(K @ mode - lam * mode))
        if not (resid <= 0.1 * abs(lam) or resid <= LOBPCG_TOL * float(np.abs(K.diagonal()).max())):
            return None, None
        return lam, mode if mode[np.argmax(np.abs(mode))] > 0 else -mode

    def collider_reactions(self) -> np.ndarray:
        """The force (N, (n_colliders, 3), 2D z = 0) each of the scene's colliders carries at the state of the last
        residual evaluation (after :meth:`write_state`: the equilibrium): minus the contact forces on the bodies."""
        if self._scene_contact is None:
            return np.zeros((len(self.sim.control.colliders), 3))
        return self._scene_contact.reaction.copy()

    def write_state(self) -> None:
        """Put the equilibrium into the simulation's state: x and F of the last residual, v = C = 0."""
        self._scatter(self.u_nodes, self.field_level, self.gravity_level)
        state = self.sim.state
        wp.copy(state.x, self.x)
        wp.copy(state.F, self.F)
        state.v.zero_()
        state.C.zero_()
