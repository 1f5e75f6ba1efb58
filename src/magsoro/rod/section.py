"""Cross-sections of a rod: area, second moments, torsion constant and shear coefficients (all SI).

Material frame convention used throughout ``magsoro.rod``: d3 is the centreline tangent of the undeformed rod,
d1 and d2 span the cross-section. For a rectangle the *width* lies along d1 and the *thickness* along d2, so
bending "through the thickness" (the soft direction of a strip) is a rotation about d1 with stiffness
E * I1, I1 = width * thickness**3 / 12.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from magsoro.errors import SceneError


def _positive(value, name: str, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SceneError(f"{name}: must be a number in {unit}, got {value!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise SceneError(f"{name}: must be a finite number > 0 {unit}, got {value!r}")
    return v


@dataclass(frozen=True)
class CrossSection:
    """Geometric properties of a rod's cross-section.

    Attributes (SI):
        shape: ``"rectangle"`` or ``"circle"``.
        area: A, m^2.
        second_moment: (I1, I2), m^4, about the d1 and d2 axes.
        torsion_constant: J, m^4 (Saint-Venant torsion constant; polar moment for a circle).
        shear_coefficient: Timoshenko shear coefficient kappa (dimensionless); shear stiffness is kappa G A.
    """

    shape: str
    area: float
    second_moment: tuple[float, float]
    torsion_constant: float
    shear_coefficient: float
    width: float | None = None
    thickness: float | None = None
    diameter: float | None = None

    @classmethod
    def rectangle(cls, width: float, thickness: float) -> "CrossSection":
        """Rectangle of ``width`` (m, along d1) and ``thickness`` (m, along d2)."""
        w = _positive(width, "cross_section.width", "m")
        t = _positive(thickness, "cross_section.thickness", "m")
        i1 = w * t**3 / 12.0
        i2 = t * w**3 / 12.0
        # Saint-Venant torsion constant of a rectangle, a = long side, b = short side (Roark's formula,
        # within ~0.5% of the exact series for every aspect ratio); the 1/3 a b^3 thin-strip limit overestimates
        # J by 60% for a square, which matters for twisted square rods.
        a, b = max(w, t), min(w, t)
        j = a * b**3 * (1.0 / 3.0 - 0.21 * (b / a) * (1.0 - b**4 / (12.0 * a**4)))
        return cls("rectangle", w * t, (i1, i2), j, 5.0 / 6.0, width=w, thickness=t)

    @classmethod
    def circle(cls, diameter: float) -> "CrossSection":
        """Solid circle of ``diameter`` (m)."""
        d = _positive(diameter, "cross_section.diameter", "m")
        i = math.pi * d**4 / 64.0
        # 9/10 is the Timoshenko coefficient of a solid circle for nu ~ 0.3-0.5 (6(1+nu)/(7+6nu) gives 0.89-0.92).
        return cls("circle", math.pi * d**2 / 4.0, (i, i), 2.0 * i, 0.9, diameter=d)
