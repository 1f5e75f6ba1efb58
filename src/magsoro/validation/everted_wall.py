"""The everted wall of seed 004's growing robot in MPM: eq 10 of the reduced model (magsoro.actuation.eversion).

Eq 10 is the radial equilibrium of a tube turned inside out: the material at reference radius R (A <= R <= B) sits
at r^2 = a^2 + (B^2 - R^2) / lambda_z, hoop stretch r / R, and the pressure P(a) on the bore a holds it there.
At lambda_z = 1 (no axial stretch) a cross-section of that tube is a plane-strain ring, which is what the MPM
checks here, at the robot's geometry (A = 0.8 mm, B = 0.9 mm) and material (dragon-skin-10-ndfeb100, G = 120 kPa,
the engine's Neo-Hookean with K = 20 G).

The everted state cannot be reached in plane strain by deforming a ring (turning it inside out needs the third
dimension), so the ring is built in its everted shape, bore ``a_i``, and each particle starts with the
deformation gradient of the eversion instead of the identity: F0 = lambda_r e_r e_r + lambda_theta e_t e_t with
lambda_theta = r / R and lambda_r = R / r (the radial reflection of dr/dR < 0 dropped: the stress depends on
F F^T only, and det F0 = 1 keeps the lattice volumes as reference volumes). The ring then settles (grid
damping) to its equilibrium under F = F_inc F0.

Checks:

1. *Free wall*: with nothing inside, the ring settles where P = 0, the pressure-free radius a0 of eq 10 (0.8041 mm:
   narrower than the uneverted tail, B = 0.9 mm, which is why the reduced model rests the wall on the tail).
   The bore is read by fitting the eversion map to the particles: a^2 = mean(r_p^2 + R_p^2 - B^2).
2. *Wall on the tail*: a rigid, frictionless disc of radius B inside (a ``sphere`` collider; the tail of the
   pressure-free robot) holds the bore at about B, and the pressure the wall presses it with follows from the
   particles' stresses by the ring's exact radial equilibrium, P a = int_a^b sigma_tt dr (no load outside),
   int sigma_tt dr = sum_p sigma_tt,p A_p / (2 pi r_p) over the particles' current areas A_p. References: eq 10
   at the fitted bore, and :func:`everted_ring_pressure`, the same plane-strain law as the engine's (compressible,
   K = 20 G) along the radius in linear elements, energy minimised by Newton's method with the bore held; with
   K / G = 1e4 the radial model gives eq 10 to 1e-4, so eq 10 is the incompressible limit of the engine's law
   and the K = 20 G material presses 3.5 % less at the same bore.

Measured (float32, two-core CPU, ``magsoro validate everted_wall``, 211 s in all): free wall, 4 cells through the wall:
0.80481 mm against 0.80410 (+0.09 %, 11 s); wall on the tail, 8 cells through the wall (13.7k particles, 62 s):
P = 4480 Pa at a = 0.9049 mm, -5.9 % from the radial model (4760 Pa) and -9.2 % from eq 10 (4934 Pa); at 4 cells
-9.0 % and -12 %. The contact acts on grid nodes up to 1.5 cells inside the wall and P(a) is steep (5 kPa per
0.1 mm here), so the resolution shows. Pressed further open, to a = 1.0 mm, the MPM falls 15 % (8 cells) to
19 % (4 cells) below the radial model (dynamic relaxation, measured while building this case): the everted
wall's pressure is a small residual of hoop stresses of both signs (compressive on the bore, tensile outside:
the wall is bent inside out), which MPM resolves slowly through four to eight cells.

3D (:func:`everted_wedge_scene`): a quarter of the tube between four symmetry planes (``mode = "symmetry"``: the
two sides through the axis hold its axisymmetry, the two ends its axial stretch), each particle starting with
the 3D eversion F0 = -lambda_r e_r e_r + lambda_theta e_t e_t - lambda_z e_z e_z (det 1; the axial flip is what
reverses an axial remanence, the flip term of the reduced model). Free at lambda_z = 0.9 and 1.2 it settles at eq
10's a0(lambda_z) to -0.38 % and +0.64 % (4 cells through the wall, built two cells wider than a0, 5.7-7.6k
particles, 58-75 s each; built at 0.80 mm instead, -0.80 % and +0.49 %: the settled bore depends on the start
by half a per cent), near the compressible radial model's -0.28 % and +0.47 %; the plane-strain ring cannot
check lambda_z.

The eversion itself (material turning round the front, the tail sliding inside) is not simulated here.
"""

