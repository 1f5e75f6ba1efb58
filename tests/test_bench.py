"""``magsoro bench``: the JSON the performance issue names, medians over alternating engine/reference rounds."""

import json
import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import run_solver


def test_bench_json_keys_and_medians():
    out = subprocess.run(
        [sys.executable, "-m", "magsoro", "bench", "beam2d", "--steps", "5", "--threads", "1", "--json"],
        capture_output=True, text=True, timeout=600,
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)  # stdout carries only the JSON object
    assert result["device"] == "cpu" and result["commit"]
    (scene,) = result["scenes"]
    for key in ("name", "n_particles", "ms_per_step", "steps_per_s", "particle_steps_per_s", "reference_particle_steps_per_s", "phases_ms", "threads"):
        assert key in scene
    assert scene["name"] == "beam2d" and scene["threads"] == 1
    assert set(scene["phases_ms"]) == {"p2g", "grid", "g2p", "other"}
    assert len(scene["ms_per_step_rounds"]) == scene["rounds"] == len(scene["reference_ms_per_step_rounds"])
    assert scene["ms_per_step"] == np.median(scene["ms_per_step_rounds"])
    assert abs(scene["steps_per_s"] * scene["ms_per_step"] - 1e3) < 1e-6
    assert abs(scene["particle_steps_per_s"] - scene["n_particles"] * scene["steps_per_s"]) <= 1e-9 * scene["particle_steps_per_s"]
    assert 0 < scene["ratio_to_reference"] < 10
    # the windowed timing of the same steps: one host read per window (5 steps here: one window per round)
    assert len(scene["window_ms_per_step_rounds"]) == scene["rounds"] and scene["window_ms_per_step"] > 0
    assert scene["host_reads_per_step"] == {"checked": 1.0, "window": 1 / 5}


def test_bench_rejects_bad_arguments():
    for args in (["--threads", "0"], ["--steps", "0"], ["no_such_scene"]):
        out = subprocess.run([sys.executable, "-m", "magsoro", "bench", *args], capture_output=True, text=True, timeout=120)
        assert out.returncode != 0
        assert ("threads" in out.stderr) or ("steps" in out.stderr) or ("no_such_scene" in out.stderr)


def test_regional_field_device_matches_host_and_refuses_bad_regions():
    import pytest
    import warp as wp

    from magsoro.fields import Regional, Rotating, Uniform
    from magsoro.fields.device import FieldEvaluator

    r = Regional([([0, 0, 0], [1, 1, 1], Uniform([1e-3, 0, 0])),
                  ([2, 0, 0], [3, 1, 1], Uniform(Rotating(0.008, 5.0, u=(1, 0, 0), v=(0, 0, 1))))])
    pts = np.array([[0.5, 0.5, 0.5], [2.5, 0.5, 0.5], [1.5, 0.5, 0.5], [2.0, 1.0, 0.0], [-0.1, 0.5, 0.5]])
    for t in (0.0, 0.03):
        B, G = FieldEvaluator([r], 3, wp.float64, "cpu").evaluate_host(pts, t)
        assert np.abs(B - r.B(pts, t)).max() < 1e-15
        assert not G.any()
        assert np.allclose(B[1], 0.008 * np.array([np.cos(2 * np.pi * 5 * t), 0, np.sin(2 * np.pi * 5 * t)]))
        assert not B[2].any() and not B[4].any()  # between and outside the boxes
    assert r.max_magnitude(pts) == pytest.approx(0.008)
    with pytest.raises(ValueError, match="overlap"):
        Regional([([0, 0, 0], [1, 1, 1], Uniform([1, 0, 0])), ([0.5, 0, 0], [2, 1, 1], Uniform([0, 1, 0]))])
    with pytest.raises(ValueError, match="Uniform"):
        Regional([([0, 0, 0], [1, 1, 1], [1e-3, 0, 0])])


@pytest.mark.slow
def test_sweep_batch_copies_move_like_the_walker_alone():
    """The batched sweep scene is 8 independent walkers: copy 0 (5 Hz) moves exactly like the walker scene
    (5 Hz) run on its own, and copy 7 (12 Hz) like the walker driven at 12 Hz; the two copies differ."""
    from magsoro.bench.scenes import SWEEP_FREQUENCIES_HZ, build
    from magsoro.fields import Rotating, Uniform
    from magsoro.mpm.model import Control
    from magsoro.mpm.solver import Solver

    def run(model, control, settings, dt, steps=150):
        return run_solver(model, control, settings, dt, steps).x.numpy() - model.host["positions"]

    single = build("walker", precision="float64")
    dt = Solver(single[0], single[2]).stable_dt(single[1])
    batch = build("sweep", precision="float64")
    assert Solver(batch[0], batch[2]).stable_dt(batch[1]) == dt  # same peak field, same step
    n = single[0].n_particles
    u_batch = run(*batch, dt)
    u_single = {0: run(*single, dt)}
    m, control, settings = build("walker", precision="float64")
    control = Control([Uniform(Rotating(0.008, SWEEP_FREQUENCIES_HZ[7], u=(1, 0, 0), v=(0, 0, 1)))], control.colliders)
    u_single[7] = run(m, control, settings, dt)
    scale = np.abs(u_single[7]).max()
    assert scale > 0
    for k in (0, 7):
        assert np.abs(u_batch[k * n:(k + 1) * n] - u_single[k]).max() < 1e-6 * scale
    assert np.abs(u_single[7] - u_single[0]).max() > 1e-2 * scale
