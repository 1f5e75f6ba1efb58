"""Check windows from drive tables (issue "GPU readiness", docs/engine.md "CUDA graph windows"): the host prepares a
window's per-step values once (dt, damping factor, uniform field, moving colliders' table), and every step of the
window is the same launch sequence, which CUDA captures once as a graph and replays. The same sequence runs here on
CPU, launched one by one (the default) and captured as Warp CPU graphs (``Solver.graph_capture = True``); both give
the plain step loop's trajectory to the bit, and the checked loop's to 1e-12 (float64). Scenes that need the host
at every step run the plain loop and say why in ``Simulation.notes`` (run.json's ``notes``)."""

import copy
import json

import numpy as np
import pytest

from magsoro.scene import parse_scene
from magsoro.simulation import Simulation, graph_off_note

STRIP = {"name": "strip", "shape": {"type": "rectangle", "center": [0.015, 0.0036], "size": [0.012, 0.001]},
         "material": {"density": 1200.0, "shear_modulus": 3e4}, "magnetization": [0.1, 0.0, 0.0]}
BASE = {
    "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.03, 0.02], "duration": 0.0012,
                   "precision": "float64", "formulation": "updated", "check_every": 64},
    "bodies": [STRIP],
    "output": {"every": 0.0003},
}

# a clamped cantilever under a ramped uniform field, total Lagrangian form (the default for one body), fixed dt
RAMP = {
    "simulation": {"formulation": "auto", "dt": 4e-6, "damping": 50.0},
    "clamps": [{"region": {"type": "rectangle", "center": [0.0095, 0.0036], "size": [0.001, 0.002]}}],
    "fields": [{"type": "uniform", "B": [0.0, 0.02, 0.0], "profile": {"type": "ramp", "duration": 0.001}}],
}
# a free strip in a rotating field, automatic time step
ROTATING = {"simulation": {"duration": 0.0025}, "fields": [{"type": "rotating", "magnitude": 0.01, "frequency": 300.0, "u": [1.0, 0.0, 0.0],
                        "v": [0.0, 1.0, 0.0]}]}
# a box that moves down and along, pressing the strip onto a slip floor (velocity-gradient "grid" variant)
MOVING = {
    "simulation": {"dt": 3e-6, "velocity_gradient": "grid"},
    "colliders": [
        {"type": "half_space", "point": [0.0, 0.003], "normal": [0.0, 1.0], "mode": "slip"},
        {"type": "box", "center": [0.015, 0.006], "size": [0.004, 0.002], "mode": "friction",
         "friction": 0.5, "path": {"times": [0.0, 0.0006, 0.0012],
                                   "positions": [[0.015, 0.0052], [0.015, 0.0044], [0.017, 0.0044]]}},
    ],
}
# a strip and a block dropped on a friction floor under gravity, contact between them (two velocity fields)
FLOOR = {
    "simulation": {"gravity": [0.0, -9.81], "duration": 0.002},
    "bodies": [STRIP, {"name": "block", "shape": {"type": "rectangle", "center": [0.014, 0.0050], "size": [0.003, 0.0015]},
                       "material": {"density": 1500.0, "shear_modulus": 5e4}, "velocity": [0.2, -0.3]}],
    "colliders": [{"type": "half_space", "point": [0.0, 0.0031], "normal": [0.0, 1.0], "mode": "friction",
                   "friction": 0.4}],
    "contact": {"friction": 0.3},
    "fields": [{"type": "uniform", "B": [0.0, 0.0, 0.0]}],
}
# a dipole moving past the strip and a resting one: non-uniform sources, whose parameters at each step come from
# the drive table (load_params) and whose kernels run at the step's positions inside the window
DIPOLE = {
    "simulation": {"dt": 3e-6},
    "fields": [{"type": "dipole", "moment": [0.0, 0.05, 0.0], "position": [0.005, 0.03, 0.0],
                "path": {"times": [0.0, 0.0012], "positions": [[0.005, 0.03, 0.0], [0.025, 0.028, 0.0]]}},
               {"type": "dipole", "moment": [0.02, 0.0, 0.0], "position": [0.03, 0.004, 0.0]}],
}
SCENES = {"ramp": RAMP, "rotating": ROTATING, "moving_collider": MOVING, "floor_contact": FLOOR, "dipole": DIPOLE}


def _scene(extra: dict, **sim_keys):
    scene = copy.deepcopy(BASE)
    for key, value in copy.deepcopy(extra).items():
        if key == "simulation":
            scene["simulation"].update(value)
        else:
            scene[key] = value
    scene["simulation"].update(sim_keys)
    return parse_scene(scene)