from __future__ import annotations

import math
import time

import numpy as np

from magsoro.validation.pressure import law_stretch_derivatives, newton_minimise
from magsoro.validation.registry import CaseResult, Context, Row, register, relative_error

#: Seed 004's robot: reference radii (m) and the material library entry of its wall.
A_REF, B_REF = 0.8e-3, 0.9e-3
MATERIAL = "dragon-skin-10-ndfeb100"
#: Grid damping (1/s) and settling time (s): the ring's breathing mode (period about 0.1 ms) is overdamped and the
#: bore's creep over the last fifth of the time is reported (``drift_m``).
DAMPING, SETTLE = 2000.0, 6e-3
#: Angle of the 3D wedge (degrees): a quarter, so that both symmetry planes lie on grid planes (a slanted plane
#: holds only its staircase of nodes and lets the bent wall's cut face turn: a 30 degree wedge settled 10 % narrow).
WEDGE_DEG = 90.0
#: Axial stretches of the 3D checks (the plane-strain ring covers lambda_z = 1).
WEDGE_STRETCHES = (0.9, 1.2)


def everted_ring_scene(bore: float, dx: float, tail_radius: float | None = None, A: float = A_REF,
                       B: float = B_REF, precision: str = "float32", damping: float = DAMPING,
                       duration: float = SETTLE) -> dict:
    """Scene dict of the everted ring built with bore ``bore`` (m): the outer radius keeps the wall's area,
    b^2 = bore^2 + B^2 - A^2. ``tail_radius``: a rigid frictionless disc inside (m), or None. Grid damping
    ``damping`` (1/s) settles it over ``duration`` (s)."""
    b = math.sqrt(bore * bore + B * B - A * A)
    half = b + 4 * dx
    scene = {
        "name": "everted wall (seed 004, plane strain, lambda_z = 1)",
        "simulation": {"dim": 2, "dx": dx, "particles_per_cell": 2, "domain_lo": [-half, -half],
                       "domain_hi": [half, half], "duration": duration, "damping": damping, "formulation": "updated",
                       "precision": precision},
        "bodies": [{"name": "wall", "material": MATERIAL,
                    "shape": {"type": "arc", "center": [0.0, 0.0], "radius": 0.5 * (bore + b), "width": b - bore,
                              "start_angle": 0.0, "end_angle": 360.0}}],
        "output": {"particles": False},
    }
    if tail_radius is not None:
        scene["colliders"] = [{"type": "sphere", "center": [0.0, 0.0], "radius": tail_radius}]
    return scene


def eversion_deformation(X: np.ndarray, bore: float, A: float = A_REF, B: float = B_REF):
    """(F0 (n, 2, 2), R (n,)): the eversion's deformation gradient at particles ``X`` (n, 2) of the ring built with
    bore ``bore`` (lambda_z = 1, the radial reflection dropped) and their reference radii R, m."""
    r = np.hypot(X[:, 0], X[:, 1])
    phi = np.arctan2(X[:, 1], X[:, 0])
    R = np.sqrt(B * B + bore * bore - r * r)
    lr, lt = R / r, r / R
    c, s = np.cos(phi), np.sin(phi)
    F0 = np.empty((len(r), 2, 2))
    F0[:, 0, 0] = lr * c * c + lt * s * s
    F0[:, 1, 1] = lr * s * s + lt * c * c
    F0[:, 0, 1] = F0[:, 1, 0] = (lr - lt) * c * s
    return F0, R


