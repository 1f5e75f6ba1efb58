"""Eversion mechanics (seed 004 eqs 1-13): closed forms against quadrature and the general hyperelastic
formulas, friction trends, the minimum field for pressure-free growth and the ``magsoro evert`` command."""

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from magsoro import MU0
from magsoro.actuation.eversion import EversionModel, Friction
from magsoro.cli import main

ROOT = Path(__file__).resolve().parents[1]
DESIGNS = ROOT / "examples" / "actuation"

CASES = [
    # A, B, lambda_z, a, field, alpha
    (0.8e-3, 0.9e-3, 1.0, 0.85e-3, 0.0, 0.0),
    (0.8e-3, 0.9e-3, 1.0, 0.5e-3, 0.04, 0.3),
    (0.8e-3, 0.9e-3, 1.2, 1.1e-3, 0.06, 0.3),
    (1.0e-3, 2.0e-3, 0.9, 1.5e-3, 0.02, -0.2),
    (5.0e-3, 6.0e-3, 1.5, 4.0e-3, 0.1, 1.0),
]


def _quadrature(m: EversionModel, a: float, field: float):
    """Eqs 10 and 11 integrated numerically in r, straight from the stretches of eq 5."""
    b = float(m.everted_outer_radius(a))
    lz = m.axial_stretch
    mu = float(m.shear_modulus_at(field))

    def lt(r):
        return r / np.sqrt(m.outer_radius**2 - lz * (r * r - a * a))

    kw = dict(epsabs=0.0, epsrel=1e-13, limit=200)
    P = mu * quad(lambda r: (lt(r) ** 2 - lt(r) ** -2 / lz**2) / r, a, b, **kw)[0]
    el = np.pi * mu * quad(lambda r: (2 * lz**2 - lt(r) ** 2 - lt(r) ** -2 / lz**2) * r, a, b, **kw)[0]
    I4 = (field / MU0 / lz) ** 2
    maxwell = np.pi * quad(lambda r: MU0 * I4 * (lz**2 - lz**-2) * r, a, b, **kw)[0]
    return P, el + np.pi * a * a * P + maxwell


@pytest.mark.parametrize("A,B,lz,a,field,alpha", CASES)
def test_pressure_and_tip_force_match_quadrature(A, B, lz, a, field, alpha):
    m = EversionModel(A, B, 60e3, magnetic_stiffening=alpha, saturation_field=0.05, axial_stretch=lz)
    P_q, N_q = _quadrature(m, a, field)
    assert float(m.pressure(a, field)) == pytest.approx(P_q, rel=1e-6)
    assert float(m.tip_force_ideal(a, field)) == pytest.approx(N_q, rel=1e-6)
    # both closed forms are exact: the agreement is at rounding level
    assert abs(float(m.pressure(a, field)) / P_q - 1) < 1e-9
    assert abs(float(m.tip_force_ideal(a, field)) / N_q - 1) < 1e-9


def _neo_hookean_general(mu, A, B, lz, a):
    """Zero-field result from the general incompressible formulas with W(l1, l2, l3) = mu/2 (sum l^2 - 3)
    differentiated numerically: P = int (lt W_t - lr W_r) dr/r, N = pi int (2 lz W_z - lr W_r - lt W_t) r dr
    + pi a^2 P (radial equilibrium of the tube wall)."""

    def W(l1, l2, l3):
        return 0.5 * mu * (l1 * l1 + l2 * l2 + l3 * l3 - 3.0)

    def dW(i, lam, h=1e-6):
        up, dn = list(lam), list(lam)
        up[i] += h
        dn[i] -= h
        return (W(*up) - W(*dn)) / (2 * h)

    def stretches(r):
        R = np.sqrt(B * B - lz * (r * r - a * a))
        lt = r / R
        return 1.0 / (lt * lz), lt, lz  # lambda_r from det F = 1 (eq 4)

    def s(r):
        lam = stretches(r)
        return [lam[i] * dW(i, lam) for i in range(3)]

    b = np.sqrt(a * a + (B * B - A * A) / lz)
    kw = dict(epsabs=0.0, epsrel=1e-10, limit=200)  # the central differences carry ~1e-10 noise
    P = quad(lambda r: (s(r)[1] - s(r)[0]) / r, a, b, **kw)[0]
    N = np.pi * quad(lambda r: (2 * s(r)[2] - s(r)[0] - s(r)[1]) * r, a, b, **kw)[0] + np.pi * a * a * P
    return P, N


