"""Pressure loads on a body's surface facing a cavity (``[bodies.pressure]``, docs/engine.md "Pressure loads")."""

import copy

import numpy as np
import pytest

from magsoro.errors import SceneError
from magsoro.scene import parse_scene
from magsoro.scene.build import build
from magsoro.simulation import Simulation
from magsoro.validation.pressure import RING_A, RING_B, RING_G, lame_displacement, radial_displacement, ring_scene


def test_faces_of_a_closed_cavity_sum_to_zero_and_project_its_width():
    """2D ring and 3D spherical shell: the loaded faces' area vectors sum to zero (a pressure in a closed cavity
    exerts no net force), and those facing +x add up to the cavity's projected width (2D: 2a times the depth)
    within one particle spacing."""
    built = build(parse_scene(ring_scene(1e3)))
    h = built.model.host
    area, row = h["pressure_area"], h["pressure_row"]
    assert np.all((row >= 0) == np.any(area != 0.0, axis=1))
    np.testing.assert_allclose(area.sum(axis=0), 0.0, atol=1e-15)
    depth = parse_scene(ring_scene(1e3)).simulation.depth
    spacing = 5e-4 / 2
    projected = area[:, 0][area[:, 0] > 0].sum() / depth
    assert abs(projected - 2 * RING_A) <= spacing
    r = np.linalg.norm(h["positions"], axis=1)
    assert np.all(r[row >= 0] < RING_A + spacing)  # only the bore's layer is loaded

    # 3D: a tube (bore radius 2 mm, 6 mm long) with its bore as the cavity
    tube = {"simulation": {"dim": 3, "dx": 5e-4, "domain_lo": [-0.01] * 3, "domain_hi": [0.01] * 3, "duration": 1e-3},
            "bodies": [{"name": "tube", "shape": {"type": "tube", "center": [0, 0, 0], "outer_radius": 3e-3,
                                                   "inner_radius": 2e-3, "length": 6e-3},
                        "material": {"density": 1000.0, "shear_modulus": 1e5},
                        "pressure": {"cavity": {"type": "cylinder", "center": [0, 0, 0], "radius": 2e-3, "length": 6e-3},
                                     "value": 1e3}}],
            "output": {"particles": False}}
    h3 = build(parse_scene(tube)).model.host
    area3 = h3["pressure_area"]
    np.testing.assert_allclose(area3.sum(axis=0), 0.0, atol=1e-18)
    assert np.all(area3[:, 2] == 0.0)  # the open ends carry nothing
    assert abs(area3[:, 0][area3[:, 0] > 0].sum() - 2 * 2e-3 * 6e-3) <= spacing * 6e-3

    # a cavity inside a solid body borders no free particle face
    tube["bodies"][0]["shape"]["inner_radius"] = 0.0
    with pytest.raises(SceneError, match=r"bodies\[0\]\.pressure\.cavity: no particle face of body 'tube'"):
        build(parse_scene(tube))


def _ring_run(pressure: float, static: bool):
    sim = Simulation(parse_scene(ring_scene(pressure)), device="cpu")
    if static:
        out = sim.solve_static()
        assert out.converged, out.message
    else:
        res = sim.relax()
        assert res.converged, res.message
    X = sim.model.host["positions"]
    r0 = np.linalg.norm(X, axis=1)
    u = np.linalg.norm(sim.state.numpy()["x"], axis=1) - r0
    return r0, u, float(sim.model.host["bulk_modulus"][0])


@pytest.mark.parametrize("static", [False, True], ids=["relaxation", "static"])
def test_ring_under_internal_pressure_matches_the_finite_strain_radial_model(static):
    """p = G/10 widens the bore by about 10 %. The particles of the innermost and outermost layers (two each at
    dx = 0.5 mm, two particles per cell) move on average as the radial model at their radii: measured +1.8 % and
    +1.9 % (relaxation), +2.6 % and +2.7 % (static solver); tolerance 5 %. With the load on the reference surface
    (a dead load, the engine's pressure_force without J F^-T) the same runs measured -8.8 % and -8.9 % (-8.2 % static),
    and Lame's small-strain answer is 16 % below the radial model at the bore: the follower load at finite strain
    is what is checked."""
    p = RING_G / 10
    r0, u, K = _ring_run(p, static)
    R, ur = radial_displacement(p, RING_G, K)
    spacing = 5e-4 / 2
    for lo, hi in ((RING_A, RING_A + 2 * spacing), (RING_B - 2 * spacing, RING_B)):
        sel = (r0 >= lo) & (r0 <= hi)
        ref = np.interp(r0[sel], R, ur).mean()
        assert u[sel].mean() == pytest.approx(ref, rel=0.05)
    lame_bore = lame_displacement(RING_A, p, RING_G, K)
    bore_model = np.interp(RING_A, R, ur)
    assert bore_model > 1.1 * lame_bore  # the finite-strain effect the comparison resolves


