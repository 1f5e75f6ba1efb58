"""The force on a rigid collider (``[[probes]] type = "collider_force"``, Simulation.collider_forces).

Runs: the momentum a collider takes from the grid nodes it touches, per unit time, averaged over the interval since
the last read. Checked against two closed forms:

- a block resting on a floor carries its weight, M g (momentum balance at rest: exact but for the settling
  motion left), in both formulations, with gravity straight down and tilted 25 degrees onto a friction floor
  (mu 0.7: at rest the floor takes the tangential part too); the same by the static solver (its contact's
  reaction) and by the dynamic relaxation (over its last kinetic-energy cycle);
- a layer squeezed between a slip floor and a slip plate lowered in steps: the force at each hold against the
  homogeneous plane-strain solution of the engine's own law at the layer's measured stretch (an independent
  closed form up to one root-finding; its small-strain slope is E / (1 - nu^2) w depth / h).
"""

import math

import numpy as np
import pytest

BLOCK = """
name = "block"
[simulation]
dim = 2
dx = 2.5e-4
particles_per_cell = 2
domain_lo = [-0.004, -0.001]
domain_hi = [0.004, 0.004]
duration = 0.06
damping = 300.0
gravity = [{gx}, {gy}]
depth = 1.0e-3
formulation = "{form}"
precision = "float64"

[[bodies]]
name = "block"
shape = {{ type = "rectangle", center = [0.0, 0.001], size = [0.004, 0.002] }}
material = {{ density = 1000.0, shear_modulus = 2.0e4 }}

[[colliders]]
type = "half_space"
point = [0.0, 0.0]
normal = [0.0, 1.0]
mode = "friction"
friction = 0.7

[[probes]]
type = "collider_force"
name = "floor"
collider = 0
"""


def _sim(tmp_path, text, name="scene.toml"):
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    path = tmp_path / name
    path.write_text(text)
    return Simulation(load_scene(path), source=str(path))


def _weight(sim, g):
    return sim.model.host["mass"].sum() * np.asarray(g)


@pytest.mark.parametrize("form", ["updated", "total"])
@pytest.mark.parametrize("angle", [0.0, 25.0])
def test_floor_carries_the_weight_of_a_resting_block(tmp_path, form, angle):
    """Settled 40 ms (damping 300/s, about 12 times the slowest decay time), then read over 20 ms: the floor's
    force is minus the weight within 0.5 % of its size in each component (measured: below 0.1 %)."""
    g = 9.81
    gravity = (g * math.sin(math.radians(angle)), -g * math.cos(math.radians(angle)))
    sim = _sim(tmp_path, BLOCK.format(gx=gravity[0], gy=gravity[1], form=form))
    assert sim.probe_values() == {"floor_Fx": 0.0, "floor_Fy": 0.0}  # no time has passed
    sim.advance_to(0.04)
    sim.probe_values()  # the settling's mean
    sim.advance_to(0.06)
    v = sim.probe_values()
    weight = _weight(sim, gravity)
    force = np.array([v["floor_Fx"], v["floor_Fy"]])
    assert np.allclose(force, weight, rtol=0.0, atol=5e-3 * np.linalg.norm(weight))
    # a second read at the same time repeats the value
    assert sim.probe_values() == v


def test_static_and_relaxed_reactions_are_the_weight(tmp_path):
    """The static solver's contact reaction equals the weight to its tolerance; the dynamic relaxation's force
    over its last kinetic-energy cycle within 1 %."""
    gravity = (0.0, -9.81)
    text = BLOCK.format(gx=0.0, gy=-9.81, form="total")
    sim = _sim(tmp_path, text)
    res = sim.solve_static(levels=[1.0])
    assert res.converged, res.message
    v = sim.probe_values()
    weight = _weight(sim, gravity)
    assert np.allclose([v["floor_Fx"], v["floor_Fy"]], weight, rtol=0.0, atol=1e-6 * np.linalg.norm(weight))
    rel = _sim(tmp_path, text, "relax.toml")
    out = rel.relax()
    assert out.converged or out.stalled, out.message
    v = rel.probe_values()
    assert np.allclose([v["floor_Fx"], v["floor_Fy"]], weight, rtol=0.0, atol=1e-2 * np.linalg.norm(weight))


