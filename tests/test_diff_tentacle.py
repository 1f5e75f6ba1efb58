"""The shape-forming example of the differentiable-simulation issue, end to end (slow: about 2 minutes).

Acceptance: the optimised magnetisation lowers the shape error at least 5x from the naive design, and the forward
re-run of the written scene (plain engine) reproduces the optimised shape.
"""

import importlib.util
import json
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "differentiable" / "tentacle_shape.py"


@pytest.mark.slow
def test_tentacle_shape_forming(tmp_path):
    spec = importlib.util.spec_from_file_location("tentacle_shape", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    from magsoro.cli import main

    target = mod.make_target(tmp_path)
    rc = main(["optimize", str(mod.SCENE), "--target", str(target), "--vars", "magnetisation", "--bodies", ",".join(mod.SEGMENTS),
               "--method", "lbfgs", "--iterations", "60", "--out", str(tmp_path)])
    assert rc == 0
    result = json.loads((tmp_path / "result.json").read_text())
    # shape error: RMS distance of the centreline points (m)
    assert result["final_error"] < result["initial_error"] / 5
    # the written scene, run by the plain engine, lands on the optimised shape
    assert result["rerun_error"] == pytest.approx(result["final_error"], rel=1e-6, abs=1e-9)
    assert result["rerun_max_particle_deviation_m"] < 1e-9
    assert Path(result["scene_out"]).is_file()
