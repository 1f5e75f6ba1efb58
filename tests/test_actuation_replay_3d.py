"""The 3D MPM replay of a magnet-path plan (seed 004's magnetic-tip growing robot steered into a retroflexion):
the robot as a free beam in the magnet's whole field, and on a frictionless floor with gravity."""

import json
from pathlib import Path

import numpy as np
import pytest

from magsoro.actuation.config import PlanConfig, load
from magsoro.actuation.replay import _rigid_fit, beam_robot, replay
from magsoro.actuation.planning import plane_strain_modulus
from magsoro.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "actuation"
PLAN = EXAMPLES / "plan_retroflexion_tip.toml"


@pytest.fixture(scope="module")
def planned():
    cfg = load(PlanConfig, PLAN)
    robot, target, planner, strip = cfg.build()
    return cfg, robot, strip, planner.plan(target)


def test_rigid_fit_recovers_a_rotation_in_3d():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(3)
    R = Rotation.random(random_state=7).as_matrix()
    X = rng.standard_normal((40, 3))
    x = X @ R.T + [0.1, -0.2, 0.3]
    R_fit, Xc, xc = _rigid_fit(X, x)
    assert np.allclose(R_fit, R, atol=1e-12) and np.allclose(xc - Xc @ R.T, [0.1, -0.2, 0.3], atol=1e-12)


def test_beam_robot_carries_youngs_modulus(planned):
    _, robot, strip, _ = planned
    beam = beam_robot(robot, strip)
    G, K = strip.shear_modulus, strip.bulk_modulus
    E = 9 * K * G / (3 * K + G)
    assert beam.bending_stiffness == pytest.approx(E * strip.thickness**3 * strip.depth / 12, rel=1e-12)
    assert beam.bending_stiffness / robot.bending_stiffness == pytest.approx(E / plane_strain_modulus(G, K), rel=1e-12)
    assert beam.link_length == robot.link_length and np.array_equal(beam.link_moments, robot.link_moments)


@pytest.mark.slow
def test_free_3d_replay_grows_in_the_plane_and_then_leaves_it(planned):
    """dx = 3 mm (two cells across the 6 mm section, 768 particles). While the robot grows straight the magnet
    lies far on its axis (B_z = 0 on the robot): the tip follows the plan to 0.1 mm and stays in the plane. When
    the magnet comes under the plane to bend it, B_z turns the tip's moment out of the plane (m x B) and the
    gradient pulls it down: the free robot first lifts its tip, then swings under, towards the magnet."""
    cfg, robot, strip, plan = planned
    r = replay(plan, strip, 0.003, cfg.replay.step_duration, dim=3)
    assert r.dim == 3 and r.tip_mpm.shape[1] == 3 and r.particles == 768
    assert r.step_end_errors[:3].max() < 1e-4  # measured 0.02 mm
    assert np.abs(r.out_of_plane[:30]).max() < 1e-4  # the three growth steps: 10 samples each
    z = r.step_end_mpm[:, 2] - r.plane_z
    assert z[3] > 0.003  # measured +7.4 mm (dx 1.5 mm: +7.8 mm): the tip lifts out of the plane
    assert z[4] < -0.02 and z[5] < -0.02  # measured -39.6 and -39.1 mm (dx 1.5 mm: -35.1, -35.2): under the plane
    assert r.step_end_in_plane_errors[4] > 0.03  # measured 74 mm: the planar plan does not hold for a free robot