def test_relaxation_before_any_step_with_two_colliders(tmp_path):
    """The colliders' accumulator is sized at the first step: a relaxation as the first thing a scene with two
    colliders does reads them (a regression: the read assumed one collider's size) and reports the floor's load."""
    text = BLOCK.format(gx=0.0, gy=-9.81, form="total") + """
[[colliders]]
type = "half_space"
point = [0.0035, 0.0]
normal = [-1.0, 0.0]
mode = "slip"
"""
    sim = _sim(tmp_path, text)
    out = sim.relax()
    assert out.converged or out.stalled, out.message
    forces = sim.collider_forces()
    weight = _weight(sim, (0.0, -9.81))
    assert forces.shape == (2, 3)
    assert np.allclose(forces[0, :2], weight, rtol=0.0, atol=1e-2 * np.linalg.norm(weight))
    assert np.allclose(forces[1], 0.0)  # the wall is not touched


PLATE = """
name = "squeeze"
[simulation]
dim = 2
dx = 2.5e-4
particles_per_cell = 2
domain_lo = [-0.004, -0.001]
domain_hi = [0.004, 0.006]
duration = 0.11
damping = 300.0
gravity = [0.0, 0.0]
depth = 1.0e-3
formulation = "{form}"
precision = "float64"

[[bodies]]
name = "layer"
shape = {{ type = "rectangle", center = [0.0, 0.002], size = [0.004, 0.004] }}
material = {{ density = 1000.0, shear_modulus = 2.0e4 }}

[[colliders]]
type = "half_space"
point = [0.0, 0.0]
normal = [0.0, 1.0]
mode = "slip"

[[colliders]]
type = "half_space"
point = [0.0, {top}]
normal = [0.0, -1.0]
mode = "slip"
path = {{ times = [0.0, 0.01, 0.03, 0.06, 0.08, 0.11], positions = [[0.0, {top}], [0.0, {top}], [0.0, {p1}], [0.0, {p1}], [0.0, {p2}], [0.0, {p2}]] }}

[[probes]]
type = "collider_force"
name = "plate"
collider = 1

[[probes]]
type = "collider_force"
name = "floor"
collider = 0
"""


def plane_strain_force(stretch: float, shear: float, bulk: float, width: float, depth: float) -> float:
    """Compressive force (N) on a layer of the engine's Neo-Hookean law (W = G/2 (J^-2/3 I1 - 3) + K/2 (J - 1)^2)
    stretched by ``stretch`` through its height between frictionless plates: plane strain (lambda_z = 1), the width
    free (lambda_x from sigma_xx = 0), the nominal stress dW/dlambda_y times the reference width and depth. At
    small strain its slope is E / (1 - nu^2) w depth / h; at 5 % compression the secant is 8 % stiffer."""
    from scipy.optimize import brentq

    G, K = shear, bulk

    def dW(lx, ly):
        J, I1 = lx * ly, lx * lx + ly * ly + 1.0
        return (G / 2 * (J ** (-2 / 3) * 2 * lx - 2 / 3 * J ** (-5 / 3) * ly * I1) + K * (J - 1) * ly,
                G / 2 * (J ** (-2 / 3) * 2 * ly - 2 / 3 * J ** (-5 / 3) * lx * I1) + K * (J - 1) * lx)

    lx = brentq(lambda v: dW(v, stretch)[0], 0.5, 2.0)
    return -dW(lx, stretch)[1] * width * depth


def test_plane_strain_reference_has_the_small_strain_modulus():
    from magsoro.validation.hertz import elastic_moduli

    G = 2.0e4
    _, _, e_plane = elastic_moduli(G, 20.0 * G)  # E / (1 - nu^2)
    assert plane_strain_force(1.0 - 1e-6, G, 20.0 * G, 1.0, 1.0) == pytest.approx(e_plane * 1e-6, rel=1e-4)