def everted_ring_pressure(a: float, shear: float, bulk: float, A: float = A_REF, B: float = B_REF,
                          n: int = 200, axial_stretch: float = 1.0) -> float:
    """Pressure (Pa) on the bore that holds an everted plane-strain ring (reference radii A < B; the reference
    inner surface R = A outside) at bore ``a`` (m), for the engine's Neo-Hookean law W = G/2 (J^-2/3 I1 - 3) +
    K/2 (J - 1)^2 with F_zz = 1: ``n`` linear elements along the reference radius, their current radii
    decreasing in R, the node R = B held at r = a, the energy minimised by Newton's method (Hessian by central
    differences of the analytic gradient); P = (dE/dr_a) / (2 pi a lambda_z), the reaction on the held node per unit
    of current length. With
    ``axial_stretch`` lambda_z the wall is held at that stretch along the axis (F_zz = lambda_z)."""
    lz = float(axial_stretch)
    R = np.linspace(A, B, n + 1) / a  # in units of a
    Rm, dR = 0.5 * (R[1:] + R[:-1]), np.diff(R)
    k = bulk / shear
    w = 2.0 * np.pi * Rm * dR

    def gradient(r):
        l1 = -np.diff(r) / dR  # radial stretch |dr/dR|
        l2 = 0.5 * (r[1:] + r[:-1]) / Rm  # hoop stretch
        dW_dl1, dW_dl2 = law_stretch_derivatives(l1, l2, lz, k)
        g = np.zeros_like(r)
        c1 = dW_dl1 * w / dR  # dl1/dr_{i+1} = -1/dR, dl1/dr_i = +1/dR
        g[1:] -= c1
        g[:-1] += c1
        c2 = dW_dl2 * w * 0.5 / Rm
        g[1:] += c2
        g[:-1] += c2
        return g

    r = np.sqrt(1.0 + (R[-1] ** 2 - R**2) / lz)  # the incompressible map as the start, bore 1
    r = newton_minimise(gradient, r, free=len(r) - 1, iterations=60)  # the bore's node held
    return float(shear * gradient(r)[-1] / (2.0 * np.pi * lz))  # per unit current length: lambda_z


def run_everted_ring(bore: float, dx: float, tail_radius: float | None = None, settle: float = SETTLE) -> dict:
    """Build, settle (grid damping over ``settle`` s) and measure the everted ring (module docstring): the
    fitted bore a (m) and its change over the last fifth of the time, the pressure on it from the particles'
    stresses (Pa), the run's facts."""
    from magsoro.robots.tail_pull import cauchy_stress
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(everted_ring_scene(bore, dx, tail_radius, duration=settle), "everted_wall"))
    X = sim.model.host["positions"][:, :2].astype(np.float64)
    F0, R = eversion_deformation(X, bore)
    a, a_before, wall_s = _settle(sim, F0, R, 1.0, settle)
    x = sim.state.x.numpy()[:, :2].astype(np.float64)
    r = np.hypot(x[:, 0], x[:, 1])
    sigma = cauchy_stress(sim)
    F = sim.state.F.numpy().astype(np.float64)
    area = np.linalg.det(F) * sim.model.host["volumes"] / sim.scene.simulation.depth
    tx, ty = -x[:, 1] / r, x[:, 0] / r
    s_tt = tx * tx * sigma[:, 0, 0] + 2 * tx * ty * sigma[:, 0, 1] + ty * ty * sigma[:, 1, 1]
    pressure = float(np.sum(s_tt * area / r) / (2.0 * math.pi) / a)
    return {"bore_m": a, "drift_m": a - a_before, "pressure_Pa": pressure, "particles": int(len(X)),
            "steps": int(sim.steps), "wall_s": wall_s, "dx_m": dx,
            "innermost_radius_m": float(r.min()), "outermost_radius_m": float(r.max())}


def everted_wedge_scene(bore: float, dx: float, axial_stretch: float = 1.0, alpha: float = WEDGE_DEG,
                        height: float | None = None, A: float = A_REF, B: float = B_REF,
                        duration: float = SETTLE) -> dict:
    """Scene dict of a 3D wedge of the everted tube (an annular sector of ``alpha`` degrees and ``height`` m along
    the axis, bore ``bore``, outer radius from b^2 = bore^2 + (B^2 - A^2) / lambda_z) between four symmetry planes:
    the sector's two sides (the tube's axisymmetry) and its two ends (the axial stretch held at lambda_z); grid
    damping settles it over ``duration`` (s)."""
    b = math.sqrt(bore * bore + (B * B - A * A) / axial_stretch)
    H = 4 * dx if height is None else height
    sa, ca = math.sin(math.radians(alpha)), math.cos(math.radians(alpha))
    planes = [([0, 0, 0], [0, 1, 0]), ([0, 0, 0], [sa, -ca, 0]), ([0, 0, 0], [0, 0, 1]), ([0, 0, H], [0, 0, -1])]
    return {
        "name": "everted wall, 3D wedge",
        "simulation": {"dim": 3, "dx": dx, "particles_per_cell": 2, "domain_lo": [-3 * dx, -3 * dx, -3 * dx],
                       "domain_hi": [b + 3 * dx, b + 3 * dx, H + 3 * dx], "duration": duration, "damping": DAMPING,
                       "formulation": "updated"},
        "bodies": [{"name": "wall", "material": MATERIAL,
                    "shape": {"type": "arc", "center": [0.0, 0.0, 0.5 * H], "radius": 0.5 * (bore + b),
                              "width": b - bore, "start_angle": 0.0, "end_angle": alpha, "thickness": H}}],
        "colliders": [{"type": "half_space", "point": p, "normal": n, "mode": "symmetry"} for p, n in planes],
        "output": {"particles": False},
    }


