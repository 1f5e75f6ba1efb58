"""Robots strip_magnet, obstacle_beam (seed 000 sec 4.3-4.4), continuum_soft and continuum_discrete (seed 001
sec V): their scenes load, their reference models agree with closed forms and magsoro.rod, and their
reproductions pass their acceptance checks (obstacle_beam's preview in the default suite, all four as slow
tests)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from magsoro import MU0

ROOT = Path(__file__).resolve().parents[1]
BEAM_ROBOTS = ("strip_magnet", "obstacle_beam", "continuum_soft", "continuum_discrete")


@pytest.mark.parametrize("name", BEAM_ROBOTS)
def test_scene_and_preview_build(name):
    """`magsoro run scenes/NAME.toml [--preview]` is accepted: both resolutions parse and fill with particles."""
    from magsoro.robots import ROBOTS
    from magsoro.robots.base import scene
    from magsoro.scene.build import fill_bodies

    assert name in ROBOTS
    for preview in (False, True):
        sc = scene(name, preview=preview)
        parts = fill_bodies(sc)
        assert len(parts.positions) > 1000
    assert ROBOTS[name].source.startswith("seed 00")
    assert ROBOTS[name].in_ci == (name == "obstacle_beam")


def test_planar_rod_matches_magsoro_rod_for_a_uniform_rod():
    """The piecewise planar rod of continuum_discrete equals the Cosserat rod of magsoro.rod (hanging, gravity,
    axial magnetisation, fields up to a tip angle of ~70 deg) when its sections are identical."""
    from magsoro.robots.continuum_discrete import Section, planar_rod
    from magsoro.robots.continuum_soft import hanging_rod_deflection

    L, d, E, Br, rho = 0.04, 0.003, 69e3, 0.15, 2000.0
    A, inertia = math.pi * d**2 / 4, math.pi * d**4 / 64
    secs = [Section(0.0, 0.015, E * inertia, rho * A * 9.81, A * Br / MU0),
            Section(0.015, 0.04, E * inertia, rho * A * 9.81, A * Br / MU0)]
    fields = [0.002, 0.01]
    ours = [sol[-1, 1] for sol in planar_rod(secs, [(b, 0.0) for b in fields])]
    ref = hanging_rod_deflection(L, A, inertia, E, Br, rho, fields, L)
    np.testing.assert_allclose(ours, ref, rtol=1e-5)


def test_planar_rod_small_field_matches_linear_theory_for_a_stiff_tip_section():
    """Piecewise stiffness: weightless rod, magnetised only on its outer half, small field. Linear theory: the
    moment is m B (L - s) on the magnetised half and m B L/2 inside it, so the tip deflection is the sum of the two
    halves' bending with their own E I."""
    from magsoro.robots.continuum_discrete import Section, planar_rod

    L, EI1, EI2, m, B = 0.04, 2e-6, 6e-6, 0.5, 1e-5
    a = L / 2
    secs = [Section(0.0, a, EI1, 0.0, 0.0), Section(a, L, EI2, 0.0, m)]
    tip = planar_rod(secs, [(B, 0.0)])[0][-1, 1]
    M0 = m * B * (L - a)                        # constant moment on the inner half
    # inner half: slope and deflection at s = a from a constant moment; outer half: moment m B (L - s)
    th_a, w_a = M0 * a / EI1, M0 * a**2 / (2 * EI1)
    w_outer = m * B * (L - a) ** 3 / (3 * EI2)  # outer half from its base tangent: w'' = m B (L - s) / EI2
    expected = w_a + th_a * (L - a) + w_outer
    assert tip == pytest.approx(expected, rel=2e-3)


def test_bar_model_uniaxial_slope_and_gravity_stretch():
    """The strip's bar model: the engine solid's uniaxial stress has slope 9KG/(3K+G) at zero strain, and a bar
    hanging in no field stretches by rho g L / (2 E) (small strain)."""
    from magsoro.fields import Uniform
    from magsoro.robots.continuum_soft import youngs_modulus
    from magsoro.robots.strip_magnet import BarSection, bar_strain, uniaxial_stress

    G, K, rho, L = 34e3, 680e3, 1876.0, 0.1
    E = youngs_modulus(G, K)
    slope = uniaxial_stress(G, K, [1.0 + 1e-5])[0] / 1e-5
    assert slope == pytest.approx(E, rel=1e-3)
    secs = [BarSection(0.0, 0.05, 0.008, 0.012), BarSection(0.05, L, 0.008, 0.012)]
    tip, stretch = bar_strain(secs, Uniform((0.0, 0.0, 0.0)), 0.1, G, K, rho)
    assert (tip - L) / L == pytest.approx(rho * 9.81 * L / (2 * E), rel=0.02)
    assert stretch[0] > stretch[1] > 1.0  # the upper half carries more weight


