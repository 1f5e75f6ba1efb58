"""Arc-length continuation of the static solver (``[static] arc_length``, :meth:`StaticSolver._arc_length`): a
shallow clamped arch pushed down at its crown snaps through at a limit point of its equilibrium path.

The arch is stress-free in the shape y = h/2 (1 + cos 2 pi x / L) (L = 40 mm between the clamp faces, rise h =
1.5 mm, thickness t = 1 mm: t/dx = 4 in plane strain, width 20 mm), clamped with horizontal tangents, and magnetised
along its length, towards the crown in both halves' sense (+tangent on the left, -tangent on the right). A uniform
field B is then exactly a point force 2 |Br| t w B / mu0 on the crown (the magnetic energy of each half is
-(|Br| t w / mu0) B . its chord), so the reference is a discrete planar elastica of the same arch with that force
(:class:`CosineArch`, built on the bistable arch robot's elastica). At this low rise (h/t = 1.5) the symmetric path
has a limit point: the elastica's stability limit is 1.5835 mT with 40 segments, 1.5884 with 80, 1.5897 with 160
(the limit found by continuation in the load with its Hessian's lowest eigenvalue; at h = 2 mm the arch would
bifurcate asymmetrically first, at 1 mm it does not snap). The MPM path by arc length turns at 1.580 mT (steps of
0.02 / 0.05 / 0.1 of the way at first: 1.5804 / 1.5794 / 1.5766) and, on the unstable branch, at 1.093 mT; load
increments alone jump over the snap without seeing it.
"""

import math

import numpy as np
import pytest

from magsoro.constants import MU0

SPAN, RISE, THICK, WIDTH, GRIP = 0.040, 0.0015, 0.001, 0.02, 0.002
G, K, BR = 66.7e3, 1.334e6, 0.0443
PUSH_T = 3.2e-3  # the field level solved (about twice the limit): downward


def centreline(x, rise=RISE):
    inside = np.abs(x) <= 0.5 * SPAN
    y = np.where(inside, 0.5 * rise * (1.0 + np.cos(2.0 * math.pi * x / SPAN)), 0.0)
    s = np.where(inside, -rise * math.pi / SPAN * np.sin(2.0 * math.pi * x / SPAN), 0.0)
    return y, s


def arch_scene(level_T: float, rise: float = RISE, tilt_deg: float = 0.0, **static) -> dict:
    """The arch with GRIP of straight strip into a clamp at each end, 2D plane strain, dx = t/4; the field
    downward, turned by ``tilt_deg`` towards +x."""
    x = np.linspace(-0.5 * SPAN - GRIP, 0.5 * SPAN + GRIP, 241)
    y, s = centreline(x, rise)
    normal = np.stack([-s, np.ones_like(s)], axis=1) / np.sqrt(1.0 + s * s)[:, None]
    c = np.stack([x, y], axis=1)
    outline = np.concatenate([c + 0.5 * THICK * normal, (c - 0.5 * THICK * normal)[::-1]]).tolist()
    slope = f"(where(abs(x) <= {0.5 * SPAN}, -{rise * math.pi / SPAN} * sin({2.0 * math.pi / SPAN} * x), 0.0))"
    tilt = math.radians(tilt_deg)
    clamp = lambda side: {"region": {"type": "rectangle", "center": [side * (0.5 * SPAN + GRIP), 0.0],  # noqa: E731
                                      "size": [2.0 * GRIP, 4.0 * THICK]}}
    return {
        "name": "cosine_arch",
        "simulation": {"dim": 2, "dx": THICK / 4, "particles_per_cell": 2, "domain_lo": [-0.026, -0.008],
                       "domain_hi": [0.026, 0.010], "duration": 0.1, "depth": WIDTH, "precision": "float64"},
        "bodies": [{"name": "arch", "shape": {"type": "polygon", "vertices": outline},
                    "material": {"library": "dragon-skin-10-ndfeb50", "shear_modulus": G},
                    "magnetization": {"type": "expression", "x": f"{BR} * sign(-x) / sqrt(1 + {slope}**2)",
                                      "y": f"{BR} * sign(-x) * {slope} / sqrt(1 + {slope}**2)", "z": "0"},
                    "magnetic": True}],
        "clamps": [clamp(-1), clamp(1)],
        "fields": [{"name": "push", "type": "uniform", "B": [level_T * math.sin(tilt), -level_T * math.cos(tilt), 0.0]}],
        "static": {"levels": [1.0], **static},
    }


