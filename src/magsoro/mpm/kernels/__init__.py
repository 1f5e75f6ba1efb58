"""MLS-MPM kernels (seed 000 eqs 1-19), generated for a dimension (2: plane strain or plane stress, 3) and a precision.

One factory per phase builds its kernels from the same source for 2D/3D and float32/float64, so the variants
never drift apart; Warp compiles them for CPU and CUDA alike:

- :mod:`magsoro.mpm.kernels.stencil`: types, argument structs and the quadratic B-spline stencil every phase shares;
- :mod:`magsoro.mpm.kernels.p2g`: particle to grid (mass, momentum, stress impulse), contact scan, node displacements;
- :mod:`magsoro.mpm.kernels.grid`: node velocities (damping, gravity, walls, colliders, contact);
- :mod:`magsoro.mpm.kernels.g2p`: grid to particle (x, v, C, F), the velocity-gradient remap, the checks' reductions;
- :mod:`magsoro.mpm.laws.elastic`: the constitutive laws; :mod:`magsoro.mpm.kernels.contact`: the contact model;
- :mod:`magsoro.mpm.laws.eigenstrain`: stimulus-driven eigenstrain (host tables; the stress is
  :func:`magsoro.mpm.kernels.stencil.make_body_elastic`).

Notation: dx grid spacing, inv_dx = 1/dx, particles carry reference volume V0, mass, shear modulus G, bulk
modulus K, remanence Br (reference frame, in-plane part in 2D).
"""

import functools

import warp as wp

from magsoro.mpm.kernels.contact import make_contact
from magsoro.mpm.kernels.g2p import F_FROM_GRID, F_FROM_REMAP, F_REMAP_APART, F_TOTAL, make_g2p
from magsoro.mpm.kernels.grid import grid_settings_struct, make_grid
from magsoro.mpm.laws.elastic import make_material_functions, make_plane_stress_functions
from magsoro.mpm.kernels.p2g import make_p2g
from magsoro.mpm.kernels.stencil import make_body_elastic, make_types

__all__ = ["make_kernels", "grid_settings_struct", "F_FROM_GRID", "F_FROM_REMAP", "F_REMAP_APART", "F_TOTAL"]


@functools.cache
def _stress_kernel(dim: int, scalar, plane: str = "strain") -> dict:
    if plane == "axisymmetric":  # closed-form checks of the laws: the axisymmetric model's laws are the 3D ones
        plane = "strain"
    t = make_types(dim, scalar)
    if plane == "stress":
        elastic = make_plane_stress_functions(scalar)
        elastic_stress, elastic_energy = elastic["plane_stress_stress"], elastic["plane_stress_energy"]
    else:
        elastic = make_material_functions(dim, scalar)
        elastic_stress, elastic_energy = elastic["elastic_stress"], elastic["elastic_energy"]
    body = make_body_elastic(dim, scalar, plane)
    body_elastic_stress, body_elastic_energy = body.body_elastic_stress, body.body_elastic_energy
    mat, vprm, Bodies = t.mat, t.vprm, t.Bodies

    @wp.kernel(enable_backward=False)  # never under wp.Tape
    def stress_kernel(
        F: wp.array(dtype=mat), model: int, shear_modulus: scalar, bulk_modulus: scalar, prm: vprm, P: wp.array(dtype=mat),
        psi: wp.array(dtype=scalar)
    ):
        """First Piola stress and energy density of one law (shear and bulk moduli in Pa) at each F (tests and
        closed-form checks)."""
        i = wp.tid()
        P[i] = elastic_stress(F[i], model, shear_modulus, bulk_modulus, prm)
        psi[i] = elastic_energy(F[i], model, shear_modulus, bulk_modulus, prm)

    @wp.kernel(enable_backward=False)
    def body_stress_kernel(
        F: wp.array(dtype=mat), bodies: wp.array(dtype=Bodies), P: wp.array(dtype=mat), psi: wp.array(dtype=scalar)
    ):
        """Elastic first Piola stress and energy density of every particle of the model at F[p]: its law, moduli
        and stimulus eigenstrain now (:func:`magsoro.mpm.kernels.stencil.make_body_elastic`)."""
        p = wp.tid()
        b = bodies[0]
        P[p] = body_elastic_stress(F[p], b, p)
        psi[p] = body_elastic_energy(F[p], b, p)

    return {"stress_kernel": stress_kernel, "body_stress_kernel": body_stress_kernel}


def launch_stress(kernels, n, *, F, law, shear_modulus, bulk_modulus, params, P, psi, device, record=False):
    """``stress_kernel`` over ``n`` deformation gradients ``F``: stress ``P`` and energy density ``psi`` of the law
    code ``law`` with the moduli (Pa) and the law's parameters ``params``. The one place its argument order is
    written."""
    return wp.launch(kernels["stress_kernel"], dim=n, device=device, record_cmd=record,
                     inputs=[F, law, shear_modulus, bulk_modulus, params, P, psi])


def launch_body_stress(kernels, n, *, F, bodies, P, psi, device, record=False):
    """``body_stress_kernel`` over the ``n`` particles of a model: elastic stress ``P`` and energy density ``psi`` at
    ``F``. The one place its argument order is written."""
    return wp.launch(kernels["body_stress_kernel"], dim=n, device=device, record_cmd=record, inputs=[F, bodies, P, psi])


@functools.cache
def make_kernels(dim: int, scalar, contact: bool = False, differentiable: bool = False, plane: str = "strain") -> dict:
    """Every kernel and type of the engine for ``dim`` in (2, 3) and ``scalar`` in (wp.float32, wp.float64).

    ``contact``: the variant with two velocity fields per node (:mod:`magsoro.mpm.kernels.contact`). Without it the
    kernels never read their contact argument, which on CPU doubled the grid update of a single body (a few
    nanoseconds per node against about 4 ns for the whole update). ``differentiable``: p2g, grid_update, g2p,
    remap_node_velocity and remap_F with their adjoints, for the differentiable rollout (:mod:`magsoro.diff`), the
    only caller that records kernels on a wp.Tape; without it Warp builds no adjoint, which on a cold cache saves
    most of the engine's compile time (docs/engine.md, "Compile time"). ``plane`` (2D): the laws in plane strain
    or plane stress (:func:`magsoro.mpm.kernels.stencil.make_body_elastic`), chosen at compile time: the kernels that
    evaluate a law (p2g and the stress kernels) are built for one of them."""
    t = make_types(dim, scalar)
    two_fields = bool(contact)
    ct_ns = make_contact(dim, scalar)
    return dict(
        **make_p2g(dim, scalar, two_fields, differentiable, plane),
        **make_grid(dim, scalar, two_fields, differentiable),
        **make_g2p(dim, scalar, two_fields, differentiable),
        **_stress_kernel(dim, scalar, plane),
        ContactGrid=ct_ns["ContactGrid"],
        contact_classify=ct_ns["contact_classify"],
        Block=t.Block, Bodies=t.Bodies, Applied=t.Applied, GridArrays=t.GridArrays, Particles=t.Particles,
        Checks=t.Checks, Step=t.Step,
        vec=t.vec, mat=t.mat, ivec=t.ivec, v3=t.v3, m3=t.m3, vprm=t.vprm,
    )