def _check(res):
    failed = [f"{r.quantity}: {r.value:.4g} (ref {r.reference:.4g}, err {r.error:.3g} > {r.tolerance:.3g})"
              for r in res.rows if not r.passed]
    assert not failed, failed
    for f in (res.csv, res.png, res.animation):
        assert f.is_file() and f.stat().st_size > 0
    assert res.animation.stat().st_size < 1.5e6


@pytest.mark.slow
def test_obstacle_beam_preview(tmp_path):
    """CI robot: the preview passes its checks; the pin stops the obstacle twin well short of the free twin, and
    the free twin's delta_max / L is within 15 % of the Kirchhoff rod at 2 cells through the thickness. The curve
    is the static solver's, which must match the dynamics' settled shape at 10 mT within 2 % (issue "Quasi-static
    solver"; measured 0.42 % for the pressed twin: 0.4310 static, 0.4328 dynamic), the beam's surface on the pin
    (its particles' centres their radius, 0.375 mm, from it; measured 0.374 mm)."""
    from magsoro.robots import reproduce
    from magsoro.robots.base import read_csv

    res = reproduce("obstacle_beam", out=tmp_path, preview=True)
    _check(res)
    c = read_csv(res.csv)
    assert c["dmax_over_L_obstacle"][-1] < 0.8 * c["dmax_over_L_free"][-1]
    assert c["dmax_over_L_free"][-1] == pytest.approx(c["rod_dmax_over_L_free"][-1], rel=0.15)
    assert 0.3 < c["pin_gap_mm"][-1] < 0.376  # pressed on the pin: the surface law's particle radius, 0.375 mm
    for s in ("free", "obstacle"):
        assert c[f"dmax_over_L_{s}"][-1] == pytest.approx(c[f"dynamic_dmax_over_L_{s}"][-1], rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize("name", BEAM_ROBOTS)
def test_preview_reproductions(name, tmp_path):
    """Every robot's preview passes its checks, plus one physical fact each."""
    from magsoro.robots import reproduce
    from magsoro.robots.base import read_csv

    res = reproduce(name, out=tmp_path, preview=True)
    _check(res)
    c = read_csv(res.csv)
    if name == "strip_magnet":
        assert np.all(np.diff(c["strain_percent"]) > 0)     # closer magnet, more strain
        assert np.all(c["thin_over_thick_strain"] > 1.0)    # the thin sections strain more
    elif name == "obstacle_beam":
        assert c["dmax_over_L_obstacle"][-1] < c["dmax_over_L_free"][-1]
    elif name == "continuum_soft":
        # datasheet parameters (E 69 kPa) bend more than the measured ones (E 102.1 kPa)
        assert np.all(c["tip_deflection_theoretical_mm"] > c["tip_deflection_corrected_mm"])
        assert np.all(np.diff(c["tip_deflection_corrected_mm"]) > 0)
    else:
        # the measured (softer) plain sections bend more than the single datasheet modulus
        assert np.all(c["tip_deflection_corrected_mm"] > c["tip_deflection_theoretical_mm"])


@pytest.mark.slow
def test_strip_magnet_falls_back_to_the_dynamics_where_the_static_solver_refuses(tmp_path, monkeypatch):
    """strip_magnet's curve comes from the static solver; with the strip's moment following R
    (magnetization_follows = "R", which the static solver refuses) the reproduction runs the dynamic sweep
    instead and compares with the bar model of the same law: at the preview grid 1.58 and 3.88 % at 55 and 40 mm
    (bar model, R: 1.44 and 3.55 %; the F law gives 2.21 and 5.48 %). About 140 s."""
    import shutil

    from magsoro.robots import reproduce
    from magsoro.robots.base import read_csv

    scenes = tmp_path / "scenes"
    shutil.copytree(ROOT / "scenes", scenes)
    path = scenes / "strip_magnet.toml"
    text = path.read_text()
    changed = text.replace('material = "ecoflex-00-30-ndfeb100"',
                           'material = { library = "ecoflex-00-30-ndfeb100", magnetization_follows = "R" }')
    assert text.count('material = "ecoflex-00-30-ndfeb100"') > 0 and 'material = "ecoflex' not in changed
    path.write_text(changed)
    monkeypatch.setenv("MAGSORO_SCENES", str(scenes))
    res = reproduce("strip_magnet", out=tmp_path / "out", preview=True)
    _check(res)
    assert res.info["solver"] == "dynamic" and "magnetization_follows" in res.info["static_refused"]
    c = read_csv(res.csv)
    assert c["strain_percent"][-1] == pytest.approx(3.88, rel=0.01)
    assert c["bar_model_strain_percent"][-1] < 0.75 * 5.17  # the R bar model, not the F one (5.17 %)