def _run(extra: dict, mode: str, device: str = "cpu", **sim_keys) -> Simulation:
    """mode: 'plain' (a per-step callback keeps the window in the plain step loop), 'direct' (drive tables, steps
    launched one by one: the CPU default), 'captured' (drive tables, Warp CPU graphs; on CUDA, CUDA graphs: the
    default there), 'checked' (check_every 1)."""
    if mode == "checked":
        sim_keys["check_every"] = 1
    sim = Simulation(_scene(extra, **sim_keys), device=device)
    if mode == "captured":
        sim.solver.graph_capture = True
    result = sim.run(callback=(lambda s: None) if mode == "plain" else None)
    assert result.status == "completed", result.message
    return sim


def _state(sim) -> dict:
    return {k: v.astype(np.float64) for k, v in sim.state.numpy().items()}


def _max_rel(a: dict, b: dict) -> float:
    return max(np.abs(a[k] - b[k]).max() / max(np.abs(a[k]).max(), 1e-30) for k in a)


def _engine_notes(sim):
    """The run's notes that are not about the scene as given (those are in ``scene_notes`` too)."""
    return [n for n in sim.notes if n not in sim.scene_notes]


@pytest.mark.parametrize("name", list(SCENES))
def test_graph_windows_give_the_plain_loops_trajectory(name):
    extra = SCENES[name]
    plain, direct, captured = (_run(extra, mode) for mode in ("plain", "direct", "captured"))
    assert plain.solver.graph_windows == 0 and plain.steps > 250
    assert direct.solver.graph_windows == direct.windows > 0 and direct.solver.graph_captures == 0
    assert captured.solver.graph_windows == captured.windows and captured.solver.graph_captures > 0
    assert captured.solver.graph_replays >= captured.windows
    assert plain.steps == direct.steps == captured.steps
    assert plain.dt_min == direct.dt_min and plain.dt_max == direct.dt_max
    a, b, c = _state(plain), _state(direct), _state(captured)
    for key in a:  # same kernels, same values, same order: to the bit
        assert np.array_equal(a[key], b[key]), (key, np.abs(a[key] - b[key]).max())
        assert np.array_equal(a[key], c[key]), (key, np.abs(a[key] - c[key]).max())
    # the engine's own notes (the scene's, such as a thin strip, are the same for every mode)
    assert _engine_notes(direct) == _engine_notes(captured) == []
    if SCENES[name].get("simulation", {}).get("dt"):  # fixed dt: the checked loop takes the same steps
        checked = _run(extra, "checked")
        assert checked.steps == direct.steps
        assert _max_rel(_state(checked), b) <= 1e-12


def test_windows_of_odd_lengths_swap_the_states_and_replay_their_graphs():
    """Windows of 1, 2, 3, 5, 8, ... steps (binary pieces 1, 2, 4, 8, 16, 32 from either state): captured graphs
    are made once per piece and state, and replayed."""
    sims = {}
    for mode in ("plain", "captured"):
        sim = Simulation(_scene(ROTATING, dt=2e-6, check_every=64), device="cpu")
        sim.solver.graph_capture = mode == "captured"
        t = 0.0
        for n in (1, 2, 3, 5, 8, 13, 21, 34, 55, 7, 45, 63, 33):
            t += n * 2e-6
            sim.advance_to(t, callback=(lambda s: None) if mode == "plain" else None)
        sims[mode] = sim
    plain, captured = sims["plain"], sims["captured"]
    assert plain.steps == captured.steps == 290
    a, b = _state(plain), _state(captured)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert captured.solver.graph_captures <= 2 * 6  # sizes 1..32, each from either state
    assert captured.solver.graph_replays > captured.solver.graph_captures


def test_graph_windows_read_the_host_once_per_window():
    scene = _scene(ROTATING, dt=2e-6, check_every=100, duration=0.0016)
    sim = Simulation(scene, device="cpu")
    sim.solver.graph_capture = True
    beats = []
    result = sim.run(record_every=0.0004, heartbeat=lambda s: beats.append(s.steps))
    assert result.status == "completed" and result.steps == 800
    assert len(beats) >= sim.windows and beats[-1] == 800  # after each graph replayed and each window
    assert sim.windows == sim.solver.graph_windows == 8 and sim.reruns == 0
    # one read per window (bounds, flags, top speed) and one of the initial positions
    assert sim.solver.host_reads <= result.steps / 100 + 1
    assert sim.solver.host_reads / result.steps <= 1 / 100 + 1 / result.steps