@pytest.mark.parametrize("lz,a", [(1.0, 0.85e-3), (1.3, 0.6e-3), (0.8, 1.2e-3)])
def test_zero_field_reduces_to_neo_hookean(lz, a):
    A, B, mu = 0.8e-3, 0.9e-3, 60e3
    m = EversionModel(A, B, mu, magnetic_stiffening=0.7, saturation_field=0.02, axial_stretch=lz)
    assert float(m.shear_modulus_at(0.0)) == mu
    assert float(m.maxwell_force(a, 0.0)) == 0.0
    P_ref, N_ref = _neo_hookean_general(mu, A, B, lz, a)
    assert float(m.pressure(a, 0.0)) == pytest.approx(P_ref, rel=1e-6)
    assert float(m.tip_force_ideal(a, 0.0)) == pytest.approx(N_ref, rel=1e-6)
    # and a field changes the result (the reduction is not trivially satisfied)
    assert abs(float(m.tip_force_ideal(a, 0.05)) - N_ref) > 1e-3 * abs(N_ref)


def test_pressure_free_state_as_seed_describes():
    """P = 0 fixes a0 independently of the field; there N < 0 at lambda_z = 1 and N grows with lambda_z."""
    forces = []
    for lz in (1.0, 1.05, 1.1, 1.2):
        m = EversionModel(0.8e-3, 0.9e-3, 60e3, magnetic_stiffening=0.3, saturation_field=0.05, axial_stretch=lz)
        a0 = m.pressure_free_radius()
        for B in (0.0, 0.02, 0.05):
            assert abs(float(m.pressure(a0, B))) < 1e-9 * 60e3
        forces.append(float(m.pressure_free_tip_force(0.04, contact_radius=a0)))
    assert forces[0] < 0
    assert np.all(np.diff(forces) > 0) and forces[-1] > 0


def test_friction_lowers_tip_force_as_eqs_12_13():
    a, B = 0.95e-3, 0.03
    base = EversionModel(0.8e-3, 0.9e-3, 60e3, axial_stretch=1.05)
    P = float(base.pressure(a, B))
    assert P > 0
    b = float(base.everted_outer_radius(a))
    N_ideal = float(base.tip_force_ideal(a, B))

    def N(mu_k=0.3, theta=0.0, tail="cylindrical", alpha=0.5, l=0.02):
        fr = Friction.for_tail(tail, l, mu_k, alpha)
        m = EversionModel(0.8e-3, 0.9e-3, 60e3, axial_stretch=1.05, friction=fr)
        return float(m.tip_force(a, B, bend_angle=theta))

    assert N(mu_k=0.0) == pytest.approx(N_ideal, rel=1e-15)
    mus = [N(mu_k=k) for k in (0.0, 0.1, 0.3, 0.6)]
    thetas = [N(theta=t) for t in (0.0, 0.5, 1.5, np.pi)]
    assert np.all(np.diff(mus) < 0) and np.all(np.diff(thetas) < 0)
    # eq 12-13 value: l mu_k (alpha P) phi 2 pi b exp(gamma mu_k Theta)
    expect = N_ideal - 0.02 * 0.3 * 0.5 * P * 1.0 * 2 * np.pi * b * np.exp(1.0 * 0.3 * 1.5)
    assert N(theta=1.5) == pytest.approx(expect, rel=1e-12)
    # a cruciform tail (smaller perimeter and capstan factors) loses less
    assert N(tail="cruciform", theta=1.5) > N(tail="cylindrical", theta=1.5)


def test_minimum_growth_field():
    fr = Friction.for_tail("cylindrical", 0.02, 0.12, 0.1)
    m = EversionModel(0.8e-3, 0.9e-3, 50e3, magnetic_stiffening=0.05, saturation_field=0.1, axial_stretch=1.015, friction=fr)
    b_min = m.minimum_growth_field()
    assert b_min is not None and 0 < b_min < 1.0
    assert abs(float(m.pressure_free_tip_force(b_min))) < 1e-9
    assert float(m.pressure_free_tip_force(0.99 * b_min)) < 0 < float(m.pressure_free_tip_force(1.01 * b_min))
    # a load at the tip, a bend or more friction raise the field needed; a cruciform tail lowers it
    assert m.minimum_growth_field(required_force=1e-4) > b_min
    assert m.minimum_growth_field(bend_angle=np.pi) > b_min
    cruciform = EversionModel(0.8e-3, 0.9e-3, 50e3, 0.05, 0.1, 1.015, Friction.for_tail("cruciform", 0.02, 0.12, 0.1))
    assert cruciform.minimum_growth_field() < b_min
    # at lambda_z = 1 the Maxwell term vanishes and no field helps
    flat = EversionModel(0.8e-3, 0.9e-3, 50e3, 0.05, 0.1, 1.0, fr)
    assert flat.minimum_growth_field() is None


