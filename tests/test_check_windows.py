"""Check windows (issue "GPU readiness"): the step loop reads the device's error flags, particle bounds and top
speed once per window of ``simulation.check_every`` steps instead of after every step. A window gives the same
trajectory as checked steps (fixed time step, float64: to round-off), a window that needs a refit of the grid
block or fails a check runs again step by step, and an error still names its exact step with the state before it
kept."""

import copy

import numpy as np
import pytest

from magsoro.scene import parse_scene
from magsoro.simulation import Simulation

SCENE = {
    "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.03, 0.02], "duration": 0.004,
                   "precision": "float64", "gravity": [0.0, -9.81], "dt": 2e-6, "formulation": "updated"},
    "bodies": [
        {"name": "slab", "shape": {"type": "rectangle", "center": [0.015, 0.004], "size": [0.02, 0.002]},
         "material": {"density": 1200.0, "shear_modulus": 3e4}},
        {"name": "block", "shape": {"type": "rectangle", "center": [0.012, 0.0065], "size": [0.004, 0.002]},
         "material": {"density": 1500.0, "shear_modulus": 5e4}, "magnetization": [0.1, 0.0, 0.0],
         "velocity": [0.3, 0.0]},
    ],
    "clamps": [{"region": {"type": "rectangle", "center": [0.015, 0.0032], "size": [0.02, 0.0004]}}],
    "fields": [{"type": "dipole", "moment": [0.0, 0.05, 0.0], "position": [0.02, 0.03, 0.0]}],
    "contact": {"friction": 0.3},
    "output": {"every": 0.001},
}


def _sim(check_every: int, **sim_keys) -> Simulation:
    scene = copy.deepcopy(SCENE)
    scene["simulation"].update(check_every=check_every, **sim_keys)
    return Simulation(parse_scene(scene), device="cpu")


def _state(sim) -> dict:
    return {k: v.astype(np.float64) for k, v in sim.state.numpy().items()}


def test_windows_give_the_checked_trajectory_with_one_read_per_window():
    """Contact between two bodies, a gradient field, gravity: 2000 steps in windows of 100 against checked steps.
    Same arithmetic in the same order, so the states agree to round-off; the host reads once per window."""
    plain, windowed = _sim(1), _sim(100)
    r1, r2 = plain.run(), windowed.run()
    assert r1.status == r2.status == "completed" and r1.steps == r2.steps == 2000
    a, b = _state(plain), _state(windowed)
    for key in a:
        scale = max(np.abs(a[key]).max(), 1e-30)
        assert np.abs(a[key] - b[key]).max() <= 1e-12 * scale, key
    assert plain.solver.host_reads >= r1.steps
    # 20 windows (records every 500 steps end windows too) and one read of the initial positions
    assert windowed.solver.host_reads <= r2.steps / 100 + 1
    assert windowed.windows == 20


def test_a_window_that_needs_a_refit_runs_again_step_by_step():
    """A window fits the grid block with room for the motion at its starting speed; a block that starts at rest
    and is flung upwards (gravity 20,000 m/s^2 along +y: 10 mm in the 1 ms of a 500-step window) outruns that
    room, leaves the block within the window, and the window runs again in checked steps, which refit. The
    trajectory is still the checked one (fixed time step)."""
    sims = []
    for every in (1, 500):
        scene = copy.deepcopy(SCENE)
        scene["simulation"].update(duration=0.002, check_every=every, gravity=[0.0, 20000.0])
        sims.append(Simulation(parse_scene(scene), device="cpu"))
    plain, windowed = sims
    r1, r2 = plain.run(), windowed.run()
    assert r1.status == r2.status == "completed"
    assert windowed.reruns >= 1 and windowed.solver.refits >= 2
    a, b = _state(plain), _state(windowed)
    assert np.abs(a["x"] - b["x"]).max() <= 1e-12 * np.abs(a["x"]).max()


def test_a_window_makes_room_for_the_motion_it_expects():
    """A block sent upwards at 3 m/s: each window fits the grid block with room for twice the distance at the
    speed of the last check, so the windows need no second run, and the trajectory is the checked one."""
    sims = []
    for every in (1, 500):
        scene = copy.deepcopy(SCENE)
        scene["simulation"].update(duration=0.002, check_every=every)
        scene["bodies"][1]["velocity"] = [0.0, 3.0]
        sims.append(Simulation(parse_scene(scene), device="cpu"))
    plain, windowed = sims
    r1, r2 = plain.run(), windowed.run()
    assert r1.status == r2.status == "completed"
    assert windowed.reruns == 0 and plain.solver.refits >= 2
    a, b = _state(plain), _state(windowed)
    assert np.abs(a["x"] - b["x"]).max() <= 1e-12 * np.abs(a["x"]).max()


def test_an_error_inside_a_window_names_its_exact_step_and_keeps_the_state_before_it():
    """A field far too strong for the grid (20 T on a soft magnet) makes the block explode after 23 steps of
    2 us: windowed and checked runs stop at the same step with the same error and keep the same last good state
    (the fixed time step makes the arithmetic the same but for the grid block's origin, which the window fits
    with more room: round-off, which the explosion amplifies in the failing step's numbers)."""
    results = []
    for every in (1, 250):
        scene = copy.deepcopy(SCENE)
        scene["simulation"].update(check_every=every, duration=0.01)
        scene["fields"] = [{"type": "uniform", "B": [0.0, 20.0, 0.0]}]
        sim = Simulation(parse_scene(scene), device="cpu")
        result = sim.run()
        results.append((result, _state(sim), sim))
    (r1, s1, _), (r2, s2, windowed) = results
    assert r1.status == r2.status == "failed", (r1.message, r2.message)
    assert r1.steps == r2.steps == 23, r1.message
    for r in (r1, r2):
        assert r.message.startswith("step 23, t = 4.6e-05 s: a particle moved") and "cells in one step" in r.message
    assert windowed.reruns == 1
    assert np.all(np.isfinite(s2["x"])) and np.all(np.linalg.det(s2["F"]) > 0)
    for key in s1:  # measured: 4e-13 of each array's scale
        assert np.abs(s1[key] - s2[key]).max() <= 1e-9 * max(np.abs(s1[key]).max(), 1e-30), key


def test_check_every_is_validated():
    from magsoro.errors import SceneError

    scene = copy.deepcopy(SCENE)
    scene["simulation"]["check_every"] = 0
    with pytest.raises(SceneError, match=r"simulation\.check_every"):
        parse_scene(scene)


def test_an_interrupted_window_keeps_its_first_state():
    """Ctrl-C or SIGTERM inside a window: the state kept is the window's first (checked) one, not an unchecked
    one from the middle of the window."""
    sim = _sim(100)
    calls = []

    def stop_at_150(s):
        calls.append(s.steps)
        if s.steps == 150:
            raise KeyboardInterrupt

    result = sim.run(callback=stop_at_150)
    assert result.status == "interrupted"
    assert sim.steps == 100 and sim.time == pytest.approx(100 * 2e-6, rel=1e-12)
    assert calls[-1] == 150
    sim.step()  # the solver steps on from the kept state
    assert sim.steps == 101