def test_a_window_that_fails_runs_again_in_checked_steps():
    """A block flung upwards outruns the grid block's room inside a window: the window, run from drive tables,
    goes back to its first state and runs again in checked steps, as the plain loop does."""
    extra = {"simulation": {"gravity": [0.0, 20000.0], "dt": 2e-6}, "fields": [{"type": "uniform", "B": [0.0, 0.0, 0.0]}],
             "output": {"every": 0.001}}
    plain, direct = (_run(extra, mode, check_every=500, duration=0.002) for mode in ("plain", "direct"))
    assert direct.reruns >= 1 and direct.reruns == plain.reruns
    a, b = _state(plain), _state(direct)
    assert all(np.array_equal(a[k], b[k]) for k in a)


def test_a_scene_that_needs_the_host_every_step_runs_the_plain_loop_and_says_why(tmp_path):
    extra = {"output": {"every": 0.0001}}
    sim = Simulation(_scene(extra, dt=2e-6, duration=0.0002, magnetic_interaction="dipole"), device="cpu")
    from magsoro.io.recorder import RunWriter

    writer = RunWriter(tmp_path, sim, {}, particles=False)
    result = sim.run(heartbeat=writer.beat)
    writer.finish(result, result.wall_time)
    assert result.status == "completed" and sim.solver.graph_windows == 0
    reason = sim.solver.graph_refusal(sim.control)
    assert reason.startswith("the magnetic interaction")
    assert _engine_notes(sim) == [f"graph windows off (plain step loop): {reason}"]
    info = json.loads((tmp_path / "run.json").read_text())
    assert info["notes"] == sim.notes and info["graph_windows"]["windows"] == 0
    assert graph_off_note("cuda", reason) == f"CUDA graph capture off: {reason}"


def test_graph_windows_on_two_cpu_threads_launch_the_steps_one_by_one():
    plain, direct = (_run(ROTATING, mode, threads=2, dt=3e-6, duration=0.0006) for mode in ("plain", "direct"))
    assert direct.solver.threads == 2 and direct.solver.graph_windows > 0 and direct.solver.graph_captures == 0
    a, b = _state(plain), _state(direct)
    assert all(np.array_equal(a[k], b[k]) for k in a)


def test_capture_refusals():
    sim = Simulation(_scene(ROTATING, threads=2), device="cpu")
    assert sim.solver.graph_refusal(sim.control) is None
    assert "2 CPU threads" in sim.solver.capture_refusal()
    sim.solver.enable_phase_timing(True)
    assert sim.solver.graph_refusal(sim.control).startswith("phase timing")
    interacting = Simulation(_scene(ROTATING, magnetic_interaction="dipole"), device="cpu")
    assert interacting.solver.graph_refusal(interacting.control).startswith("the magnetic interaction")


def test_a_capture_that_fails_launches_the_steps_and_says_why(monkeypatch):
    """A capture that raises (a driver without graph support, an operation a graph cannot hold) runs that piece
    of the window launched one by one and captures no more; the trajectory is the same."""
    import warp as wp

    def refuse(*args, **kwargs):
        raise RuntimeError("no graphs here")

    plain = _run(ROTATING, "plain", dt=3e-6, duration=0.0006)
    monkeypatch.setattr(wp, "ScopedCapture", refuse)
    failed = _run(ROTATING, "captured", dt=3e-6, duration=0.0006)
    assert failed.solver.graph_windows == failed.windows and failed.solver.graph_captures == 0
    assert failed.solver.graph_capture is False
    assert failed.solver.capture_refusal() == "the capture failed (RuntimeError: no graphs here)"
    a, b = _state(plain), _state(failed)
    assert all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.cuda
@pytest.mark.parametrize("name", ["ramp", "moving_collider", "floor_contact"])
def test_cuda_graph_windows_follow_the_plain_loop(name):
    """On a CUDA device the windows are captured as CUDA graphs by default. The p2g scatter adds with atomics in
    an order that changes from run to run, so the two loops agree to rounding amplified over a few hundred steps,
    not to the bit: 1e-9 of the largest value (float64), and the CPU's trajectory to the same bound."""
    import warp as wp

    if wp.get_cuda_device_count() == 0:
        pytest.skip("no CUDA device")
    extra = SCENES[name]
    keys = {} if extra.get("simulation", {}).get("dt") else {"dt": 3e-6}  # a fixed dt: the same steps everywhere
    plain, captured = (_run(extra, mode, device="cuda:0", **keys) for mode in ("plain", "captured"))
    cpu = _run(extra, "direct", **keys)
    assert captured.solver.capture_refusal() is None
    assert captured.solver.graph_windows == captured.windows > 0 and captured.solver.graph_captures > 0
    assert captured.solver.graph_replays >= captured.windows
    assert plain.steps == captured.steps == cpu.steps
    assert _max_rel(_state(plain), _state(captured)) <= 1e-9
    assert _max_rel(_state(cpu), _state(captured)) <= 1e-9
