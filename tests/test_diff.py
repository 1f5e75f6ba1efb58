"""Differentiable simulation (magsoro.diff): gradients vs central finite differences for every variable kind,
checkpointing, targets, a short optimisation and the `magsoro optimize` command."""

import json
import tomllib

import numpy as np
import pytest

from magsoro.diff.optimize import Problem, optimise

BASE = """
[simulation]
dim = 2
dx = 2.5e-4
particles_per_cell = 2
domain_lo = [-0.01, -0.01]
domain_hi = [0.02, 0.01]
duration = 6.0e-4
dt = 4.0e-6
damping = 100.0
depth = 1e-3
precision = "float64"

[[bodies]]
name = "left"
shape = { type = "rectangle", center = [0.00125, 0.0], size = [0.0025, 0.001] }
material = { density = 1500.0, shear_modulus = 50.0e3 }
magnetization = [0.1, 0.0, 0.0]

[[bodies]]
name = "right"
shape = { type = "rectangle", center = [0.00375, 0.0], size = [0.0025, 0.001] }
material = { density = 1500.0, shear_modulus = 40.0e3 }
magnetization = [0.08, 0.03, 0.0]

[[clamps]]
region = { type = "rectangle", center = [0.00025, 0.0], size = [0.0005, 0.002] }

[contact]
bonded = "touching"  # the two halves are one strip

[[probes]]
type = "tip"
name = "tip"
body = "right"
region = { type = "rectangle", center = [0.0049, 0.0], size = [0.0002, 0.001] }
"""

FIELDS = {
    "uniform": '[[fields]]\ntype = "uniform"\nB = [0.004, 0.02, 0.0]\nprofile = { type = "ramp", duration = 3.0e-4 }\n',
    "keyframes": '[[fields]]\ntype = "keyframes"\ntimes = [0.0, 3.0e-4, 6.0e-4]\nvalues = [[0.0, 0.0, 0.0], [0.003, 0.02, 0.0], [-0.004, 0.015, 0.0]]\n',
    "dipole": '[[fields]]\ntype = "dipole"\nposition = [0.004, 0.005, 0.0]\nmoment = [0.002, 0.01, 0.0]\n',
}

TIP = {"type": "tip", "probe": "tip", "position": [0.005, 0.0005]}
FOLD = {"type": "fold_angle", "bodies": ["left", "right"], "axis": [1.0, 0.0], "angle": 10.0}


def scene_file(tmp_path, fields=("uniform",)):
    path = tmp_path / "small.toml"
    path.write_text(BASE + "".join(FIELDS[f] for f in fields))
    return path


def fd_check(prob, components, rel_step=1e-6):
    """Relative errors |AD - FD| / |FD| of dL/dvalue for the given flat components."""
    x0 = prob.design.values()
    scale = prob.design.scales()
    _, g = prob.loss_and_grad(x0)
    errs = []
    for i in components:
        h = rel_step * scale[i]
        xp, xm = x0.copy(), x0.copy()
        xp[i] += h
        xm[i] -= h
        fd = (prob.loss_and_grad(xp, grad=False)[0] - prob.loss_and_grad(xm, grad=False)[0]) / (2 * h)
        assert abs(fd) > 0, f"finite difference of component {i} is zero: the check would be void"
        errs.append(abs(g[i] - fd) / abs(fd))
    prob.design.apply(x0)
    return np.array(errs)


@pytest.mark.parametrize(
    "kinds, fields, target, components",
    [
        (["magnetisation"], ("uniform",), TIP, [0, 1, 3, 4]),
        (["magnetisation_particles"], ("uniform",), TIP, [3 * 300, 3 * 300 + 1, 3 * 150 + 1]),
        (["field"], ("uniform",), TIP, [0, 1]),
        (["keyframes"], ("keyframes",), TIP, [3, 4, 6, 7]),
        (["epm"], ("dipole",), TIP, [0, 1, 3, 4]),
        (["material"], ("uniform",), TIP, [0, 1]),
        (["magnetisation"], ("uniform",), FOLD, [0, 1, 3, 4]),
    ],
    ids=["magnetisation", "magnetisation_particles", "field", "keyframes", "epm", "material", "fold_angle"],
)
def test_gradient_matches_central_differences(tmp_path, kinds, fields, target, components):
    prob = Problem(scene_file(tmp_path, fields), target, kinds)
    if kinds == ["magnetisation_particles"]:
        assert len(prob.design.values()) > 3 * 300
    errs = fd_check(prob, components)
    assert np.all(errs < 0.02), errs


def test_centreline_target_gradient(tmp_path):
    spec = {"type": "centreline", "bodies": ["left", "right"], "points": [[0.001 * i, 0.0002 * i] for i in range(5)]}
    prob = Problem(scene_file(tmp_path), spec, ["magnetisation", "field"])
    assert np.all(fd_check(prob, [1, 4, 6, 7]) < 0.02)


def test_checkpointed_gradients_equal_single_segment(tmp_path):
    path = scene_file(tmp_path, ("uniform", "dipole"))
    kinds = ["magnetisation", "field", "epm", "material"]
    a = Problem(path, TIP, kinds)
    b = Problem(path, TIP, kinds, segment=17)  # 150 steps: 9 segments, the last one short
    assert b.rollout.n_segments == 9 and a.rollout.n_segments == 1
    La, ga = a.loss_and_grad(a.design.values())
    Lb, gb = b.loss_and_grad(b.design.values())
    assert La == Lb
    np.testing.assert_allclose(gb, ga, rtol=1e-10, atol=1e-14 * np.max(np.abs(ga)))


