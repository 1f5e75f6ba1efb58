"""Robot parts, magnetisation profiles (expression, rotating, table, file, Python callable), overlap rules, and the
published robots' scenes (load, fill, a few steps)."""

import copy
from pathlib import Path

import numpy as np
import pytest

from magsoro.errors import SceneError
from magsoro.geometry.magnetization import ExpressionError, compile_expression
from magsoro.scene import load_scene, parse_scene
from magsoro.scene.build import fill_bodies
from magsoro.simulation import Simulation
from tests.test_scene_cli import BASE, _toml

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _with_mag(mag, material=None):
    d = copy.deepcopy(BASE)
    d["bodies"][0]["magnetization"] = mag
    if material is not None:
        d["bodies"][0]["material"] = material
    return d


def test_expression_profile_equals_function_at_particles():
    expr = {"type": "expression", "x": "0.1 * cos(2 * pi * x / 0.01)", "y": "0.05 * sin(2 * pi * x / 0.01) * (y > 0.005)", "z": "-0.02 + 3 * y**2"}
    p = fill_bodies(parse_scene(_with_mag(expr)))
    X, Br = p.positions, p.remanence
    expected = np.stack([0.1 * np.cos(2 * np.pi * X[:, 0] / 0.01), 0.05 * np.sin(2 * np.pi * X[:, 0] / 0.01) * (X[:, 1] > 0.005), -0.02 + 3 * X[:, 1] ** 2], axis=1)
    np.testing.assert_allclose(Br, expected, rtol=0, atol=1e-15)
    assert np.ptp(Br[:, 1]) > 0  # the comparison selects part of the body


def test_python_callable_magnetization_reaches_the_model():
    def fn(X):
        return np.stack([0.2 * np.sin(300 * X[:, 0]), 0.1 * X[:, 1] / 0.01, np.full(len(X), 0.03)], axis=1)

    scene = parse_scene(copy.deepcopy(BASE)).set_magnetization(fn, body="beam")
    sim = Simulation(scene)
    X = sim.model.host["positions"]
    X3 = np.c_[X, np.zeros(len(X))]
    np.testing.assert_allclose(sim.model.host["remanence"], fn(X3), rtol=0, atol=1e-15)
    with pytest.raises(SceneError, match="no body named 'arm'"):
        parse_scene(copy.deepcopy(BASE)).set_magnetization(fn, body="arm")
    bad = parse_scene(copy.deepcopy(BASE)).set_magnetization(lambda X: np.full((len(X), 3), np.nan))
    with pytest.raises(SceneError, match="not finite"):
        fill_bodies(bad)


@pytest.mark.parametrize("text", ["__import__('os').system('true')", "x.real", "(lambda: 1)()", "open('f')", "[1, 2]", "x if y else z", "'a' * 3", "q + 1"])
def test_unsafe_expressions_are_refused(text):
    with pytest.raises(ExpressionError):
        compile_expression(text)
    with pytest.raises(SceneError, match=r"bodies\[0\]\.magnetization"):
        fill_bodies(parse_scene(_with_mag({"type": "expression", "x": text})))


def test_rotating_and_table_profiles_use_library_remanence():
    lib = "ecoflex-00-30-ndfeb100"
    rot = {"type": "rotating", "axis": [1, 0, 0], "origin": [0.003, 0, 0], "period": 0.01, "u": [1, 0, 0], "v": [0, 1, 0], "phase": 90.0}
    p = fill_bodies(parse_scene(_with_mag(rot, lib)))
    from magsoro.materials import get_material

    Br0 = get_material(lib).remanence
    t = 2 * np.pi * (p.positions[:, 0] - 0.003) / 0.01 + np.pi / 2
    np.testing.assert_allclose(p.remanence, Br0 * np.stack([np.cos(t), np.sin(t), 0 * t], axis=1), atol=1e-15)
    table = {"type": "table", "axis": [1, 0, 0], "origin": [0.003, 0, 0], "positions": [0.0, 0.005], "vectors": [[0, 1, 0], [0, -2, 0]], "magnitude": 0.05}
    p = fill_bodies(parse_scene(_with_mag(table)))
    first = p.positions[:, 0] < 0.008
    assert np.allclose(p.remanence[first], [0, 0.05, 0]) and np.allclose(p.remanence[~first], [0, -0.05, 0])
    with pytest.raises(SceneError, match=r"magnetization\.magnitude: required"):
        fill_bodies(parse_scene(_with_mag({"type": "uniform", "direction": [1, 0, 0]})))


