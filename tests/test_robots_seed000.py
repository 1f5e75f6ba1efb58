"""Robots of seed 000 sec 4.5: Hu et al.'s sheet walker, Xu et al.'s six-arm gripper, Pittiglio et al.'s
tentacle (docs/robots.md). The walker's preview reproduction runs in the default suite; the full reproductions
are slow tests."""

import numpy as np
import pytest

from magsoro.robots import ROBOTS, reproduce
from magsoro.robots.base import scene

SEED000 = ("walker", "gripper", "tentacle")


@pytest.mark.parametrize("name", SEED000)
def test_preview_scene_builds(name):
    sc = scene(name, preview=True)
    assert sc.simulation.dx > scene(name).simulation.dx  # the preview is coarser than the full scene
    assert ROBOTS[name].source == "seed 000 sec 4.5"


def _check_walker(res):
    assert res.passed, [r.as_dict() for r in res.rows]
    d = np.array(res.info["displacement_per_cycle_mm"]) * 1e-3
    length = res.info["body_length_m"]
    # a walking gait advances a fraction of the body per cycle (tumbling end over end would move about 1-2 body
    # lengths per cycle, and the other way)
    assert 0 < d[-1] < 0.5 * length
    # the sheet stays on the floor: never more than a cell into it, never higher than half its length
    assert res.info["lowest_y_m"] > -res.info["dx_m"]
    assert res.info["highest_y_m"] < 0.5 * length
    for f in (res.csv, res.png, res.animation):
        assert f.exists() and f.stat().st_size > 0
    assert res.animation.stat().st_size < 1.5e6


@pytest.mark.slow
def test_walker_preview_walks_and_speeds_up_with_field(tmp_path):
    _check_walker(reproduce("walker", out=tmp_path, preview=True))


@pytest.mark.slow
def test_walker_full(tmp_path):
    _check_walker(reproduce("walker", out=tmp_path))


def _check_tentacle(res):
    assert res.passed, [r.as_dict() for r in res.rows]
    tips = np.array(res.info["tip_mpm_m"])
    # the S forms: at the design field the tip has moved sideways by a good part of the length, towards +x
    assert tips[-1, 0] > 0.3 * 0.032
    # and the tip moves further out as the field grows
    assert np.all(np.diff(tips[:, 0]) > 0)


@pytest.mark.slow
def test_tentacle_preview(tmp_path):
    _check_tentacle(reproduce("tentacle", out=tmp_path, preview=True))


@pytest.mark.slow
def test_tentacle_full(tmp_path):
    _check_tentacle(reproduce("tentacle", out=tmp_path))


def _check_gripper(res):
    assert res.passed, [r.as_dict() for r in res.rows]
    info = res.info
    # the object is a soft particle body: it deforms while held (its lowest point is well above the floor and the
    # grasp lasts at least the required second)
    assert info["held_s"] >= 1.0 and info["min_bead_height_last_s_m"] > 1e-3
    # closing: the arms have swung in (opposite tips at most 60 % of the flat span apart)
    assert info["max_tip_gap_last_s_m"] < 0.6 * info["tip_gap_flat_m"]


@pytest.mark.slow
def test_gripper_preview(tmp_path):
    _check_gripper(reproduce("gripper", out=tmp_path, preview=True))


@pytest.mark.slow
def test_gripper_full(tmp_path):
    _check_gripper(reproduce("gripper", out=tmp_path))


def test_gripper_object_is_a_soft_particle_body():
    from magsoro.simulation import Simulation

    sc = scene("gripper", preview=True)
    names = [b.name for b in sc.bodies]
    assert "bead" in names
    assert all(c.type != "sphere" for c in sc.colliders)  # the object is not a rigid collider
    sim = Simulation(sc)
    h = sim.model.host
    bead = h["body"] == sim.built.body_names.index("bead")
    assert bead.sum() > 500 and np.all(h["shear_modulus"][bead] < 2e4)  # an elastic (Ecoflex 00-30) body
