"""Two magnetised cubes on a friction floor snap together when the dipole attraction beats friction (issue
"Magnetic interaction"), and a block on a friction floor near the domain's edge holds on a slope (the grid update
applies colliders before the domain walls).

Cubes of side a = 4 mm, Br = 0.1 T along the line between them, 1500 kg/m^3, on a floor with mu = 0.3 under
gravity: each moves when 3 mu0 m^2 / (2 pi d^4) > mu rho a^3 g, i.e. closer than d* = 15.3 mm = 3.83 a. At
0.9 d* the force is 1.52 mu N and the gap closes (3.5 mm between 20 and 40 ms, then they touch); at 1.1 d* it is
0.68 mu N and they stay (after a settling shift of 0.3 mm in the first 20 ms, while the weight builds up on the
floor, 0.06 mm from 20 to 40 ms). The window 20-40 ms separates them by a factor of 60.
"""

import math
from pathlib import Path

import pytest

from magsoro.constants import MU0

A, BR, RHO, MU, G = 4e-3, 0.1, 1500.0, 0.3, 9.81
MOMENT = BR * A**3 / MU0
D_STAR = (3 * MU0 * MOMENT**2 / (2 * math.pi * MU * RHO * A**3 * G)) ** 0.25

SCENE = """
[simulation]
dim = 3
dx = 1.0e-3
domain_lo = [0.0, 0.0, 0.0]
domain_hi = [0.04, 0.012, 0.012]
duration = 0.04
gravity = [0.0, -9.81, 0.0]
magnetic_interaction = "dipole"
interaction_every = 10

[[bodies]]
name = "a"
shape = {{ type = "box", center = [{xa}, 0.004, 0.006], size = [0.004, 0.004, 0.004] }}
material = {{ density = 1500.0, shear_modulus = 3.0e5 }}
magnetization = [0.1, 0.0, 0.0]

[[bodies]]
name = "b"
shape = {{ type = "box", center = [{xb}, 0.004, 0.006], size = [0.004, 0.004, 0.004] }}
material = {{ density = 1500.0, shear_modulus = 3.0e5 }}
magnetization = [0.1, 0.0, 0.0]

[[colliders]]
type = "half_space"
point = [0.0, 0.002, 0.0]
normal = [0.0, 1.0, 0.0]
mode = "friction"
friction = 0.3

[[probes]]
type = "centroid"
name = "a"
body = "a"

[[probes]]
type = "centroid"
name = "b"
body = "b"
"""


def _gap_closing(tmp_path, factor):
    """How far the gap between the cubes closes from 20 to 40 ms (m), starting ``factor`` d* apart."""
    from magsoro.simulation import Simulation

    d = factor * D_STAR
    path = Path(tmp_path) / f"snap_{factor}.toml"
    path.write_text(SCENE.format(xa=0.02 - d / 2, xb=0.02 + d / 2))
    sim = Simulation.from_file(path)
    sim.advance_to(0.02)
    v = sim.probe_values()
    gap0 = v["b_x"] - v["a_x"]
    sim.advance_to(0.04)
    v = sim.probe_values()
    return gap0 - (v["b_x"] - v["a_x"])


@pytest.mark.slow
def test_cubes_snap_together_inside_the_friction_distance(tmp_path):
    assert D_STAR == pytest.approx(15.32e-3, rel=1e-3)
    closer, farther = _gap_closing(tmp_path, 0.9), _gap_closing(tmp_path, 1.1)
    assert closer > 1e-3, f"at 0.9 d* the gap closed only {closer * 1e3:.3f} mm from 20 to 40 ms"
    assert farther < 0.15e-3, f"at 1.1 d* the gap closed {farther * 1e3:.3f} mm from 20 to 40 ms"


SLOPE = """
[simulation]
dim = 3
dx = 1.0e-3
domain_lo = [0.0, 0.0, 0.0]
domain_hi = [0.04, 0.012, 0.012]
duration = 0.04
gravity = [{gx}, {gy}, 0.0]
formulation = "total"

[[bodies]]
name = "a"
shape = {{ type = "box", center = [0.02, 0.004, 0.006], size = [0.004, 0.004, 0.004] }}
material = {{ density = 1500.0, shear_modulus = 3.0e5 }}

[[colliders]]
type = "half_space"
point = [0.0, 0.002, 0.0]
normal = [0.0, 1.0, 0.0]
mode = "friction"
friction = 0.3

[[probes]]
type = "centroid"
name = "a"
body = "a"
"""


def test_friction_floor_two_cells_above_the_domain_edge_holds(tmp_path):
    """A block on a friction floor (mu 0.3) whose contact nodes lie in the domain wall's two-cell band, on a slope
    of tan 0.204: it stays (measured 0.0003 mm in 40 ms). Applied after a slip wall, the collider found no
    approaching velocity left and the block slid freely, g sin = 1.96 m/s^2 (1.57 mm in 40 ms)."""
    from magsoro.simulation import Simulation

    theta = math.atan(0.68 * MU)
    path = Path(tmp_path) / "slope.toml"
    path.write_text(SLOPE.format(gx=G * math.sin(theta), gy=-G * math.cos(theta)))
    sim = Simulation.from_file(path)
    x0 = sim.probe_values()["a_x"]
    sim.advance_to(0.04)
    assert abs(sim.probe_values()["a_x"] - x0) < 0.01e-3
