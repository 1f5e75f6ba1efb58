"""Bad input gets one line naming the file and the key (issue "Reliability"). Findings 6 and 7: inf used to crash
the build and NaN in vectors was silently wrong (a floor normal [nan, 1, 0] let the body fall through and the run
said "completed"); the others are named at each test. Output folders and output errors: tests/test_outputs.py;
mutations of every scene file: tests/test_scene_mutations.py; SIGTERM: tests/test_signals.py."""

import copy
import math
from pathlib import Path

import numpy as np
import pytest

from magsoro.errors import SceneError
from magsoro.scene import parse_scene

BASE = {
    "simulation": {"dim": 2, "dx": 1e-3, "domain_lo": [0.0, 0.0], "domain_hi": [0.02, 0.02], "duration": 0.01},
    "bodies": [{"name": "b", "shape": {"type": "rectangle", "center": [0.01, 0.01], "size": [0.004, 0.002]},
                "material": {"density": 1000.0, "shear_modulus": 1e5}, "magnetization": [0.1, 0.0, 0.0]}],
    "colliders": [{"type": "half_space", "point": [0.0, 0.005], "normal": [0.0, 1.0]}],
    "fields": [{"type": "uniform", "B": [0.0, 0.01, 0.0]}],
}


def _base_with(path: tuple, value) -> dict:
    """A copy of BASE with the entry at ``path`` (keys and list indices) set to ``value``."""
    scene = copy.deepcopy(BASE)
    target = scene
    for p in path[:-1]:
        target = target[p]
    target[path[-1]] = value
    return scene


@pytest.mark.parametrize("path, value, key", [
    (("bodies", 0, "material", "density"), math.inf, "bodies[0].material.density"),
    (("bodies", 0, "material", "shear_modulus"), math.nan, "bodies[0].material.shear_modulus"),
    (("bodies", 0, "shape", "center"), [math.inf, 0.01], "bodies[0].shape.center[0]"),
    (("bodies", 0, "magnetization"), [0.1, math.nan, 0.0], "bodies[0].magnetization"),
    (("colliders", 0, "normal"), [math.nan, 1.0], "colliders[0].normal[0]"),
    (("simulation", "domain_hi"), [math.nan, 0.02], "simulation.domain_hi[0]"),
    (("simulation", "duration"), math.inf, "simulation.duration"),
    (("fields", 0, "B"), [0.0, math.inf, 0.0], "fields[0]"),
])
def test_non_finite_values_are_refused_naming_the_key(path, value, key):
    parse_scene(copy.deepcopy(BASE))  # the base scene is valid
    scene = _base_with(path, value)
    with pytest.raises(SceneError) as exc:
        parse_scene(scene)
    msg = str(exc.value)
    assert key in msg and "finite" in msg and "\n" not in msg.strip(), msg


def test_a_body_too_large_for_memory_is_refused_before_filling():
    """A body whose lattice would not fit in memory (a mm-vs-m slip, finding 3: 119 TiB were requested) is refused
    from its bounding box, in well under a second, naming the key, the size and the limit."""
    import time

    scene = copy.deepcopy(BASE)
    scene["simulation"].update(dim=3, dx=1e-4, domain_lo=[0.0, 0.0, 0.0], domain_hi=[2.0, 2.0, 2.0])
    scene["bodies"][0]["shape"] = {"type": "box", "center": [1.0, 1.0, 1.0], "size": [1.0, 1.0, 1.0]}
    scene["bodies"][0]["magnetization"] = [0.1, 0.0, 0.0]
    scene["colliders"][0] = {"type": "half_space", "point": [0.0, 0.0, 0.4], "normal": [0.0, 0.0, 1.0]}
    from magsoro.simulation import Simulation

    t0 = time.perf_counter()
    with pytest.raises(SceneError, match=r"bodies\[0\]\.shape: body 'b' .* lattice sites .* at most 1e\+08"):
        Simulation(parse_scene(scene))
    assert time.perf_counter() - t0 < 5.0


def test_a_body_outside_the_domain_is_refused_before_filling():
    scene = copy.deepcopy(BASE)
    scene["bodies"][0]["shape"] = {"type": "rectangle", "center": [10.0, 10.0], "size": [4.0, 2.0]}  # metres, not mm
    from magsoro.simulation import Simulation

    with pytest.raises(SceneError, match=r"bodies\[0\]\.shape: body 'b' spans .* outside the domain .*scale = 1e-3"):
        Simulation(parse_scene(scene))