@pytest.mark.slow
def test_plan_cli_replays_in_3d_on_a_floor(tmp_path, capsys):
    """The CLI's [replay] dim = 3, floor = true at dx = 3 mm: files, summary keys, the z column; on the floor the
    tip stays within a few millimetres of the plane and of the plan."""
    text = PLAN.read_text().replace("dx = 0.0015", "dx = 0.003\ndim = 3\nfloor = true")
    plan = tmp_path / "plan3d.toml"
    plan.write_text(text)
    assert main(["plan", str(plan), "--out", str(tmp_path / "out"), "--replay", "--json"]) == 0
    r = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["replay"]
    assert r["dim"] == 3 and r["floor"] is True
    assert max(r["step_end_in_plane_tip_errors_m"][:3]) < 1e-4  # straight growth: measured 0.01 mm
    assert r["step_end_in_plane_tip_errors_m"][3] < 0.005  # measured 1.8 mm (dx 1.5 mm: 1.6 mm)
    assert r["max_abs_tip_z_m"] < 0.004  # measured 1.8 mm (the tip lifts off the floor at the first bend)
    header = (tmp_path / "out" / "replay.csv").read_text().splitlines()[0]
    assert header == "t,tip_mpm_x,tip_mpm_y,tip_mpm_z,tip_prb_x,tip_prb_y,error"
    assert (tmp_path / "out" / "replay.png").stat().st_size > 0


def test_plan_cli_refuses_a_floor_in_2d(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(PLAN.read_text().replace("dx = 0.0015", "dx = 0.0015\nfloor = true"))
    assert main(["plan", str(bad), "--out", str(tmp_path / "o"), "--replay"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "replay: floor = true needs dim = 3" in err
    bad.write_text(PLAN.read_text().replace("dx = 0.0015", "dx = 0.0015\ndim = 4"))
    assert main(["plan", str(bad), "--out", str(tmp_path / "o"), "--replay"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "replay.dim" in err


def test_planar_pair_has_the_magnets_in_plane_field_on_the_plane_and_no_bz(planned):
    """The mirror pair of replay(planar_field=True): on the plane z = plane_z its field is (B_x, B_y, 0) of the
    magnet, its in-plane gradients the magnet's, and the in-plane field does not change across the plane."""
    from magsoro.actuation.replay import planar_pair

    cfg, robot, strip, plan = planned
    src = plan.keyframes(cfg.replay.step_duration, 0.5)
    for z0 in (0.0, 0.004):
        pair = planar_pair(src, z0)
        rng = np.random.default_rng(1)
        pts = np.column_stack([rng.uniform(-0.04, 0.07, 20), rng.uniform(-0.03, 0.05, 20), np.full(20, z0)])
        for t in (0.1, 2.5 * cfg.replay.step_duration, 5.9 * cfg.replay.step_duration):
            B, Bp = src.B(pts, t), pair.B(pts, t)
            scale = np.abs(B).max()
            assert np.allclose(Bp[:, :2], B[:, :2], atol=1e-12 * scale) and np.allclose(Bp[:, 2], 0.0, atol=1e-12 * scale)
            G, Gp = src.grad_B(pts, t), pair.grad_B(pts, t)
            gscale = np.abs(G).max()
            # d B_i / d x_j for in-plane i, j: the magnet's; d B_x / dz = d B_y / dz = 0 on the plane
            assert np.allclose(Gp[:, :2, :2], G[:, :2, :2], atol=1e-10 * gscale)
            assert np.allclose(Gp[:, :2, 2], 0.0, atol=1e-10 * gscale) and np.allclose(Gp[:, 2, :2], 0.0, atol=1e-10 * gscale)


@pytest.mark.slow
def test_free_3d_replay_in_the_planar_field_stays_in_the_plane(planned):
    """In the pair's field (symmetric about the plane) the free robot stays in the plane, and it follows the beam
    PRB (dx = 3 mm: 2.2, 2.6, 7.5 mm at 60, 120, 180 degrees; dx = 1.5 mm: 2.2, 0.8, 4.8 mm)."""
    cfg, robot, strip, plan = planned
    r = replay(plan, strip, 0.003, cfg.replay.step_duration, dim=3, planar_field=True,
               check_robot=beam_robot(robot, strip))
    assert np.abs(r.out_of_plane).max() < 5e-4  # measured 0.02 mm (dx 1.5 mm: 0.16 mm)
    assert r.step_end_in_plane_errors[:5].max() < 0.004 and r.step_end_in_plane_errors[5] < 0.01
    with pytest.raises(ValueError, match="planar_field needs dim = 3"):
        replay(plan, strip, 0.003, cfg.replay.step_duration, planar_field=True)