def test_array_file_profile(tmp_path):
    pts = np.array([[0.005, 0.005, 0.0, 0.1, 0.0, 0.0], [0.011, 0.005, 0.0, 0.0, 0.2, 0.0]])
    np.savetxt(tmp_path / "m.csv", pts, delimiter=",", header="x,y,z,Brx,Bry,Brz", comments="")
    p = fill_bodies(parse_scene(_with_mag({"type": "file", "file": "m.csv"}), base_dir=tmp_path))
    left = p.positions[:, 0] < 0.008
    assert np.allclose(p.remanence[left], [0.1, 0, 0]) and np.allclose(p.remanence[~left], [0, 0.2, 0])


def _two_bodies(shift, **extra):
    d = copy.deepcopy(BASE)
    second = copy.deepcopy(d["bodies"][0])
    second["name"] = "patch"
    second["shape"] = {"type": "rectangle", "center": [0.008 + shift, 0.005], "size": [0.002, 0.002]}
    second["magnetization"] = [0.0, 0.3, 0.0]
    second.update(extra)
    d["bodies"].append(second)
    return d


def test_overlap_needs_a_rule_and_priority_wins():
    with pytest.raises(SceneError, match=r"bodies\[1\]\.priority: bodies 'beam' and 'patch' overlap \(\d+ particles\)"):
        fill_bodies(parse_scene(_two_bodies(0.0)))
    alone = fill_bodies(parse_scene(copy.deepcopy(BASE)))
    p = fill_bodies(parse_scene(_two_bodies(0.0, priority=1)))
    # the union keeps one particle per lattice site: as many as the beam alone (the patch lies inside it)
    assert len(p.positions) == len(alone.positions)
    assert len(np.unique(np.round(p.positions / 1e-6), axis=0)) == len(p.positions)
    inside_patch = (np.abs(p.positions[:, 0] - 0.008) < 0.001) & (np.abs(p.positions[:, 1] - 0.005) < 0.001)
    assert np.all(p.body[inside_patch] == 1) and np.allclose(p.remanence[inside_patch], [0, 0.3, 0])
    assert p.report[0]["overlap_removed"] == int(inside_patch.sum())
    fill_bodies(parse_scene(_two_bodies(0.008)))  # side by side: no overlap, no rule needed


@pytest.mark.parametrize(
    "mutate,key,hint",
    [
        (lambda b: b.update(material="ecoflex-99"), "bodies[0].material", "unknown material 'ecoflex-99'"),
        (lambda b: b.update(material={"library": "nope", "shear_modulus": 1e4}), "bodies[0].material.library", "unknown material 'nope'"),
        (lambda b: b.update(magnetization=[0.0, 0.0, 0.0], magnetic=True), "bodies[0].magnetization", "marked magnetic"),
        (lambda b: b.update(material="ecoflex-00-30", magnetization={"type": "uniform", "direction": [1, 0, 0]}, magnetic=True), "bodies[0].magnetization", "marked magnetic"),
        (lambda b: b.update(magnetization={"type": "uniform", "direction": [0, 0, 0]}), "bodies[0].magnetization", "direction must be non-zero"),
        (lambda b: b.update(magnetization={"type": "file", "file": "absent.csv"}), "bodies[0].magnetization.file", "not found"),
    ],
)
def test_broken_parts_give_one_line_errors(tmp_path, capsys, mutate, key, hint):
    from magsoro.cli import main

    d = copy.deepcopy(BASE)
    mutate(d["bodies"][0])
    scene = tmp_path / "scene.toml"
    scene.write_text(_toml(d))
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and key in err and hint in err and str(scene) in err, err
    assert not (tmp_path / "out").exists()


