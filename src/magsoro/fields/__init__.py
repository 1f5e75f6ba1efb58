"""Magnetic field sources.

Every source gives ``B(points, t)`` -> (N, 3) tesla and ``grad_B(points, t)`` -> (N, 3, 3) tesla/metre with
``grad_B[n, i, j] = dB_i/dx_j`` for (N, 3) points in metres, and a device form the engine evaluates per particle
(see :mod:`magsoro.fields.base`). Sources add with ``+``.
"""

from magsoro.fields.base import FieldSource, FieldSum
from magsoro.fields.cuboid import CuboidMagnet
from magsoro.fields.cylinder import CylinderMagnet
from magsoro.fields.dipole import Dipole
from magsoro.fields.epm import EPMPose, epm_pose
from magsoro.fields.loops import CurrentLoop, HelmholtzPair, MaxwellPair
from magsoro.fields.magpylib_source import MagpylibSource
from magsoro.fields.profiles import Keyframes
from magsoro.fields.uniform import KeyframedVector, Ramp, Regional, Rotating, Sine, Uniform

__all__ = [
    "FieldSource",
    "FieldSum",
    "Uniform",
    "Ramp",
    "Sine",
    "Rotating",
    "KeyframedVector",
    "Regional",
    "Keyframes",
    "Dipole",
    "CylinderMagnet",
    "CuboidMagnet",
    "CurrentLoop",
    "HelmholtzPair",
    "MaxwellPair",
    "MagpylibSource",
    "EPMPose",
    "epm_pose",
]
