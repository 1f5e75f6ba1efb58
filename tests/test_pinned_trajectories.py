"""Pinned float64 trajectories of three scenes: the engine's restructuring must leave them unchanged.

The reference states in ``tests/data/pinned_trajectories.npz`` were written by this module
(``python tests/test_pinned_trajectories.py --write``) on the engine before its restructure (commit ebec015).
A restructure (moving kernels between modules, grouping arguments, renaming) keeps the arithmetic and so the
states to round-off: 1e-12 relative to each array's scale. A change that alters physics on purpose (a new contact
law) must say so and rewrite the file in the same commit, with the reason in the commit message.

Scenes (single bodies, so inter-body contact does not enter; the floors are rigid colliders):
- beam2d: Zhao et al.'s clamped beam at t/dx = 4 in a perpendicular field, 300 steps of fixed dt;
- walker: the 3D benchmark walker (rotating field, friction floor), 200 steps;
- cube_dipole: the cube pulled by a dipole over the friction floor (scenes/cube_dipole_3d.toml), 300 steps.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

if __name__ == "__main__":  # run as a script (--write): the tests package is not on the path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.conftest import run_solver  # noqa: E402

DATA = Path(__file__).parent / "data" / "pinned_trajectories.npz"
ROOT = Path(__file__).resolve().parents[1]


def _solver_run(name: str, steps: int, dt: float) -> dict:
    from magsoro.bench.scenes import build

    return run_solver(*build(name, device="cpu", precision="float64"), dt, steps).numpy()


def _cube_dipole() -> dict:
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    scene = load_scene(ROOT / "scenes" / "cube_dipole_3d.toml")
    scene.simulation.precision = "float64"
    scene.simulation.formulation = "updated"  # pinned in the updated form, the scene default when it was written
    scene.simulation.threads = 1
    sim = Simulation(scene, device="cpu")
    for _ in range(300):
        sim.step(2e-6)
    return sim.state.numpy()


def trajectories() -> dict:
    """Final x, v, C, F of each pinned run, keyed 'scene/array'."""
    runs = {
        "beam2d": lambda: _solver_run("beam2d", 300, 2e-6),
        "walker": lambda: _solver_run("walker", 200, 4e-6),
        "cube_dipole": _cube_dipole,
    }
    out = {}
    for name, run in runs.items():
        for key, arr in run().items():
            out[f"{name}/{key}"] = np.asarray(arr, dtype=np.float64)
    return out


def test_pinned_trajectories_unchanged():
    if not DATA.exists():
        pytest.fail(f"{DATA} is missing; write it with: python {Path(__file__).name} --write")
    ref = np.load(DATA)
    now = trajectories()
    assert sorted(ref.files) == sorted(now)
    for key in ref.files:
        r, n = ref[key], now[key]
        scale = max(float(np.abs(r).max()), 1e-30)
        err = float(np.abs(n - r).max()) / scale
        assert err <= 1e-12, f"{key}: relative change {err:.3e} (scale {scale:.3e})"
    # the runs did something: the pinned states are not their initial states
    assert np.abs(ref["walker/v"]).max() > 1e-4
    assert np.abs(ref["beam2d/v"]).max() > 1e-4
    assert np.abs(ref["cube_dipole/v"]).max() > 1e-4


if __name__ == "__main__":
    if "--write" in sys.argv:
        DATA.parent.mkdir(exist_ok=True)
        np.savez_compressed(DATA, **trajectories())
        print(f"wrote {DATA}")