def test_evert_cli_writes_curves_and_summary(tmp_path, capsys):
    assert main(["evert", str(DESIGNS / "design_cruciform.toml"), "--out", str(tmp_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    for name in ("eversion.csv", "eversion.png", "summary.json"):
        assert (tmp_path / name).stat().st_size > 0
    data = np.genfromtxt(tmp_path / "eversion.csv", delimiter=",", names=True)
    assert len(data) == 200 and "P_Pa_50mT" in data.dtype.names
    assert summary["minimum_growth_field_T"] == pytest.approx(0.1573, rel=1e-3)
    assert main(["evert", str(DESIGNS / "design_cylindrical.toml"), "--out", str(tmp_path / "cyl"), "--json"]) == 0
    cyl = json.loads(capsys.readouterr().out)
    assert cyl["minimum_growth_field_T"] > summary["minimum_growth_field_T"]


def test_evert_cli_rejects_bad_design(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[tube]\ninner_radius = 0.8e-3\nouter_radius = 0.9e-3\nshear_modulus = 5e4\n[friction]\nmu = 0.1\n")
    assert main(["evert", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "friction.mu: unknown key" in err and "friction_coefficient" in err
    bad.write_text("[tube]\ninner_radius = 0.9e-3\nouter_radius = 0.8e-3\nshear_modulus = 5e4\n")
    assert main(["evert", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "inner_radius" in capsys.readouterr().err


def _zeeman_energy_per_length(m: EversionModel, everted: bool, B0: float, a: float, n: int = 400) -> float:
    """Magnetic energy per unit reference length (J/m) of the tube wall in an axial field B0 e_z, the tail's
    remanence -|Br| e_z, integrated over the reference annulus with the deformation gradient of the everted map
    taken by finite differences of the map itself (x = (r(R) cos t, r(R) sin t, -lambda_z Z)) rather than from
    the model's formulas."""
    from scipy.linalg import polar

    A, B, lz = m.inner_radius, m.outer_radius, m.axial_stretch
    Br = np.array([0.0, 0.0, -m.remanence])
    field = np.array([0.0, 0.0, B0])

    def x_of(X):
        R, th = np.hypot(X[0], X[1]), np.arctan2(X[1], X[0])
        if not everted:
            return np.array(X, dtype=float)
        r = np.sqrt(a * a + (B * B - R * R) / lz)
        return np.array([r * np.cos(th), r * np.sin(th), -lz * X[2]])

    total = 0.0
    Rs = A + (np.arange(n) + 0.5) * (B - A) / n
    h = 1e-9
    for R in Rs:
        X = np.array([R, 0.0, 0.0])  # axisymmetric: one azimuth suffices
        F = np.column_stack([(x_of(X + h * e) - x_of(X - h * e)) / (2 * h) for e in np.eye(3)])
        if m.magnetization_follows == "R":
            F = polar(F)[0]
        total += -(field @ (F @ Br)) / MU0 * 2 * np.pi * R * (B - A) / n
    return total


@pytest.mark.parametrize("follows,lz", [("F", 1.0), ("F", 1.2), ("R", 1.2), ("R", 0.9)])
def test_flip_force_is_the_zeeman_energy_released_per_front_advance(follows, lz):
    """The flip term against virtual work done independently: the energy released per unit reference length
    everted (the everted map's F from finite differences, the engine's energy -(1/mu0) B . F Br or R Br) divided
    by the front's advance per reference length, lambda_z."""
    m = EversionModel(0.8e-3, 0.9e-3, 120e3, axial_stretch=lz, remanence=0.11, magnetization_follows=follows)
    B0 = 0.043
    a = 0.9e-3
    released = _zeeman_energy_per_length(m, False, B0, a) - _zeeman_energy_per_length(m, True, B0, a)
    assert released > 0  # the field against the tail's remanence favours eversion
    assert float(m.flip_force(B0)) == pytest.approx(released / lz, rel=1e-6)
    assert float(m.flip_force(-B0)) == pytest.approx(-released / lz, rel=1e-12)  # along it: retraction


def test_flip_term_lets_a_field_alone_evert_at_unit_stretch():
    """lambda_z = 1, P = 0: eqs 10-11 alone give no growing field; with the tail's remanence the smallest field
    is -N_el / (dN_flip/dB0) without friction, and friction raises it; the friction coefficient that makes a given
    field the threshold reproduces that field."""
    A, B, G, Br = 0.8e-3, 0.9e-3, 120e3, 0.1123
    bare = EversionModel(A, B, G)
    assert bare.minimum_growth_field() is None
    m = EversionModel(A, B, G, remanence=Br)
    n_el = float(m.pressure_free_tip_force(0.0))
    assert n_el < 0
    per_tesla = 2 * Br / MU0 * np.pi * (B * B - A * A)
    assert m.flip_force_per_tesla() == pytest.approx(per_tesla, rel=1e-12)
    b_min = m.minimum_growth_field()
    assert b_min == pytest.approx(-n_el / per_tesla, rel=1e-9)
    assert 0.015 < b_min < 0.025  # 20.3 mT: the wall resting on the tail (a = B)
    fr = Friction.for_tail("cylindrical", 0.02, 0.0, 0.67)
    with_friction = EversionModel(A, B, G, remanence=Br, friction=fr)
    mu = with_friction.friction_coefficient_for_growth_field(0.043)
    assert mu is not None and 0 < mu < 0.05
    from dataclasses import replace
    fitted = replace(with_friction, friction=replace(fr, friction_coefficient=mu))
    assert fitted.minimum_growth_field() == pytest.approx(0.043, rel=1e-6)
    assert with_friction.friction_coefficient_for_growth_field(0.5 * b_min) is None  # below the frictionless threshold


def test_evert_cli_seed004_design(tmp_path, capsys):
    assert main(["evert", str(DESIGNS / "design_seed004.toml"), "--out", str(tmp_path), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["minimum_growth_field_T"] == pytest.approx(0.02026, rel=1e-3)
    assert s["minimum_growth_field_without_friction_T"] == pytest.approx(s["minimum_growth_field_T"], rel=1e-9)
    assert s["implied_friction_coefficient"] == pytest.approx(0.005483, rel=1e-3)


def test_axially_magnetised_tail_exerts_no_field_on_the_everted_wall():
    """The reason wall attraction leaves the flip term alone (docs/actuation.md): a long, uniformly axially
    magnetised tube (the tail, A = 0.8, B = 0.9 mm, |Br| = 0.1123 T) has no field outside its own wall, so the
    everted wall around it (0.9-0.99 mm) sits in none at mid-length (magpylib's closed form, 40 mm tube: the ends'
    poles give 2e-5 T, 2e-4 of Br); the same tube magnetised across its axis (the robot's first half) puts
    Br (B^2 - A^2) / (2 r^2) there, the 2D dipole's 9 % of Br."""
    magpylib = pytest.importorskip("magpylib")
    A, B, Br, L = 0.8e-3, 0.9e-3, 0.1123, 40e-3
    r = 0.5 * (0.9e-3 + np.sqrt(0.9e-3**2 + B * B - A * A))  # mid-radius of the everted wall resting on the tail
    phi = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    pts = np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros_like(phi)], axis=1)

    def field(polarization):
        tube = magpylib.magnet.CylinderSegment(polarization=polarization, dimension=(A, B, L, 0.0, 360.0))
        return tube.getB(pts)

    axial = np.linalg.norm(field((0.0, 0.0, Br)), axis=1)
    assert axial.max() < 5e-4 * Br
    across = np.linalg.norm(field((Br, 0.0, 0.0)), axis=1)
    expect = Br * (B * B - A * A) / (2 * r * r)
    assert np.allclose(across, expect, rtol=0.01)


def test_growth_pressure():
    """Growth under a fluid pressure: with the wall resting on the tail (a = B) and the whole section pressurised
    (eq 11's pi a^2 P) the front force is N_el(B) + pi B^2 P, so the start pressure is -N_el(B) / (pi B^2) in closed
    form (760 Pa for the robot); with only the annulus between tail and wall pressurised the wall must inflate off
    the tail first (9.17 kPa, a = 1.068 mm); a field against the tail's remanence lowers both; the thick tube
    (B/A = 1.5) follows the same closed form with the full section (17 kPa)."""
    m = EversionModel(0.8e-3, 0.9e-3, 120033.33, remanence=0.1123)
    P = m.growth_pressure(front="full")
    assert P == pytest.approx(-float(m.elastic_force(0.9e-3)) / (np.pi * 0.9e-3**2), rel=1e-9)
    assert m.pressurised_radius(P) == pytest.approx(0.9e-3, rel=1e-12)
    gap = m.growth_pressure(front="gap")
    assert abs(m.pressurised_tip_force(gap, front="gap")) < 1e-12
    assert m.pressurised_tip_force(0.99 * gap, front="gap") < 0
    assert m.pressurised_radius(gap) > 0.9e-3 and float(m.pressure(m.pressurised_radius(gap))) == pytest.approx(gap, rel=1e-9)
    assert 8e3 < gap < 1e4 and 700 < P < 800
    assert m.growth_pressure(field=0.01, front="full") < P and m.growth_pressure(field=0.01, front="gap") < gap
    thick = EversionModel(2e-3, 3e-3, 120033.33)
    assert thick.growth_pressure(front="full") == pytest.approx(-float(thick.elastic_force(3e-3)) / (np.pi * 9e-6), rel=1e-9)
    with pytest.raises(ValueError, match="front"):
        m.pressurised_tip_force(100.0, front="annulus")
