"""``magsoro bench``: the JSON the performance issue names, medians over alternating engine/reference rounds."""

import json
import subprocess
import sys

import numpy as np


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


def test_bench_rejects_bad_arguments():
    for args in (["--threads", "0"], ["--steps", "0"], ["no_such_scene"]):
        out = subprocess.run([sys.executable, "-m", "magsoro", "bench", *args], capture_output=True, text=True, timeout=120)
        assert out.returncode != 0
        assert ("threads" in out.stderr) or ("steps" in out.stderr) or ("no_such_scene" in out.stderr)
