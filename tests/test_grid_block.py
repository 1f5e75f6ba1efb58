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