def test_ring_small_pressure_matches_lame():
    """p = G/200: small strain; the mean radial displacement of the whole ring against Lame's at the particles'
    radii, measured +2.3 % at dx = 0.5 mm (+1.8 % at 0.25 mm; the radial model, which keeps the 0.8 % of finite
    strain at this load, +1.5 %); tolerance 4 %."""
    p = RING_G / 200
    r0, u, K = _ring_run(p, static=False)
    assert u.mean() == pytest.approx(lame_displacement(r0, p, RING_G, K).mean(), rel=0.04)


def test_pressure_ramp_sets_the_table_in_time_and_keeps_the_steps_off_graph_windows():
    scene = ring_scene(2e3, ramp=0.01)
    sim = Simulation(parse_scene(scene), device="cpu")
    m = sim.model
    assert m.pressures_at(0.0) == (0.0,)
    assert m.pressures_at(0.005) == pytest.approx((1e3,))
    assert m.pressures_at(0.02) == (2e3,)
    assert "pressure ramp" in sim.solver.graph_refusal(sim.built.control)
    m.update_pressures(0.0025)
    assert m.pressure_value.numpy()[0] == pytest.approx(500.0)
    steady = Simulation(parse_scene(ring_scene(2e3)), device="cpu")
    assert steady.solver.graph_refusal(steady.built.control) is None  # a constant pressure stays in windows
    assert steady.model.pressure_value.numpy()[0] == 2e3


@pytest.mark.parametrize("change, message", [
    (lambda s: s["bodies"][0]["pressure"].update(ramp=-1.0), r"bodies\[0\]\.pressure\.ramp: Input should be greater than or equal to 0"),
    (lambda s: s["bodies"][0]["pressure"].update(value=float("nan")), r"bodies\[0\]\.pressure\.value"),
    (lambda s: s["bodies"][0]["pressure"].update(valeu=1.0), r"valeu"),
    (lambda s: s["bodies"][0]["pressure"]["cavity"].update(radius=1e-3, width=2e-3), r"no particle face"),
])
def test_pressure_input_errors_name_the_key(change, message):
    scene = copy.deepcopy(ring_scene(1e3))
    change(scene)
    with pytest.raises(SceneError, match=message):
        build(parse_scene(scene))


def test_free_thin_ring_under_pressure_does_not_drift():
    """A closed cavity's pressure exerts no net force. On the lattice the faces close up in the reference
    configuration, but mapped by each particle's own F (Nanson) they sum to about 2.6e-4 of the load round a thin
    ring whose lattice is not symmetric about its centre (A = 0.8, B = 0.9 mm, 4 cells through the wall, p = 0.04 G):
    before the engine took that net force back, the free ring drifted 17 um in 6 ms at grid damping 2000/s (and
    would accelerate without damping). Now its centroid moves 0.27 um (measured), all of it in the first 2 ms."""
    a, b, half = 0.8e-3, 0.9e-3, 1.68e-3
    data = {"simulation": {"dim": 2, "dx": 25e-6, "domain_lo": [-half, -half], "domain_hi": [half, half],
                           "duration": 1.0, "damping": 2000.0},
            "bodies": [{"name": "ring", "material": "dragon-skin-10-ndfeb100",
                        "shape": {"type": "arc", "center": [0, 0], "radius": 0.5 * (a + b), "width": b - a,
                                  "start_angle": 0.0, "end_angle": 360.0},
                        "pressure": {"cavity": {"type": "arc", "center": [0, 0], "radius": 0.5 * a, "width": a,
                                                "start_angle": 0.0, "end_angle": 360.0},
                                     "value": 4750.0, "ramp": 0.003}}],
            "output": {"particles": False}}
    sim = Simulation(parse_scene(data, "thin ring"))
    assert sim.model.closed_pressures == [0]
    x0 = sim.state.x.numpy().astype(np.float64).mean(axis=0)
    sim.advance_to(2e-3)
    x2 = sim.state.x.numpy().astype(np.float64).mean(axis=0)
    sim.advance_to(6e-3)
    x6 = sim.state.x.numpy().astype(np.float64).mean(axis=0)
    assert np.linalg.norm(x6 - x0) < 1e-6
    assert np.linalg.norm(x6 - x2) < 0.1e-6  # no steady drift once loaded
    r = np.linalg.norm(sim.state.x.numpy().astype(np.float64) - x6, axis=1)
    assert r.min() > 0.89e-3  # inflated (bore 0.905 mm) and round