@pytest.mark.parametrize("form", ["updated", "total"])
def test_squeezed_layer_force_against_its_stretch(tmp_path, form):
    """A 4 x 4 mm layer (G = 20 kPa, K = 20 G) between slip plates, the top one lowered in two steps and held:
    at each hold the plate's force against :func:`plane_strain_force` at the layer's stretch (the distance between
    its top and bottom particle rows over the reference one), within 5 %; the floor carries the same force.
    Measured: updated -0.4 % and -1.2 % at 3.6 % and 5.0 % compression, total +3.4 % and +1.9 % at 4.2 % and 6.7 %
    (the stretch read from the outer particle rows, next to the plates' node contact, is the larger error)."""
    top = 0.00415  # the plate starts above the layer (touching its outer node layer after the first lowering)
    d1, d2 = 0.0003, 0.0004
    sim = _sim(tmp_path, PLATE.format(form=form, top=top, p1=top - d1, p2=top - d2))
    X = sim.model.host["positions"]
    h0 = X[:, 1].max() - X[:, 1].min()
    G = 2.0e4
    for t_settled, t_end in ((0.05, 0.06), (0.10, 0.11)):
        sim.advance_to(t_settled)
        sim.probe_values()
        sim.advance_to(t_end)
        v = sim.probe_values()
        x = sim.state.x.numpy()
        stretch = (x[:, 1].max() - x[:, 1].min()) / h0
        assert 0.92 < stretch < 0.98
        expected = plane_strain_force(stretch, G, 20.0 * G, 0.004, 1.0e-3)
        assert v["plate_Fy"] == pytest.approx(expected, rel=0.05), f"{form}: {v['plate_Fy']:.5g} N at stretch {stretch:.5f}"
        assert v["floor_Fy"] == pytest.approx(-v["plate_Fy"], rel=1e-3)


def test_static_squeeze_moves_the_plate_along_its_path(tmp_path):
    """--static at a time when the plate has been lowered: the colliders start where they are at the scene's start
    and the load increments move them along their paths to the solve's time, so the plate presses the layer (points
    that start clear of a collider are not held where it will be). The layer's top particle row rests one particle
    radius below the plate (the surface law), the floor carries the plate's force to the solver's tolerance, and
    the force is the plane-strain law's at the layer's stretch within 5 % (measured +2.6 % at 3.9 % and 6.4 %
    compression: the same discretisation error as the dynamics)."""
    top = 0.00415
    d1, d2 = 0.0003, 0.0004
    sim = _sim(tmp_path, PLATE.format(form="total", top=top, p1=top - d1, p2=top - d2))
    X = sim.model.host["positions"]
    h0 = X[:, 1].max() - X[:, 1].min()
    r = 0.25 * 2.5e-4  # half the particle spacing
    G = 2.0e4
    for t, plate in ((0.06, top - d1), (0.11, top - d2)):
        res = sim.solve_static(levels=[1.0], t=t)
        assert res.converged, res.message
        x = sim.state.x.numpy()
        # one radius below the plate, less the penalty's overlap (about p / (10 (K + 4G/3)) cells: 1e-3 cells here)
        assert x[:, 1].max() == pytest.approx(plate - r, abs=5e-3 * 2.5e-4)
        v = sim.probe_values()
        assert v["floor_Fy"] == pytest.approx(-v["plate_Fy"], rel=1e-6)
        stretch = (x[:, 1].max() - x[:, 1].min()) / h0
        expected = plane_strain_force(stretch, G, 20.0 * G, 0.004, 1.0e-3)
        assert v["plate_Fy"] == pytest.approx(expected, rel=0.05), f"static: {v['plate_Fy']:.5g} N at stretch {stretch:.5f}"


def test_collider_force_probe_names_a_collider(tmp_path):
    """A probe of a collider the scene does not have: one line naming the key and the indices allowed."""
    from magsoro.errors import SceneError

    text = BLOCK.format(gx=0.0, gy=-9.81, form="total").replace("collider = 0", "collider = 3")
    with pytest.raises(SceneError, match=r"probes\[0\]\.collider: 3 is not a collider of the scene \(it has 1: indices 0 to 0"):
        _sim(tmp_path, text)
