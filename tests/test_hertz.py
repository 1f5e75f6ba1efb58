"""Hertz contact (magsoro.validation.hertz): the closed forms, the finite-element model that supplies the
hemisphere's far-field term, the scene builder, and (slow) the engine against Hertz."""

import math

import numpy as np
import pytest

from magsoro.validation.hertz import (
    HemisphereFE,
    HertzSetup,
    elastic_moduli,
    hertz_force,
    hertz_indentation,
    hertz_scene,
    write_hemisphere_mesh,
)


def test_elastic_moduli_and_hertz_closed_form():
    G = 3e5
    nu, E, e_star = elastic_moduli(G, 20 * G)
    assert nu == pytest.approx(58 / 122, rel=1e-12)  # (3K - 2G) / (2 (3K + G)) at K = 20 G
    assert E == pytest.approx(9 * 20 * G * G / (3 * 20 * G + G), rel=1e-12)  # 9 K G / (3 K + G)
    assert e_star == pytest.approx(3.8125 * G, rel=1e-4)  # E* = E / (1 - nu^2)
    assert elastic_moduli(G, 2 * G * 1.25 / 1.5)[0] == pytest.approx(0.25, rel=1e-12)
    R, d = 5e-3, np.array([1e-5, 2e-4, 5e-4])
    F = hertz_force(d, R, e_star)
    assert F[1] == pytest.approx(4 / 3 * e_star * math.sqrt(R) * 2e-4**1.5, rel=1e-12)
    assert np.allclose(hertz_indentation(F, R, e_star), d, rtol=1e-12)


@pytest.fixture(scope="module")
def coarse_fe():
    return HemisphereFE(58 / 122, h0=0.004, grow=0.12, hmax=0.06)


def test_fe_hemisphere_tends_to_hertz_with_a_far_field_term_linear_in_the_load(coarse_fe):
    """Under a small weight the model's centre-of-mass approach is Hertz's d plus kappa F / (E* R) with kappa the
    same at two loads a factor 8 apart (so it vanishes against d ~ F^(2/3) as F -> 0), the contact radius is
    sqrt(R d), and the plane carries the weight."""
    kappas = []
    for d in (0.0025, 0.01):
        F = 4 / 3 * d**1.5  # units R = 1, E* = 1
        res = coarse_fe.rest(F)
        assert res["reaction"] == pytest.approx(F, rel=1e-8)
        assert res["contact_radius"] == pytest.approx(math.sqrt(d), rel=0.08)
        kappas.append((res["approach"] - d) / F)
    assert -0.66 < kappas[0] < -0.56 and kappas[1] == pytest.approx(kappas[0], abs=0.03)


def test_fe_far_field_matches_boussinesq(coarse_fe):
    """Between depths 0.1 R and 0.2 R below a small contact the axis shortens as under a point load on a
    half-space, F (3 - 2 nu) / (2 pi E* (1 - nu)) (1/z1 - 1/z2) (within 3 %: the body is finite)."""
    nu, d = coarse_fe.nu, 0.0004
    F = 4 / 3 * d**1.5
    res = coarse_fe.rest(F)
    nodes, u = coarse_fe.nodes, res["u"]
    axis = np.flatnonzero(np.abs(nodes[:, 0]) < 1e-12)
    axis = axis[np.argsort(nodes[axis, 1])]
    depth, uz = nodes[axis, 1] + 1.0, u[2 * axis + 1]
    shortening = np.interp(0.1, depth, uz) - np.interp(0.2, depth, uz)
    boussinesq = F * (3 - 2 * nu) / (2 * math.pi * (1 - nu)) * (1 / 0.1 - 1 / 0.2)
    assert shortening == pytest.approx(boussinesq, rel=0.03)


def test_fe_mesh_convergence_of_the_far_field_term(coarse_fe):
    """The coarse mesh of the fixture and the default mesh (element size halved) agree within 0.5 % on the
    centre-of-mass approach at d = 0.1 R (converged: the default is what the case uses)."""
    F = 4 / 3 * 0.1**1.5
    fine = HemisphereFE(coarse_fe.nu)
    assert coarse_fe.rest(F)["approach"] == pytest.approx(fine.rest(F)["approach"], rel=0.005)


def test_scene_builder_hemisphere(tmp_path):
    """The scene's hemisphere: lattice particles of the right volume, symmetric about the axis, lowest layer half
    a particle spacing above z = -R, the plane floor_gap cells below it, and a weight of Hertz's force."""
    from magsoro.scene import parse_scene
    from magsoro.scene.build import build

    setup = HertzSetup(cells=8)
    mesh = write_hemisphere_mesh(tmp_path / "h.stl", setup.radius)
    scene = hertz_scene(setup, mesh, 0.1)
    built = build(parse_scene(scene))
    X, mass = built.model.host["positions"], built.model.host["mass"]
    R, h = setup.radius, setup.dx / setup.particles_per_cell
    assert mass.sum() == pytest.approx(setup.continuum_mass, rel=0.02)
    assert np.allclose(X[:, :2].mean(axis=0), 0.0, atol=1e-12)
    assert X[:, 2].min() == pytest.approx(-R + h / 2, abs=1e-12) and X[:, 2].max() == pytest.approx(-h / 2, abs=1e-12)
    assert scene["colliders"][0]["point"][2] == pytest.approx(-R - setup.floor_gap * setup.dx)
    _, _, e_star = setup.moduli
    weight = setup.continuum_mass * -scene["simulation"]["gravity"][2]
    assert weight == pytest.approx(float(hertz_force(0.1 * R, R, e_star)), rel=1e-12)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "engine softer than Hertz at R = 16 dx: weights 5.3, 12.4, 10.2, 9.0 % below Hertz's force at the local "
    "indentations d = 0.026, 0.055, 0.081, 0.107 R, Hertz constant 0.903 of 4/3 E* R^1/2 (two levels miss 10 %). "
    "The contact offset grows with the load by 0.09 cells (0.20 -> 0.29 cells), the same in cells at R = 20 dx, so "
    "the error falls at first order in dx: R = 12 dx a/a_H = 0.852, R = 20 dx 0.931 with every row within 10 % "
    "(about 10 min on 2 CPU cores); magsoro.validation.hertz docstring"))
def test_hemisphere_on_plane_follows_hertz():
    """The registered case (R = 16 dx, float32, four weights up to d = 0.1 R): every row within 10 %."""
    from magsoro.validation.hertz import hertz_case
    from magsoro.validation.registry import Context

    res = hertz_case(Context(log=print))
    for r in res.rows:
        print(f"{r.quantity} {r.inputs.get('d_over_R', '')}: value {r.value:.4g} reference {r.reference:.4g} "
              f"error {r.error:.3f} (tolerance {r.tolerance})")
    print({k: res.info[k] for k in ("contact_offset_cells", "drift_cells", "level_wall_s")})
    bad = [(r.quantity, r.inputs.get("d_over_R"), round(r.value, 4), round(r.reference, 4), round(r.error, 3))
           for r in res.rows if not r.passed]
    assert not bad, bad
