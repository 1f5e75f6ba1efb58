"""Contact with rigid colliders: floor support, Coulomb friction deceleration mu g, sticky and moving colliders."""

import numpy as np
import pytest

from magsoro.mpm.colliders import Collider
from magsoro.fields.profiles import Keyframes
from magsoro.mpm.model import Control, SolverSettings
from magsoro.mpm.solver import Solver
from tests.conftest import make_block_model

G_ACC = 9.81


def _block_on_floor(mode, friction=0.0, v0=0.0, floor_y=0.002, steps=1500, vy0=0.0):
    dx = 2.5e-4
    lo, hi = [0.004, floor_y + 0.6 * dx], [0.008, floor_y + 0.6 * dx + 0.002]
    model = make_block_model(lo, hi, dx, ppc=2, G=2e5, domain=([0.0, 0.0], [0.04, 0.01]))
    solver = Solver(model, SolverSettings(gravity=(0.0, -G_ACC)))
    floor = Collider.half_space([0, floor_y, 0], [0, 1, 0], mode=mode, friction=friction)
    control = Control([], [floor])
    X = model.host["positions"]
    v = np.zeros_like(X)
    v[:, 0] = v0
    v[:, 1] = vy0
    a, b = solver.new_state(v), solver.new_state()
    dt = solver.stable_dt(control, max_speed=abs(v0) + abs(vy0))
    mass = model.host["mass"]
    history = []
    for k in range(steps):
        solver.step(a, b, control, dt)
        a, b = b, a
        s = a.numpy()
        history.append((a.time, (mass * s["v"][:, 0]).sum() / mass.sum(), s["x"][:, 1].min()))
    return np.array(history), floor_y, dx


def test_floor_supports_block_under_gravity():
    vy0 = -0.3
    h, floor_y, dx = _block_on_floor("slip", steps=3000, vy0=vy0)
    # unobstructed, the block would travel several cells below the floor; the floor stops it within a cell
    t = h[-1, 0]
    assert -vy0 * t + 0.5 * G_ACC * t**2 > 4 * dx
    assert h[:, 2].min() > floor_y - 1.0 * dx


@pytest.mark.parametrize("mu", [0.2, 0.5])
def test_coulomb_friction_decelerates_at_mu_g(mu):
    v0 = 0.05
    h, _, _ = _block_on_floor("friction", friction=mu, v0=v0, steps=2500)
    t, vx = h[:, 0], h[:, 1]
    # fit the deceleration while sliding (after the block has settled on the floor, before it stops)
    sliding = (t > 0.3 * t[-1]) & (vx > 0.2 * v0)
    slope = np.polyfit(t[sliding], vx[sliding], 1)[0]
    assert -slope == pytest.approx(mu * G_ACC, rel=0.1)


def test_slip_floor_keeps_horizontal_velocity():
    h, _, _ = _block_on_floor("slip", v0=0.05, steps=1500)
    assert h[-1, 1] == pytest.approx(0.05, rel=1e-3)


def test_moving_sticky_collider_drags_body():
    """A sticky box moving at 0.1 m/s through a block's end carries that end with it."""
    dx = 2.5e-4
    model = make_block_model([0.004, 0.004], [0.010, 0.006], dx, ppc=2, G=5e4, domain=([0.0, 0.0], [0.03, 0.01]))
    solver = Solver(model)
    path = Keyframes([0.0, 0.01], [[0.011, 0.005, 0.0], [0.012, 0.005, 0.0]])  # 0.1 m/s along x
    box = Collider.box([0.011, 0.005, 0.0], [0.0015, 0.003, 1.0], mode="sticky", path=path)
    control = Control([], [box])
    a, b = solver.new_state(), solver.new_state()
    dt = solver.stable_dt(control, max_speed=0.1)
    while a.time < 0.005:
        solver.step(a, b, control, dt)
        a, b = b, a
    x = a.numpy()["x"]
    X = model.host["positions"]
    inside = box.signed_distance(np.c_[x, np.zeros(len(x))], a.time) < -dx
    assert inside.any()
    assert np.mean(a.numpy()["v"][inside, 0]) == pytest.approx(0.1, rel=0.05)
    # the far end stays put (clamped by inertia for this short time): much smaller motion
    far = X[:, 0] < 0.005
    assert np.abs(x[far, 0] - X[far, 0]).max() < np.abs(x[inside, 0] - X[inside, 0]).mean()


def test_collider_signed_distances():
    p = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 0.5], [3.0, 0.0, 0.0]])
    assert Collider.sphere([0, 0, 0], 1.0).signed_distance(p) == pytest.approx([1.0, -0.5, 2.0])
    assert Collider.box([0, 0, 0], [1.0, 1.0, 1.0]).signed_distance(p) == pytest.approx([1.0, -0.5, 2.0])
    assert Collider.half_space([0, 0, 1.0], [0, 0, 1]).signed_distance(p) == pytest.approx([1.0, -0.5, -1.0])
    cyl = Collider.cylinder([0, 0, 0], 1.0, 1.0, axis=[0, 0, 1])
    assert cyl.signed_distance(p) == pytest.approx([1.0, -0.5, 2.0])


def test_two_bodies_meet_through_the_shared_grid():
    """A moving block hits a block at rest: momentum passes to it through the common grid (no contact code)."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    body = lambda name, cx, v: {  # noqa: E731
        "name": name, "shape": {"type": "rectangle", "center": [cx, 0.005], "size": [0.003, 0.003]},
        "material": {"density": 1000.0, "shear_modulus": 5e4}, "velocity": v,
    }
    scene = {
        "simulation": {"dim": 2, "dx": 2.5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.02, 0.01], "duration": 4e-3, "precision": "float64"},
        "bodies": [body("a", 0.005, [0.5, 0.0]), body("b", 0.0095, [0.0, 0.0])],
    }
    sim = Simulation(parse_scene(scene))
    mass = sim.model.host["mass"]
    ids = sim.model.host["body"]
    p0 = (mass[:, None] * sim.particles()["v"]).sum(axis=0)
    sim.run()
    v = sim.particles()["v"]
    x = sim.particles()["x"]
    pb = (mass[ids == 1, None] * v[ids == 1]).sum(axis=0)
    # the gap (1.5 mm) closes after 3 ms; by 4 ms b carries a good share of the momentum
    assert pb[0] > 0.2 * p0[0]
    np.testing.assert_allclose((mass[:, None] * v).sum(axis=0), p0, rtol=1e-10, atol=1e-12 * abs(p0[0]))
    # they do not pass through each other: b's particles all stay right of a's
    assert x[ids == 0, 0].max() < x[ids == 1, 0].min() + 2.5e-4