def test_rollout_matches_engine(tmp_path):
    """The differentiable rollout reproduces the engine's trajectory (same kernels, same dt) in the updated form,
    the one its kernels run (the scene's 'auto' runs the engine in the total form)."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    path = scene_file(tmp_path, ("uniform", "dipole"))
    prob = Problem(path, TIP, ["magnetisation"])
    x = prob.final_state()["x"]
    scene = load_scene(path)
    scene.simulation.formulation = "updated"
    sim = Simulation(scene, device="cpu")
    for _ in range(prob.n_steps):
        sim.step(prob.dt)
    xe = sim.state.x.numpy()
    assert np.max(np.abs(x - xe)) < 1e-12 * np.max(np.abs(xe)) + 1e-15
    assert np.max(np.abs(x - prob.built.model.host["positions"])) > 1e-7  # it moved


def test_grid_block_exit_is_reported(tmp_path):
    from magsoro.diff import DiffError

    prob = Problem(scene_file(tmp_path), TIP, ["field"], margin=0.0)
    with pytest.raises(DiffError, match="fixed grid block"):
        prob.loss_and_grad(prob.design.values() * 200.0)


def reachable_tip(path, kinds, shift):
    """Tip target taken from a forward run with the design shifted by ``shift`` (so an exact optimum exists)."""
    prob = Problem(path, TIP, kinds, duration=4.0e-4)
    x = prob.final_state(prob.design.values() + shift)["x"]
    return Problem(path, {"type": "tip", "probe": "tip", "position": prob.target.point(x).tolist()}, kinds, duration=4.0e-4)


def test_short_optimisation_lowers_loss(tmp_path):
    path = scene_file(tmp_path)
    prob = reachable_tip(path, ["magnetisation"], np.array([0.0, 0.05, 0.0, 0.0, 0.05, 0.0]))
    res = optimise(prob, method="adam", iterations=10, lr=0.2)
    assert res["loss"] < 0.2 * res["initial_loss"]
    prob = reachable_tip(path, ["field"], np.array([0.002, 0.01, 0.0]))
    res = optimise(prob, method="lbfgs", iterations=5)
    assert res["loss"] < 0.01 * res["initial_loss"]


def test_optimize_command_writes_a_runnable_scene(tmp_path):
    from magsoro.cli import main
    from magsoro.scene import load_scene

    target = tmp_path / "target.toml"
    target.write_text('type = "tip"\nprobe = "tip"\nposition = [0.005, 0.0003]\n')
    out = tmp_path / "out"
    rc = main(["optimize", str(scene_file(tmp_path)), "--target", str(target), "--vars", "magnetisation,field",
               "--out", str(out), "--iterations", "3", "--duration", "3.0e-4"])
    assert rc == 0
    res = json.loads((out / "result.json").read_text())
    assert res["final_loss"] < res["initial_loss"]
    assert res["rerun_max_particle_deviation_m"] < 1e-9
    written = out / "small_optimized.toml"
    scene = load_scene(written)
    data = tomllib.loads(written.read_text())
    assert data["bodies"][1]["magnetization"] == pytest.approx(res["variables"]["right.magnetization[0]"][1:2] + [res["variables"][f"right.magnetization[{j}]"][1] for j in (1, 2)])
    assert scene.fields[0].B == pytest.approx([res["variables"][f"fields[0].B[{j}]"][1] for j in range(3)])
    for name in ("history.csv", "before.png", "after.png"):
        assert (out / name).stat().st_size > 0


def test_bad_inputs_are_refused(tmp_path):
    from magsoro.errors import MagsoroError

    path = scene_file(tmp_path)
    with pytest.raises(MagsoroError, match="unknown variable kind"):
        Problem(path, TIP, ["shape"])
    with pytest.raises(MagsoroError, match="no 'dipole' field"):
        Problem(path, TIP, ["epm"])
    with pytest.raises(MagsoroError, match="target.type"):
        Problem(path, {"type": "curve"}, ["field"])
    with pytest.raises(MagsoroError, match="no probe named"):
        Problem(path, {"type": "tip", "probe": "nope", "position": [0, 0]}, ["field"])


def test_adjoints_are_built_for_the_rollouts_kernels_only():
    """Warp generates and compiles a kernel's adjoint unless told not to. The engine asks for it only in the
    variant the differentiable rollout takes (make_kernels(..., differentiable=True)), and there only on the five
    kernels it launches under wp.Tape; the kernels a simulation runs have none. Those adjoints cost a cold start
    most of its compile time (benchmarks/results/*-compile-time.json) and were never called. A kernel the rollout
    launches without its adjoint would fail test_gradient_matches_central_differences; this pins the lists."""
    import warp as wp

    from magsoro.mpm.kernels import make_kernels

    rollout = {"p2g", "grid_update", "g2p", "remap_node_velocity", "remap_F"}
    for dim in (2, 3):
        for contact in (False, True):
            for differentiable in (False, True):
                k = make_kernels(dim, wp.float64, contact=contact, differentiable=differentiable)
                with_adjoint = {n for n, v in k.items() if isinstance(v, wp.Kernel) and v.options.get("enable_backward", True)}
                assert with_adjoint == (rollout if differentiable else set()), (dim, contact, differentiable)
