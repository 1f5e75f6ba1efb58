"""Seed 003's letter robots (s_shape, l_shape, c_shape; magsoro.robots._letters): registry, scenes, target
letters, the rod model built from a scene, the mixture-rule numbers of the L robot's concentration study, and
(slow) the preview reproductions with their acceptance checks."""

import math
import shutil

import numpy as np
import pytest

from magsoro.robots import ROBOTS
from magsoro.robots._letters import (
    PATH_TOL,
    SHAPE_TOL,
    library_remanence,
    plane_strain_modulus,
    rms,
    rod_model,
    rod_sweep,
    strip,
    target_local,
    turning_angle,
    write_vectors,
)
from magsoro.robots.base import RobotError, scene, scene_data, scenes_dir

NAMES = ("s_shape", "l_shape", "c_shape")


def _letter(name):
    import importlib

    return importlib.import_module(f"magsoro.robots.{name}").LETTER


def test_registry_names_and_entries():
    assert {"s_shape", "l_shape", "c_shape"} <= set(ROBOTS)
    for name in NAMES:
        r = ROBOTS[name]
        assert r.source.startswith("seed 003")
        assert r.scene_path.is_file()
        assert (scenes_dir() / name / "reproduce.py").is_file() and (scenes_dir() / name / "design.py").is_file()
        assert r.in_ci is False


@pytest.mark.parametrize("name", NAMES)
def test_scene_loads_and_strip_sits_on_lattice_lines(name):
    sc = scene(name)
    data = scene_data(name)
    st = strip(data)
    assert len(st.segments) == 10
    assert st.length == pytest.approx(0.020, abs=1e-12)
    assert st.thickness == pytest.approx(0.0005) and st.depth == pytest.approx(0.004)
    assert sc.simulation.dim == 2 and sc.simulation.precision == "float64"
    for dx in (sc.simulation.dx, scene(name, preview=True).simulation.dx):
        lo = np.asarray(sc.simulation.domain_lo[:2])
        # faces (segment ends, the strip's sides) on lattice lines: a partly filled layer changes the statics
        faces = [(st.origin + st.axis * e) for e in st.edges] + [st.origin + st.normal * st.thickness / 2]
        for f in faces:
            cells = (f - lo) / dx
            assert np.allclose(cells, np.round(cells), atol=1e-6), (name, dx, f)
    # the field is the design field and lies in the plane
    assert np.linalg.norm(st.field) == pytest.approx(0.02)
    assert st.field[2] == 0.0


@pytest.mark.parametrize("name", NAMES)
def test_designed_magnetisation_is_feasible_and_in_plane(name):
    data = scene_data(name)
    st = strip(data)
    lib, br_max = library_remanence(data)
    assert lib == "dragon-skin-10-ndfeb100"
    assert br_max == pytest.approx(0.1123, abs=2e-4)
    norms = np.linalg.norm(st.vectors, axis=1)
    assert np.all(norms <= br_max * (1 + 1e-9))
    assert np.all(norms > 0.0)
    for p in data["robot"]["parts"]:
        if p["name"] in st.segments:
            assert p["magnetization"][2] == 0.0


def test_target_letters_have_the_closed_form_ends():
    L = 0.02
    s = np.array([0.0, L])
    S, Lt, C = (_letter(n).pieces for n in NAMES)
    # S: two half circles of radius L / (2 pi): ends 4 R to the left of the start, heading the same way
    end = target_local(S, s, L)[-1]
    assert end == pytest.approx([0.0, 2 * L / math.pi], abs=1e-7)
    assert turning_angle(S, [0.5, 1.0]) == pytest.approx([math.pi, 0.0])
    # C: 3 mm arm, half circle over 14 mm (R = 0.7 L / pi), 3 mm arm back: ends above the start
    R = 0.7 * L / math.pi
    assert target_local(C, s, L)[-1] == pytest.approx([0.0, 2 * R], abs=1e-7)
    assert turning_angle(C, [0.15, 0.85, 1.0]) == pytest.approx([0.0, math.pi, math.pi])
    # L: 11 mm stem, quarter circle of radius 0.1 L / (pi / 2), 7 mm foot to the left
    r = 0.1 * L / (math.pi / 2)
    assert target_local(Lt, s, L)[-1] == pytest.approx([0.55 * L + r, r + 0.35 * L], abs=1e-7)
    # half the turns at half scale (the design's intermediate targets)
    assert turning_angle(Lt, [1.0], 0.5) == pytest.approx([math.pi / 4])
    with pytest.raises(RobotError):
        turning_angle(((0.5, 90.0),), [0.2])


