"""Robot growing_retroflexion (seed 004, the magnetic-tip growing robot curled to 180 degrees by the planned
magnet, replayed in 3D): the scene file against the plan it stands for, and the preview reproduction."""

from __future__ import annotations

import json

import numpy as np
import pytest

from magsoro.robots import growing_retroflexion as gr


def test_scene_file_is_the_plans_robot_under_its_last_pose():
    """scenes/growing_retroflexion.toml holds the plan's robot (10 links of 6 mm, the tip's remanence) on the floor
    under the magnet of the plan's last step, to the digits written there."""
    from magsoro.actuation.replay import link_remanence
    from magsoro.robots.base import scene_data

    cfg, robot, strip, plan = gr._plan()
    data = scene_data(gr.NAME)
    links = [b for b in data["bodies"] if b["name"].startswith("link")]
    assert len(links) == robot.n_links
    br = link_remanence(robot, strip)
    for j, b in enumerate(links):
        assert b["shape"]["center"][0] == pytest.approx((j + 0.5) * robot.link_length, abs=1e-9)
        assert b["shape"]["size"] == pytest.approx([robot.link_length, strip.thickness, strip.depth], abs=1e-12)
        assert np.allclose(b.get("magnetization", [0.0, 0.0, 0.0]), br[j], atol=1e-12)
        m = b["material"]
        assert (m["shear_modulus"], m["bulk_modulus"], m["density"]) == (strip.shear_modulus, strip.bulk_modulus,
                                                                         strip.density)
    epm = next(f for f in data["fields"] if f["name"] == "epm")
    assert np.allclose(epm["position"], plan.steps[-1].position, atol=1e-5)
    assert np.allclose(epm["moment"], plan.steps[-1].moment, atol=1e-3)
    assert data["colliders"][0]["point"][2] == pytest.approx(robot.plane_z - 0.5 * strip.depth)


@pytest.mark.slow
def test_preview_reproduction(tmp_path):
    """The preview (dx 3 mm, two cells across the section, about 25 s): growth follows the plan, the bends at 60
    and 120 degrees lie within 10 % of the length of the beam PRB, the tip stays near the floor; free in space
    the robot leaves the plane. The 180-degree bend is the documented gap (measured 31 % of the length here,
    25 % at dx 1.5 mm)."""
    from magsoro.robots import reproduce

    res = reproduce(gr.NAME, out=tmp_path, preview=True, log=lambda msg: None)
    rows = {r.quantity: r for r in res.rows}
    assert len(rows) == 7
    for q, r in rows.items():
        if "growth step" in q or "60 deg" in q or "120 deg" in q or "height" in q:
            assert r.passed, (q, r.value)
    assert next(r for q, r in rows.items() if "180 deg" in q).value < 0.2  # measured 0.12
    free = np.array(res.info["free_tips_mm"])
    assert free[3, 2] > 3.0 and free[4, 2] < -20.0  # measured +7.4 and -39.6 mm
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["name"] == gr.NAME and len(result["checks"]) == 7
    for f in ("growing_retroflexion.csv", "growing_retroflexion.png", "growing_retroflexion.gif"):
        assert (tmp_path / f).stat().st_size > 0
    header = (tmp_path / "growing_retroflexion.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["t_s", "floor_tip_x_mm", "floor_tip_y_mm", "floor_tip_z_mm"]