def eversion_deformation_3d(X: np.ndarray, bore: float, axial_stretch: float = 1.0, A: float = A_REF,
                            B: float = B_REF):
    """(F0 (n, 3, 3), R (n,)): the eversion's deformation gradient in 3D at particles ``X`` (n, 3) of the tube
    built with bore ``bore``: F0 = -lambda_r e_r e_r + lambda_theta e_t e_t - lambda_z e_z e_z (det 1: the wall is
    turned inside out, dr/dR < 0, and back along the axis), lambda_theta = r / R, lambda_r = R / (lambda_z r),
    R^2 = B^2 - lambda_z (r^2 - bore^2)."""
    lz = axial_stretch
    r = np.hypot(X[:, 0], X[:, 1])
    th = np.arctan2(X[:, 1], X[:, 0])
    R = np.sqrt(B * B - lz * (r * r - bore * bore))
    er = np.stack([np.cos(th), np.sin(th), np.zeros_like(th)], axis=1)
    et = np.stack([-np.sin(th), np.cos(th), np.zeros_like(th)], axis=1)
    ez = np.zeros_like(er)
    ez[:, 2] = 1.0
    outer = lambda u, c: c[:, None, None] * np.einsum("ni,nj->nij", u, u)  # noqa: E731
    F0 = outer(er, -R / (lz * r)) + outer(et, r / R) + outer(ez, np.full(len(r), -lz))
    return F0, R