def test_robot_file_expands_into_bodies(tmp_path):
    robot = {
        "name": "two-part",
        "parts": [
            {"name": "body", "shape": {"type": "rectangle", "center": [0.008, 0.005], "size": [0.01, 0.002]}, "material": "my-silicone", "clamped": False},
            {"name": "head", "shape": {"type": "rectangle", "center": [0.0135, 0.005], "size": [0.001, 0.002]}, "material": "ecoflex-00-30-ndfeb150",
             "magnetization": {"type": "uniform", "direction": [0, 1, 0]}, "magnetic": True},
        ],
        "material_library": ["lib.toml"],
    }
    (tmp_path / "lib.toml").write_text('[[materials]]\nname = "my-silicone"\ndensity = 1100.0\nshear_modulus = 2.0e4\nsource = "test"\nmeasured = ["shear_modulus"]\n')
    (tmp_path / "robot.toml").write_text(_toml(robot))
    d = copy.deepcopy(BASE)
    del d["bodies"]
    d["robot"] = "robot.toml"
    d["clamps"][0]["body"] = "body"
    d["probes"][0]["body"] = "head"
    d["probes"][0]["region"]["center"] = [0.0138, 0.005]
    scene = parse_scene(d, source="scene.toml", base_dir=tmp_path)
    assert [b.name for b in scene.bodies] == ["body", "head"]
    sim = Simulation(scene)
    h = sim.model.host
    assert np.allclose(h["shear_modulus"][h["body"] == 0], 2.0e4) and np.allclose(h["density"][h["body"] == 0], 1100.0)
    from magsoro.materials import get_material

    assert np.allclose(h["remanence"][h["body"] == 1], [0, get_material("ecoflex-00-30-ndfeb150").remanence, 0])
    for _ in range(3):
        sim.step()
    assert np.all(np.isfinite(sim.state.x.numpy()))
    # an error inside the robot file names the robot file and its key
    robot["parts"][1]["magnetization"] = {"type": "uniform", "direction": [0, 1, 0], "strength": 1.0}
    (tmp_path / "robot.toml").write_text(_toml(robot))
    with pytest.raises(SceneError, match=r"robot\.toml: parts\[1\]\.magnetization\.strength: unknown key"):
        parse_scene(d, source="scene.toml", base_dir=tmp_path)
    d["robot"] = "absent.toml"
    with pytest.raises(SceneError, match=r"scene\.toml: robot: robot file '.*absent\.toml' not found"):
        parse_scene(d, source="scene.toml", base_dir=tmp_path)


def test_clamped_part_is_held():
    d = copy.deepcopy(BASE)
    d["clamps"] = []
    d["bodies"].append({"name": "holder", "shape": {"type": "rectangle", "center": [0.0025, 0.005], "size": [0.001, 0.002]}, "material": "dragon-skin-10", "clamped": True})
    p = fill_bodies(parse_scene(d))
    assert np.array_equal(p.clamped, p.body == 1) and p.clamped.any()


@pytest.mark.parametrize("name", ["tentacle", "walker", "gripper"])
def test_published_robot_scenes_build_and_step(name):
    scene = load_scene(SCENES / f"{name}.toml")
    sim = Simulation(scene, source=name)
    rep = sim.built.fill_report
    for r in rep:
        assert abs(r["filled_volume"] / r["shape_volume"] - 1) < 0.05, r
    Br = np.linalg.norm(sim.model.host["remanence"], axis=1)
    assert Br.max() > 0.04  # magnetised with the library's composite remanence (T)
    x0 = sim.state.x.numpy().copy()
    for _ in range(4):
        sim.step()
    x = sim.state.x.numpy()
    assert np.all(np.isfinite(x)) and np.abs(x - x0).max() < scene.simulation.dx
