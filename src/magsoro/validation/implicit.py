"""Validation case ``implicit``: the implicit integrator (:mod:`magsoro.mpm.newton.implicit`) against closed forms.

Zhao et al.'s cantilever (scenes/cantilever_2d.toml, 2D plane strain, 17.8 mm free length, 0.8 mm as the particle
lattice fills it) released from its gravity-deflected static shape: the first mode's period against the
Euler-Bernoulli beam, the amplitude lost per period by generalised-alpha (rho_inf 0.8) and by backward Euler against
its closed form, at 20 steps a period; a block on a 30 degree friction floor against g (sin - mu cos).
tests/test_implicit.py asserts the same numbers.
"""

import math
import tempfile
from pathlib import Path

import numpy as np

from magsoro.validation.registry import CaseResult, Context, Row, register, relative_error


def cantilever_scene_path() -> Path:
    from magsoro.robots.base import scenes_dir

    return scenes_dir() / "cantilever_2d.toml"


#: the cantilever's free length from the clamp's face (m) and the thickness its 8 particle rows fill (m)
LENGTH, THICKNESS = 0.0178, 0.0008
#: first root of the clamped-free beam's frequency equation, cos(x) cosh(x) = -1
BETA1 = 1.8751040687


def euler_bernoulli_period(G=303e3, bulk_ratio=20.0, density=1030.0):
    """First-mode period (s) of the plane-strain Euler-Bernoulli cantilever: E' = E / (1 - nu^2)."""
    K = bulk_ratio * G
    E = 9.0 * K * G / (3.0 * K + G)
    nu = (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))
    E_plane = E / (1.0 - nu * nu)
    omega = BETA1 ** 2 / LENGTH ** 2 * math.sqrt(E_plane * THICKNESS ** 2 / (12.0 * density))
    return 2.0 * math.pi / omega


def cantilever(scheme="generalized_alpha", rho_inf=0.8, gravity=(0.0, -5.0), linear_solver="auto"):
    """The cantilever without its field, damping 0, under gravity (the deflecting load, taken off at release);
    ``linear_solver`` as implicit.linear_solver."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    scene = load_scene(cantilever_scene_path())
    scene.simulation.integrator = "implicit"
    scene.simulation.damping = 0.0
    scene.simulation.gravity = list(gravity)
    scene.fields = []
    scene.implicit.scheme = scheme
    scene.implicit.rho_inf = rho_inf
    scene.implicit.linear_solver = linear_solver
    return Simulation(scene, source=str(cantilever_scene_path()))


def first_mode(integ):
    """(omega_1 rad/s, its mode on the unknowns) of the unloaded discretisation: K phi = omega^2 M phi."""
    from scipy.sparse.linalg import eigsh

    K = -integ.tangent(np.zeros_like(integ.u_nodes), 0.0, 0.0)
    vals, vecs = eigsh(K, k=1, M=integ.mass_matrix, sigma=0.0, which="LM")
    return math.sqrt(vals[0]), vecs[:, 0]


def released(scheme, rho_inf, periods, steps_per_period=20, linear_solver="auto"):
    """Release the gravity-deflected cantilever and follow its first-mode coordinate q = phi^T M u over
    ``periods`` periods at dt = T1 / steps_per_period. Returns (T1 discrete, times, q, simulation)."""
    sim = cantilever(scheme, rho_inf, linear_solver=linear_solver)
    integ = sim.implicit_integrator()
    omega, phi = first_mode(integ)
    T1 = 2.0 * math.pi / omega
    assert integ.solve_level(0.0, 1.0).converged  # the static shape under gravity
    integ.gravity_level = 0.0  # release
    integ.a_nodes = integ.consistent_acceleration()
    integ.write_state()
    dt = T1 / steps_per_period
    sim.dt = sim.implicit_dt_max = dt
    sim.implicit_dt_min = dt / 100

    def q():
        return float(phi @ (integ.mass_matrix @ integ.unknowns_of(integ.u_nodes)))

    ts, qs = [0.0], [q()]
    sim.advance_to(periods * T1, callback=lambda s: (ts.append(s.time), qs.append(q())))
    return T1, np.array(ts), np.array(qs), sim


def period_and_loss(ts, qs):
    """Period (s, from the zero crossings) and the amplitude lost per period (fraction) of a decaying oscillation."""
    from scipy.interpolate import CubicSpline

    tt = np.linspace(0.0, ts[-1], 40000)
    yy = CubicSpline(ts, qs)(tt)
    crossings = tt[1:][np.sign(yy[1:]) != np.sign(yy[:-1])]
    period = 2.0 * float(np.mean(np.diff(crossings)))
    peaks = np.array([np.abs(yy[(tt >= a) & (tt < b)]).max() for a, b in zip(crossings[:-1], crossings[1:])])
    half_periods = len(peaks) - 1
    loss = 1.0 - (peaks[-1] / peaks[0]) ** (2.0 / half_periods)
    return period, loss


BLOCK = """
name = "block_on_incline"
[simulation]
dim = 2
dx = 5.0e-4
particles_per_cell = 2
domain_lo = [-0.006, -0.003]
domain_hi = [0.1, 0.006]
duration = 0.2
gravity = [{gx}, {gy}]
depth = 1.0e-3
integrator = "implicit"

[implicit]
scheme = "{scheme}"
dt = 1.0e-3
dt_max = 1.0e-3

[[bodies]]
name = "block"
shape = {{ type = "rectangle", center = [0.0, 0.001], size = [0.004, 0.002] }}
material = {{ density = 1000.0, shear_modulus = 1.0e4 }}

[[colliders]]
type = "half_space"
point = [0.0, 0.0]
normal = [0.0, 1.0]
mode = "friction"
friction = {mu}