def test_world_frame_letters_stand_upright():
    """S and C curl from the clamp towards -y (the left normal of a strip running to -x); the L's foot runs to +x."""
    for name in NAMES:
        st = strip(scene_data(name))
        pts = st.to_world(target_local(_letter(name).pieces, np.linspace(0, st.length, 81), st.length))
        if name == "l_shape":
            assert pts[-1, 0] > 0.005 and pts[-1, 1] < -0.010
        else:
            assert pts[:, 1].min() < -0.008 and np.all(pts[:, 1] <= 1e-9)


def test_strip_errors_name_the_problem():
    data = scene_data("s_shape")
    bad = {**data, "robot": {"parts": [p for p in data["robot"]["parts"] if p["name"] != "base"]}}
    with pytest.raises(RobotError, match="base"):
        strip(bad)
    bad = {**data, "fields": []}
    with pytest.raises(RobotError, match="drive"):
        strip(bad)


def test_plane_strain_modulus():
    G = 1.0e5
    assert plane_strain_modulus(G, 20 * G) == pytest.approx(4 * 61 / 64 * G)
    E, nu = 9 * 20 * G * G / (3 * 20 * G + G), (3 * 20 * G - 2 * G) / (2 * (3 * 20 * G + G))
    assert plane_strain_modulus(G, 20 * G) == pytest.approx(E / (1 - nu**2))


def test_rod_of_a_straight_strip_bends_like_a_beam():
    """The rod built from a scene: a strip magnetised along its axis bends towards the field, as linear beam
    theory says for a small field (tip deflection c L^3 / (3 E I), c = A Br B / mu0 the couple per length)."""
    from magsoro.constants import MU0

    st = strip(scene_data("s_shape"))
    E = 4.5e5
    axial = np.tile(0.1 * st.axis, (len(st.segments), 1))
    B = 1e-5 * st.normal
    rod = rod_model(st, E, axial)
    sol = rod.solve((B[0], B[1], 0.0))
    w = (sol.tip_position[:2] - st.origin) @ st.normal
    c = st.depth * st.thickness * 0.1 * np.linalg.norm(B) / MU0
    expect = c * st.length**3 / (3 * E * st.depth * st.thickness**3 / 12)
    assert w == pytest.approx(expect, rel=5e-3)


@pytest.mark.parametrize("name", NAMES)
def test_design_holds_for_the_rod(name):
    """The rod swept to the design field with the scene's vectors forms the target within the acceptance."""
    from magsoro.materials import get_material

    data = scene_data(name)
    st = strip(data)
    G = get_material(library_remanence(data)[0]).shear_modulus  # the scene's K is the default 20 G
    rod = rod_model(st, plane_strain_modulus(G, 20 * G), n_nodes=41)
    s = np.linspace(0.0, st.length, 41)
    shapes, msg = rod_sweep(rod, [st.field * f for f in (0.25, 0.5, 0.75, 1.0)], s)
    assert msg == ""
    target = st.to_world(target_local(_letter(name).pieces, s, st.length))
    assert rms(shapes[-1], target, st.length) < SHAPE_TOL
    assert 0 < SHAPE_TOL <= PATH_TOL