def test_unbounded_output_is_refused_naming_the_key():
    """output.every = 1e-12 used to eat gigabytes building output times (finding 5)."""
    scene = copy.deepcopy(BASE)
    scene["output"] = {"every": 1e-12}
    with pytest.raises(SceneError, match=r"output\.every = 1e-12 s gives 1e\+10 records .* at least 1e-07 s"):
        parse_scene(scene)


@pytest.mark.parametrize("duration", ["inf", "nan", "-1", "1e300"])
def test_run_duration_override_is_checked_before_the_output_folder(duration, tmp_path):
    """`magsoro run --duration inf` used to overflow and leave run.json 'running' (finding 5); now one line and no
    output folder. 1e300 s with the scene's 0.5 ms output interval would record 2e303 frames."""
    import subprocess
    import sys

    scene_file = tmp_path / "s.toml"
    from magsoro.io.tomlwrite import dumps

    scene = copy.deepcopy(BASE)
    scene["output"] = {"every": 5e-4}
    scene_file.write_text(dumps(scene))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "magsoro", "run", str(scene_file), "--out", str(out), "--quiet",
                        "--duration", duration], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.strip().splitlines() if not ln.startswith("Warp")]  # Warp's no-GPU notice
    assert "Traceback" not in r.stderr and len(lines) == 1, r.stderr
    assert "--duration" in r.stderr or "records" in r.stderr
    assert not out.exists()


@pytest.mark.slow
def test_first_time_step_counts_the_initial_velocity():
    """A body sent at 500 m/s crossed 2.5 cells in its first step (finding 9): the first step's CFL bound now
    includes the initial speed, so it moves at most cfl cells."""
    from magsoro.simulation import Simulation

    scene = copy.deepcopy(BASE)
    scene["bodies"][0]["velocity"] = [500.0, 0.0]
    scene["colliders"] = []
    sim = Simulation(parse_scene(scene))
    x0 = sim.state.x.numpy().copy()
    c = sim._wave_speed
    assert sim.dt == pytest.approx(0.4 * 1e-3 / (c + 500.0), rel=1e-12)
    sim.step()
    moved = float(np.abs(sim.state.x.numpy() - x0).max())
    assert moved <= 0.4 * 1e-3 * (1 + 1e-6)


def test_a_state_that_fails_the_checks_is_not_kept_as_last_good():
    """When a step refuses its input (a state the previous step reached is outside the domain or not finite), the
    simulation goes back to the state before it, which passed the checks: that is what a failed run writes as
    last_good.npz (finding 8). The bad state is made by hand here: after two good steps, a position is set to NaN."""
    from magsoro.errors import SimulationError
    from magsoro.simulation import Simulation

    scene = copy.deepcopy(BASE)
    scene["simulation"]["formulation"] = "updated"  # the form whose step checks the current positions on entry
    sim = Simulation(parse_scene(scene))
    sim.step()
    t_good = sim.time
    sim.step()
    x = sim.state.x.numpy()
    x[0, 0] = np.nan
    sim.state.x.assign(x)
    sim.solver.forget_bounds()  # the next step takes the bounds from the (edited) positions
    with pytest.raises(SimulationError, match="not finite") as exc:
        sim.step()
    assert exc.value.input_rejected
    assert sim.time == t_good and sim.steps == 1
    assert np.all(np.isfinite(sim.state.x.numpy()))