[[probes]]
type = "centroid"
name = "c"
body = "block"
"""


def block_run(tmp_path, mu, scheme):
    """A 4 x 2 mm block resting on a friction floor, gravity tilted 30 degrees: the centroid's x over 0.2 s."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    g, a = 9.81, math.radians(30.0)
    path = tmp_path / f"block_{mu}_{scheme}.toml"
    path.write_text(BLOCK.format(gx=g * math.sin(a), gy=-g * math.cos(a), mu=mu, scheme=scheme))
    sim = Simulation(load_scene(path), source=str(path))
    ts, xs = [0.0], [sim.probe_values()["c_x"]]
    sim.advance_to(0.2, callback=lambda s: (ts.append(s.time), xs.append(s.probe_values()["c_x"])))
    return np.array(ts), np.array(xs) - xs[0], sim



def coulomb_acceleration(mu: float, angle_deg: float = 30.0, g: float = 9.81) -> float:
    """g (sin a - mu cos a), m/s^2."""
    a = math.radians(angle_deg)
    return g * (math.sin(a) - mu * math.cos(a))


def block_acceleration(tmp_path, mu: float, scheme: str) -> float:
    """The block's acceleration along the floor (a parabola fitted to its centroid from 0.05 s on), m/s^2."""
    ts, xs, _ = block_run(tmp_path, mu, scheme)
    late = ts > 0.05
    return 2.0 * float(np.polyfit(ts[late], xs[late], 2)[0])


def viscous_cantilever(prony, shear_scale=1.0, integrator="implicit", scheme="backward_euler", rho_inf=0.0, dt=0.005):
    """scenes/cantilever_2d.toml with a Prony material (``prony``; None: elastic with its shear modulus scaled by
    ``shear_scale``), the bulk modulus held at 20 times the instantaneous shear modulus, backward Euler."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    scene = load_scene(cantilever_scene_path())
    scene.simulation.integrator = integrator
    scene.simulation.precision = "float64"
    mat = scene.bodies[0].material
    mat.bulk_modulus = 20.0 * mat.shear_modulus
    mat.shear_modulus = mat.shear_modulus * shear_scale
    mat.prony = prony
    scene.simulation.formulation = "total"
    scene.implicit.scheme, scene.implicit.rho_inf = scheme, rho_inf
    scene.implicit.dt = scene.implicit.dt_max = dt
    return Simulation(scene, source=str(cantilever_scene_path()))


def tip_deflection(sim) -> float:
    """Mean y displacement (m) of the particles within two cells of the beam's free end."""
    X = sim.model.host["positions"]
    tip = X[:, 0] > X[:, 0].max() - 2.0 * float(sim.model.dx)
    return float((sim.state.x.numpy() - X)[tip, 1].mean())


def relaxed_tip(g: float = 0.5, tau: float = 0.01, end: float = 0.3):
    """(tip deflection of the Prony cantilever after ``end`` s of implicit backward-Euler steps, the static
    solver's tip deflection of the elastic beam with the long-term shear modulus (1 - g) G0), m."""
    sim = viscous_cantilever([[g, tau]])
    sim.advance_to(end)
    ref = viscous_cantilever(None, shear_scale=1.0 - g, integrator="explicit")
    if not ref.solve_static(levels=[1.0], t=end).converged:
        raise RuntimeError("the relaxed beam's static solve did not converge")
    return tip_deflection(sim), tip_deflection(ref)


@register("implicit", "implicit integrator: the released 2D cantilever's first-mode period (generalised-alpha, 20 steps a "
          "period) vs Euler-Bernoulli, amplitude loss per period (generalised-alpha rho_inf 0.8; backward Euler vs its "
          "closed form), a block on a 30 degree friction floor (mu 0.2, dt 1 ms) vs g (sin - mu cos), a Prony "
          "cantilever relaxed vs the static beam of its long-term modulus",
          quick=False, cost="~10 s")
def implicit_case(ctx: Context) -> CaseResult:
    rows = []
    T1, ts, qs, _ = released("generalized_alpha", 0.8, periods=4)
    period, loss = period_and_loss(ts, qs)
    T_eb = euler_bernoulli_period()
    inputs = {"scheme": "generalized_alpha", "rho_inf": 0.8, "dt": "T1/20"}
    rows.append(Row("implicit", "first-mode period (s)", inputs, T_eb, period, relative_error(period, T_eb), 0.01))
    rows.append(Row("implicit", "amplitude loss per period", inputs, 0.0, loss, abs(loss), 0.02))
    _, ts, qs, _ = released("backward_euler", 0.8, periods=3)
    _, loss_be = period_and_loss(ts, qs)
    expected = 1.0 - (1.0 + (2.0 * math.pi / 20) ** 2) ** (-10)
    rows.append(Row("implicit", "amplitude loss per period", {"scheme": "backward_euler", "dt": "T1/20"}, expected,
                    loss_be, abs(loss_be - expected), 0.02))
    with tempfile.TemporaryDirectory() as tmp:
        accel = block_acceleration(Path(tmp), 0.2, "backward_euler")
    ref = coulomb_acceleration(0.2)
    rows.append(Row("implicit", "block acceleration (m/s^2)", {"mu": 0.2, "scheme": "backward_euler", "dt": 1e-3}, ref,
                    accel, relative_error(accel, ref), 0.02))
    d, dr = relaxed_tip()
    rows.append(Row("implicit", "Prony cantilever's tip after 30 tau (m)",
                    {"prony": [[0.5, 0.01]], "scheme": "backward_euler", "dt": 0.005,
                     "reference": "static solver, shear modulus (1 - g) G0"}, dr, d, relative_error(d, dr), 0.002))
    return CaseResult("implicit", rows, [], {"discrete_first_period_s": T1})
