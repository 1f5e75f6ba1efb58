"""Eversion mechanics of a magnetoelastic soft growing robot (seed 004 sec II-A/B, eqs 1-13).

The robot is an incompressible, isotropic Neo-Hookean tube with reference radii A <= R <= B (eq 1). Everted, it
occupies a <= r <= b with the inner reference surface R = A on r = b and the outer one R = B on r = a (eq 2), and
is stretched axially by lambda_z. Incompressibility (eq 4) gives (eq 5)

    r^2 = a^2 + (B^2 - R^2) / lambda_z,        b^2 = a^2 + (B^2 - A^2) / lambda_z,

so lambda_theta = r / R and lambda_r = 1 / (lambda_theta lambda_z) at every radius.

Magnetoelastic coupling. The energy depends on the field through I4 = H_L . H_L (eq 8) with H_L = J F^-1 H
(eq 9). For the axial field of the seed's experiments (H = B0 / mu0 e_z, J = 1) this is I4 = (B0 / (mu0
lambda_z))^2, uniform through the wall, so the shear modulus becomes a constant mu(I4) for a given field and the
radial problem keeps its purely elastic form with that reduced modulus (the seed's remark before eq 10).
The seed does not print mu(I4); we use the form of Dorfmann & Ogden (2004) and Saxena (2017) for magnetoelastic
tubes, mu(I4) = mu (1 + alpha tanh(I4 / I4_sat)), I4_sat = (B_sat / mu0)^2. alpha = 0 is a field-blind material.

Internal pressure (eq 10) and tip force (eq 11) in closed form. With u = r^2, R^2 = K - lambda_z u,
K = B^2 + lambda_z a^2, the integrands are rational in u and integrate to logarithms:

    P / mu(I4) = int_a^b (lambda_theta^2 - lambda_theta^-2 lambda_z^-2) dr / r
               = ln(B b / (A a)) / lambda_z - K (B^2 - A^2) / (2 lambda_z^3 a^2 b^2)

    N_el / mu(I4) = pi int_a^b (2 lambda_z^2 - lambda_theta^2 - lambda_theta^-2 lambda_z^-2) r dr
                  = pi [(lambda_z^2 + 1/lambda_z) (b^2 - a^2) + (K / lambda_z^2) ln(A a / (B b))]

    N_ideal = N_el + pi a^2 P + (pi mu0 / 2) (b^2 - a^2) I4 (lambda_z^2 - lambda_z^-2).

The seed prints eq 11 with 2 pi in front of the elastic integral. The axial resultant of a tube wall follows from
radial equilibrium as pi int_a^b (2 sigma_zz - sigma_rr - sigma_thetatheta) r dr + pi a^2 P (Ogden, Non-linear
Elastic Deformations, sec 5.3); only the factor pi gives the uniaxial result mu (lambda^2 - 1/lambda) pi (b^2 - a^2)
for a homogeneously stretched tube, and it is the factor the seed's own Maxwell term carries:
(pi/2)(b^2 - a^2) = pi int_a^b r dr. We therefore use pi and read the printed 2 pi as a typesetting slip.

Friction (eqs 12-13). N = N_ideal - l mu_k p_n phi (2 pi b) g(Theta), g = exp(gamma mu_k Theta), with
p_n = alpha_c P the part of the internal pressure transmitted as normal load between tail and wall (clipped at
zero: a wall that would need suction does not press on the tail).

Hard-magnetic tail (the flip term). Seed 004 magnetises the second half of its robot axially ("to minimize
self-attraction between walls"); that half is the tail that everts last. Eversion turns the wall inside out and
back along the axis (F e_z = -lambda_z e_z in the everted wall), so the axial remanence of tail material reverses
direction as it passes the front. With the engine's hard-magnetic energy per reference volume,
W = -(1/mu0) B . F Br ("F", Zhao's law, the default) or -(1/mu0) B . R Br ("R"), and the tail's remanence
|Br| directed against an axial field B0, everting one reference volume lowers the energy by
(1 + lambda_F) |Br| B0 / mu0 (lambda_F = lambda_z under "F", 1 under "R"). The front advances lambda_z per unit
reference length everted, so by virtual work the front gains the force

    N_flip = (1 + lambda_F) / lambda_z  |Br| B0 / mu0  pi (B^2 - A^2),

positive when the field opposes the tail's magnetisation (B0 > 0 here), negative when it is along it. This is
the field-alone eversion the seed describes; mu(I4) and the Maxwell term (the soft-magnetic response of eqs
8-11) stay as they are. A uniform field exerts no net force on the tube, so N_flip is the only field term at
lambda_z = 1.

Sign and growth. N is the force the front can push with: the front advances against a tip load N_load when
N >= N_load. In eqs 10-11 alone N < 0 at lambda_z = 1 and P = 0 (the elastic integrand 2 - lambda^2 - lambda^-2
is never positive) and the Maxwell term vanishes there, so those equations cannot make a field alone evert the
tube; the seed's sentence "for lambda_z = 1 and P = 0, we found N < 0, indicating that the magnetic field alone
can induce eversion" holds with the flip term of its axially magnetised tail, which is positive and linear in
the field: the smallest growing field is then -N_el / (dN_flip/dB0) without friction. Friction lowers N (eq 12).

Pressure-free growth. Without fluid pressure, eq 10 with P = 0 fixes the everted radius a0(lambda_z), the same
for every field because mu(I4) factors out. For a thin tube a0 < B: the free everted wall would be narrower than
the uneverted tail (outer radius B) it encloses, so it rests on the tail at a = B ("without internal pressure,
the everted walls remain in contact", seed sec III-B). P(B) of eq 10 is then the support the tail supplies by
contact: it loads the friction term (p_n = alpha_c P) but no fluid pushes on the front, so the pi a^2 P term is
absent. The operating radius is therefore max(a0, B) unless given. :meth:`EversionModel.minimum_growth_field`
finds the smallest axial |B| with N_pressure_free(B) >= N_load; the field helps through the flip term (when the
tail is magnetised, ``remanence`` > 0) and through the Maxwell term (positive for lambda_z > 1 only). Without
remanence and at lambda_z = 1 no field makes a stalled tube grow.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magsoro.constants import MU0

#: Tail-geometry presets (perimeter factor phi, capstan geometry factor gamma). The seed's pulling test (Fig. 4)
#: found a cruciform tail needs about five times less pulling force than a cylindrical one, hence phi = 0.2 for
#: a cruciform tail relative to the full perimeter of a cylindrical one. The seed gives no number for gamma, only
#: that it is smaller for a cruciform tail; 0.5 is an illustrative value, override it from measurements.
TAIL_PRESETS = {
    "cylindrical": {"perimeter_factor": 1.0, "capstan_factor": 1.0},
    "cruciform": {"perimeter_factor": 0.2, "capstan_factor": 0.5},
}


@dataclass(frozen=True)
class Friction:
    """Tail-wall sliding losses of eqs 12-13.

    contact_length : l, sliding contact length, m.
    friction_coefficient : mu_k, kinetic friction coefficient (-).
    contact_factor : alpha_c in [0, 1], fraction of the internal pressure carried as normal contact load (-).
    perimeter_factor : phi in [0, 1], effective fraction of the perimeter 2 pi b in contact (-).
    capstan_factor : gamma in [0, 1], geometry factor of the capstan amplification exp(gamma mu_k Theta) (-).
    """

    contact_length: float = 0.0
    friction_coefficient: float = 0.0
    contact_factor: float = 1.0
    perimeter_factor: float = 1.0
    capstan_factor: float = 1.0

    @classmethod
    def for_tail(cls, tail: str, contact_length: float, friction_coefficient: float, contact_factor: float = 1.0,
                 perimeter_factor: float | None = None, capstan_factor: float | None = None) -> "Friction":
        """Friction with the presets of ``tail`` ("cylindrical" or "cruciform"), any factor overridable."""
        if tail not in TAIL_PRESETS:
            raise ValueError(f"tail must be one of {sorted(TAIL_PRESETS)}, got {tail!r}")
        p = TAIL_PRESETS[tail]
        return cls(
            contact_length, friction_coefficient, contact_factor,
            p["perimeter_factor"] if perimeter_factor is None else perimeter_factor,
            p["capstan_factor"] if capstan_factor is None else capstan_factor,
        )

    def capstan(self, bend_angle) -> np.ndarray:
        """g(Theta) = exp(gamma mu_k Theta) of eq 13 for a cumulative bending angle Theta (rad, its magnitude)."""
        return np.exp(self.capstan_factor * self.friction_coefficient * np.abs(np.asarray(bend_angle, dtype=float)))

    def drag(self, contact_pressure, outer_radius, bend_angle=0.0) -> np.ndarray:
        """Friction force l mu_k p_n phi (2 pi b) g(Theta), N, for a contact pressure p_n (Pa, clipped at 0) and
        the everted outer radius b (m)."""
        pn = np.maximum(np.asarray(contact_pressure, dtype=float), 0.0)
        return (self.contact_length * self.friction_coefficient * pn * self.perimeter_factor
                * 2.0 * np.pi * np.asarray(outer_radius, dtype=float) * self.capstan(bend_angle))


@dataclass(frozen=True)
class EversionModel:
    """Incompressible Neo-Hookean magnetoelastic tube everting under pressure and/or an axial field.

    inner_radius, outer_radius : reference radii A < B, m.
    shear_modulus : zero-field shear modulus mu, Pa.
    magnetic_stiffening : alpha of mu(I4) = mu (1 + alpha tanh(I4 / I4_sat)) (-); 0 = field-independent.
    saturation_field : B_sat giving I4_sat = (B_sat / mu0)^2, T.
    axial_stretch : lambda_z (-).
    friction : :class:`Friction` (default: none).
    remanence : |Br| of the tail wall's axial remanent magnetisation, T (0: a tail without axial remanence).
    magnetization_follows : how the deformation carries the remanence, "F" (Zhao's law, the engine's default)
        or "R" (the rotation of F), as ``material.magnetization_follows`` in a scene.

    Fields are flux densities B0 = mu0 H in tesla along the tube axis, positive against the tail's remanence
    (the direction in which the flip term helps growth; the soft-magnetic terms depend on B0^2 only);
    pressures in Pa, forces in N.
    """

    inner_radius: float
    outer_radius: float
    shear_modulus: float
    magnetic_stiffening: float = 0.0
    saturation_field: float = 0.1
    axial_stretch: float = 1.0
    friction: Friction = Friction()
    remanence: float = 0.0
    magnetization_follows: str = "F"

    def __post_init__(self):
        if not (0 < self.inner_radius < self.outer_radius):
            raise ValueError(f"need 0 < inner_radius < outer_radius, got A = {self.inner_radius} m, B = {self.outer_radius} m")
        if not self.shear_modulus > 0:
            raise ValueError(f"shear_modulus must be > 0 Pa, got {self.shear_modulus}")
        if not self.axial_stretch > 0:
            raise ValueError(f"axial_stretch must be > 0, got {self.axial_stretch}")
        if not self.saturation_field > 0:
            raise ValueError(f"saturation_field must be > 0 T, got {self.saturation_field}")
        if self.magnetic_stiffening <= -1:
            raise ValueError(f"magnetic_stiffening must be > -1 (mu(I4) stays positive), got {self.magnetic_stiffening}")
        if not self.remanence >= 0:
            raise ValueError(f"remanence must be >= 0 T (its magnitude; the field's sign gives the direction), got {self.remanence}")
        if self.magnetization_follows not in ("F", "R"):
            raise ValueError(f"magnetization_follows must be 'F' or 'R', got {self.magnetization_follows!r}")

    # -- kinematics (eq 5) ---------------------------------------------------------------------------------
    def everted_outer_radius(self, a) -> np.ndarray:
        """b(a) = sqrt(a^2 + (B^2 - A^2) / lambda_z), m."""
        a = np.asarray(a, dtype=float)
        return np.sqrt(a * a + (self.outer_radius**2 - self.inner_radius**2) / self.axial_stretch)

    def reference_radius(self, r, a) -> np.ndarray:
        """R(r) = sqrt(B^2 - lambda_z (r^2 - a^2)) of the material now at radius r, m."""
        r, a = np.asarray(r, dtype=float), np.asarray(a, dtype=float)
        return np.sqrt(self.outer_radius**2 - self.axial_stretch * (r * r - a * a))

    # -- magnetic invariants -------------------------------------------------------------------------------
    def I4(self, field) -> np.ndarray:
        """I4 = |J F^-1 H|^2 for an axial applied field B0 (T): (B0 / (mu0 lambda_z))^2, (A/m)^2."""
        h = np.asarray(field, dtype=float) / MU0
        return (h / self.axial_stretch) ** 2

    def shear_modulus_at(self, field) -> np.ndarray:
        """mu(I4) in Pa for an axial field B0 (T)."""
        i4_sat = (self.saturation_field / MU0) ** 2
        return self.shear_modulus * (1.0 + self.magnetic_stiffening * np.tanh(self.I4(field) / i4_sat))

    # -- reduced integrals (per unit mu(I4)) ------------------------------------------------------------------
    def _reduced_pressure(self, a):
        A, B, lz = self.inner_radius, self.outer_radius, self.axial_stretch
        a = np.asarray(a, dtype=float)
        b = self.everted_outer_radius(a)
        K = B * B + lz * a * a
        return np.log(B * b / (A * a)) / lz - K * (B * B - A * A) / (2.0 * lz**3 * a * a * b * b)

    def _reduced_elastic_force(self, a):
        A, B, lz = self.inner_radius, self.outer_radius, self.axial_stretch
        a = np.asarray(a, dtype=float)
        b = self.everted_outer_radius(a)
        K = B * B + lz * a * a
        return np.pi * ((lz * lz + 1.0 / lz) * (b * b - a * a) + K / (lz * lz) * np.log(A * a / (B * b)))

    # -- eqs 10-12 -----------------------------------------------------------------------------------------
    def pressure(self, a, field=0.0) -> np.ndarray:
        """Internal pressure P (Pa) holding the everted inner radius ``a`` (m) in an axial field ``field`` (T), eq 10."""
        return self.shear_modulus_at(field) * self._reduced_pressure(a)

    def maxwell_force(self, a, field=0.0) -> np.ndarray:
        """Maxwell-stress term of eq 11, (pi mu0 / 2)(b^2 - a^2) I4 (lambda_z^2 - lambda_z^-2), N."""
        a = np.asarray(a, dtype=float)
        b = self.everted_outer_radius(a)
        lz = self.axial_stretch
        return 0.5 * np.pi * MU0 * (b * b - a * a) * self.I4(field) * (lz * lz - 1.0 / (lz * lz))

    def flip_force_per_tesla(self) -> float:
        """dN_flip/dB0 (N/T): the front force the reversal of the tail's axial remanence gives per tesla of
        axial field against it, (1 + lambda_F) / lambda_z |Br| / mu0 pi (B^2 - A^2)."""
        lz = self.axial_stretch
        lam_f = lz if self.magnetization_follows == "F" else 1.0
        area = np.pi * (self.outer_radius**2 - self.inner_radius**2)
        return float((1.0 + lam_f) / lz * self.remanence / MU0 * area)

    def flip_force(self, field=0.0) -> np.ndarray:
        """N_flip (N): front force from the axial remanence of the tail turning round the front, for an axial
        field ``field`` (T, positive against the tail's remanence). Zero without remanence."""
        return self.flip_force_per_tesla() * np.asarray(field, dtype=float)

    def elastic_force(self, a, field=0.0) -> np.ndarray:
        """Elastic term of eq 11, pi mu(I4) int (2 lz^2 - lt^2 - lt^-2 lz^-2) r dr, N."""
        return self.shear_modulus_at(field) * self._reduced_elastic_force(a)

    def tip_force_ideal(self, a, field=0.0, pressure=None) -> np.ndarray:
        """N_ideal (N) of eq 11 plus the flip term at inner radius ``a`` (m) and axial field ``field`` (T).

        ``pressure`` (Pa) is the fluid pressure acting on the front; default the eq-10 pressure at ``a``.
        """
        P = self.pressure(a, field) if pressure is None else np.asarray(pressure, dtype=float)
        a = np.asarray(a, dtype=float)
        return self.elastic_force(a, field) + np.pi * a * a * P + self.maxwell_force(a, field) + self.flip_force(field)

    def tip_force(self, a, field=0.0, bend_angle=0.0, pressure=None) -> np.ndarray:
        """Friction-corrected tip force N (N) of eqs 12-13.

        ``bend_angle``: cumulative bending angle Theta of the body (rad). ``pressure``: fluid pressure (Pa),
        default the eq-10 pressure at ``a``; the contact pressure is alpha_c times the eq-10 pressure.
        """
        P = self.pressure(a, field)
        b = self.everted_outer_radius(a)
        return self.tip_force_ideal(a, field, pressure) - self.friction.drag(self.friction.contact_factor * P, b, bend_angle)

    # -- growth under pressure -----------------------------------------------------------------------------
    def _pressure_limit(self, field=0.0) -> tuple[float, float]:
        """(a, P) where eq 10's P(a) stops rising (the everted wall's inflation limit, beyond which it balloons),
        searched up to 100 B."""
        a = np.geomspace(self.pressure_free_radius(), 100.0 * self.outer_radius, 4000)
        P = self.pressure(a, field)
        k = int(np.argmax(P))
        return float(a[k]), float(P[k])

    def pressurised_radius(self, pressure: float, field=0.0) -> float | None:
        """Everted inner radius (m) under a fluid pressure (Pa) between the tail and the wall: the eq-10 radius
        when it exceeds the tail's outer radius B, else B (the wall rests on the tail, which carries the rest);
        None above the inflation limit (the wall balloons)."""
        from scipy.optimize import brentq

        a0 = self.pressure_free_radius()
        if pressure <= 0.0:
            return max(a0, self.outer_radius)
        a_lim, p_lim = self._pressure_limit(field)
        if pressure >= p_lim:
            return None
        a = float(brentq(lambda x: float(self.pressure(x, field)) - pressure, a0, a_lim, xtol=1e-15, rtol=1e-13))
        return max(a, self.outer_radius)

    def pressurised_tip_force(self, pressure: float, field=0.0, bend_angle=0.0, front: str = "full") -> float | None:
        """Tip force N (N) under a fluid pressure (Pa): eqs 11-13 at :meth:`pressurised_radius`, the pressure
        acting on the front over pi a^2 (``front = "full"``, eq 11: the whole section is pressurised, as with a
        flat or sealed tail) or pi (a^2 - B^2) (``"gap"``: only the annulus between the tail and the wall, the
        tail's lumen open to the outside through the tip). Friction is loaded with alpha_c times the eq-10
        pressure at that radius (the fluid's, or with the wall on the tail the contact's). None above the
        inflation limit."""
        if front not in ("full", "gap"):
            raise ValueError(f"front must be 'full' or 'gap', got {front!r}")
        a = self.pressurised_radius(pressure, field)
        if a is None:
            return None
        area = np.pi * a * a if front == "full" else np.pi * (a * a - self.outer_radius**2)
        drag = self.friction.drag(self.friction.contact_factor * float(self.pressure(a, field)),
                                  float(self.everted_outer_radius(a)), bend_angle)
        return float(self.elastic_force(a, field) + area * pressure + self.maxwell_force(a, field)
                     + self.flip_force(field) - drag)

    def growth_pressure(self, field=0.0, bend_angle=0.0, required_force: float = 0.0, front: str = "full") -> float | None:
        """Smallest fluid pressure (Pa) at which the front reaches ``required_force`` (N): 0 when it does without
        pressure, None when no pressure below the inflation limit does (see :meth:`pressurised_tip_force`)."""
        def excess(P):
            N = self.pressurised_tip_force(P, field, bend_angle, front)
            return -np.inf if N is None else N - required_force

        if excess(0.0) >= 0.0:
            return 0.0
        _, p_lim = self._pressure_limit(field)
        return _first_reaching(excess, np.linspace(0.0, p_lim, 801)[:-1], xtol=1e-9)

    # -- pressure-free growth ------------------------------------------------------------------------------
    def pressure_free_radius(self) -> float:
        """The everted inner radius a0 (m) where eq 10 gives P = 0 (the same for every field)."""
        from scipy.optimize import brentq

        lo, hi = 1e-6 * self.outer_radius, 100.0 * self.outer_radius
        f = self._reduced_pressure
        if not (f(lo) < 0 < f(hi)):
            raise ValueError("no everted radius with zero pressure found between 1e-6 B and 100 B")
        return float(brentq(f, lo, hi, xtol=1e-15 * self.outer_radius, rtol=1e-14, maxiter=500))

    def operating_radius(self, contact_radius: float | None = None) -> float:
        """Everted inner radius without fluid pressure, m: ``contact_radius`` when given, else max(a0, B) (the
        wall rests on the uneverted tail when the pressure-free radius a0 is narrower than the tail)."""
        if contact_radius is not None:
            if not contact_radius > 0:
                raise ValueError(f"contact_radius must be > 0 m, got {contact_radius}")
            return float(contact_radius)
        return max(self.pressure_free_radius(), self.outer_radius)

    def pressure_free_tip_force(self, field, bend_angle=0.0, contact_radius: float | None = None) -> np.ndarray:
        """Tip force N (N) without fluid pressure, for an axial field ``field`` (T), at
        :meth:`operating_radius`. The eq-10 pressure there is carried by contact with the tail: it loads the
        friction term and does not push on the front (zero at a = a0, where there is no contact)."""
        return self.tip_force(self.operating_radius(contact_radius), field, bend_angle, pressure=0.0)

    def minimum_growth_field(self, required_force: float = 0.0, bend_angle: float = 0.0,
                             contact_radius: float | None = None, max_field: float = 2.0) -> float | None:
        """Smallest axial field |B| (T) in [0, max_field] for which the pressure-free tip force reaches
        ``required_force`` (N); 0 when it does so without field, None when no field up to ``max_field`` does."""
        def excess(B):
            return float(self.pressure_free_tip_force(B, bend_angle, contact_radius)) - required_force

        if excess(0.0) >= 0.0:
            return 0.0
        return _first_reaching(excess, np.linspace(0.0, max_field, 401), xtol=1e-12)

    def friction_coefficient_for_growth_field(self, field: float, required_force: float = 0.0, bend_angle: float = 0.0,
                                              contact_radius: float | None = None, max_coefficient: float = 10.0) -> float | None:
        """The kinetic friction coefficient mu_k (-) for which ``field`` (T) is exactly the smallest growing field
        without pressure, the other friction factors (l, alpha_c, phi, gamma) kept: the friction a measured
        growth threshold implies. None when the front cannot reach ``required_force`` at that field even without
        friction, or when the friction has no lever (l, alpha_c, phi or the contact pressure zero) or would need
        mu_k > ``max_coefficient``."""
        from dataclasses import replace

        from scipy.optimize import brentq

        def excess(mu_k):
            m = replace(self, friction=replace(self.friction, friction_coefficient=mu_k))
            return float(m.pressure_free_tip_force(field, bend_angle, contact_radius)) - required_force

        lo, hi = excess(0.0), excess(max_coefficient)
        if lo < 0.0 or hi > 0.0 or lo == hi:
            return None
        return float(brentq(excess, 0.0, max_coefficient, xtol=1e-14, rtol=1e-12))


def _first_reaching(excess, grid: np.ndarray, xtol: float) -> float | None:
    """The smallest x at which ``excess(x)`` reaches 0, for an ``excess`` negative at grid[0]: the first grid
    point where it is >= 0, refined by Brent's method against the point before; None when no grid point reaches
    it."""
    from scipy.optimize import brentq

    values = np.array([excess(x) for x in grid])
    above = np.flatnonzero(values >= 0.0)
    if len(above) == 0:
        return None
    k = int(above[0])
    return float(brentq(excess, grid[k - 1], grid[k], xtol=xtol, rtol=1e-12))


# ------------------------------------------------------------------------------------------- report
def curves(model_at_stretch: "EversionModel", fields, radii) -> dict:
    """P (Pa), N_ideal (N) and N (N) of eqs 10-12 over inner radii ``radii`` (m) for each field (T).

    Returns {"radius": (M,), "pressure": (F, M), "tip_force_ideal": (F, M), "tip_force": (F, M)}.
    """
    radii = np.asarray(radii, dtype=float)
    fields = np.asarray(fields, dtype=float)
    m = model_at_stretch
    return {
        "radius": radii,
        "pressure": np.array([m.pressure(radii, B) for B in fields]),
        "tip_force_ideal": np.array([m.tip_force_ideal(radii, B) for B in fields]),
        "tip_force": np.array([m.tip_force(radii, B) for B in fields]),
    }


def write_report(design, out) -> dict:
    """Curves (CSV, PNG) and the pressure-free growth summary (JSON) of an
    :class:`~magsoro.actuation.config.EversionDesign` into folder ``out``; returns the summary dict."""
    import csv
    import json
    from pathlib import Path

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    pl = design.plot
    plot_model = design.model(pl.axial_stretch)
    A, B = plot_model.inner_radius, plot_model.outer_radius
    lo = pl.radius_min if pl.radius_min is not None else 0.5 * A
    hi = pl.radius_max if pl.radius_max is not None else 1.5 * B
    radii = np.linspace(lo, hi, pl.points)
    c = curves(plot_model, pl.fields, radii)

    header = ["a_m"]
    for B0 in pl.fields:
        tag = f"{1e3 * B0:g}mT"
        header += [f"P_Pa_{tag}", f"N_ideal_N_{tag}", f"N_N_{tag}"]
    with (out / "eversion.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i, a in enumerate(radii):
            row = [f"{a:.9e}"]
            for k in range(len(pl.fields)):
                row += [f"{c['pressure'][k, i]:.9e}", f"{c['tip_force_ideal'][k, i]:.9e}", f"{c['tip_force'][k, i]:.9e}"]
            w.writerow(row)

    op = design.operating
    model = design.model()
    a0 = model.pressure_free_radius()
    a_op = model.operating_radius(op.contact_radius)
    b_min = model.minimum_growth_field(op.required_tip_force, op.bend_angle, op.contact_radius, op.max_field)
    from dataclasses import replace

    frictionless = replace(model, friction=replace(model.friction, friction_coefficient=0.0))
    b_min_0 = frictionless.minimum_growth_field(op.required_tip_force, op.bend_angle, op.contact_radius, op.max_field)
    summary = {
        "design": design.name,
        "reference_radii_m": [A, B],
        "axial_stretch": model.axial_stretch,
        "pressure_free_radius_m": a0,
        "operating_radius_m": a_op,
        "contact_pressure_Pa": float(model.pressure(a_op, 0.0)),
        "pressure_free_tip_force_at_zero_field_N": float(model.pressure_free_tip_force(0.0, op.bend_angle, op.contact_radius)),
        "required_tip_force_N": op.required_tip_force,
        "bend_angle_rad": op.bend_angle,
        "minimum_growth_field_T": b_min,
        "minimum_growth_field_without_friction_T": b_min_0,
        "max_field_searched_T": op.max_field,
        "remanence_T": model.remanence,
        "magnetization_follows": model.magnetization_follows,
        "flip_force_per_tesla_N_per_T": model.flip_force_per_tesla(),
        "perimeter_factor": model.friction.perimeter_factor,
        "capstan_factor": model.friction.capstan_factor,
        "files": ["eversion.csv", "eversion.png", "summary.json"],
    }
    for front in ("full", "gap"):
        summary[f"growth_pressure_{front}_front_Pa"] = model.growth_pressure(0.0, op.bend_angle, op.required_tip_force, front)
    if op.measured_growth_field is not None:
        summary["measured_growth_field_T"] = op.measured_growth_field
        summary["implied_friction_coefficient"] = model.friction_coefficient_for_growth_field(
            op.measured_growth_field, op.required_tip_force, op.bend_angle, op.contact_radius)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for k, B0 in enumerate(pl.fields):
        label = f"|B| = {1e3 * B0:g} mT"
        axes[0].plot(1e3 * radii, 1e-3 * c["pressure"][k], label=label)
        axes[1].plot(1e3 * radii, 1e3 * c["tip_force"][k], label=label)
    for ax in axes:
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.axvline(1e3 * A, color="0.8", lw=0.8, ls=":")
        ax.axvline(1e3 * B, color="0.8", lw=0.8, ls=":")
        ax.set_xlabel("everted inner radius a [mm]")
        ax.legend(fontsize=8)
    axes[0].set_ylabel("pressure P [kPa] (eq 10)")
    axes[1].set_ylabel("tip force N [mN] (eqs 11-12)")
    fig.suptitle(f"{design.name or 'eversion'}: B/A = {B / A:.4g}, lambda_z = {pl.axial_stretch:g}")
    fig.tight_layout()
    fig.savefig(out / "eversion.png", dpi=120)
    plt.close(fig)
    return summary