def _elastica_class():
    from magsoro.actuation.planning import plane_strain_modulus
    from magsoro.robots.bistable_arch import ArchElastica

    class CosineArch(ArchElastica):
        """The stress-free cosine arch as a discrete planar elastica (extensible, plane-strain modulus from G and
        K), clamped with horizontal tangents at x = +-L/2, with the field's point force on the crown."""

        def __init__(self, n: int = 40):
            super().__init__(SPAN, 1.0, THICK, WIDTH, plane_strain_modulus(G, K), 1000.0, BR, n)
            x = np.linspace(-0.5 * SPAN, 0.5 * SPAN, n + 1)
            self.rest = np.stack([x, centreline(x)[0]], axis=1)
            seg = np.diff(self.rest, axis=0)
            self.l0 = np.hypot(seg[:, 0], seg[:, 1])
            self.turn0 = self._turns(np.arctan2(seg[:, 1], seg[:, 0]))
            self.weights = np.empty(n + 1)
            self.weights[1:-1] = self.bending / (0.5 * (self.l0[:-1] + self.l0[1:]))
            self.weights[0], self.weights[-1] = 2.0 * self.bending / self.l0[0], 2.0 * self.bending / self.l0[-1]
            self.force_per_T = 2.0 * BR * THICK * WIDTH / MU0

        def _turns(self, theta):
            turn = np.empty(self.n + 1)
            turn[0] = theta[0]
            turn[1:-1] = (np.diff(theta) + math.pi) % (2.0 * math.pi) - math.pi
            turn[-1] = -theta[-1]
            return turn

        def natural(self):
            return self.rest[1:-1].ravel().copy()

        def energy_gradient(self, q, B):
            p = self.nodes(q)
            s = np.diff(p, axis=0)
            length = np.hypot(s[:, 0], s[:, 1])
            dturn = self._turns(np.arctan2(s[:, 1], s[:, 0])) - self.turn0
            f = self.force_per_T * np.asarray(B, dtype=np.float64)[:2]
            mid = self.n // 2
            energy = (0.5 * self.axial * np.sum((length - self.l0) ** 2 / self.l0)
                      + 0.5 * np.sum(self.weights * dturn**2) - f @ p[mid])
            grad_s = (self.axial * (length - self.l0) / self.l0 / length)[:, None] * s
            moment = self.weights * dturn
            grad_s += (moment[:-1] - moment[1:])[:, None] * np.stack([-s[:, 1], s[:, 0]], axis=1) / (length * length)[:, None]
            grad_p = np.zeros_like(p)
            grad_p[1:] += grad_s
            grad_p[:-1] -= grad_s
            grad_p[mid] -= f
            return float(energy), grad_p[1:-1].ravel()

    return CosineArch


@pytest.fixture(scope="module")
def elastica_limit():
    ref = _elastica_class()(40)
    assert np.abs(ref.energy_gradient(ref.natural(), (0.0, 0.0))[1]).max() == 0.0  # stress-free at rest
    level, _ = ref.static_threshold((0.0, -1.0), q0=ref.natural(), first=5e-4, rtol=1e-5)
    assert 1.55e-3 < level < 1.62e-3  # the 40-segment value in the module docstring
    return level


def _solve(**static):
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(arch_scene(PUSH_T, **static)))
    X = sim.model.host["positions"]
    crown = np.abs(X[:, 0]) < 0.5 * sim.model.dx
    res = sim.solve_static()
    return res, float(sim.state.x.numpy()[crown, 1].mean())


def test_arc_length_passes_the_snap_through_at_the_elastica_limit(elastica_limit):
    res, crown = _solve(arc_length=True)
    level = res.levels[-1]
    assert res.converged and level.arc_length_steps > 3
    limits = [f * PUSH_T for f in level.limit_levels]
    assert len(limits) == 2, limits                    # up to the snap, back along the unstable branch, up again
    assert limits[0] == pytest.approx(elastica_limit, rel=0.02)   # measured -0.2 % (-0.6 % from 160 segments)
    assert 0.5 * limits[0] < limits[1] < limits[0]     # the unstable branch's lower turn (1.09 mT)
    assert crown < -0.5 * RISE                         # ends snapped through, below the clamps
    assert level.lowest_eigenvalue > 0.0               # on a stable branch


