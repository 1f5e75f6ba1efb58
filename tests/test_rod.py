"""Checks of magsoro.rod against closed forms and an independent elastica solver.

Conventions used below: the default clamp puts the rod axis d3 along +x, the width d1 along +y and the
thickness d2 along +z, so bending through the thickness is rotation about y with stiffness E*I1,
I1 = width * thickness**3 / 12. A remanence (0, 0, Br) is axial.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_bvp
from scipy.optimize import brentq
from scipy.special import ellipk

from magsoro import MU0, MagsoroError, SceneError, SimulationError
from magsoro.rod import CrossSection, MagnetSegment, Rod
from magsoro.rod.config import load_rod_config, parse_rod_config
from magsoro.rod.output import read_centreline_csv

# Zhao et al. (JMPS 2019) hard-magnetic beam
ZHAO_L, ZHAO_W, ZHAO_T = 17.2e-3, 5.0e-3, 0.84e-3  # m
ZHAO_G, ZHAO_BR = 303e3, 0.258  # Pa, T


def zhao_rod(shear_modulus=ZHAO_G, remanence=ZHAO_BR, length=ZHAO_L, thickness=ZHAO_T, width=ZHAO_W):
    # incompressible elastomer: E = 3 G (also the default G = E/3 of Rod)
    return Rod(length, CrossSection.rectangle(width, thickness), 3.0 * shear_modulus,
               magnetisation=(0.0, 0.0, remanence))


def field_for(normalised, shear_modulus=ZHAO_G, remanence=ZHAO_BR):
    """Field B (T) along +z for a normalised field Br*B/(mu0*G)."""
    return np.array([0.0, 0.0, normalised * MU0 * shear_modulus / remanence])


def planar_elastica(k2_values, phi):
    """Independent reference: tangent angle theta(s) of a Kirchhoff cantilever carrying the couple of an
    axially magnetised rod in a uniform in-plane field at angle phi from the undeformed axis.

    Moment balance of a planar rod without distributed force: m' + l = 0 with m = E I theta' and the magnetic
    couple l = A (Br/mu0) B sin(phi - theta) (|t x B|, signed), so in s/L

        theta'' = -k^2 sin(phi - theta),  k^2 = A Br B L^2 / (mu0 E I),  theta(0) = 0,  theta'(1) = 0,

    integrated with the tip position x' = cos theta, z' = sin theta by scipy's collocation solver solve_bvp
    (the rod module uses RK4 shooting on the full 3D Cosserat equations). Returns the tip (x, z)/L per k^2,
    continuing each solution from the previous one.
    """
    s = np.linspace(0.0, 1.0, 101)
    y = np.zeros((4, s.size))
    y[2] = s
    tips = []
    for k2 in k2_values:
        def rhs(_, y, k2=k2):
            return np.vstack([y[1], -k2 * np.sin(phi - y[0]), np.cos(y[0]), np.sin(y[0])])

        def bc(a, b):
            return np.array([a[0], b[1], a[2], a[3]])

        sol = solve_bvp(rhs, bc, s, y, tol=1e-10, max_nodes=200_000)
        assert sol.success, sol.message
        s, y = sol.x, sol.y
        tips.append((y[2, -1], y[3, -1]))
    return np.array(tips)


# --------------------------------------------------------------------------------------------------------------
# (1) closed forms


def test_end_moment_bends_rod_into_circular_arc():
    """A pure end moment M about d1 gives a constant internal moment, hence constant curvature k = M/(E I1):
    the centreline is a circular arc, tip = (sin(kL)/k, 0, -(1 - cos kL)/k) for M along +y (rotation of +x
    about +y turns it towards -z). Exact for the Kirchhoff rod at any k; here kL = 1.5 rad (86 degrees)."""
    L, E = 0.05, 1.0e6
    cs = CrossSection.rectangle(4e-3, 1e-3)
    ei = E * cs.second_moment[0]
    k = 1.5 / L
    sol = Rod(L, cs, E, tip_moment=(0.0, k * ei, 0.0)).solve()
    expected = np.array([np.sin(k * L) / k, 0.0, -(1.0 - np.cos(k * L)) / k])
    # integration error of RK4 at h = L/100 on a circle is ~1e-9 L (measured 4e-10 L)
    assert np.abs(sol.tip_position - expected).max() < 1e-6 * L
    assert np.allclose(sol.internal_moment, [0.0, k * ei, 0.0], atol=1e-9 * k * ei)
    # tip tangent turned by kL about y
    assert np.allclose(sol.tangents[-1], [np.cos(k * L), 0.0, -np.sin(k * L)], atol=1e-7)


def test_oblique_end_moment_on_round_rod_gives_helix():
    """For an isotropic section (E I1 = E I2) a constant internal moment m makes the tangent precess about m:
    t' = m x t / (E I), so t rotates about m^ at rate w = |m|/(E I), whatever the torsional stiffness. With
    t0 = e_x split into t_par = (m^.t0) m^ and t_perp, the tip is
        p(L) = t_par L + t_perp sin(wL)/w + (m^ x t0)(1 - cos wL)/w.
    This exercises the full 3D rotation integration (bending about both axes plus twist)."""
    L, E, d = 0.05, 1.0e6, 1.0e-3
    cs = CrossSection.circle(d)
    ei = E * cs.second_moment[0]
    direction = np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])
    moment = direction * 2.0 * ei / L  # w L = 2 rad
    sol = Rod(L, cs, E, tip_moment=moment).solve()
    w = 2.0 / L
    t0 = np.array([1.0, 0.0, 0.0])
    t_par = direction * (direction @ t0)
    expected = t_par * L + (t0 - t_par) * np.sin(w * L) / w + np.cross(direction, t0) * (1.0 - np.cos(w * L)) / w
    assert np.abs(sol.tip_position - expected).max() < 1e-6 * L  # measured 1.3e-9 L
    # orientations stay rotations
    R = sol.rotations
    assert np.abs(np.einsum("kji,kjl->kil", R, R) - np.eye(3)).max() < 1e-8


def test_small_field_magnetic_cantilever_matches_linear_beam_theory():
    """Axially magnetised strip, field B along +z (perpendicular), small deflection.

    The magnetic couple per length is l = A (R Br/mu0) x B; with the tangent at angle theta from x,
    |l| = c cos(theta), c = A Br B / mu0, about -y. Linearising (cos theta ~ 1) the couple is uniform, so the
    moment balance m' = -l with m(L) = 0 gives m(s) = c (L - s), curvature kappa = c (L - s)/(E I) and

        w(L) = int_0^L (L - s) kappa(s) ds = c L^3 / (3 E I),    theta(L) = c L^2 / (2 E I).

    With theta(L) = 0.01 rad the neglected terms are O(theta^2) ~ 1e-4, far inside the 0.5% asked.
    """
    L, E, Br = 0.05, 1.0e6, 0.1
    cs = CrossSection.rectangle(4e-3, 1e-3)
    ei = E * cs.second_moment[0]
    tip_angle = 0.01
    B = tip_angle * 2.0 * ei * MU0 / (cs.area * Br * L**2)
    sol = Rod(L, cs, E, magnetisation=(0.0, 0.0, Br)).solve((0.0, 0.0, B))
    c = cs.area * Br * B / MU0
    w_ref = c * L**3 / (3.0 * ei)
    assert sol.tip_position[2] == pytest.approx(w_ref, rel=5e-3)  # measured -4.6e-5
    # the clamp balances the whole magnetic couple, c L about -y, with c L about +y (to first order)
    assert sol.clamp_moment[1] == pytest.approx(c * L, rel=5e-3)


def test_segmented_magnetisation_matches_linear_theory():
    """Only a < s < L magnetised (axially), small perpendicular field. Linear theory as above with the couple
    c on [a, L] only: m(s) = c (L - max(s, a)), so
        w(L) = (c / E I) [ (L - a)(L a - a^2 / 2) + (L - a)^3 / 3 ].
    a = 0.373 L is not a uniform node: the segment end must become one. A callable profile of the same shape
    (the jump then falls inside an RK4 step) agrees to first order in the step."""
    L, E, Br, a = 0.05, 1.0e6, 0.1, 0.373 * 0.05
    cs = CrossSection.rectangle(4e-3, 1e-3)
    ei = E * cs.second_moment[0]
    B = 0.01 * 2.0 * ei * MU0 / (cs.area * Br * L**2)
    rod = Rod(L, cs, E, magnetisation=[MagnetSegment(a, L, (0.0, 0.0, Br))])
    assert np.any(np.isclose(rod.solve((0.0, 0.0, B)).s, a, rtol=0, atol=1e-15))
    sol = rod.solve((0.0, 0.0, B))
    c = cs.area * Br * B / MU0
    w_ref = c / ei * ((L - a) * (L * a - a**2 / 2) + (L - a) ** 3 / 3)
    assert sol.tip_position[2] == pytest.approx(w_ref, rel=5e-3)  # measured -3.7e-5
    as_callable = Rod(L, cs, E, magnetisation=lambda s: (0.0, 0.0, Br if s >= a else 0.0)).solve((0.0, 0.0, B))
    assert as_callable.tip_position[2] == pytest.approx(sol.tip_position[2], rel=1e-2)


def test_gravity_cantilever_matches_euler_bernoulli():
    """Weight q = rho A g per length on a horizontal cantilever: w(L) = q L^4 / (8 E I) (Euler-Bernoulli).
    Parameters give w/L ~ 1.6e-3, so geometric nonlinearity is ~1e-6 relative."""
    L, E, rho = 0.02, 2.0e7, 1100.0
    cs = CrossSection.rectangle(5e-3, 2e-3)
    ei = E * cs.second_moment[0]
    sol = Rod(L, cs, E, density=rho).solve()
    q = rho * cs.area * 9.81
    w_ref = q * L**4 / (8.0 * ei)
    assert w_ref / L < 2e-3
    assert -sol.tip_position[2] == pytest.approx(w_ref, rel=1e-2)  # measured -2.1e-6
    # the clamp carries the whole weight
    assert sol.clamp_force == pytest.approx([0.0, 0.0, q * L], rel=1e-9, abs=1e-15)


def test_extensible_rod_stretches_and_shears_as_timoshenko():
    """Extensible option: an axial tip force F stretches the rod by F L/(E A) (exact, n uniform); a transverse
    tip force gives the Timoshenko deflection F L^3/(3 E I) + F L/(kappa G A) to first order."""
    L, E = 0.012, 1.0e6
    cs = CrossSection.rectangle(4e-3, 2e-3)  # stubby (L/t = 6), so shear adds 2.5% to the deflection
    F = 0.05
    sol = Rod(L, cs, E, tip_force=(F, 0.0, 0.0), extensible=True).solve()
    assert sol.tip_position[0] - L == pytest.approx(F * L / (E * cs.area), rel=1e-9)
    ei = E * cs.second_moment[0]
    F = 1e-3 * 3 * ei / L**2  # bending deflection 1e-3 L
    rod = Rod(L, cs, E, tip_force=(0.0, 0.0, F), extensible=True)
    w_ref = F * L**3 / (3 * ei) + F * L / (cs.shear_coefficient * rod.shear_modulus * cs.area)
    assert rod.solve().tip_position[2] == pytest.approx(w_ref, rel=5e-3)  # measured -1.0e-6
    # the Kirchhoff default misses exactly the shear part
    kirchhoff = Rod(L, cs, E, tip_force=(0.0, 0.0, F)).solve().tip_position[2]
    assert kirchhoff == pytest.approx(F * L**3 / (3 * ei), rel=5e-3)
    assert w_ref / kirchhoff - 1 > 0.02


def general_3d_rod(**overrides):
    """Rectangular strip with two differently magnetised halves, weight and a sideways tip force."""
    kwargs = dict(
        magnetisation=[MagnetSegment(0.0, 0.02, (0.05, 0.0, 0.1)), MagnetSegment(0.02, 0.05, (0.0, 0.08, -0.05))],
        density=1500.0, tip_force=(0.0, 1e-4, 0.0))
    kwargs.update(overrides)
    return Rod(0.05, CrossSection.rectangle(4e-3, 1e-3), 1.0e6, **kwargs)


GENERAL_FIELD = np.array([0.01, 0.02, -0.015])  # T; load A |Br| |B| L^2 / (mu0 E I1) ~ 50


def test_general_3d_solution_satisfies_the_cosserat_equations():
    """A 3D case with bending about both axes, twist, weight, a tip force and a jump in Br: the returned arrays
    must satisfy the equations they claim, checked with independent quadratures of the output:
    * force balance n(s) = F + rho A g (L - s) (exact);
    * moment balance m(s) = M + int_s^L (p' x n + A (R Br/mu0) x B) ds' (midpoint rule, O(h^2): measured
      8e-5 of max |m| at 201 nodes, 2e-5 at 401);
    * constitutive law R^T R' = [K_bt^-1 R^T m]x (central differences, O(h^2): measured 4e-4 at 201 nodes,
      away from the kink in u' at the Br jump)."""
    rod = general_3d_rod(n_nodes=201)
    sol = rod.solve(GENERAL_FIELD)
    assert np.abs(sol.tip_position).max() > 0.5 * rod.length  # large 3D deflection
    assert np.ptp(sol.positions, axis=0).min() > 0.2 * rod.length  # genuinely out of plane
    s, R, n, m, t = sol.s, sol.rotations, sol.internal_force, sol.internal_moment, sol.tangents
    weight = rod.density * rod.cross_section.area * rod.gravity
    assert np.abs(n - (rod.tip_force + np.outer(rod.length - s, weight))).max() < 1e-15

    mid = 0.5 * (s[1:] + s[:-1])
    R_mid, t_mid, n_mid = 0.5 * (R[1:] + R[:-1]), 0.5 * (t[1:] + t[:-1]), 0.5 * (n[1:] + n[:-1])
    couple = rod.cross_section.area * np.cross(np.einsum("kij,kj->ki", R_mid, rod.magnetisation(mid)) / MU0,
                                               GENERAL_FIELD)
    increments = (np.cross(t_mid, n_mid) + couple) * np.diff(s)[:, None]
    from_tip = np.concatenate([np.cumsum(increments[::-1], axis=0)[::-1], np.zeros((1, 3))])
    assert np.abs(m - (rod.tip_moment + from_tip)).max() < 2.5e-4 * np.abs(m).max()

    dR = (R[2:] - R[:-2]) / (s[2:] - s[:-2])[:, None, None]
    U = np.einsum("kji,kjl->kil", R[1:-1], dR)
    u = np.stack([U[:, 2, 1], U[:, 0, 2], U[:, 1, 0]], axis=1)
    u_ref = np.einsum("kji,kj->ki", R[1:-1], m[1:-1]) / rod.bending_stiffness
    away = np.abs(s[1:-1] - 0.02) > 1e-9
    assert np.abs(u - u_ref)[away].max() < 1.5e-3 * np.abs(u_ref).max()
    assert np.abs(np.einsum("kji,kjl->kil", R, R) - np.eye(3)).max() < 1e-12
    assert np.all(np.linalg.det(R) > 0)


def test_rotating_the_whole_setup_rotates_the_solution():
    """Frame invariance: turning the clamp, the field, gravity and the tip force by the same rotation Q (and
    moving the clamp) turns and moves the equilibrium the same way."""
    Q = np.array([[0.36, 0.48, -0.8], [-0.8, 0.6, 0.0], [0.48, 0.64, 0.6]])  # a proper rotation
    offset = np.array([0.01, -0.02, 0.03])
    sol = general_3d_rod().solve(GENERAL_FIELD)
    turned = general_3d_rod(base_rotation=Q @ general_3d_rod().base_rotation, base_position=offset,
                            gravity=Q @ np.array([0.0, 0.0, -9.81]), tip_force=Q @ np.array([0.0, 1e-4, 0.0]))
    sol_q = turned.solve(Q @ GENERAL_FIELD)
    assert np.abs(sol_q.positions - (offset + sol.positions @ Q.T)).max() < 1e-9 * 0.05
    assert np.abs(sol_q.rotations - Q @ sol.rotations).max() < 1e-8


# --------------------------------------------------------------------------------------------------------------
# (2) large deflection against an independent elastica solution


def test_zhao_beam_large_deflection_matches_elastica():
    """Zhao beam (L = 17.2 mm, 5 x 0.84 mm, G = 303 kPa, E = 3G, Br = 0.258 T, axial) in a perpendicular field,
    normalised fields Br B/(mu0 G) up to 0.02, solved as one quasi-static sweep and compared with the planar
    elastica solved by collocation (planar_elastica). k^2 = A Br B L^2/(mu0 E I) = 4 (Br B/(mu0 G)) (L/t)^2."""
    normalised = np.array([0.0025, 0.005, 0.01, 0.015, 0.02])
    rod = zhao_rod()
    sweep = rod.sweep([field_for(nb) for nb in normalised])
    k2 = 4.0 * normalised * (ZHAO_L / ZHAO_T) ** 2
    ref = planar_elastica(k2, phi=np.pi / 2)
    for sol, (x_ref, z_ref), nb in zip(sweep, ref, normalised):
        tip = sol.tip_position / ZHAO_L
        # 1% would do; both solvers are converged far tighter (measured max 1.4e-8 L, at Br B/(mu0 G) = 0.02)
        assert abs(tip[0] - x_ref) < 1e-4 and abs(tip[2] - z_ref) < 1e-4, (nb, tip, x_ref, z_ref)
        assert abs(tip[1]) < 1e-12
    # the strongest field nearly aligns the tip with the field: a genuinely large deflection
    assert sweep[-1].tangents[-1][2] > 0.99
    # the clamp balances the total magnetic couple (there is no distributed force):
    # its moment is c int_0^L cos(theta) ds = c x(L) about +y, c = A Br B / mu0
    c = ZHAO_W * ZHAO_T * ZHAO_BR * field_for(0.02)[2] / MU0
    assert sweep[-1].clamp_moment[1] == pytest.approx(c * sweep[-1].tip_position[0], rel=1e-6)


def test_deflection_depends_only_on_normalised_field_and_slenderness():
    """In the Kirchhoff rod the shape scales with Br B/(mu0 G) and L/t only: multiplying G and Br by 3.7, or
    all lengths by 2.5 (and the width arbitrarily), leaves tip/L unchanged."""
    nb = 0.008
    base = zhao_rod().solve(field_for(nb)).tip_position / ZHAO_L
    scaled = zhao_rod(shear_modulus=3.7 * ZHAO_G, remanence=3.7 * ZHAO_BR).solve(
        field_for(nb, 3.7 * ZHAO_G, 3.7 * ZHAO_BR))
    assert field_for(nb, 3.7 * ZHAO_G, 3.7 * ZHAO_BR)[2] == pytest.approx(field_for(nb)[2])  # same B
    assert np.abs(scaled.tip_position / ZHAO_L - base).max() < 1e-6
    bigger = zhao_rod(length=2.5 * ZHAO_L, thickness=2.5 * ZHAO_T, width=1.3 * ZHAO_W).solve(field_for(nb))
    assert np.abs(bigger.tip_position / (2.5 * ZHAO_L) - base).max() < 1e-6
    # and a different slenderness does change it (so the checks above can fail)
    thinner = zhao_rod(thickness=0.8 * ZHAO_T).solve(field_for(nb))
    assert np.abs(thinner.tip_position / ZHAO_L - base).max() > 1e-2


# --------------------------------------------------------------------------------------------------------------
# branches: field opposite the magnetisation


def test_axial_magnetisation_in_uniform_field_is_a_dead_tip_force_and_shear_barely_matters():
    """A uniformly, axially magnetised strip in a uniform field stores -(Br A / mu0) B . (p(L) - p(0)): the
    same as a dead tip force Br A B / mu0. So the magnetised Kirchhoff rod and the unmagnetised rod with that
    tip force have the same equilibrium (checked on the Zhao beam in an opposite field at Br B/(mu0 G) = 0.012,
    tip turned by 171 deg). With the force formulation the extensible, shearable rod (E A, kappa G A) carries
    the real internal force; it moves the tip by under 1 % of L there (measured 0.6 % in x, < 0.1 % in z), so
    the Kirchhoff rod is a sound reference for the engine's opposite-field rows (docs/validation.md)."""
    L, t, w, G, Br = 17.2e-3, 0.84e-3, 5e-3, 303e3, 0.258
    E = 3.81 * G  # plane-strain modulus of the engine beam (K = 20 G)
    cs = CrossSection.rectangle(w, t)
    b = 0.012 * MU0 * G / Br
    F = Br * cs.area * b / MU0
    magnet = Rod(L, cs, E, shear_modulus=G, magnetisation=(0.0, 0.0, Br))
    start = magnet.solve((-b, 0.0, 0.0), perturbation=(0.0, 0.0, 0.05 * b))
    sols = {}
    for ext in (False, True):
        nudged = Rod(L, cs, E, shear_modulus=G, tip_force=(-F, 0.0, 0.05 * F), extensible=ext).solve()
        sols[ext] = Rod(L, cs, E, shear_modulus=G, tip_force=(-F, 0.0, 0.0), extensible=ext).solve(initial_guess=nudged)
    assert np.abs(sols[False].tip_position - start.tip_position).max() < 1e-6 * L
    diff = np.abs(sols[True].tip_position - sols[False].tip_position) / L
    assert diff.max() < 0.01
    assert start.tip_position[2] > 0.4 * L and start.tip_position[0] < -0.4 * L  # well past the buckling


def test_antiparallel_field_buckles_beyond_critical_field():
    """Axially magnetised rod in a field B antiparallel to Br: theta'' = -k^2 sin(theta) (planar elastica with
    phi = pi), the buckling problem of a clamped-free column. The straight rod loses stability at
    k L = pi/2; past it the tip angle theta_L solves K(sin^2(theta_L/2)) = k L (complete elliptic integral of
    the first kind, parameter m). Checked three ways: a sweep rotating the field from +z to -x (following the
    branch), a solve with a transverse perturbation, and the refusal to cross the bifurcation silently."""
    L, E, Br = 0.05, 1.0e6, 0.1
    cs = CrossSection.rectangle(4e-3, 1e-3)
    ei = E * cs.second_moment[0]
    b_crit = (np.pi / 2) ** 2 * ei * MU0 / (cs.area * Br * L**2)
    rod = Rod(L, cs, E, magnetisation=(0.0, 0.0, Br))
    factor = 1.6
    kl = np.sqrt(factor) * np.pi / 2
    theta_ref = 2.0 * np.arcsin(np.sqrt(brentq(lambda m: ellipk(m) - kl, 0.0, 1.0 - 1e-15)))

    def tip_angle(sol):
        t = sol.tangents[-1]
        return np.arctan2(t[2], t[0])

    # rotate a field of magnitude 1.6 B_crit from +z (perpendicular) to -x (antiparallel)
    angles = np.linspace(np.pi / 2, np.pi, 7)
    sweep = rod.sweep([factor * b_crit * np.array([np.cos(a), 0.0, np.sin(a)]) for a in angles])
    assert tip_angle(sweep[-1]) == pytest.approx(theta_ref, abs=1e-5)  # measured 1.3e-8 rad
    # the same equilibrium reached by a small transverse perturbation, removed at the end
    perturbed = rod.solve((-factor * b_crit, 0.0, 0.0), perturbation=(0.0, 0.0, 0.02 * b_crit))
    assert tip_angle(perturbed) == pytest.approx(theta_ref, abs=1e-5)
    assert np.abs(perturbed.tip_position - sweep[-1].tip_position).max() < 1e-6 * L
    # below the critical field the perturbation dies out: the rod is straight
    straight = rod.solve((-0.8 * b_crit, 0.0, 0.0), perturbation=(0.0, 0.0, 0.02 * b_crit))
    assert np.abs(straight.tip_position - [L, 0.0, 0.0]).max() < 1e-9 * L
    # past the critical field without a perturbation the straight rod is unstable: refuse, say why, and say
    # where: the continuation stops at the bifurcation, i.e. at the buckling field (measured within 1e-4)
    for f in (factor, 12.0):  # 12 B_crit lies past the 2nd critical field too (9 B_crit): no silent pass
        with pytest.raises(SimulationError, match="perturbation") as info:
            rod.solve((-f * b_crit, 0.0, 0.0))
        stalled = float(re.search(r"at field \[([-+0-9.e]+),", str(info.value)).group(1))
        assert -stalled == pytest.approx(b_crit, rel=1e-3)


# --------------------------------------------------------------------------------------------------------------
# (4) inputs, files and the command line

GOOD = {
    "length": 0.0172,
    "youngs_modulus": 909e3,
    "cross_section": {"shape": "rectangle", "width": 5e-3, "thickness": 0.84e-3},
    "magnetisation": [{"start": 0.0, "end": 0.0172, "remanence": [0.0, 0.0, 0.258]}],
    "field": [0.0, 0.0, 0.005],
}


@pytest.mark.parametrize(
    "patch, key",
    [
        ({"youngs_modulos": 1e6}, "youngs_modulos"),
        ({"youngs_modulus": -1e6}, "youngs_modulus"),
        ({"shear_modulus": 0.0}, "shear_modulus"),
        ({"cross_section": {"shape": "rectangle", "widht": 5e-3, "thickness": 1e-3}}, "cross_section.widht"),
        ({"cross_section": {"shape": "rectangle", "width": 5e-3}}, "thickness"),
        ({"cross_section": {"shape": "hexagon", "diameter": 1e-3}}, "cross_section.shape"),
        ({"magnetisation": [{"end": 0.05, "remanence": [0, 0, 0.2]}]}, "magnetisation[0].end"),
        ({"magnetisation": [{"end": 0.01, "remanence": [0, 0.2]}]}, "magnetisation[0].remanence"),
        ({"field": [0.0, 0.01]}, "field"),
        ({"n_nodes": 1}, "n_nodes"),
    ],
)
def test_bad_scene_keys_give_one_line_error_naming_the_key(patch, key):
    data = {**GOOD, **patch}
    with pytest.raises(SceneError) as info:
        parse_rod_config(data, "rod.toml")
    message = str(info.value)
    assert key in message and "\n" not in message


def test_bad_arguments_to_the_api_raise_scene_error():
    cs = CrossSection.rectangle(5e-3, 1e-3)
    with pytest.raises(SceneError, match="length"):
        Rod(-0.01, cs, 1e6)
    with pytest.raises(SceneError, match="youngs_modulus"):
        Rod(0.01, cs, -1e6)
    with pytest.raises(SceneError, match="width"):
        CrossSection.rectangle(0.0, 1e-3)
    with pytest.raises(SceneError, match="magnetisation"):
        Rod(0.01, cs, 1e6, magnetisation=[(0.0, 0.02, (0, 0, 0.1))])  # beyond the rod's end
    with pytest.raises(SceneError, match="overlap"):
        Rod(0.01, cs, 1e6, magnetisation=[(0.0, 0.006, (0, 0, 0.1)), (0.005, 0.01, (0, 0, -0.1))])
    with pytest.raises(SceneError, match="base_rotation"):
        Rod(0.01, cs, 1e6, base_rotation=np.diag([1.0, 1.0, -1.0]))
    assert issubclass(SceneError, MagsoroError)


EXAMPLE_SCENE = Path(__file__).resolve().parents[1] / "scenes" / "rod_cantilever.toml"


def test_example_scene_and_cli(tmp_path, capsys):
    from magsoro.cli import main

    scene = str(EXAMPLE_SCENE)
    config = load_rod_config(scene)
    api_tip = config.build().solve((0.0, 0.0, 0.004)).tip_position
    assert api_tip[2] > 0.1 * config.length  # a visible deflection, so the comparisons below mean something
    out = tmp_path / "rod"
    rc = main(["rod", scene, "--field", "0", "0", "0.004", "--out", str(out), "--json"])
    assert rc == 0
    result = json.loads(capsys.readouterr().out)
    assert np.allclose(result["tip_position_m"], api_tip, rtol=0, atol=1e-12)
    table = read_centreline_csv(out / "centreline.csv")
    assert list(table) == ["s", "x", "y", "z", "tx", "ty", "tz"]
    assert table["s"][-1] == pytest.approx(0.0172)
    assert np.allclose([table["x"][-1], table["y"][-1], table["z"][-1]], api_tip, atol=1e-12)
    assert np.allclose(np.hypot(np.hypot(table["tx"], table["ty"]), table["tz"]), 1.0)
    assert (out / "centreline.png").stat().st_size > 10_000

    bad = tmp_path / "bad.toml"
    bad.write_text("length = 0.01\nyoungs_modulus = -5.0\n[cross_section]\nwidth = 1e-3\nthickness = 1e-3\n")
    rc = main(["rod", str(bad), "--out", str(tmp_path / "bad")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "youngs_modulus" in err and len(err.splitlines()) == 1
