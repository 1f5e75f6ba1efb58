"""Pinned float64 trajectories of short runs over the engine's paths: its restructuring must leave them unchanged.

The reference states in ``tests/data/pinned_trajectories.npz`` were written by this module
(``python tests/test_pinned_trajectories.py --write [RUN ...]``): the first three runs on the engine before its
restructure (commit ebec015), the others on the engine of commit 2bf7fed (before the seams of the "Implicit engine"
issue, item 1). A restructure (moving kernels between modules, grouping arguments, renaming) keeps the arithmetic
and so the states to round-off: 1e-12 relative to each array's scale. A change that alters physics on purpose (a
new contact law) must say so and rewrite the file in the same commit (``--write RUN ...`` rewrites only the runs
named, keeping the others' arrays), with the reason in the commit message.

Runs (x, v, C, F after the last step; the engine's path each one pins):
- beam2d: Zhao et al.'s clamped beam at t/dx = 4 in a perpendicular field, 300 steps of fixed dt (2D updated form,
  clamp, uniform field, remap);
- walker: the 3D benchmark walker (rotating field, friction floor, gravity), 200 steps (3D updated form);
- cube_dipole: the cube pulled by a dipole over the friction floor (scenes/cube_dipole_3d.toml), 300 steps (3D
  updated form, non-uniform field);
- cantilever_total: scenes/cantilever_2d.toml with its field held from the start, on two CPU threads, 1000 steps
  (2D total form, majority-held clamp nodes, uniform field, the threads' grids summed);
- cube_clamped_total: scenes/cube_dipole_clamped_3d.toml, 200 steps (3D total form, clamp, dipole, gravity);
- slope_collider_total: a block falling onto a friction collider under tilted gravity, 500 steps (2D total form,
  collider skin);
- slope_collider_grid: the same in the updated form with velocity_gradient = "grid" (F from the grid update);
- slab_contact: the block falling onto a clamped elastic slab, Coulomb friction 0.2 between them, 500 steps (2D
  updated form, two velocity fields per node);
- slab_contact_total: the same in the total form, 300 steps (the contact pass on a grid of the current
  configuration);
- collider_modes: a magnetised 2D block against a symmetry plane, on a friction floor, under a sticky box moving
  down along a path and a slip sphere, next to friction walls, 500 steps (2D updated form, every collider mode and
  kind but the cylinder, a moving collider's velocity, the walls);
- collider_modes_total: the same in the total form.
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


def _scene_run(scene, steps: int, dt: float, threads: int = 1, **simulation) -> dict:
    """Final state of ``steps`` steps of ``dt`` of a parsed scene in float64 on ``threads`` CPU threads, with the
    ``simulation`` keys set."""
    from magsoro.simulation import Simulation

    scene.simulation.precision = "float64"
    scene.simulation.threads = threads
    for key, value in simulation.items():
        setattr(scene.simulation, key, value)
    sim = Simulation(scene, device="cpu")
    for _ in range(steps):
        sim.step(dt)
    return sim.state.numpy()


def _scene_file(name: str):
    from magsoro.scene import load_scene

    return load_scene(ROOT / "scenes" / name)


def _cube_dipole() -> dict:
    # pinned in the updated form, the scene default when it was written
    return _scene_run(_scene_file("cube_dipole_3d.toml"), 300, 2e-6, formulation="updated")


def _cantilever_total() -> dict:
    scene = _scene_file("cantilever_2d.toml")
    scene.fields[0].profile = None  # the field from the start: the beam moves within the run
    return _scene_run(scene, 1000, 1e-6, threads=2, formulation="total")


def _slope(support: str, steps: int, **simulation) -> dict:
    from magsoro.scene import parse_scene
    from magsoro.validation.contact import slope_scene

    scene = parse_scene(slope_scene(0.2, support, dx=5e-4, start_sites=1, precision="float64"))
    return _scene_run(scene, steps, 2e-6, **simulation)


def _collider_modes(formulation: str) -> dict:
    from magsoro.fields import Uniform
    from magsoro.fields.profiles import Keyframes
    from magsoro.mpm.colliders import Collider
    from magsoro.mpm.model import Control, SolverSettings
    from tests.conftest import make_block_model

    dx = 5e-4
    model = make_block_model((0.0, 0.0), (4e-3, 2e-3), dx, G=1e5, Br=(0.05, 0.0, 0.0),
                             domain=((-0.004, -0.002), (4e-3 + 2.5 * dx, 0.006)))
    # the box's centre from half a cell above the block's top face to 0.2 cells into it in 1 ms
    press = Keyframes([0.0, 1e-3], [[2e-3, 3e-3 + 0.5 * dx, 0.0], [2e-3, 3e-3 - 0.2 * dx, 0.0]])
    colliders = [
        Collider.half_space([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], mode="symmetry"),
        Collider.half_space([0.0, -0.25 * dx, 0.0], [0.0, 1.0, 0.0], mode="friction", friction=0.3),
        Collider.box([2e-3, 3e-3 + 0.5 * dx, 0.0], [1e-3, 1e-3, 1e-3], mode="sticky", path=press),
        Collider.sphere([4e-3, 2.5e-3, 0.0], 1e-3, mode="slip"),
    ]
    control = Control([Uniform([0.0, 0.004, 0.0])], colliders)
    settings = SolverSettings(damping=20.0, gravity=(2.0, -9.81), walls="friction", wall_friction=0.2,
                              formulation=formulation)
    return run_solver(model, control, settings, 2e-6, 500).numpy()


RUNS = {
    "beam2d": lambda: _solver_run("beam2d", 300, 2e-6),
    "walker": lambda: _solver_run("walker", 200, 4e-6),
    "cube_dipole": _cube_dipole,
    "cantilever_total": _cantilever_total,
    "cube_clamped_total": lambda: _scene_run(_scene_file("cube_dipole_clamped_3d.toml"), 200, 4e-6, formulation="total"),
    "slope_collider_total": lambda: _slope("collider", 500, formulation="total"),
    "slope_collider_grid": lambda: _slope("collider", 500, formulation="updated", velocity_gradient="grid"),
    "slab_contact": lambda: _slope("slab", 500, formulation="updated"),
    "slab_contact_total": lambda: _slope("slab", 300, formulation="total"),
    "collider_modes": lambda: _collider_modes("updated"),
    "collider_modes_total": lambda: _collider_modes("total"),
}


def trajectories(names=None) -> dict:
    """Final x, v, C, F of the pinned runs ``names`` (default all), keyed 'run/array'."""
    out = {}
    for name in RUNS if names is None else names:
        for key, arr in RUNS[name]().items():
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
    for name in RUNS:
        assert np.abs(ref[f"{name}/v"]).max() > 1e-4, name


if __name__ == "__main__":
    if "--write" in sys.argv:
        names = [a for a in sys.argv[1:] if a != "--write"] or None
        unknown = sorted(set(names or ()) - set(RUNS))
        if unknown:
            sys.exit(f"no pinned run named {', '.join(unknown)}; the runs: {', '.join(RUNS)}")
        keep = {}
        if names is not None and DATA.exists():  # the runs not named keep their arrays
            with np.load(DATA) as old:
                keep = {k: old[k] for k in old.files if k.split("/")[0] not in names}
        DATA.parent.mkdir(exist_ok=True)
        np.savez_compressed(DATA, **keep, **trajectories(names))
        print(f"wrote {DATA}")
