"""CPU threads: a step split over threads (particle ranges, a private grid per extra thread, grids summed node by
node) gives the one-thread result up to the order of floating-point sums."""

import numpy as np
import pytest

from magsoro.fields import Dipole, Uniform
from magsoro.mpm.colliders import Collider
from magsoro.mpm.model import Control, SolverSettings
from magsoro.mpm.runtime import resolve_threads
from magsoro.mpm.solver import Solver
from magsoro.errors import MagsoroError, SceneError
from magsoro.scene import parse_scene
from tests.conftest import make_block_model

LO, HI, DX = (0.0, 0.0, 0.0), (4e-3, 1e-3, 1e-3), 0.5e-3


def _model(dim):
    lo, hi = LO[:dim], HI[:dim]
    return make_block_model(
        lo, hi, DX, G=5e4, Br=(0.0, 0.1, 0.05), precision="float64",
        domain=(np.array(lo) - 8 * DX, np.array(hi) + 8 * DX), clamped=lambda X: X[:, 0] < 0.6e-3,
    )


def _run(dim, threads, velocity_gradient, steps=60):
    model = _model(dim)
    settings = SolverSettings(damping=20.0, gravity=(0.0, -9.81, 0.0), threads=threads, velocity_gradient=velocity_gradient)
    # a uniform field bends the clamped block, a dipole pulls on it (gradient force), a floor it may touch
    control = Control(
        sources=[Uniform([0.0, 0.0, 0.02]) if dim == 3 else Uniform([0.02, 0.0, 0.0]), Dipole(moment=[0.0, 0.05, 0.0], position=[2e-3, -6e-3, 0.5e-3])],
        colliders=[Collider.half_space([0.0, -0.2e-3, 0.0], [0.0, 1.0, 0.0], mode="friction", friction=0.3)],
    )
    solver = Solver(model, settings)
    a, b = solver.new_state(), solver.new_state()
    dt = 0.5 * solver.stable_dt(control)
    for _ in range(steps):
        solver.step(a, b, control, dt)
        a, b = b, a
    return solver, a


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("velocity_gradient", ["remap", "grid"])
def test_threaded_step_equals_one_thread(dim, velocity_gradient):
    one, s1 = _run(dim, 1, velocity_gradient)
    three, s3 = _run(dim, 3, velocity_gradient)  # uneven ranges; more threads than this machine's cores is fine
    assert one.threads == 1 and three.threads == 3
    x1, x3 = s1.x.numpy(), s3.x.numpy()
    disp = np.abs(x1 - one.model.host["positions"]).max()
    assert disp > 1e-2 * DX  # the body moved: the comparison means something
    # float64: only the order of the node sums differs (about 1e-16 per step, a few hundred steps' growth at most)
    assert np.abs(x3 - x1).max() <= 1e-10 * disp
    assert np.abs(s3.F.numpy() - s1.F.numpy()).max() <= 1e-10
    assert np.abs(s3.v.numpy() - s1.v.numpy()).max() <= 1e-9 * max(np.abs(s1.v.numpy()).max(), 1e-12)
    assert three.last_max_speed() == pytest.approx(one.last_max_speed(), rel=1e-9)
    assert three.grid_info() == one.grid_info()


def test_resolve_threads(monkeypatch):
    monkeypatch.delenv("MAGSORO_THREADS", raising=False)
    assert resolve_threads(None, "cuda:0", 10**6) == 1  # one CUDA stream, never CPU threads
    assert resolve_threads(4, "cuda", 10**6) == 1
    assert resolve_threads(None, "cpu", 100) == 1  # too small to pay for a second thread
    assert resolve_threads(3, "cpu", 100) == 3
    assert resolve_threads(8, "cpu", 5) == 5  # never more threads than particles
    monkeypatch.setenv("MAGSORO_THREADS", "1")
    assert resolve_threads(None, "cpu", 10**6) == 1
    assert resolve_threads(2, "cpu", 10**6) == 2  # the scene's own setting wins over the environment
    monkeypatch.setenv("MAGSORO_THREADS", "two")
    with pytest.raises(MagsoroError, match="MAGSORO_THREADS"):
        resolve_threads(None, "cpu", 10**6)


def test_threads_setting_is_checked():
    model = _model(2)
    with pytest.raises(ValueError, match="threads"):
        Solver(model, SolverSettings(threads=0))
    scene = {
        "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.02, 0.01], "duration": 2e-3, "threads": 0},
        "bodies": [{"name": "b", "shape": {"type": "rectangle", "center": [0.008, 0.005], "size": [0.01, 0.002]}, "material": {"density": 1000.0, "shear_modulus": 5e4}}],
    }
    with pytest.raises(SceneError, match=r"simulation\.threads"):
        parse_scene(scene)
    scene["simulation"]["threads"] = 2
    assert parse_scene(scene).simulation.threads == 2


def test_workers_run_every_launch_and_pass_errors_on():
    """The helper threads of a CPU step run their launches, wait for all of them, and re-raise a worker's
    error in the stepping thread (after the others have finished: they write into the same arrays)."""
    import threading
    import time

    from magsoro.mpm.runtime import Workers

    ran = []

    class Job:
        def __init__(self, name, fail=False, delay=0.0):
            self.name, self.fail, self.delay = name, fail, delay

        def launch(self):
            time.sleep(self.delay)
            ran.append((self.name, threading.current_thread().name))
            if self.fail:
                raise RuntimeError(f"{self.name} failed")

    w = Workers(2)
    w.run([Job("a"), Job("b"), Job("c")])
    assert sorted(n for n, _ in ran) == ["a", "b", "c"]
    assert {t for _, t in ran} == {threading.current_thread().name, "magsoro-step-1", "magsoro-step-2"}
    ran.clear()
    with pytest.raises(RuntimeError, match="c failed"):
        w.run([Job("a"), Job("b", delay=0.05), Job("c", fail=True)])
    assert sorted(n for n, _ in ran) == ["a", "b", "c"]  # b finished before the error came back
    ran.clear()
    w.run([Job("a"), Job("b"), Job("c")])  # still usable after an error
    assert len(ran) == 3
