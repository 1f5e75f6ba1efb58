"""Robot tail_crush (seed 004, lateral crushing of the everted growing robot): the tails' geometry, the scene file
against the module that builds it, the stiffness readings, and the crushing rig against the closed form of a thin
ring squeezed between plates (quick at the preview's two cells through the wall, slow at the full resolution)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from magsoro.robots import tail_crush as tc


def _built(tail: str, angle: float, preview: bool = True):
    from magsoro.robots.base import scene
    from magsoro.scene.build import contact_groups, fill_bodies

    sc = scene(tc.NAME, tc.case_scene(tail, angle), preview=preview)
    parts = fill_bodies(sc)
    groups = contact_groups(sc, parts.positions, parts.body)
    return sc, parts, groups


def test_scene_file_holds_the_cylindrical_tail_the_module_builds():
    """scenes/tail_crush.toml (what `magsoro run` shows) is the module's cylindrical tail with its fold at the top."""
    from magsoro.robots.base import scene_data

    in_file = {p["name"]: p for p in scene_data(tc.NAME)["robot"]["parts"]}
    built = {p["name"]: p for p in tc.cylindrical_tail(90.0)}
    assert set(in_file) == set(built)
    for name, part in built.items():
        for key, value in part["shape"].items():
            if isinstance(value, str):
                assert in_file[name]["shape"].get(key, value) == value
            else:
                got = in_file[name]["shape"].get(key, 0.0 if key == "angle" else None)
                assert got is not None and np.allclose(np.ravel(got), np.ravel(value), rtol=1e-8, atol=1e-12), (name, key)


def test_cylindrical_tail_has_the_tube_perimeter_and_clears_the_bore():
    r = tc.tail_radius()
    fold = tc.cylindrical_tail(0.0)[1]["shape"]["size"][0] - tc.WALL / 2.0  # root at the ring's outer face
    # mid-line: the ring's arc without the root, plus both walls of the fold (to the fold's inner end)
    perimeter = 2.0 * math.pi * r - 2.0 * tc.WALL + 2.0 * fold
    assert perimeter == pytest.approx(2.0 * math.pi * tc.WALL_RADIUS, rel=1e-9)
    assert r + tc.WALL / 2.0 == pytest.approx(tc.WALL_RADIUS - tc.WALL / 2.0 - tc.GAP)


@pytest.mark.parametrize("tail, angle", [("cylindrical", 90.0), ("cylindrical", 0.0), ("cruciform", 90.0), ("cruciform", 45.0)])
def test_tails_fill_inside_the_bore_as_one_contact_group(tail, angle):
    """Every tail particle lies inside the wall's bore, clear of it; the tail's parts are one contact group apart
    from the wall's; the tail's area is its mid-line perimeter times the wall (the lattice rounds it by a few %)."""
    sc, parts, groups = _built(tail, angle)
    names = [b.name for b in sc.bodies]
    X, body = parts.positions, parts.body
    wall = names.index("wall")
    tail_ids = [i for i, n in enumerate(names) if n != "wall"]
    r_tail = np.hypot(*X[np.isin(body, tail_ids)].T)
    r_wall = np.hypot(*X[body == wall].T)
    assert r_tail.max() < r_wall.min()
    assert len({groups[i] for i in tail_ids}) == 1 and groups[wall] not in {groups[i] for i in tail_ids}
    h = sc.simulation.dx / sc.simulation.particles_per_cell
    area = np.isin(body, tail_ids).sum() * h * h
    mid = 2.0 * math.pi * tc.WALL_RADIUS
    expected = mid * tc.WALL if tail == "cruciform" else (mid - 2.0 * (tc.cylindrical_tail(0.0)[1]["shape"]["size"][0] - tc.WALL / 2.0)) * tc.WALL + tc.cylindrical_tail(0.0)[1]["shape"]["size"][0] * 2.0 * tc.WALL
    assert area == pytest.approx(expected, rel=0.12)


def test_cruciform_outline_turns_with_its_angle():
    a0 = np.array(tc.cruciform_tail(90.0)[0]["shape"]["vertices"])
    a45 = np.array(tc.cruciform_tail(135.0)[0]["shape"]["vertices"])
    reach = 2.0 * math.pi * tc.WALL_RADIUS / 8.0 + tc.WALL / 2.0
    assert np.abs(a0).max() == pytest.approx(reach)
    c = math.cos(math.radians(45.0))
    assert np.allclose(a45, a0 @ np.array([[c, c], [-c, c]]), atol=1e-15)


