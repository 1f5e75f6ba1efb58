"""Robot tail_pull (seed 004, the tail pulled through the everted wall): the tails' geometry, the scene file against
the module that writes it, and the contact-force reading (int T dphi) against a ring under a known pressure."""

from __future__ import annotations

import math

import numpy as np
import pytest

from magsoro.robots import tail_pull as tp
from magsoro.robots.tail_crush import ARM_HALF_WIDTH, WALL, WALL_RADIUS


def test_scene_file_holds_the_cylindrical_tail_the_module_builds():
    from magsoro.robots.base import scene_data

    data = scene_data(tp.NAME)
    grow, duration = tp._timing(data)
    assert (grow, duration) == (0.02, 0.06)
    in_file = data["robot"]["parts"]
    built = tp.cylindrical_tail(grow)
    assert [p["name"] for p in in_file] == [p["name"] for p in built]
    for a, b in zip(in_file, built):
        for key in ("radius", "width", "start_angle", "end_angle"):
            assert a["shape"][key] == pytest.approx(b["shape"][key], rel=1e-12)
        sa, sb = a["material"]["stimulus"], b["material"]["stimulus"]
        assert np.allclose(sa["stretch"], sb["stretch"], rtol=1e-12, atol=0)
        assert sa["direction"] == pytest.approx(sb["direction"], rel=1e-12, abs=1e-15)


def test_grown_tails_have_their_natural_size():
    """Grown, the cylindrical tail's mid-line is the wall's (the same tube); the cruciform's arm tips reach the
    asked radius; both start GAP inside the bore."""
    cyl = tp.cylindrical_tail(0.02)
    r0 = cyl[0]["shape"]["radius"]
    assert r0 * cyl[0]["material"]["stimulus"]["stretch"][1][1] == pytest.approx(WALL_RADIUS)
    assert r0 + WALL / 2.0 == pytest.approx(tp.inner_radius())
    # each arc grows along the tangent at its middle
    mid = math.radians(0.5 * (cyl[3]["shape"]["start_angle"] + cyl[3]["shape"]["end_angle"]))
    assert cyl[3]["material"]["stimulus"]["direction"] == pytest.approx([-math.sin(mid), math.cos(mid)])
    for tip in tp.CRU_TIPS:
        parts = {p["name"]: p for p in tp.cruciform_tail(tip, 0.02)}
        side = parts["arm0_side2"]
        stretch = side["material"]["stimulus"]["stretch"][1][1]
        inner_end = side["shape"]["center"][0] - side["shape"]["size"][0] / 2.0
        # grown: the side wall's outer end plus the cap's thickness is the tip
        assert inner_end + side["shape"]["size"][0] * stretch + WALL == pytest.approx(tip)
        assert side["shape"]["center"][1] == pytest.approx(ARM_HALF_WIDTH)
        cap = parts["arm0_cap"]
        corner = math.hypot(cap["shape"]["center"][0] + WALL / 2.0, ARM_HALF_WIDTH + WALL / 2.0)
        assert corner == pytest.approx(tp.inner_radius() - tp.GAP)
    with pytest.raises(Exception, match="fits the bore"):
        tp.cruciform_tail(0.7e-3, 0.02)


@pytest.mark.parametrize("tail, tip", [("cylindrical", None), ("cruciform", 0.9e-3)])
def test_tails_fill_as_one_contact_group_inside_the_bore(tail, tip):
    from magsoro.robots.base import scene
    from magsoro.scene.build import contact_groups, fill_bodies

    sc = scene(tp.NAME, tp.case_scene(tail, tip), preview=True)
    parts = fill_bodies(sc)
    groups = contact_groups(sc, parts.positions, parts.body)
    names = [b.name for b in sc.bodies]
    wall = names.index("wall")
    tail_ids = [i for i, n in enumerate(names) if n != "wall"]
    assert len({groups[i] for i in tail_ids}) == 1 and groups[wall] != groups[tail_ids[0]]
    r_tail = np.hypot(*parts.positions[np.isin(parts.body, tail_ids)].T)
    r_wall = np.hypot(*parts.positions[parts.body == wall].T)
    assert r_tail.max() < r_wall.min()


