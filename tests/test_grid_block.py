"""The active grid block follows the bodies: its size does not depend on the domain size."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from grid_domain_scaling import robot_scene  # noqa: E402

from magsoro.scene import parse_scene  # noqa: E402
from magsoro.simulation import Simulation  # noqa: E402


def test_grid_block_independent_of_domain():
    info = []
    for domain in (0.02, 1.0):
        sim = Simulation(parse_scene(robot_scene(domain, 2, "cpu")))
        for _ in range(50):
            sim.step()
        info.append(sim.solver.grid_info())
    assert info[0]["nodes"] == info[1]["nodes"]
    assert info[0]["capacity"] == info[1]["capacity"]
    # the block is a small multiple of the robot's cells (10 x 2 mm at 0.25 mm is 40 x 8 cells), not of the domain
    assert info[1]["nodes"] < 60 * 20


def test_safe_box_is_inside_the_fit_and_the_domain():
    """The step skips the refit and domain checks while the particle bounds stay inside a box computed at each
    refit; every bound inside that box must pass the full checks (Solver._fits and the domain test)."""
    import numpy as np

    sim = Simulation(parse_scene(robot_scene(0.02, 2, "cpu")))
    sim.step()
    solver, m = sim.solver, sim.solver.model
    rng = np.random.default_rng(3)
    lo_box, hi_box = solver._safe_lo, solver._safe_hi
    assert np.all(hi_box > lo_box)
    # bounds on and near the box faces, inside and just outside
    for _ in range(2000):
        lo = lo_box + rng.uniform(-2, 2, m.dim) * m.dx * rng.choice([1e-9, 1e-3, 0.5, 1.0], m.dim)
        hi = hi_box + rng.uniform(-2, 2, m.dim) * m.dx * rng.choice([1e-9, 1e-3, 0.5, 1.0], m.dim)
        if np.all(lo >= lo_box) and np.all(hi < hi_box):
            assert solver._fits(lo, hi)
            assert np.all(lo >= m.domain_lo) and np.all(hi <= m.domain_hi)
    # and the box is tight: a bound 0.01 dx outside any face fails the fit or the domain test
    for a in range(m.dim):
        for side in (0, 1):
            lo, hi = lo_box.copy(), hi_box.copy() - 1e-6 * m.dx
            if side == 0:
                lo[a] -= 0.01 * m.dx
            else:
                hi[a] += 0.01 * m.dx
            assert not solver._fits(lo, hi) or lo[a] < m.domain_lo[a] or hi[a] > m.domain_hi[a]


def test_an_oversized_block_is_fitted_again(monkeypatch):
    """A block holding more than GRID_SHRINK times the nodes a fit needs (left by a body that folded up and
    flattened again, or by the room a fast phase asked for) is fitted again at the next check, where before it
    was kept as long as the particles stayed inside it. The trajectory is the same to 1e-12 (the nodes keep
    their global positions)."""
    import numpy as np

    import magsoro.mpm.solver as solver_module

    scene = {
        "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.04, 0.02], "duration": 0.004,
                       "precision": "float64", "formulation": "updated", "dt": 2e-5, "gravity": [0.0, -9.81],
                       "check_every": 20},
        "bodies": [{"name": "strip", "shape": {"type": "rectangle", "center": [0.02, 0.01], "size": [0.008, 0.001]},
                    "material": {"density": 1200.0, "shear_modulus": 3e4}, "velocity": [0.5, 0.2]}],
        "fields": [{"type": "uniform", "B": [0.0, 0.01, 0.0]}],
    }
    runs = {}
    for shrink in (2.0, float("inf")):
        monkeypatch.setattr(solver_module, "GRID_SHRINK", shrink)
        sim = Simulation(parse_scene(scene), device="cpu")
        sim.solver._refit(np.array([0.002, 0.002]), np.array([0.038, 0.018]))  # the whole domain
        big = sim.solver.grid_info()["nodes"]
        sim.run()
        runs[shrink] = (sim.state.x.numpy().astype(np.float64), sim.solver.grid_info(), big)
    (x, info, big), (x_kept, info_kept, _) = runs[2.0], runs[float("inf")]
    assert info_kept["nodes"] == big  # nothing left the block: it was kept
    assert info["nodes"] < 0.25 * big and info["refits"] > info_kept["refits"]
    assert np.abs(x - x_kept).max() <= 1e-12 * np.abs(x).max()
