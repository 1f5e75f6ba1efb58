"""Gradients of a static target by the adjoint of the converged Newton system (issue "Quasi-static solver"):
:mod:`magsoro.diff.static_adjoint` and ``magsoro optimize --static``."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "cantilever_2d.toml"


def test_adjoint_gradient_matches_central_differences():
    """The tip target's gradient with respect to the beam's magnetisation (T) and shear modulus (Pa) on
    scenes/cantilever_2d.toml (static, 5.9 mT): within 2 % of central differences of whole static solves
    (measured 9e-7, 8e-6 and 8e-6 relative; the adjoint is one linear solve, each difference two solves)."""
    from magsoro.diff.static_adjoint import StaticProblem

    spec = {"type": "tip", "probe": "tip", "position": [0.012, 0.012]}
    prob = StaticProblem(SCENE, spec, ["magnetisation", "material"])
    x0 = prob.design.values()
    assert prob.design.names() == ["beam.magnetization[0]", "beam.magnetization[1]", "beam.magnetization[2]",
                                   "beam.material.shear_modulus[0]"]
    _, g = prob.loss_and_grad(x0)
    assert g[2] == 0.0  # an out-of-plane remanence exerts no in-plane couple
    for k in (0, 1, 3):
        h = 1e-3 * prob.design.scales()[k]
        xp, xm = x0.copy(), x0.copy()
        xp[k] += h
        xm[k] -= h
        fd = (prob.loss_and_grad(xp, grad=False)[0] - prob.loss_and_grad(xm, grad=False)[0]) / (2 * h)
        assert g[k] == pytest.approx(fd, rel=0.02)


@pytest.mark.slow
def test_optimize_static_cli(tmp_path):
    """`magsoro optimize --static`: the tip moves towards a target reached by the magnetisation turned 15 degrees
    (the error falls by more than half in 6 Adam steps), the design is written back and a fresh static solve of
    the written scene reproduces the optimised error; refused variables and flags give one line."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    scene = load_scene(SCENE)
    scene.simulation.precision = "float64"
    turn = np.radians(15.0)
    sim = Simulation(scene)
    rot = np.array([[np.cos(turn), -np.sin(turn), 0], [np.sin(turn), np.cos(turn), 0], [0, 0, 1]])
    sim.model.host["remanence"][:] = sim.model.host["remanence"] @ rot.T
    sim.model.Br.assign(sim.model.host["remanence"])
    assert sim.solve_static(levels=[1.0]).converged
    goal = [sim.probe_values()["tip_x"], sim.probe_values()["tip_y"]]
    target = tmp_path / "target.toml"
    target.write_text(f'type = "tip"\nprobe = "tip"\nposition = [{goal[0]!r}, {goal[1]!r}]\n')
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "magsoro", "optimize", str(SCENE), "--static", "--target", str(target),
                          "--vars", "magnetisation", "--out", str(out), "--iterations", "6", "--lr", "0.1"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    res = json.loads((out / "result.json").read_text())
    assert res["static"] and res["final_error"] < 0.5 * res["initial_error"]
    assert res["rerun_error"] == pytest.approx(res["final_error"], rel=1e-6, abs=1e-9)
    assert (out / "cantilever_2d_optimized.toml").is_file()
    bad = subprocess.run([sys.executable, "-m", "magsoro", "optimize", str(SCENE), "--static", "--target", str(target),
                          "--vars", "field", "--out", str(tmp_path / "o2")], capture_output=True, text=True)
    ours = [ln for ln in bad.stderr.strip().splitlines() if not ln.startswith("Warp")]
    assert bad.returncode != 0 and len(ours) == 1 and "static design" in ours[0]