def run_everted_wedge(bore: float, dx: float, axial_stretch: float = 1.0, settle: float = SETTLE) -> dict:
    """Settle the 3D wedge of the free everted tube (:func:`everted_wedge_scene`) and fit its bore (m), as
    :func:`run_everted_ring` does for the plane-strain ring."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    lz = axial_stretch
    sim = Simulation(parse_scene(everted_wedge_scene(bore, dx, lz, duration=settle), "everted_wall"))
    X = sim.model.host["positions"].astype(np.float64)
    F0, R = eversion_deformation_3d(X, bore, lz)
    a, a_before, wall_s = _settle(sim, F0, R, lz, settle)
    return {"bore_m": a, "drift_m": a - a_before, "axial_stretch": lz, "particles": int(len(X)),
            "steps": int(sim.steps), "wall_s": wall_s, "dx_m": dx}


def _settle(sim, F0: np.ndarray, R: np.ndarray, axial_stretch: float, settle: float) -> tuple[float, float, float]:
    """Start ``sim``'s particles at the eversion's deformation gradient ``F0``, settle them over ``settle`` s and
    fit the bore to the eversion map, a^2 = mean(r^2 + (R^2 - B^2) / lambda_z) over the particles' current radii r
    and reference radii R: (a at the end, a at 0.8 settle, m; wall time, s)."""

    def fitted_bore():
        x = sim.state.x.numpy().astype(np.float64)
        return math.sqrt(float(np.mean(x[:, 0] ** 2 + x[:, 1] ** 2 + (R * R - B_REF**2) / axial_stretch)))

    sim.state.F.assign(F0.astype(sim.model.np_scalar))
    t0 = time.perf_counter()
    sim.advance_to(0.8 * settle)
    a_before = fitted_bore()
    sim.advance_to(settle)
    return fitted_bore(), a_before, round(time.perf_counter() - t0, 1)


@register("everted_wall", "seed 004's everted wall (plane strain, lambda_z = 1) in MPM against eq 10: the free "
          "wall's radius, and the pressure on the tail it rests on", quick=False, cost="~4 min")
def everted_wall(ctx: Context) -> CaseResult:
    from magsoro.actuation.eversion import EversionModel
    from magsoro.materials.library import get_material

    G = get_material(MATERIAL).shear_modulus
    model = EversionModel(A_REF, B_REF, G)
    a0 = model.pressure_free_radius()
    inputs = {"A_m": A_REF, "B_m": B_REF, "shear_modulus_Pa": G, "bulk_over_shear": 20.0}
    # 1. free wall, 4 cells through the wall, built 2 cells wider than a0
    dx_free = 25e-6
    free = run_everted_ring(0.85e-3, dx_free)
    ctx.log(f"  free wall: a = {free['bore_m'] * 1e3:.5f} mm (eq 10: {a0 * 1e3:.5f}), {free['wall_s']} s")
    # 2. wall on the tail (radius B), 8 cells through the wall, built half a cell off the tail
    dx_tail = 12.5e-6
    tail = run_everted_ring(B_REF + 0.5 * dx_tail, dx_tail, tail_radius=B_REF)
    a = tail["bore_m"]
    p_radial = everted_ring_pressure(a, G, 20.0 * G)
    p_eq10 = float(model.pressure(a))
    ctx.log(f"  wall on the tail: a = {a * 1e3:.5f} mm, P = {tail['pressure_Pa']:.1f} Pa (radial model "
            f"{p_radial:.1f}, eq 10 {p_eq10:.1f}), {tail['wall_s']} s")
    # 3. eq 10 is the incompressible limit of the engine's law (independent radial model, K / G = 1e4)
    p_limit = everted_ring_pressure(B_REF, G, 1e4 * G)
    # 4. 3D, a quarter of the tube between symmetry planes, held at an axial stretch: eq 10's a0(lambda_z)
    wedges = {}
    for lz in WEDGE_STRETCHES:  # built two cells wider than a0(lambda_z), as the ring above
        a0_lz = EversionModel(A_REF, B_REF, G, axial_stretch=lz).pressure_free_radius()
        wedges[lz] = run_everted_wedge(a0_lz + 2 * dx_free, dx_free, lz)
        ctx.log(f"  3D quarter, lambda_z = {lz:g}: a = {wedges[lz]['bore_m'] * 1e3:.5f} mm (eq 10: "
                f"{EversionModel(A_REF, B_REF, G, axial_stretch=lz).pressure_free_radius() * 1e3:.5f}), "
                f"{wedges[lz]['wall_s']} s")
    rows = [
        Row("everted_wall", "free_wall_bore_m", {**inputs, "dx_m": dx_free}, a0, free["bore_m"],
            relative_error(free["bore_m"], a0), 0.01),
        Row("everted_wall", "pressure_on_tail_Pa_vs_same_law_radial_model", {**inputs, "dx_m": dx_tail}, p_radial,
            tail["pressure_Pa"], relative_error(tail["pressure_Pa"], p_radial), 0.10),
        Row("everted_wall", "pressure_on_tail_Pa_vs_eq10", {**inputs, "dx_m": dx_tail}, p_eq10,
            tail["pressure_Pa"], relative_error(tail["pressure_Pa"], p_eq10), 0.10),
        Row("everted_wall", "radial_model_incompressible_limit_Pa_vs_eq10", {**inputs, "bulk_over_shear": 1e4},
            float(model.pressure(B_REF)), p_limit, relative_error(p_limit, float(model.pressure(B_REF))), 1e-3),
    ]
    for lz, w in wedges.items():
        a0_lz = EversionModel(A_REF, B_REF, G, axial_stretch=lz).pressure_free_radius()
        rows.append(Row("everted_wall", "free_wall_bore_3d_quarter_m", {**inputs, "dx_m": dx_free, "axial_stretch": lz},
                        a0_lz, w["bore_m"], relative_error(w["bore_m"], a0_lz), 0.02))
    return CaseResult("everted_wall", rows, [], info={"free_wall": free, "wall_on_tail": tail,
                                                      "quarters_3d": {str(k): v for k, v in wedges.items()},
                                                      "pressure_free_radius_eq10_m": a0,
                                                      "radial_model_K20G_Pa": p_radial, "eq10_Pa": p_eq10})
