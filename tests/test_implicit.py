"""Implicit time integration (issue "Implicit engine"): :mod:`magsoro.mpm.newton.implicit`.

Zhao et al.'s cantilever (scenes/cantilever_2d.toml, 2D plane strain, 17.8 mm free length, 0.8 mm as the particle
lattice fills it) released from a static shape: its first mode against the Euler-Bernoulli beam and the
discretisation's own eigenvalue, the schemes' amplitude loss per period against their closed forms; the same beam
under a slow field ramp against the static solver; a block on a 30 degree friction floor against g (sin - mu cos).
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from magsoro.validation.implicit import (block_run, cantilever, euler_bernoulli_period, period_and_loss,
                                        released, relaxed_tip, viscous_cantilever)

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ROOT / "scenes" / "cantilever_2d.toml"
def test_scheme_coefficients():
    """Generalised-alpha is second order (gamma = 1/2 - alpha_m + alpha_f) for every rho_inf and is the
    trapezoidal rule at rho_inf = 1; backward Euler is its own first-order member."""
    from magsoro.mpm.newton.implicit import Scheme

    for rho in (0.0, 0.5, 0.8, 1.0):
        s = Scheme.make("generalized_alpha", rho)
        assert s.gamma == pytest.approx(0.5 - s.alpha_m + s.alpha_f)
        assert s.beta == pytest.approx(0.25 * (0.5 + s.gamma) ** 2)
    t = Scheme.make("generalized_alpha", 1.0)
    assert (t.beta, t.gamma, t.alpha_m, t.alpha_f) == pytest.approx((0.25, 0.5, 0.5, 0.5))
    with pytest.raises(ValueError, match="rho_inf"):
        Scheme.make("generalized_alpha", 1.5)


def test_free_vibration_generalized_alpha():
    """Released from its gravity-deflected static shape, no damping, dt = T1/20: the first mode's period lies
    within 1 % of the Euler-Bernoulli beam's (measured +0.42 %) and within the scheme's period elongation of the
    discrete eigenperiod (Omega^2/12 = 0.82 % at Omega = 2 pi/20; measured +0.86 %); it loses under 2 % of its
    amplitude per period (measured 0.015 %)."""
    T1, ts, qs, _ = released("generalized_alpha", 0.8, periods=4)
    period, loss = period_and_loss(ts, qs)
    T_eb = euler_bernoulli_period()
    assert abs(T1 / T_eb - 1.0) < 0.01  # the discretisation's own first mode (measured -0.44 %)
    assert abs(period / T_eb - 1.0) < 0.01
    omega_dt = 2.0 * math.pi / 20
    assert period / T1 - 1.0 == pytest.approx(omega_dt ** 2 / 12.0, abs=0.002)
    assert 0.0 <= loss < 0.02


def test_free_vibration_backward_euler_loss_matches_its_closed_form():
    """Backward Euler at dt = T1/20 multiplies a mode's amplitude by (1 + Omega^2)^(-1/2) per step (Omega =
    omega dt): a loss of 1 - (1 + Omega^2)^(-10) = 61.0 % per period. Measured 62.1 % (the mode's period also
    lengthens, so a period holds a little more than 20 steps)."""
    T1, ts, qs, _ = released("backward_euler", 0.8, periods=3)
    _, loss = period_and_loss(ts, qs)
    omega_dt = 2.0 * math.pi / 20
    expected = 1.0 - (1.0 + omega_dt ** 2) ** (-10)
    assert loss == pytest.approx(expected, abs=0.02)


def test_iterative_linear_solver_follows_the_direct_one():
    """implicit.linear_solver = 'iterative' (multigrid-preconditioned CG): the released cantilever's first-mode
    coordinate over one period equals the direct solver's within 5e-5 of its amplitude (measured 1.5e-5): each of
    the 20 steps leaves up to 1e-6 of the step's force scale (about the deflecting load) in the residual, in each
    run, and the two stop at different iterates. The run counts its Krylov iterations."""
    runs = {kind: released("generalized_alpha", 0.8, periods=1, linear_solver=kind) for kind in ("direct", "iterative")}
    (_, td, qd, simd), (_, ti, qi, simi) = runs["direct"], runs["iterative"]
    assert len(td) == len(ti) and np.allclose(td, ti, rtol=1e-9, atol=0.0)
    qi = qi * np.sign(qi[0] * qd[0])  # the mode's sign is the eigensolver's choice
    assert np.abs(qi - qd).max() <= 5e-5 * np.abs(qd).max()
    integ = simi.implicit_integrator()
    assert integ.linear_kinds == {"iterative"} and integ.linear_iterations > 0 and integ.linear_fallbacks == 0
    assert simd.implicit_integrator().linear_kinds == {"direct"}


@pytest.mark.slow
def test_free_vibration_against_the_explicit_engine():
    """The explicit engine released from the same static shape (float64, total form): its first-mode period
    within 1 % of the implicit one at dt = T1/20 (the tip's zero crossings over two periods)."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    T1, ts, qs, sim = released("generalized_alpha", 0.8, periods=2)
    # the released state again, for the explicit engine
    sim2 = cantilever()
    integ = sim2.implicit_integrator()
    assert integ.solve_level(0.0, 1.0).converged
    integ.write_state()
    scene = load_scene(CANTILEVER)
    scene.simulation.precision, scene.simulation.formulation = "float64", "total"
    scene.simulation.damping = 0.0
    scene.fields = []
    explicit = Simulation(scene, source=str(CANTILEVER))
    explicit.state.assign(sim2.state)
    explicit.state.v.zero_()
    explicit.state.C.zero_()
    explicit.state.time = 0.0
    times, tips = [0.0], [explicit.probe_values()["tip_y"]]
    for k in range(1, 41):
        explicit.advance_to(k * 2 * T1 / 40)
        times.append(explicit.time)
        tips.append(explicit.probe_values()["tip_y"])
    period_explicit, _ = period_and_loss(np.array(times), np.array(tips))
    period_implicit, _ = period_and_loss(ts, qs)
    assert abs(period_implicit / period_explicit - 1.0) < 0.01


def test_slow_field_ramp_ends_at_the_static_shape(tmp_path):
    """The cantilever's field ramped over 1 s and held to 1.2 s (the scene's damping, 150/s), implicit at
    dt = 10 ms: the tip ends within 0.5 % of the deflection from `--static` (measured 0.01 %)."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    scene = load_scene(CANTILEVER)
    scene.simulation.integrator = "implicit"
    scene.simulation.duration = 1.2
    scene.fields[0].profile.duration = 1.0
    scene.implicit.dt = scene.implicit.dt_max = 0.01
    sim = Simulation(scene, source=str(CANTILEVER))
    sim.advance_to(1.2)
    tip = np.array([sim.probe_values()["tip_x"], sim.probe_values()["tip_y"]])
    info = sim.integrator_info()
    assert info["steps"] == 120 and info["rejected_steps"] == 0

    static_scene = load_scene(CANTILEVER)
    static_scene.simulation.precision = "float64"
    static = Simulation(static_scene, source=str(CANTILEVER))
    assert static.solve_static(levels=[1.0]).converged
    ref = np.array([static.probe_values()["tip_x"], static.probe_values()["tip_y"]])
    start = np.array([0.0198, 0.0])
    assert np.linalg.norm(tip - ref) < 0.005 * np.linalg.norm(ref - start)


@pytest.mark.parametrize("scheme", ["backward_euler", "generalized_alpha"])
def test_block_slides_at_coulomb_acceleration(tmp_path, scheme):
    """mu = 0.2, dt = 1 ms: the acceleration (a parabola fitted from 0.05 s on) within 2 % of g (sin 30 - mu cos
    30) = 3.206 m/s^2 (measured: backward Euler 3.2058582, to 1e-9; generalised-alpha 3.2040, -0.06 %)."""
    g, a = 9.81, math.radians(30.0)
    ts, xs, _ = block_run(tmp_path, 0.2, scheme)
    late = ts > 0.05
    accel = 2.0 * np.polyfit(ts[late], xs[late], 2)[0]
    assert accel == pytest.approx(g * (math.sin(a) - 0.2 * math.cos(a)), rel=0.02)


@pytest.mark.parametrize("scheme", ["backward_euler", "generalized_alpha"])
def test_block_sticks_above_the_friction_angle(tmp_path, scheme):
    """mu = 0.7 > tan 30: the block stays, moving less than a quarter cell in 0.2 s (measured 2.7 um with backward
    Euler, 9.4 um with generalised-alpha: the friction law's elastic slip, 5e-3 cells, and the contact's spring)."""
    ts, xs, sim = block_run(tmp_path, 0.7, scheme)
    assert np.abs(xs).max() < 0.25 * sim.model.dx


def test_refusals_name_the_key(tmp_path):
    """What the implicit integrator cannot take yet is refused in one line naming the key: the updated
    formulation, the bodies' own field; a step bound that contradicts another."""
    from magsoro.errors import SceneError, SimulationError
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    text = CANTILEVER.read_text().replace("duration = 0.12", "duration = 0.12\nintegrator = \"implicit\"")
    path = tmp_path / "c.toml"
    path.write_text(text.replace("depth = 5.0e-3", "depth = 5.0e-3\nformulation = \"updated\""))
    with pytest.raises(SceneError, match="simulation.formulation"):
        Simulation(load_scene(path))
    path.write_text(text.replace("depth = 5.0e-3", "depth = 5.0e-3\nmagnetic_interaction = \"dipole\""))
    sim = Simulation(load_scene(path))
    with pytest.raises(SimulationError, match="simulation.magnetic_interaction"):
        sim.implicit_integrator()
    path.write_text(text + "\n[implicit]\ndt = 0.01\ndt_max = 0.001\n")
    with pytest.raises(SceneError, match="implicit.dt_max"):
        load_scene(path)


def test_run_writes_the_integrator_to_run_json(tmp_path):
    """`magsoro run` with simulation.integrator = 'implicit': completes, and run.json says which integrator ran,
    its scheme, steps, rejected steps and Newton iterations, and that it ran in float64."""
    text = CANTILEVER.read_text().replace("duration = 0.12", "duration = 0.04\nintegrator = \"implicit\"")
    path = tmp_path / "c.toml"
    path.write_text(text + "\n[implicit]\ndt = 0.005\ndt_max = 0.005\n")
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "magsoro", "run", str(path), "--out", str(out), "--quiet"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "completed" and info["precision"] == "float64"
    integ = info["integrator"]
    assert integ["kind"] == "implicit" and integ["scheme"] == "generalized_alpha"
    assert integ["steps"] == 8 and integ["rejected_steps"] == 0 and integ["newton_iterations"] >= 8
    assert integ["linear_solver"] == "direct" and integ["linear_iterations"] == 0
    assert integ["linear_solves"] >= integ["newton_iterations"] and 1 <= integ["linear_setups"] == integ["tangents"]
    assert any("float64" in n for n in info["notes"])


@pytest.mark.slow
def test_snap_through_against_the_explicit_engine(tmp_path):
    """scenes/bistable_arch.toml (preview grid, float64, total form), pre-buckled and relaxed by the explicit engine,
    then snapped by field steps with each integrator (implicit: generalised-alpha, dt = 0.5 ms): the mid-plane
    crossing time within 10 % of the explicit engine's at two steps (measured at 45 mT: 10.08 ms against 10.04 ms),
    and the snap threshold, bracketed by bisection to 1/32 of [15, 20] mT, within 2 % of the explicit one."""
    from magsoro.robots import bistable_arch as BA
    from magsoro.robots.base import Context, scene_data

    data = scene_data(BA.NAME)
    data["simulation"] = dict(data["simulation"], precision="float64", formulation="total")
    implicit = dict(data, simulation=dict(data["simulation"], integrator="implicit"),
                    implicit={"dt": 5e-4, "dt_max": 5e-4})
    ctx = Context(out=tmp_path, preview=True, device="cpu", log=lambda msg: None)
    prm = BA.scene_parameters(data)
    rest, _ = BA.prebuckle(ctx, data)
    height = BA._crown(rest)

    def snap(d, level):
        ts, crown, _ = BA.step_run(ctx, d, rest, level, prm)
        return BA.snap_times(ts, crown, height)

    for level in (0.030, 0.045):
        ok_e, cross_e, _ = snap(data, level)
        ok_i, cross_i, _ = snap(implicit, level)
        assert ok_e and ok_i
        assert cross_i == pytest.approx(cross_e, rel=0.10)
    brackets = []
    for d in (data, implicit):
        lo, hi = 0.015, 0.020
        for _ in range(5):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if snap(d, mid)[0] else (mid, hi)
        brackets.append(0.5 * (lo + hi))
    assert brackets[1] == pytest.approx(brackets[0], rel=0.02)


def test_prony_tangent_is_the_residuals_derivative():
    """The implicit step's tangent with a Prony material (g = 0.4, tau = 20 ms) after a few steps under the field
    (the internal stresses nonzero): J v against central differences of the step's residual along a random v,
    within 1e-5 (both take the overstress after the update to each trial F; measured 1.7e-8, and 3.6e-3 with the
    law's tangent alone)."""
    sim = viscous_cantilever([[0.4, 0.02]])
    sim.advance_to(0.03)
    integ = sim.implicit_integrator()
    assert float(np.abs(integ.H_n.numpy()).max()) > 0.0
    u0 = integ.u_nodes.copy()
    integ.begin_step(0.005)
    try:
        J = integ.tangent(u0, 1.0, 1.0)
        v = np.random.default_rng(7).standard_normal(J.shape[0])
        v *= 1e-3 * float(sim.model.dx) / np.abs(v).max()
        h = 1e-3
        plus = integ.residual(u0 + integ.nodes_of(h * v), 1.0, 1.0)
        minus = integ.residual(u0 - integ.nodes_of(h * v), 1.0, 1.0)
    finally:
        integ.end_step()
    fd = (plus - minus) / (2.0 * h)
    assert np.linalg.norm(J @ v - fd) <= 1e-5 * np.linalg.norm(fd)


def test_prony_cantilever_relaxes_to_the_long_term_modulus():
    """The cantilever under its field with a Prony material (g = 0.5, tau = 10 ms), implicit backward Euler at
    5 ms: after 0.3 s (30 tau; the relaxed beam's first mode damped by the scene's 150/s) the tip lies where the
    static solver puts an elastic beam of shear modulus g_inf G0 = 0.5 G0 (same bulk modulus), within 0.2 % of
    its deflection (measured 1e-7); an elastic beam of G0 deflects 9.6 % less (the tip turns down by about 14.5 mm
    of the beam's 18.8 mm, where the field's torque falls off with the rotation)."""
    d, dr = relaxed_tip()
    assert abs(dr) > 1e-4  # the relaxed beam bends (a fifth of its length or more)
    assert abs(d / dr - 1.0) < 2e-3


@pytest.mark.slow
def test_prony_cantilever_against_the_explicit_engine():
    """The Prony cantilever (g = 0.5, tau = 10 ms) under its field ramp (40 ms), damping 150/s: the implicit
    integrator (generalised-alpha, rho_inf 0.8, dt 1 ms) and the explicit engine (float64, total form) give the
    tip's deflection within 1 % of its final value at 10, 20, 40 and 80 ms (measured 0.019 % at most): the creep
    while the internal stresses relax, not only its end."""
    times = (0.01, 0.02, 0.04, 0.08)
    runs = {}
    for integrator in ("implicit", "explicit"):
        sim = viscous_cantilever([[0.5, 0.01]], integrator=integrator, scheme="generalized_alpha", rho_inf=0.8,
                                  dt=0.001)
        X = sim.model.host["positions"]
        tip = X[:, 0] > X[:, 0].max() - 2.0 * float(sim.model.dx)
        out = []
        for t in times:
            sim.advance_to(t)
            out.append(float((sim.state.x.numpy() - X)[tip, 1].mean()))
        runs[integrator] = np.array(out)
    imp, exp = runs["implicit"], runs["explicit"]
    assert np.abs(imp - exp).max() <= 0.01 * abs(exp[-1])


def test_a_state_placed_by_the_nodes_projects_back_to_them():
    """The integrator starts from the simulation's state by fitting node displacements and velocities to the
    particles' positions and F (velocities and dF/dt = C F), clamped particles left out. A state that some node
    displacements placed comes back to them, light nodes at the faces included (a fit of the positions alone left
    the 3D strip's face nodes 0.13 cells and its light nodes 4 cells off, and its settled state out of balance)."""
    sim = cantilever()
    integ = sim.implicit_integrator()
    rng = np.random.default_rng(3)
    u = np.zeros_like(integ.u_nodes)
    u[integ.free] = 1e-4 * rng.standard_normal((len(integ.free), integ.dim))  # well within a cell (0.8 mm)
    v = np.zeros_like(u)
    v[integ.free] = 1e-2 * rng.standard_normal((len(integ.free), integ.dim))
    integ.u_nodes, integ.v_nodes = u, v
    integ.write_state()
    again = cantilever()
    again.state.assign(sim.state)
    fitted = again.implicit_integrator()
    moving = integ.node_mass[integ.free] > 0.0
    nodes = integ.free[moving]
    assert np.abs(fitted.u_nodes[nodes] - u[nodes]).max() <= 1e-9 * np.abs(u).max()
    assert np.abs(fitted.v_nodes[nodes] - v[nodes]).max() <= 1e-9 * np.abs(v).max()


def test_anderson_mixing_beats_the_plain_kept_tangent_iteration():
    """Anderson acceleration of u <- u - K0^-1 R(u) on a linear R = A u - b whose kept tangent K0 is A's diagonal:
    the plain iteration contracts at the Jacobi rate (0.95 here); the mixed one reaches 1e-10 in fewer than half the
    iterations (depth 5: 168 against 403)."""
    from magsoro.mpm.newton.implicit import Anderson

    n = 40
    rng = np.random.default_rng(0)
    A = np.diag(np.full(n, 2.0)) - np.diag(np.full(n - 1, 0.95), 1) - np.diag(np.full(n - 1, 0.95), -1)
    b = rng.standard_normal(n)
    exact = np.linalg.solve(A, b)

    def iterations(depth):
        u, mix = np.zeros(n), Anderson(depth, "K0")
        for k in range(1, 2000):
            f = (b - A @ u) / np.diag(A)
            step = mix.step(f)
            u = u + step
            mix.moved(1.0)
            if np.abs(u - exact).max() <= 1e-10 * np.abs(exact).max():
                return k
        return 2000

    plain, mixed = iterations(0), iterations(5)
    assert plain > 300
    assert mixed < plain / 2  # measured 168 against 403


def _triangle_on_its_plate(light: bool = True):
    """The triangle of seed 002 (preview grid, 808 particles) drawn resting on its friction plate, gravity and a weak
    magnet's field (seed 002's actuator, 80 mm under the top vertex: about 2 mT there) on at t = 0, backward Euler
    at dt 20 ms for 0.1 s; ``light``: with the light nodes' spring (implicit.LightNodes)."""
    import copy

    from magsoro.robots._seed002_speeds import actuator
    from magsoro.robots.base import scene_data, simulation

    data = copy.deepcopy(scene_data("triangle"))
    magnet = actuator(data, 1.0)
    magnet.pop("path", None)
    magnet["position"] = [0.0, 0.019, -0.08]
    data["simulation"].update(duration=0.1, integrator="implicit")
    data["implicit"] = {"dt": 0.02, "dt_max": 0.02, "scheme": "backward_euler"}
    sim = simulation("triangle", data, preview=True, device="cpu")
    if not light:
        sim.implicit_integrator().light = None
    z0 = sim.model.host["positions"][:, 2].copy()
    reach = []  # per 20 ms: the particles' largest displacement (cells)
    for k in range(1, 6):
        sim.advance_to(0.02 * k)
        d = sim.state.x.numpy()[:, :3] - sim.model.host["positions"][:, :3]
        reach.append(float(np.abs(d).max()) / float(sim.model.dx))
    return sim, z0, reach


def test_robot_set_down_on_its_friction_plate_settles():
    """The triangle set down on its plate (_triangle_on_its_plate): its 20 ms steps converge, in few Newton
    iterations, none of the lowest particles sinks into the plate by a hundredth of a cell, and the plate settles:
    its particles' largest displacement grows by less in the last 20 ms than in the second. Measured: 5 steps, none
    halved, 34 Newton iterations; the largest displacement 0.42, 0.69, 0.85, 0.94, 0.99 cells. Without the light
    nodes' spring the light nodes ran off by 12 cells in the first step and 110 by 0.1 s, and dragged the particles
    on at 0.3 cells per step (0.57 to 1.98 cells), the plate never settling; without the contact set settled on
    each fresh tangent's linearised step (implicit.SETTLE_CONTACTS) the first step was halved eight times, to 78 us,
    and the line search stalled at each length. With a tangential stiffness on the points that the settled set
    adds (static_contact.ColliderPenalty.revise), or a kept tangent's step taken because it changed the contact
    set, it took 83 to 131 iterations and halved 1 to 3 steps."""
    sim, z0, reach = _triangle_on_its_plate()
    integ = sim.implicit
    assert integ.light is not None and integ.light.count > 0
    assert sim.state.time == pytest.approx(0.1)
    assert integ.rejected <= 1
    assert integ.newton_iterations <= 60
    z = sim.state.x.numpy()[:, 2]
    lowest = z0 < z0.min() + 1e-9
    assert np.all(z[lowest] > z0[lowest] - 0.01 * sim.model.dx)  # none pressed into the plate
    assert reach[4] - reach[3] < 0.5 * (reach[1] - reach[0])
    m = integ.node_mass
    light = (m > 0) & (m < 1e-2 * m.max())
    assert float(np.abs(integ.u_nodes[light]).max()) < 3.0 * float(sim.model.dx)


def test_triangle_takes_its_first_step_as_the_passing_magnets_field_comes_on():
    """The triangle of seed 002 (preview grid) on its friction plate with the pass's magnet at its start (y = 90 mm,
    under the plate; its field on at t = 0, so the robot warps and most of its 404 contact points lift): backward
    Euler's first 12.5 ms step converges at full length within 12 Newton iterations. Measured: 8 iterations. While
    the contact rounds gave the points joining the set friction's tangential stiffness (static_contact.
    ColliderPenalty.revise) the step stalled, each iteration's step shrinking 25-fold, and failed after 20
    iterations; at half length it took 20 more."""
    import copy

    from magsoro.robots import _seed002_speeds as sp
    from magsoro.robots.base import scene_data, simulation

    data = copy.deepcopy(scene_data("triangle"))
    magnet = sp.actuator(data, 1.0)
    magnet.pop("path", None)
    magnet["position"] = [0.0, sp.PASS_FROM, sp.Z_TOP]
    S = data["simulation"]
    S.update(duration=0.05, integrator="implicit", damping=0.0)
    S["domain_lo"], S["domain_hi"] = [-0.036, -0.170, -0.014], [0.036, 0.110, 0.040]
    data["implicit"] = {"dt": 0.0125, "dt_max": 0.0125, "scheme": "backward_euler", "linear_solver": "direct"}
    sim = simulation("triangle", data, preview=True, device="cpu")
    sim.advance_to(0.0125)
    integ = sim.implicit
    assert integ.steps == 1 and integ.rejected == 0
    assert integ.newton_iterations <= 12


@pytest.mark.slow
def test_robot_on_its_plate_creeps_without_the_light_nodes_spring():
    """The counter-case of test_robot_set_down_on_its_friction_plate_settles: without the light nodes' spring the
    light nodes run off by tens of cells and the particles' largest displacement grows at a steady rate instead of
    levelling off (measured 0.57, 1.03, 1.40, 1.71, 1.98 cells)."""
    sim, _, reach = _triangle_on_its_plate(light=False)
    integ = sim.implicit
    m = integ.node_mass
    light = (m > 0) & (m < 1e-2 * m.max())
    assert float(np.abs(integ.u_nodes[light]).max()) > 20.0 * float(sim.model.dx)
    assert reach[4] - reach[3] > 0.5 * (reach[1] - reach[0])


def test_light_nodes_spring_spares_affine_motion():
    """The light nodes' spring (implicit.LightNodes) costs nothing for a displacement affine in X, a finite rotation
    of 40 degrees with a uniform strain and a shift (relative force below 1e-9 of what the same-sized random field
    gets), and its tangent is its forces' derivative (it is quadratic)."""
    from magsoro.robots.base import scene_data, simulation

    data = scene_data("triangle")
    data["simulation"]["integrator"] = "implicit"
    sim = simulation("triangle", data, preview=True, device="cpu")
    integ = sim.implicit_integrator()
    light = integ.light
    assert light is not None and light.count > 10
    X = integ.node_positions()[2]  # the nodes' reference positions
    rng = np.random.default_rng(3)
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    a = math.radians(40.0)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K
    B = R @ (np.eye(3) + 0.05 * rng.standard_normal((3, 3))) - np.eye(3)
    u = (X - X.mean(axis=0)) @ B.T + np.array([1e-3, -2e-3, 5e-4])
    f_affine = np.abs(light.forces(u)).max()
    f_random = np.abs(light.forces(np.abs(u).max() * rng.standard_normal(u.shape))).max()
    assert f_random > 0.0
    assert f_affine < 1e-9 * f_random
    step = rng.standard_normal(light.tangent.shape[1])  # on the unknowns, as Newton sees it
    fd = integ._reduce(light.forces(u) - light.forces(u + integ.nodes_of(step)))
    assert np.linalg.norm(light.tangent @ step - fd) <= 1e-9 * np.linalg.norm(fd)


@pytest.mark.parametrize("scheme", ["generalized_alpha", "backward_euler"])
def test_a_free_body_falls_under_gravity(scheme):
    """A block free in space (no clamp, no collider: the static solver refuses it, the implicit integrator's mass
    term holds its step) falls as a rigid body: after N steps of dt the drop is g t^2 / 2 for the second-order
    scheme (exact for a constant acceleration), g t^2 (1 + 1/N) / 2 for backward Euler (v_n+1 = v_n + g dt,
    x_n+1 = x_n + v_n+1 dt), to 1e-6; it does not deform."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    g, dt, n = 9.81, 1e-3, 20
    scene = {"simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [-0.01, -0.01], "domain_hi": [0.01, 0.01],
                            "duration": n * dt, "gravity": [0.0, -g], "precision": "float64", "integrator": "implicit"},
             "implicit": {"scheme": scheme, "dt": dt, "dt_max": dt},
             "bodies": [{"name": "block", "shape": {"type": "rectangle", "center": [0.0, 0.004], "size": [4e-3, 2e-3]},
                         "material": {"density": 1100.0, "shear_modulus": 3e5}}],
             "output": {"particles": False}}
    sim = Simulation(parse_scene(scene))
    x0 = sim.state.x.numpy().copy()
    sim.advance_to(n * dt)
    drop = x0[:, 1] - sim.state.x.numpy()[:, 1]
    t = n * dt
    expected = 0.5 * g * t * t * (1.0 if scheme == "generalized_alpha" else 1.0 + 1.0 / n)
    assert sim.steps == n
    assert drop.mean() == pytest.approx(expected, rel=1e-6)
    assert np.ptp(drop) < 1e-6 * expected


def test_max_move_sizes_the_steps_by_how_far_the_body_moves():
    """implicit.max_move: after each step dt is scaled by max_move over the largest particle motion of that step.
    A block falling freely under backward Euler moves v_n+1 dt in a step, with v_n+1 = g t_n+1 exactly, so the next
    step is max_move dx / (g t): at t = 0.1 s and max_move 0.5 cells of 0.5 mm, 0.255 ms (to Newton's tolerance),
    where without max_move the steps stay at dt_max = 1 ms."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    g, dx, t_end = 9.81, 5e-4, 0.1

    def run(implicit):
        scene = {"simulation": {"dim": 2, "dx": dx, "domain_lo": [-0.01, -0.06], "domain_hi": [0.01, 0.01],
                                "duration": t_end, "gravity": [0.0, -g], "precision": "float64", "integrator": "implicit"},
                 "implicit": {"scheme": "backward_euler", "dt": 1e-3, "dt_max": 1e-3, **implicit},
                 "bodies": [{"name": "block", "shape": {"type": "rectangle", "center": [0.0, 0.004], "size": [4e-3, 2e-3]},
                             "material": {"density": 1100.0, "shear_modulus": 3e5}}],
                 "output": {"particles": False}}
        sim = Simulation(parse_scene(scene))
        sim.advance_to(t_end)
        return sim

    plain, moved = run({}), run({"max_move": 0.5})
    assert plain.dt == pytest.approx(1e-3) and plain.steps == 100
    assert moved.dt == pytest.approx(0.5 * dx / (g * t_end), rel=1e-5)
    assert moved.steps > 150  # the steps shrank once the block moved 0.5 cells in 1 ms (t = 0.026 s): about 200


def test_auto_linear_solver_turns_iterative_only_where_tangents_are_not_kept(tmp_path, monkeypatch):
    """implicit.linear_solver = 'auto' between the static solver's threshold and implicit.DIRECT_MAX_UNKNOWNS
    (here the static threshold is lowered to 0 so the small block lies in between): the block sliding on its
    friction floor keeps its factorisations (measured 5 setups in 209 Newton iterations) and stays direct; steps
    that make a new linear solver at every iteration turn it iterative once they fill more than half of the last
    REUSE_WINDOW iterations (a step in progress counts as far as it went), for the rest of the run; below the static threshold it is direct whatever the steps do."""
    from magsoro.mpm.newton import implicit, linear

    monkeypatch.setattr(linear, "DIRECT_MAX_UNKNOWNS", 0)
    ts, xs, sim = block_run(tmp_path, 0.2, "backward_euler")
    integ = sim.implicit
    n = integ.E.shape[1]
    assert integ.linear_kinds == {"direct"} and integ.linear_setups < 0.1 * integ.newton_iterations
    assert implicit.REUSE_WINDOW == 32 and implicit.REUSE_MAX == 0.5
    for _ in range(2):  # with the block's last steps (one iteration each, no setup): 8 and 16 setups of 32
        integ._note_reuse(8, 8)
        assert integ._linear_kind(n) == "direct"
    integ._note_reuse(8, 8)  # 24 of 32
    assert integ._linear_kind(n) == "iterative"
    for _ in range(implicit.REUSE_WINDOW):
        integ._note_reuse(3, 0)
    assert integ._linear_kind(n) == "iterative"
    # a step in progress counts before its end: more than REUSE_MAX * REUSE_WINDOW setups in its first iterations
    integ._reuse, integ._per_iteration = [], False
    integ._live = (integ.linear_setups, 1)
    integ.linear_setups += 16
    assert integ._linear_kind(n) == "direct"
    integ.linear_setups += 1
    assert integ._linear_kind(n) == "iterative"
    monkeypatch.setattr(linear, "DIRECT_MAX_UNKNOWNS", n)
    assert integ._linear_kind(n) == "direct"
    assert integ._linear_kind(implicit.DIRECT_MAX_UNKNOWNS + 1) == "iterative"


def test_steps_land_on_the_keyframes_of_the_loads(tmp_path, monkeypatch):
    """The implicit steps land on every keyframe of the scene's tables (here a keyframed field turning at 13 ms,
    between the 5 ms steps), evened out to there (three of 13/3 ms, not 5, 5 and 3), and a step that starts on a
    keyframe is told so (``turn``: Newton starts from the last state)."""
    from magsoro.mpm.newton import implicit
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    text = CANTILEVER.read_text().replace("duration = 0.12", "duration = 0.03\nintegrator = \"implicit\"")
    text = text.replace('type = "uniform"\nB = [0.0, 0.0059, 0.0]\nprofile = { type = "ramp", duration = 0.04 }',
                        'type = "keyframes"\ntimes = [0.0, 0.013, 0.03]\n'
                        'values = [[0.0, 0.0, 0.0], [0.0, 0.004, 0.0], [0.0, 0.0059, 0.0]]')
    assert 'type = "keyframes"' in text
    path = tmp_path / "c.toml"
    path.write_text(text + "\n[implicit]\ndt = 0.005\ndt_max = 0.005\n")
    sim = Simulation(load_scene(path), source=str(path))
    turns = []
    try_step = implicit.ImplicitIntegrator.try_step

    def recorded(integ, dt, turn=False):
        turns.append((round(integ.t, 9), round(dt, 9), turn))
        return try_step(integ, dt, turn=turn)

    monkeypatch.setattr(implicit.ImplicitIntegrator, "try_step", recorded)
    sim.advance_to(0.03)
    starts = [t for t, _, _ in turns]
    assert 0.013 in starts and sim.time == pytest.approx(0.03)
    assert [dt for t, dt, _ in turns if t < 0.013] == pytest.approx([0.013 / 3] * 3)
    assert [dt for t, dt, _ in turns if t >= 0.013] == pytest.approx([0.017 / 4] * 4)  # 17 ms in four even steps
    assert [t for t, _, turn in turns if turn] == [0.0, 0.013]