@pytest.mark.parametrize("path, value, key", [
    (("simulation", "damping"), True, "simulation.damping"),
    (("simulation", "dx"), "2e-4", "simulation.dx"),
    (("bodies", 0, "magnetic"), "yes", "bodies[0].magnetic"),
    (("simulation", "particles_per_cell"), 2.0, "simulation.particles_per_cell"),
])
def test_values_of_the_wrong_type_are_not_coerced(path, value, key):
    """`damping = true` became 1.0, `dx = "2e-4"` became 2e-4, `magnetic = "yes"` became true (finding 12)."""
    scene = _base_with(path, value)
    with pytest.raises(SceneError, match=key.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        parse_scene(scene)


@pytest.mark.parametrize("path, value, message", [
    (("colliders", 0, "normal"), [0.0, 0.0], r"colliders\[0\]\.normal: must be a direction of non-zero length"),
    (("bodies", 0, "shape", "size"), [0.004, -0.002], r"bodies\[0\]\.shape\.size: every edge length must be > 0"),
])
def test_degenerate_vectors_are_refused(path, value, message):
    """A zero normal or a negative size (finding 7: a box collider with negative size was accepted)."""
    scene = _base_with(path, value)
    with pytest.raises(SceneError, match=message):
        parse_scene(scene)


def test_box_collider_size_and_cylinder_axis_are_checked():
    """Finding 6: a cylinder axis of the wrong length gave a reshape error; finding 7: negative box size."""
    scene = copy.deepcopy(BASE)
    scene["simulation"].update(dim=3, domain_lo=[0.0, 0.0, 0.0], domain_hi=[0.02, 0.02, 0.02])
    scene["bodies"][0]["shape"] = {"type": "cylinder", "center": [0.01, 0.01, 0.01], "radius": 0.002, "length": 0.004,
                                   "axis": [0.0, 1.0]}
    scene["colliders"] = [{"type": "box", "center": [0.01, 0.01, 0.002], "size": [0.01, -0.01, 0.002]}]
    with pytest.raises(SceneError, match=r"bodies\[0\]\.shape\.axis: List should have at least 3 items"):
        parse_scene(copy.deepcopy(scene))
    scene["bodies"][0]["shape"]["axis"] = [0.0, 1.0, 0.0]
    with pytest.raises(SceneError, match=r"colliders\[0\]\.size: every edge length must be > 0"):
        parse_scene(scene)


def test_a_mistake_in_a_robot_part_is_reported_at_its_key():
    """Any mistake inside [[robot.parts]] was reported as `robot.str: Input should be a valid string` (finding 4)."""
    part = copy.deepcopy(BASE["bodies"][0])
    part["material"]["density"] = -1.0
    scene = copy.deepcopy(BASE)
    scene["bodies"] = []
    scene["robot"] = {"parts": [part]}
    with pytest.raises(SceneError, match=r"scene: robot\.parts\[0\]\.material\.density: .*greater than 0"):
        parse_scene(scene)
    part["material"]["density"] = 1000.0
    part["shap"] = part.pop("shape")
    with pytest.raises(SceneError, match=r"robot\.parts\[0\]\.shap: unknown key 'shap' \(did you mean 'shape'\?\); allowed keys here: .*shape"):
        parse_scene(scene)


ROD = Path(__file__).resolve().parents[1] / "scenes" / "rod_cantilever.toml"
TENSILE = Path(__file__).resolve().parents[1] / "examples" / "characterization" / "tensile_yeoh.csv"
TENTACLE = Path(__file__).resolve().parents[1] / "examples" / "differentiable" / "tentacle_2d.toml"


def _encodings(text: str) -> dict[str, bytes]:
    """The same text as UTF-16, with a Latin-1 byte in a comment, and as a binary file."""
    return {"utf16": text.encode("utf-16"), "latin1": b"# r\xe9sum\xe9\n" + text.encode(),
            "binary": b"\x00\x01\x02\xff" * 64}


@pytest.mark.parametrize("kind", ["utf16", "latin1", "binary"])
def test_files_that_are_not_utf8_are_one_line_naming_the_file(kind, tmp_path, capsys):
    """UTF-16, a Latin-1 byte in a comment or a binary file gave UnicodeDecodeError in run, rod, optimize and
    fit-material (finding 10)."""
    from magsoro.cli import main
    from magsoro.io.tomlwrite import dumps

    cases = {
        "run": (dumps(BASE), lambda f: ["run", str(f), "--out", str(tmp_path / "o"), "--quiet"]),
        "rod": (ROD.read_text(), lambda f: ["rod", str(f), "--out", str(tmp_path / "r")]),
        "optimize": (TENTACLE.read_text(), lambda f: ["optimize", str(f), "--target", str(f), "--vars", "magnetization",
                                                     "--out", str(tmp_path / "p")]),
        "fit-material": (TENSILE.read_text(), lambda f: ["fit-material", str(f)]),
    }
    for command, (text, argv) in cases.items():
        bad = tmp_path / f"{command}_{kind}{'.csv' if command == 'fit-material' else '.toml'}"
        bad.write_bytes(_encodings(text)[kind])
        assert main(argv(bad)) == 2, command
        err = capsys.readouterr().err
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        assert len(lines) == 1 and "Traceback" not in err, err
        assert str(bad) in lines[0] and ("UTF-8" in lines[0] or "binary" in lines[0]), lines[0]


def test_deeply_nested_arrays_are_one_line(tmp_path):
    """2000 nested arrays gave RecursionError (finding 10)."""
    from magsoro.scene import load_scene

    f = tmp_path / "deep.toml"
    f.write_text("deep = " + "[" * 2000 + "]" * 2000 + "\n")
    with pytest.raises(SceneError, match=r"deep\.toml: .*nested too deeply"):
        load_scene(f)
    scene = copy.deepcopy(BASE)
    scene["bodies"][0]["shape"]["center"] = [[[[[[[[[[[[[[[[[[[0.0]]]]]]]]]]]]]]]]]]]
    with pytest.raises(SceneError, match=r"scene: bodies: tables or arrays nested more than 16 deep"):
        parse_scene(scene)


def test_report_on_a_corrupt_frame_is_one_line(tmp_path, capsys):
    """`magsoro report` on a run with a cut-short particle frame gave an XML ParseError (finding 10)."""
    from magsoro.cli import main
    from magsoro.io.tomlwrite import dumps

    scene = copy.deepcopy(BASE)
    scene["simulation"]["duration"] = 0.002
    scene["output"] = {"every": 0.001}
    f = tmp_path / "s.toml"
    f.write_text(dumps(scene))
    out = tmp_path / "out"
    assert main(["run", str(f), "--out", str(out), "--quiet"]) == 0
    frame = out / "frames" / "frame_00001.vtp"
    frame.write_bytes(frame.read_bytes()[:300])
    capsys.readouterr()
    assert main(["report", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert "frame_00001.vtp: not a readable particle frame" in err


def test_probe_names_and_other_names_are_column_safe():
    """A comma in a probe name corrupted the metrics.csv header (finding 13)."""
    scene = copy.deepcopy(BASE)
    scene["probes"] = [{"type": "centroid", "name": "tip,x", "body": "b"}]
    with pytest.raises(SceneError, match=r"probes\[0\]\.name: a name of letters, digits, '_' and '-'.*\(got 'tip,x'\)"):
        parse_scene(scene)


def test_a_shape_without_type_lists_the_allowed_types():
    """A shape without `type` listed "allowed:" and nothing (finding 13)."""
    scene = copy.deepcopy(BASE)
    del scene["bodies"][0]["shape"]["type"]
    with pytest.raises(SceneError, match=r"bodies\[0\]\.shape: needs a 'type' key; allowed types: box, .*rectangle"):
        parse_scene(scene)


def test_a_garbage_mesh_says_what_is_wrong(tmp_path):
    """A garbage mesh reported "No module named 'charset_normalizer'" (finding 13)."""
    from magsoro.geometry.mesh import MeshError, load_mesh

    f = tmp_path / "junk.stl"
    f.write_bytes(bytes(range(256)) * 12)
    with pytest.raises(MeshError) as exc:
        load_mesh(f)
    assert "junk.stl" in str(exc.value) and "module" not in str(exc.value), exc.value


@pytest.mark.parametrize("flag, value", [("--duration", "-1"), ("--duration", "inf"), ("--dt", "0"), ("--lr", "nan")])
def test_optimize_options_are_checked_by_name(flag, value, tmp_path, capsys):
    """`optimize --duration -1` said "dt must be > 0" (finding 13)."""
    from magsoro.cli import main

    argv = ["optimize", str(TENTACLE), "--target", str(TENTACLE), "--vars", "magnetization", "--out", str(tmp_path),
            flag, value]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"magsoro optimize: error: {flag}: must be a finite number") and "\n" not in err, err


def test_a_particle_moving_more_than_a_cell_in_a_step_is_an_error():
    """With a fixed time step too large for the motion (500 m/s, 2.5 cells per step), the step is refused rather
    than smeared over the grid, and the state kept is the one before it (issue "Reliability": "a particle that
    moves more than a cell in a step is an error, not a silent smear")."""
    from magsoro.errors import SimulationError
    from magsoro.simulation import Simulation

    scene = copy.deepcopy(BASE)
    scene["bodies"][0]["velocity"] = [500.0, 0.0]
    scene["colliders"] = []
    scene["simulation"]["dt"] = 2.5 * 1e-3 / 500.0
    sim = Simulation(parse_scene(scene))
    x0 = sim.state.x.numpy().copy()
    with pytest.raises(SimulationError, match=r"a particle moved 2\.5 cells in one step \(speed 500 m/s"):
        sim.step()
    assert sim.steps == 0 and np.array_equal(sim.state.x.numpy(), x0)
