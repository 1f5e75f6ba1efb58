"""The engine's closed categories, each named once: the settings' string choices as ``Literal`` types, and the
integer codes the kernels take as ``IntEnum``s.

Warp kernels compare plain integers, so each kernel module keeps its codes as ``wp.constant`` ints; those ints
are made from the enums here (``wp.constant(int(ColliderMode.STICKY))``), and host code names the members, never
the numbers. The string settings (scene keys, :class:`magsoro.mpm.model.SolverSettings`) stay strings; where a
kernel needs one as a code, the enum maps the name (:meth:`ColliderMode.named`).
"""

from enum import IntEnum, IntFlag
from typing import Literal, get_args

#: the MPM formulation (:class:`magsoro.mpm.model.SolverSettings` ``formulation``): "updated" Lagrangian (grid
#: weights at the current positions) or "total" Lagrangian (weights, node forces and the velocity gradient on the
#: reference configuration)
Formulation = Literal["updated", "total"]
FORMULATIONS: tuple[str, ...] = get_args(Formulation)

#: where the updated form's F update takes its velocity gradient from (SolverSettings ``velocity_gradient``):
#: "remap" (the particles' new affine velocities transferred back to the grid) or "grid" (the node velocities of
#: the momentum update)
VelocityGradient = Literal["remap", "grid"]
VELOCITY_GRADIENTS: tuple[str, ...] = get_args(VelocityGradient)

#: the 2D idealisation (Model ``plane``, scene key simulation.plane): "strain" (F_zz = 1, long bodies) or "stress"
#: (zero normal stress, the thickness stretch solved per particle: thin plates loaded in their plane, wide strips
#: bending like beams; :func:`magsoro.mpm.laws.elastic.make_plane_stress_functions`). A compile-time choice: the
#: kernels that evaluate a law (p2g, the static solver's, the stress kernels) are built for one of them.
#: "axisymmetric" (scene key simulation.dim = "axisymmetric"): the 2D plane is the (r, z) half-plane of a body of
#: revolution about the y axis, F_thetatheta = r / R (docs/engine.md, "Axisymmetric bodies").
Plane = Literal["strain", "stress", "axisymmetric"]
PLANES: tuple[str, ...] = get_args(Plane)


def plane_stress_modulus(shear_modulus, bulk_modulus):
    """E / (1 - nu^2) = 4 G (3 K + G) / (3 K + 4 G), Pa: the plane-stress P-wave (and beam) modulus, which
    replaces K + 4 G / 3 (plane strain, 3D) in the wave speed of a plane-stress body."""
    return 4.0 * shear_modulus * (3.0 * bulk_modulus + shear_modulus) / (3.0 * bulk_modulus + 4.0 * shear_modulus)

#: the bodies' own field (SolverSettings ``magnetic_interaction``): "none", or "dipole" (:mod:`magsoro.mpm.interaction`)
InteractionMode = Literal["none", "dipole"]
INTERACTION_MODES: tuple[str, ...] = get_args(InteractionMode)

#: the name of a contact mode of a rigid surface (a collider's ``mode``, the domain walls' SolverSettings ``walls``)
ColliderModeName = Literal["sticky", "slip", "friction", "symmetry"]


class ColliderMode(IntEnum):
    """How a rigid surface (a collider, the domain walls) acts on the node velocities it touches (the grid
    update's ``project``): the codes of the kernels and of DeviceCollider.mode."""

    STICKY = 0  # the node moves with the surface
    SLIP = 1  # the approaching normal component is removed (frictionless)
    FRICTION = 2  # also the tangential part shrinks by mu |v_n| (Coulomb), stopping when it would reverse
    SYMMETRY = 3  # a mirror plane (half-spaces): the normal component is removed, approaching or not

    @classmethod
    def named(cls, name: str) -> "ColliderMode":
        """The mode of a setting's name ('sticky', 'slip', 'friction', 'symmetry'); ValueError for another."""
        try:
            return cls[name.upper()]
        except (KeyError, AttributeError):
            raise ValueError(f"contact mode must be one of {sorted(COLLIDER_MODES)}, got {name!r}") from None


#: mode name -> kernel code
COLLIDER_MODES: dict[str, int] = {m.name.lower(): int(m) for m in ColliderMode}
assert tuple(COLLIDER_MODES) == get_args(ColliderModeName)


class ColliderKind(IntEnum):
    """A collider's shape: the codes of DeviceCollider.kind (:func:`magsoro.mpm.colliders.collider_sdf`)."""

    HALF_SPACE = 0
    BOX = 1
    SPHERE = 2
    CYLINDER = 3


class P2GFlag(IntFlag):
    """Bits of p2g's ``flags`` argument (:mod:`magsoro.mpm.kernels.p2g`)."""

    TOTAL = 1  # total Lagrangian: the weights at the reference positions
    APART = 2  # store each particle's affine matrix and momentum for p2g_scatter (the GPU's scatter threads)


class FUpdate(IntEnum):
    """Where g2p's F update takes its velocity gradient from (its ``f_update`` argument, :mod:`magsoro.mpm.kernels.g2p`)."""

    FROM_GRID = 0  # the node velocities of the momentum update
    FROM_REMAP = 1  # the remap: g2p scatters the new affine velocities, remap_F gathers F
    TOTAL = 2  # total Lagrangian: F grows by dt grad_X v on the reference grid
    REMAP_APART = 3  # the remap with its scatter in remap_scatter (the GPU's scatter threads)


class NodeClass(IntEnum):
    """A grid node's class in the contact classification (:mod:`magsoro.mpm.kernels.contact`)."""

    SINGLE = 0  # one velocity field
    BODIES = 1  # two contact groups meet
    FOLD = 2  # two layers of one body (self-contact)


class MagnetizationFollows(IntEnum):
    """The map that carries a particle's remanence (material.magnetization_follows, :mod:`magsoro.mpm.kernels.stencil`)."""

    F = 0  # the deformation gradient (Zhao's law)
    R = 1  # the rotation of its polar decomposition F = R U