def test_secant_and_depth_readings():
    d = np.linspace(0.0, tc.CRUSH, 301)
    F = 20.0 * d + 1e8 * d**3
    assert tc.secant_at(d, F, tc.CRUSH) == pytest.approx(20.0 + 1e8 * tc.CRUSH**2, rel=1e-9)
    assert tc.secant_at(d, F, 0.7e-3) == pytest.approx(20.0 + 1e8 * 0.49e-6, rel=2e-3)
    # F / d = 20 + 1e8 d^2 reaches 121 N/m at d = sqrt(101e-8)
    assert tc.depth_for(d, F, 121.0) == pytest.approx(math.sqrt(101e-8), rel=1e-3)
    assert math.isnan(tc.depth_for(d, F, 1e6))


def _ring_slope(dx: float) -> tuple[float, float]:
    """Crush the wall alone by 0.1 mm over 20 ms (five periods of its first mode) and return (dF/dd from 0.025
    to 0.09 mm, the closed form), both N/m. The closed form: a thin ring between plates in plane strain,
    F = E' I / ((pi/4 - 2/pi) R^3) delta per unit length, E' = E / (1 - nu^2) of the engine's law (K, G)."""
    from magsoro.robots.base import scene_data
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    data = scene_data(tc.NAME)
    data.pop("robot")
    data["contact"]["self_contact"] = False
    T, dmax = 0.02, 0.1e-3
    data["simulation"].update(dx=dx, duration=T)
    top = tc.WALL_RADIUS + tc.WALL / 2.0
    moving = [c for c in data["colliders"] if c.get("path")][0]
    moving["path"] = {"times": [0.0, T], "positions": [[0.0, top], [0.0, top - dmax]]}
    sim = Simulation(parse_scene(data, "tail_crush ring"))
    rows = []

    def record(s):
        if s.time > 0.0:
            rows.append(((s.time - T / 80.0) * dmax / T, s.collider_forces()[1, 1]))

    assert sim.run(T, record=record, record_every=T / 40.0).status == "completed"
    d, F = np.array(rows).T
    use = (d >= 0.025e-3) & (d <= 0.09e-3)
    slope = float(np.polyfit(d[use], F[use], 1)[0])
    G, K = float(sim.model.host["shear_modulus"][0]), float(sim.model.host["bulk_modulus"][0])
    E = 9.0 * K * G / (3.0 * K + G)
    nu = (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))
    EI = E / (1.0 - nu**2) * tc.WALL**3 / 12.0
    closed = EI / ((math.pi / 4.0 - 2.0 / math.pi) * tc.WALL_RADIUS**3) * sim.scene.simulation.depth
    return slope, closed


@pytest.mark.slow
def test_rig_crushes_a_thin_ring_like_the_closed_form_preview():
    """Two cells through the wall (the preview): measured +8.6 % (2D MPM bends stiff at so few cells)."""
    slope, closed = _ring_slope(5e-5)
    assert closed == pytest.approx(8.35, rel=0.01)
    assert slope == pytest.approx(closed, rel=0.12)


@pytest.mark.slow
def test_rig_crushes_a_thin_ring_like_the_closed_form_full():
    """Four cells through the wall (the reproduction): measured +1 %."""
    slope, closed = _ring_slope(2.5e-5)
    assert slope == pytest.approx(closed, rel=0.03)


@pytest.mark.slow
def test_preview_reproduction_passes_its_model_checks(tmp_path):
    """The preview (three crushes, about 3 minutes): quasi-static loading, the fold direction matters, the
    cruciform is stiffer than the cylindrical tail's softer direction where the stiffer one reaches 121 N/m; the
    seed's numbers at 1.5 mm are far off (the documented gap: the layers are squeezed) and stay reported."""
    from magsoro.robots import reproduce

    res = reproduce(tc.NAME, out=tmp_path, preview=True, log=lambda msg: None)
    rows = {r.quantity: r for r in res.rows}
    assert all(r.passed for q, r in rows.items() if q.startswith("quasi-static"))
    fold = next(r for q, r in rows.items() if q.startswith("cylindrical tail: stiffer / softer"))
    assert fold.passed and fold.value > 2.0
    soft = next(r for q, r in rows.items() if q.startswith("cruciform stiffer") and "fold across" in q)
    assert soft.passed
    at15 = [r for q, r in rows.items() if q.startswith("stiffness F(1.5 mm)")]
    assert len(at15) == 3 and all(r.value > 10 * r.reference for r in at15)
    assert (tmp_path / "tail_crush_secant.csv").is_file() and (tmp_path / "result.json").is_file()
