"""Cosserat-rod model of magnetic continuum robots (seed 003; Till et al. 2019, Rucker & Webster 2011).

    >>> from magsoro.rod import Rod, CrossSection
    >>> rod = Rod(0.0172, CrossSection.rectangle(5e-3, 0.84e-3), youngs_modulus=909e3,
    ...           magnetisation=(0.0, 0.0, 0.258))           # axial remanence, T
    >>> sol = rod.solve(field=(0.0, 0.0, 0.01))             # uniform field, T
    >>> sol.tip_position                                     # m
"""

from magsoro.rod.magnetisation import MagnetSegment, Magnetisation
from magsoro.rod.model import DEFAULT_BASE_ROTATION, Rod, RodSolution, solve, sweep
from magsoro.rod.section import CrossSection

__all__ = [
    "CrossSection",
    "DEFAULT_BASE_ROTATION",
    "MagnetSegment",
    "Magnetisation",
    "Rod",
    "RodSolution",
    "solve",
    "sweep",
]