def test_arc_length_and_load_increments_agree_below_the_limit():
    """At a fourth of the push (below the limit) both ways reach the same equilibrium; arc length reports no turn."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    crowns = []
    for arc in (False, True):
        sim = Simulation(parse_scene(arch_scene(0.25 * PUSH_T, arc_length=arc)))
        X = sim.model.host["positions"]
        res = sim.solve_static()
        assert res.converged and res.levels[-1].limit_levels == []
        assert (res.levels[-1].arc_length_steps > 0) == arc
        crowns.append(float(sim.state.x.numpy()[np.abs(X[:, 0]) < 0.5 * sim.model.dx, 1].mean()))
    assert crowns[1] == pytest.approx(crowns[0], rel=1e-6)
    assert 0.5 * RISE < crowns[0] < RISE               # pushed down, not through


def test_failed_load_increments_fall_back_to_arc_length(elastica_limit):
    """With 3 Newton iterations per increment the load increments crawl up to the limit and fail there; the
    solver then follows the path by arc length and reports the same limit."""
    res, crown = _solve(max_iterations=3)
    level = res.levels[-1]
    assert res.converged and level.arc_length_steps > 0 and crown < -0.5 * RISE
    assert level.limit_levels and level.limit_levels[0] * PUSH_T == pytest.approx(elastica_limit, rel=0.02)


def test_arc_length_refuses_colliders():
    from magsoro.errors import SimulationError
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    data = arch_scene(PUSH_T, arc_length=True)
    data["colliders"] = [{"type": "half_space", "point": [0.0, -0.006], "normal": [0.0, 1.0]}]
    sim = Simulation(parse_scene(data))
    with pytest.raises(SimulationError, match="arc_length"):
        sim.solve_static()


def test_stability_check_finds_a_negative_eigenvalue_behind_a_positive_one():
    """A higher arch (rise 4 mm) under a field tilted 2 degrees loses stability by its asymmetric mode at about
    6.6 mT (the elastica of the test above, with this rise: 6.62 mT). Solved at 10 mT straight from rest, Newton
    lands on the near-symmetric equilibrium, which is unstable, but the eigenvalue nearest zero there is a positive
    one (+0.0036 N/m; the check used to take it and accept the state, crown 3.05 mm up). The determinant's sign
    (an odd number of negative eigenvalues) sends the check on to the negative one: the level is reported
    buckled and ends on the stable, snapped-through branch."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(arch_scene(0.010, rise=0.004, tilt_deg=2.0)))
    X = sim.model.host["positions"]
    res = sim.solve_static()
    level = res.levels[-1]
    crown = float(sim.state.x.numpy()[np.abs(X[:, 0]) < 0.5 * sim.model.dx, 1].mean())
    assert res.converged and level.buckled
    assert level.lowest_eigenvalue > 0.0
    assert crown < -0.002                                # snapped (the stable branch at 10 mT), not 3 mm up


def test_permutation_parity_and_negative_count():
    import scipy.sparse as sp

    from magsoro.mpm.newton.static import _odd_negative_count, _permutation_parity

    assert _permutation_parity([0, 1, 2, 3]) == 0 and _permutation_parity([1, 0, 2, 3]) == 1
    assert _permutation_parity([1, 2, 0]) == 0 and _permutation_parity([3, 2, 1, 0]) == 0
    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.normal(size=(12, 12)))
    for negatives in range(4):
        w = np.concatenate([-np.arange(1, negatives + 1), np.arange(1, 13 - negatives)]) * 0.7
        K = sp.csc_matrix(Q @ np.diag(w) @ Q.T)
        assert _odd_negative_count(K) == (negatives % 2 == 1)


def test_limit_load_is_the_vertex_of_the_parabola_through_three_steps():
    from magsoro.mpm.newton.static import _vertex

    def a(s):  # a parabola with its top, 0.7, at s = 2
        return 0.7 - 0.3 * (s - 2.0) ** 2

    assert _vertex([(s, a(s)) for s in (1.0, 1.6, 3.1)]) == pytest.approx(0.7, abs=1e-12)
    assert _vertex([(s, a(s)) for s in (1.7, 2.1, 2.2)]) == pytest.approx(0.7, abs=1e-12)  # unequal steps
    assert _vertex([(0.0, 0.1), (1.0, 0.2), (2.0, 0.3)]) == 0.2  # (nearly) a straight line: the middle point
    assert _vertex([(s, a(s)) for s in (0.0, 0.5, 1.0)]) == a(0.5)  # the top is beyond the three points
