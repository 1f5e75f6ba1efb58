"""The scatters with one thread per (particle, stencil node) (``Solver.spread_scatter``, the GPU default) give the
same states as one thread per particle (the CPU default).

On the CPU a launch runs its threads one after another in index order, so with thread p 3^dim + q every node
still receives its particles' terms in increasing particle order, as with one thread per particle: the sums, and
so the states, are the same to the bit. (On a GPU the order of the atomic adds changes from run to run either
way; tests/test_graph_windows.py compares the device's runs with the CPU's.) Both scatters are covered: p2g's, and
the velocity-gradient remap's (the walker runs the updated form with the remap), in 3D without contact and in 2D
with the two-field contact grid (a block resting on a clamped slab).
"""

import numpy as np
import pytest

from magsoro.scene import parse_scene
from magsoro.simulation import Simulation
from magsoro.validation.contact import slope_scene


def _walker(spread: bool, steps: int = 40, device: str = "cpu") -> dict:
    from magsoro.bench.scenes import build
    from magsoro.mpm.solver import Solver

    model, control, settings = build("walker", device=device, precision="float64")
    settings.threads = 1
    solver = Solver(model, settings)
    assert solver.spread_scatter is (device != "cpu")  # the CPU's default, and the GPU's for 9,600 particles
    solver.spread_scatter = spread
    a, b = solver.new_state(), solver.new_state()
    for _ in range(steps):
        solver.step(a, b, control, 4e-6)
        a, b = b, a
    return a.numpy()


def _block_on_slab(spread: bool, steps: int = 150, device: str = "cpu") -> dict:
    scene = slope_scene(0.3, "slab", dx=5e-4, precision="float64")
    scene["simulation"]["threads"] = 1
    sim = Simulation(parse_scene(scene), device=device)
    assert sim.solver.contact_active  # the two-field variant of the kernels
    sim.solver.spread_scatter = spread
    for _ in range(steps):
        sim.step(2e-6)
    return sim.state.numpy()


@pytest.mark.parametrize("run", [_walker, _block_on_slab], ids=["walker_3d_remap", "block_on_slab_2d_contact"])
def test_thread_per_node_scatter_equals_thread_per_particle(run):
    per_particle, per_node = run(False), run(True)
    for key in ("x", "v", "C", "F"):
        a, b = per_particle[key], per_node[key]
        assert np.all(np.isfinite(a))
        np.testing.assert_array_equal(a, b, err_msg=key)
    assert np.abs(per_particle["v"]).max() > 0.0  # the runs moved: the comparison is not of two rest states


@pytest.mark.cuda
@pytest.mark.parametrize("run", [_walker, _block_on_slab], ids=["walker_3d_remap", "block_on_slab_2d_contact"])
def test_cuda_thread_per_node_scatter_follows_thread_per_particle_and_the_cpu(run):
    """On a GPU the atomic adds land in an order that changes from run to run, with either scatter, so the two
    agree to rounding amplified over the run, not to the bit: 1e-9 of the largest value (float64), as the graph
    windows against the plain loop (tests/test_graph_windows.py); and both follow the CPU to the same bound."""
    import warp as wp

    if wp.get_cuda_device_count() == 0:
        pytest.skip("no CUDA device")
    cpu = run(False)
    per_particle, per_node = run(False, device="cuda:0"), run(True, device="cuda:0")
    for key in ("x", "v", "C", "F"):
        scale = max(np.abs(cpu[key]).max(), 1e-30)
        assert np.abs(per_node[key] - per_particle[key]).max() <= 1e-9 * scale, key
        assert np.abs(per_node[key] - cpu[key]).max() <= 1e-9 * scale, key
        assert np.abs(per_particle[key] - cpu[key]).max() <= 1e-9 * scale, key
    assert np.abs(cpu["v"]).max() > 0.0
