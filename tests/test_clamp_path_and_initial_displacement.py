"""Moving clamps (clamps[].path) and initial displacement fields (bodies[].initial_displacement), issue 56."""

import numpy as np
import pytest

from magsoro.errors import SceneError, SimulationError
from magsoro.scene.load import parse_scene


def strip(duration=0.02, path=True, displacement=None, formulation="total", integrator="explicit"):
    data = {
        "simulation": {"dim": 2, "dx": 1e-3, "particles_per_cell": 2, "domain_lo": [-0.01, -0.01],
                       "domain_hi": [0.05, 0.01], "duration": duration, "precision": "float64", "damping": 50.0,
                       "formulation": formulation, "integrator": integrator},
        "bodies": [{"name": "strip", "shape": {"type": "rectangle", "center": [0.02, 0.0], "size": [0.04, 0.002]},
                    "material": {"density": 1000.0, "shear_modulus": 1e5, "bulk_modulus": 1e6}}],
        "clamps": [{"region": {"type": "rectangle", "center": [0.0005, 0.0], "size": [0.003, 0.01]}},
                   {"region": {"type": "rectangle", "center": [0.0395, 0.0], "size": [0.003, 0.01]}}],
    }
    if path:
        data["clamps"][1]["path"] = {"times": [0.0, duration / 2], "positions": [[0.0, 0.0], [-5e-4, 0.0]]}
    if displacement is not None:
        data["bodies"][0]["initial_displacement"] = {"expression": displacement}
        data["clamps"] = []
        data["bodies"][0]["clamped"] = False
    return parse_scene(data)


def test_a_clamp_moved_half_a_millimetre_arrives_there():
    from magsoro.simulation import Simulation

    sim = Simulation(strip())
    m = sim.solver.model
    moving, fixed = m.host["clamp_row"] == 0, m.host["clamp_code"] == 1
    assert moving.any() and fixed.any()
    sim.advance_to(0.02)
    x, X = sim.state.x.numpy(), m.host["positions"]
    assert np.abs(x[moving] - (X[moving] + [-5e-4, 0.0])).max() < 1e-9
    assert np.abs(x[fixed] - X[fixed]).max() == 0.0
    # the strip between them is pushed along: its free particles moved inwards on average
    free = m.host["clamp_code"] == 0
    assert (x[free] - X[free])[:, 0].mean() < -1e-4
    # at rest again at the end of the path: held particles' velocity is the path's (zero after it ends)
    assert np.abs(sim.state.v.numpy()[moving]).max() == 0.0


def test_clamp_path_is_checked_and_refused_where_not_supported():
    from magsoro.scene.build import build

    bad = strip()
    bad.clamps[1].path.positions[0] = [1e-4, 0.0]
    with pytest.raises(SceneError, match=r"clamps\[1\].path"):
        build(bad)
    with pytest.raises(SceneError, match=r"clamps\[1\].path: a moving clamp needs"):
        build(strip(formulation="updated"))
    from magsoro.simulation import Simulation
    from magsoro.mpm.static import check_supported

    with pytest.raises(SimulationError, match=r"clamps\[\]\.path"):
        check_supported(Simulation(strip()))


def test_linear_initial_displacement_gives_its_strain():
    from magsoro.simulation import Simulation

    a = 2e-3
    sim = Simulation(strip(path=False, displacement=[f"{a} * x", "0"]))
    X = sim.solver.model.host["positions"]
    x, F = sim.state.x.numpy(), sim.state.F.numpy()
    assert np.abs(x - X - np.stack([a * X[:, 0], 0 * X[:, 0]], axis=1)).max() < 1e-15
    assert np.abs(F - np.diag([1.0 + a, 1.0])).max() < 1e-9


def test_sine_imperfection_of_a_hundredth_of_a_millimetre_is_in_the_start_positions():
    from magsoro.simulation import Simulation

    sim = Simulation(strip(path=False, displacement=["0", "1e-5 * sin(pi * x / 0.04)"]))
    X = sim.solver.model.host["positions"]
    x, F = sim.state.x.numpy(), sim.state.F.numpy()
    want = 1e-5 * np.sin(np.pi * X[:, 0] / 0.04)
    assert np.abs(x[:, 1] - X[:, 1] - want).max() < 1e-15
    assert (x[:, 1] - X[:, 1]).max() > 0.99e-5  # the lattice fill alone has no such offset
    assert np.abs(F[:, 1, 0] - 1e-5 * np.pi / 0.04 * np.cos(np.pi * X[:, 0] / 0.04)).max() < 1e-9


def test_initial_displacement_expressions_are_checked():
    from magsoro.scene.build import build

    with pytest.raises(SceneError, match="initial_displacement.expression.*not allowed"):
        build(strip(path=False, displacement=["__import__('os')", "0"]))
    with pytest.raises(SceneError, match="needs 2 components"):
        build(strip(path=False, displacement=["0", "0", "0"]))
    with pytest.raises(SceneError, match="inverts"):
        build(strip(path=False, displacement=["-2 * x", "0"]))
