"""Field sources of magsoro.fields driving the engine, and named from scene files."""

import numpy as np
import pytest

from magsoro import MU0
from magsoro.fields import CylinderMagnet
from magsoro.mpm.model import Control
from magsoro.mpm.solver import Solver
from magsoro.scene import parse_scene
from magsoro.simulation import Simulation
from tests.conftest import make_block_model


def test_cube_pulled_by_cylinder_magnet_with_predicted_force():
    """A 2 mm magnetised cube 25 mm above a 10 x 10 mm N45-like cylinder accelerates towards it with
    F = (m . grad) B of the source's closed form (within 3 %), and its centroid follows x = F t^2 / (2 M)."""
    magnet = CylinderMagnet(diameter=0.01, length=0.01, remanence=1.3, position=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0))
    a, dx = 2e-3, 2.5e-4
    centre = np.array([0.002, 0.001, 0.025])
    Br = np.array([0.0, 0.0, 0.15])  # aligned with the magnet's field at the cube: attraction, no torque
    model = make_block_model(centre - a / 2, centre + a / 2, dx, ppc=2, density=1500.0, G=1e5, Br=Br)
    control = Control([magnet])
    solver = Solver(model)
    dt = 0.5 * solver.stable_dt(control)
    s0, s1 = solver.new_state(), solver.new_state()
    mass = model.host["mass"]
    M = mass.sum()
    m = model.host["volumes"].sum() * Br / MU0
    expected = magnet.grad_B(centre[None])[0] @ m
    assert expected[2] < 0  # pulled down, towards the magnet
    n = 600
    for _ in range(n):
        solver.step(s0, s1, control, dt)
        s0, s1 = s1, s0
    t = n * dt
    s = s0.numpy()
    force = (mass[:, None] * s["v"]).sum(axis=0) / t
    assert np.linalg.norm(force - expected) < 0.03 * np.linalg.norm(expected)
    shift = (mass[:, None] * s["x"]).sum(axis=0) / M - centre
    assert shift[2] == pytest.approx(0.5 * expected[2] / M * t**2, rel=0.03)


@pytest.mark.parametrize(
    "spec",
    [
        {"type": "cylinder_magnet", "diameter": 0.01, "length": 0.005, "remanence": 1.2, "position": [0.006, -0.01, 0.0]},
        {"type": "cylinder_magnet", "diameter": 0.01, "length": 0.01, "remanence": 1.2, "position": [0.006, -0.02, 0.0], "model": "multipole", "order": 9},
        {"type": "cuboid_magnet", "dimensions": [0.005, 0.005, 0.005], "remanence": [0.0, 1.2, 0.0], "position": [0.006, -0.01, 0.0]},
        {"type": "loop", "radius": 0.01, "current": 50.0, "turns": 10, "position": [0.006, -0.01, 0.0], "axis": [0, 1, 0]},
        {"type": "helmholtz", "radius": 0.05, "current": 100.0, "turns": 20, "axis": [0, 1, 0]},
        {"type": "maxwell", "radius": 0.05, "current": 100.0, "turns": 20, "axis": [0, 1, 0]},
    ],
    ids=["cylinder", "cylinder_multipole", "cuboid", "loop", "helmholtz", "maxwell"],
)
def test_scene_sources_match_host_forms(spec):
    """Every source can be named in a scene; the engine sees the field the host form gives."""
    scene = {
        "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.012, 0.008], "duration": 1e-4, "plane_z": 0.0},
        "bodies": [{"name": "b", "shape": {"type": "rectangle", "center": [0.006, 0.004], "size": [0.004, 0.002]},
                    "material": {"density": 1000.0, "shear_modulus": 1e5}, "magnetization": [0.0, 0.1, 0.0]}],
        "fields": [spec],
    }
    sim = Simulation(parse_scene(scene))
    src = sim.control.sources[0]
    X = sim.model.host["positions"]
    pts = np.c_[X, np.zeros(len(X))]
    from magsoro.fields.device import FieldEvaluator

    import warp as wp

    ev = FieldEvaluator([src], 2, wp.float64, "cpu")
    B, G = ev.evaluate_host(X)
    np.testing.assert_allclose(B, src.B(pts), rtol=1e-9, atol=1e-12 * np.abs(src.B(pts)).max())
    np.testing.assert_allclose(G, src.grad_B(pts), rtol=1e-9, atol=1e-12 * np.abs(src.grad_B(pts)).max())
    result = sim.run()
    assert result.status == "completed"