def _pressed_ring(dx: float, p: float):
    """The wall alone under a gauge pressure p on its bore, settled."""
    from magsoro.robots.base import scene_data
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    data = scene_data(tp.NAME)
    data.pop("robot")
    data.pop("contact")
    data["simulation"].update(dx=dx, duration=0.03)
    # a cavity circumscribing the bore (a polygon inscribed in the bore would leave out faces at its edges)
    bore = (WALL_RADIUS - WALL / 2.0) / math.cos(math.pi / 72) + 1e-6
    cavity = [[bore * math.cos(a), bore * math.sin(a)] for a in np.linspace(0.0, 2.0 * math.pi, 73)[:-1]]
    data["bodies"][0]["pressure"] = {"cavity": {"type": "polygon", "vertices": cavity}, "value": p, "ramp": 0.01}
    sim = Simulation(parse_scene(data, "pressed ring"))
    assert sim.run(0.03).status == "completed"
    return sim


@pytest.mark.slow
def test_contact_force_reading_on_a_pressed_ring():
    """int T dphi of the wall under a pressure p equals p times the bore's current perimeter times the depth: the
    loads the reading stands for (measured +2.3 % at two cells through the wall)."""
    p = 2000.0
    sim = _pressed_ring(5e-5, p)
    host = sim.model.host
    faces = host["pressure_area"][:, :2]
    X = host["positions"]
    radial = -float(np.sum(faces * X / np.linalg.norm(X, axis=1, keepdims=True)))  # the faces' reference area
    assert radial == pytest.approx(2.0 * math.pi * (WALL_RADIUS - WALL / 2.0) * sim.scene.simulation.depth, rel=0.01)
    # the bore's hoop stretch: the inner particle layer's radius over its reference radius
    r = np.hypot(*sim.state.x.numpy().T)
    R = np.hypot(*X.T)
    inner = R < R.min() + 1e-9
    stretch = float(np.mean(r[inner] / R[inner]))
    expected = p * radial * stretch
    assert tp.ring_contact_force(sim, 0) == pytest.approx(expected, rel=0.04)
    with pytest.raises(Exception, match="bin holds no particle"):
        tp.ring_contact_force(sim, 0, bins=5000)


@pytest.mark.slow
def test_preview_reproduction_passes_its_model_checks(tmp_path):
    """The preview (the cylindrical tail and the robot-sized cruciform, about 3 minutes): both settle, and the
    cruciform needs less pull force (the seed's ordering); the ratio against the seed's five is reported."""
    from magsoro.robots import reproduce

    res = reproduce(tp.NAME, out=tmp_path, preview=True, log=lambda msg: None)
    rows = {r.quantity: r for r in res.rows}
    assert all(r.passed for q, r in rows.items() if q.startswith("settled"))
    assert next(r for q, r in rows.items() if q.startswith("cruciform tail needs less")).passed
    ratio = next(r for q, r in rows.items() if q.startswith("pull force ratio"))
    assert ratio.value > 1.0 and ratio.reference == tp.PAPER_RATIO
    # against two concentric rings sharing the misfit: tail and wall mid-lines 0.8 and 0.9 mm (touching, their
    # mean the tube's 0.85), hoop strains -+1/17, N = 2 pi E' t (1/17) L with E' the plane-strain modulus of the
    # engine's law (K = 20 G); measured -7 % (the pair buckles into a rounded square, relieving some of it)
    from magsoro.materials.library import get_material

    G = get_material(tp.MATERIAL).shear_modulus
    K = 20.0 * G
    E = 9.0 * K * G / (3.0 * K + G)
    nu = (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))
    closed = 2.0 * math.pi * E / (1.0 - nu**2) * WALL * (WALL / 2.0 / WALL_RADIUS) * tp.LENGTH
    assert res.info["contact_force_N"]["cylindrical"] == pytest.approx(closed, rel=0.2)
