"""Robots of seed 002 sec 5.3-5.5: pentahedron, hexahedron and arch (scenes/*.toml, magsoro.robots.*)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from magsoro.robots import ROBOTS, reproduce
from magsoro.robots.base import read_csv, scene, scene_data
from magsoro.robots.pentahedron import (magnet_center_for, magnet_entry, magnet_source, strip_fold_angle,
                                        sweep_path)

NAMES = ["pentahedron", "hexahedron", "arch"]


@pytest.mark.parametrize("name", NAMES)
def test_scene_and_preview_load(name):
    """The scene and its [preview] variant are accepted by the loader, and the robot is registered."""
    full = scene(name)
    prev = scene(name, preview=True)
    assert prev.simulation.dx > full.simulation.dx
    assert name in ROBOTS and ROBOTS[name].source.startswith("seed 002 sec 5.")


@pytest.mark.parametrize("name,up,point", [("pentahedron", 2, (0.0, 0.0, 0.001)), ("arch", 1, (0.0, 0.001, 0.0))])
def test_magnet_distance_gives_the_level(name, up, point):
    """The sweep puts the magnet where its field at the robot's centre is the level, and the magnet's face stays
    below the plate (z or y = 0) at 45 mT: the level is reachable through the 1 mm plate."""
    entry = magnet_entry(scene_data(name))
    path, reads, centres = sweep_path(entry, [0.0, 0.015, 0.045], point, 0.01, 0.02, 0.05, up=up)
    for level, h in zip([0.015, 0.045], centres[1:]):
        c = [0.0, 0.0, 0.0]
        c[up] = h
        B = magnet_source(entry, c).B(np.asarray([point]))[0]
        assert B[up] == pytest.approx(level, rel=1e-5)
    assert centres[-1] + entry["length"] / 2 < -0.001
    # the measured 50 mT at the face centre (seed 002 sec 4.1) that sets the scenes' remanence
    face = [0.0, 0.0, 0.0]
    face[up] = entry["length"] / 2 + 1e-9
    assert abs(magnet_source(entry, (0.0, 0.0, 0.0)).B(np.asarray([face]))[0][up]) == pytest.approx(0.05, rel=1e-3)
    assert len(reads) == 3 and reads[-1] == pytest.approx(0.01 + 2 * 0.07)


def test_strip_elastica_small_field_matches_beam_theory():
    """The reduced model against linear beam theory: a weightless uniform strip, magnetised along itself, in a
    small uniform field bends with tip angle q L^2 / (2 EI) and chord angle q L^2 / (3 EI)."""
    E, t, L, Br, B = 2.0e5, 0.002, 0.01, 0.0443, 1e-4
    q = Br / (4e-7 * math.pi) * B * t
    EI = E * t ** 3 / 12
    chord = strip_fold_angle([(L, "tangent", 1.0)], B, 0.0, Br, E, t, rho=1000.0, chord=(0.0, L), g=0.0)
    assert chord == pytest.approx(math.degrees(q * L ** 2 / (3 * EI)), rel=1e-3)


@pytest.mark.slow
def test_pentahedron_preview(tmp_path):
    """The CI reproduction: coarse, levels 0 and 45 mT. Its checks must pass, and the side squares must fold by
    a sizeable, symmetric angle below vertical."""
    res = reproduce("pentahedron", out=tmp_path, preview=True)
    assert res.passed, [r.as_dict() for r in res.rows if not r.passed]
    data = read_csv(res.csv)
    alpha = data["alpha_deg"]
    assert data["B_mT"][-1] == pytest.approx(45.0)
    assert abs(alpha[0]) < 0.5                      # flat on the plate without a field
    assert 25.0 < alpha[-1] < 75.0                  # folds up, short of the box (2 mm squares, 44 mT remanence)
    sides = [data[f"alpha_side_{k}_deg"][-1] for k in ("px", "nx", "py", "ny")]
    assert max(sides) - min(sides) < 1.0            # the magnet is on the robot's axis: all four alike
    assert (tmp_path / "pentahedron.gif").stat().st_size < 1.5e6


def test_arch_magnetoelastic_number_by_hand():
    """The arch's saturation explained (magsoro.robots.arch.magnetoelastic_level): N = 12 |Br| B R^2 / (mu0 E' t^2)
    with the scene's |Br| 44.3 mT, G 66.7 kPa, K 1.334 MPa (E 196.8 kPa, nu 0.4754, E' 254.3 kPa), mid radius 19 mm,
    thickness 2 mm: 150.1 per tesla, so N = 1 at 6.66 mT, inside the measured jump of the major axis (40.7 mm at
    3 mT, 54.7 at 6, flat 59.9 at 9: docs/robots/arch/arch.csv)."""
    from magsoro.robots.arch import magnetoelastic_level
    from magsoro.robots.base import simulation

    data = scene_data("arch")
    sim = simulation("arch", data, preview=True, device="cpu")
    per_tesla, b_one, br = magnetoelastic_level(sim, data)
    G, K = 66.7e3, 1.334e6
    E, nu = 9 * K * G / (3 * K + G), (3 * K - 2 * G) / (2 * (3 * K + G))
    assert br == pytest.approx(0.0443, rel=1e-6)
    assert per_tesla == pytest.approx(12 * 0.0443 * 0.019 ** 2 / (4e-7 * math.pi * E / (1 - nu ** 2) * 0.002 ** 2), rel=1e-3)
    assert per_tesla == pytest.approx(150.1, rel=2e-3)
    assert 3e-3 < b_one < 9e-3


# -- full resolution (slow): one run per robot, shared by its tests ---------------------------------------------
# The comparisons with the paper's numbers fail with the seed's material data and our stated assumptions (see
# docs/robots/NAME/result.json): they are kept as strict xfails, so a change that makes them pass is noticed.
PAPER_MISS = {
    "pentahedron": "alpha(45 mT) ~41 deg vs the paper's 90: E = 0.2 MPa, |Br| = 44.3 mT, 2 mm squares fold less",
    "hexahedron": "beta(45 mT) ~50 deg vs the paper's 70 with the same material",
    "arch": "our arch is flat (59.7 mm) from ~9 mT on, the paper's is 50 mm at 45 mT: its magneto-elastic number "
            "12 |Br| B R^2 / (mu0 E' t^2) passes 1 at 6.7 mT with |Br| = 44.3 mT, E = 0.2 MPa",
}


@pytest.fixture(scope="module")
def full_runs(tmp_path_factory):
    cache = {}

    def get(name):
        if name not in cache:
            out = tmp_path_factory.mktemp(name)
            cache[name] = reproduce(name, out=out, preview=False)
        return cache[name]

    return get


def _physics_rows_pass(res):
    bad = [r.as_dict() for r in res.rows if not r.passed and "vs paper" not in r.quantity]
    assert not bad, bad


@pytest.mark.slow
def test_pentahedron_full(full_runs):
    res = full_runs("pentahedron")
    assert res.animation.stat().st_size < 1.5e6
    alpha = read_csv(res.csv)["alpha_deg"]
    assert np.all(np.diff(alpha) > 0)
    _physics_rows_pass(res)


@pytest.mark.slow
def test_hexahedron_full(full_runs):
    res = full_runs("hexahedron")
    assert res.animation.stat().st_size < 1.5e6
    data = read_csv(res.csv)
    assert data["lid_fold_deg"][-1] > data["lid_fold_deg"][1]   # the lid closes over as the field rises
    _physics_rows_pass(res)


@pytest.mark.slow
def test_arch_full(full_runs):
    res = full_runs("arch")
    assert res.animation.stat().st_size < 1.5e6
    data = read_csv(res.csv)
    assert data["major_axis_mm"][0] == pytest.approx(40.0, abs=0.5)   # the 40 mm span at rest
    _physics_rows_pass(res)


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_full_matches_paper(name, full_runs, request):
    request.applymarker(pytest.mark.xfail(strict=True, reason=PAPER_MISS[name]))
    res = full_runs(name)
    bad = [r.as_dict() for r in res.rows if not r.passed]
    assert not bad, bad


@pytest.mark.slow
@pytest.mark.parametrize("name", ["hexahedron", "arch"])
def test_preview_runs(name, tmp_path):
    res = reproduce(name, out=tmp_path, preview=True)
    assert res.passed, [r.as_dict() for r in res.rows if not r.passed]