def test_target_file_matches_the_letter():
    """scenes/NAME/target.toml (magsoro optimize's target, written by design.py) holds the letter's points."""
    import tomllib

    for name in NAMES:
        st = strip(scene_data(name))
        spec = tomllib.loads((scenes_dir() / name / "target.toml").read_text())
        assert spec["type"] == "centreline" and spec["bodies"] == st.segments
        pts = np.asarray(spec["points"])
        assert pts.shape == (40, 2)
        # the points lie on the letter: each is the target at its own arc length
        s = np.linspace(0.0, st.length, 4001)
        curve = st.to_world(target_local(_letter(name).pieces, s, st.length))
        gap = np.min(np.linalg.norm(pts[:, None, :] - curve[None], axis=2), axis=1)
        assert np.max(gap) < 1e-5


def test_mixture_rule_numbers_of_the_concentration_study():
    from magsoro.materials import get_material
    from magsoro.robots.l_shape import CONCENTRATIONS, composite

    lib = get_material("dragon-skin-10-ndfeb100")
    c = composite(100.0, "dragon-skin-10-ndfeb100")
    # at the design concentration the rules give the library entry's own numbers
    assert c["remanence"] == pytest.approx(lib.remanence, rel=1e-12)
    assert c["density"] == pytest.approx(lib.density, rel=1e-12)
    assert c["volume_fraction"] == pytest.approx(lib.volume_fraction, rel=1e-12)
    # closed forms, 50 wt% in a 1070 kg/m^3 matrix with seed 003's particles (7610 kg/m^3, 911 mT)
    c = composite(50.0, "dragon-skin-10-ndfeb100")
    phi = (0.5 / 7610) / (0.5 / 7610 + 1 / 1070)
    assert c["volume_fraction"] == pytest.approx(phi, rel=1e-12)
    assert c["remanence"] == pytest.approx(0.911 * phi, rel=1e-12)
    assert c["density"] == pytest.approx(1.5 / (1 / 1070 + 0.5 / 7610), rel=1e-12)
    assert c["volume_fraction"] == pytest.approx(0.06569, abs=1e-5)
    br = [composite(w, "dragon-skin-10-ndfeb100")["remanence"] for w in CONCENTRATIONS]
    assert np.all(np.diff(br) > 0)
    assert max(CONCENTRATIONS) <= 100.0  # Dragon Skin 10 cures with at most 100 wt% (seed 001 sec III-B)


def test_write_vectors_replaces_only_the_segment_lines(tmp_path):
    src = scenes_dir() / "c_shape.toml"
    dst = tmp_path / "c_shape.toml"
    shutil.copy(src, dst)
    st = strip(scene_data("c_shape"))
    new = np.arange(20, dtype=float).reshape(10, 2) * 1e-3
    write_vectors(dst, st.segments, new)
    import tomllib

    data = tomllib.loads(dst.read_text())
    got = strip(data).vectors
    assert got == pytest.approx(new)
    before, after = src.read_text().splitlines(), dst.read_text().splitlines()
    changed = [a for a, b in zip(before, after) if a != b]
    assert len(before) == len(after) and len(changed) == 10
    assert all(a.startswith("magnetization = [") for a in changed)
    with pytest.raises(RobotError, match="seg99"):
        write_vectors(dst, ["seg99"], new[:1])


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_preview_reproduction_passes_its_checks(name, tmp_path):
    from magsoro.robots import reproduce

    res = reproduce(name, out=tmp_path, preview=True, log=lambda m: None)
    for path in (res.csv, res.png, res.animation, tmp_path / f"{name}_shapes.csv", tmp_path / "result.json"):
        assert path.is_file()
    failed = [(r.quantity, r.value, r.tolerance) for r in res.rows if not r.passed]
    assert not failed, failed
    assert len(res.rows) == (9 if name == "l_shape" else 5)
    if name == "l_shape":
        for f in ("l_shape_concentration.csv", "l_shape_concentration.png", "l_shape_stiffness.csv", "l_shape_stiffness.png"):
            assert (tmp_path / f).is_file()
