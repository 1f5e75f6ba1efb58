"""Scene validation messages and the `magsoro run` command end to end."""

import copy
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from magsoro.cli import main
from magsoro.io.vtk import read_vtp

BASE = {
    "name": "tiny",
    "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.02, 0.01], "duration": 2e-3, "damping": 100.0},
    "bodies": [
        {
            "name": "beam",
            "shape": {"type": "rectangle", "center": [0.008, 0.005], "size": [0.01, 0.002]},
            "material": {"density": 1000.0, "shear_modulus": 5e4},
            "magnetization": [0.1, 0.0, 0.0],
        }
    ],
    "clamps": [{"region": {"type": "rectangle", "center": [0.0035, 0.005], "size": [0.001, 0.004]}}],
    "fields": [{"type": "uniform", "B": [0.0, 0.01, 0.0]}],
    "probes": [{"type": "tip", "name": "tip", "body": "beam", "region": {"type": "rectangle", "center": [0.0128, 0.005], "size": [0.0004, 0.004]}}],
    "output": {"every": 1e-3},
}


def _toml(d) -> str:
    """Minimal TOML writer for the test scenes (tables, arrays, inline tables)."""

    def val(v):
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        return repr(v)

    lines = [f"{k} = {val(v)}" for k, v in d.items() if not isinstance(v, (dict, list)) or (isinstance(v, list) and v and not isinstance(v[0], dict))]
    for k, v in d.items():
        if isinstance(v, dict):
            lines.append(f"[{k}]")
            lines += [f"{kk} = {val(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines.append(f"[[{k}]]")
                lines += [f"{kk} = {val(vv)}" for kk, vv in item.items()]
    return "\n".join(lines) + "\n"


def _write(tmp_path, d, name="scene.toml"):
    p = tmp_path / name
    p.write_text(_toml(d))
    return p


def test_toml_writer_roundtrip(tmp_path):
    assert tomllib.loads(_toml(BASE)) == BASE


def _mutate(path_fn):
    d = copy.deepcopy(BASE)
    path_fn(d)
    return d


BAD = [
    ("typo_top_level", lambda d: d.update(simulaton=d["simulation"]), "simulaton", "allowed keys"),
    ("typo_nested", lambda d: d["simulation"].update(dampign=1.0), "simulation.dampign", "allowed keys"),
    ("negative_modulus", lambda d: d["bodies"][0]["material"].update(shear_modulus=-5.0), "bodies[0].material.shear_modulus", "greater than 0"),
    ("wrong_type", lambda d: d["simulation"].update(dx="fine"), "simulation.dx", "number"),
    ("unknown_shape", lambda d: d["bodies"][0]["shape"].update(type="blob"), "bodies[0].shape", "allowed"),
    ("3d_shape_in_2d", lambda d: d["bodies"][0].update(shape={"type": "sphere", "center": [0.01, 0.005, 0.0], "radius": 0.001}), "bodies[0].shape.type", "rectangle"),
    ("body_outside_domain", lambda d: d["bodies"][0]["shape"].update(center=[0.019, 0.005]), "bodies[0].shape", "outside the domain"),
    ("missing_file", lambda d: d.update(fields=[{"type": "keyframes", "file": "nope.csv"}]), "fields[0].file", "not found"),
    ("unknown_probe_body", lambda d: d["probes"][0].update(body="arm"), "probes[0].body", "no body named 'arm'"),
    ("missing_required", lambda d: d["simulation"].pop("dx"), "simulation.dx", "required"),
    ("vector_length", lambda d: d["fields"][0].update(B=[0.0, 0.01]), "fields[0]", "3 components"),
    ("negative_duration", lambda d: d["simulation"].update(duration=-1.0), "simulation.duration", "greater than 0"),
    ("unknown_field_type", lambda d: d["fields"][0].update(type="coil"), "fields[0]", "allowed"),
    ("duplicate_body", lambda d: d["bodies"].append(copy.deepcopy(d["bodies"][0])), "bodies[1].name", "duplicate"),
    ("clamp_empty", lambda d: d["clamps"][0]["region"].update(center=[0.018, 0.009]), "clamps[0].region", "no particle"),
    ("bad_device", lambda d: d["simulation"].update(device="gpu"), "simulation.device", "pattern"),
]


@pytest.mark.parametrize("case,mutate,key,hint", BAD, ids=[b[0] for b in BAD])
def test_malformed_scene_gives_one_line_error_naming_key(tmp_path, capsys, case, mutate, key, hint):
    scene = _write(tmp_path, _mutate(mutate))
    out = tmp_path / "out"
    rc = main(["run", str(scene), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1, err
    assert key in err and hint in err, err
    assert str(scene) in err
    assert not out.exists()


def test_toml_syntax_error_and_missing_scene(tmp_path, capsys):
    p = tmp_path / "broken.toml"
    p.write_text("[simulation\ndx = 1\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    assert "not valid TOML" in capsys.readouterr().err
    assert main(["run", str(tmp_path / "absent.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "not found" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_run_writes_complete_results(tmp_path):
    scene = _write(tmp_path, BASE)
    out = tmp_path / "run"
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "completed"
    assert info["steps"] > 10 and info["time"] == pytest.approx(2e-3)
    assert info["dt"]["max"] > 0 and info["warp_version"] and info["scene"]["name"] == "tiny"
    rows = (out / "metrics.csv").read_text().splitlines()
    assert rows[0] == "time,tip_x,tip_y" and len(rows) == 4  # t = 0, 1 ms, 2 ms
    pvd = (out / "particles.pvd").read_text()
    assert pvd.count("<DataSet") == 3
    pts, data = read_vtp(out / "frames" / "frame_00002.vtp")
    final = np.load(out / "final.npz")
    assert pts.shape == (len(final["x"]), 3)
    np.testing.assert_allclose(pts[:, :2], final["x"], rtol=1e-6)
    assert set(data) >= {"velocity", "body", "J", "I1bar", "magnetization_direction"}
    # the tip moved up (field along +y bends a +x-magnetised beam towards +y)
    assert float(rows[-1].split(",")[2]) > 0.005


def test_run_failure_keeps_last_good_state(tmp_path, capsys):
    bad = _mutate(lambda d: d["simulation"].update(dt=5e-4, damping=0.0))  # far above the CFL bound
    scene = _write(tmp_path, bad)
    out = tmp_path / "run"
    rc = main(["run", str(scene), "--out", str(out), "--quiet"])
    assert rc == 1
    err = capsys.readouterr().err
    assert "failed" in err and "step" in err
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "failed"
    assert "time step" in info["message"] and "t = " in info["message"]
    assert (out / "last_good.npz").exists() and not (out / "final.npz").exists()
    good = np.load(out / "last_good.npz")
    assert np.all(np.isfinite(good["x"]))


def test_interrupted_run_is_marked(tmp_path):
    from magsoro.io.recorder import RunWriter
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(copy.deepcopy(BASE)))
    writer = RunWriter(tmp_path / "r", sim, BASE)

    def stop(s):
        if s.steps == 5:
            raise KeyboardInterrupt

    result = sim.run(callback=stop, record=writer.record)
    writer.finish(result, 0.0)
    # stopped inside the first check window: the state kept is the window's first (checked) one
    assert result.status == "interrupted" and result.steps == 0 and result.time == 0.0
    assert json.loads((tmp_path / "r" / "run.json").read_text())["status"] == "interrupted"


def test_api_run_with_callback_and_arrays():
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(copy.deepcopy(BASE)))
    seen = []
    result = sim.run(duration=5e-4, callback=lambda s: seen.append(s.time))
    assert result.status == "completed" and len(seen) == result.steps
    assert seen[-1] == pytest.approx(5e-4)
    p = sim.particles()
    assert p["x"].shape == (sim.model.n_particles, 2)
    assert np.allclose(np.linalg.norm(p["magnetization"], axis=1), 1.0)
    assert set(sim.probe_values()) == {"tip_x", "tip_y"}


def test_docs_scenes_md_is_generated_from_models():
    from magsoro.scene.docs import scene_reference

    doc = Path(__file__).resolve().parents[1] / "docs" / "scenes.md"
    assert doc.read_text() == scene_reference(), "regenerate with: magsoro docs scenes --out docs/scenes.md"


@pytest.mark.parametrize("path", sorted(str(p) for p in (Path(__file__).resolve().parents[1] / "scenes").glob("*.toml")))
def test_example_scenes_are_valid(path):
    from magsoro.scene import load_scene

    if Path(path).name.startswith("rod"):
        pytest.skip("rod model file (magsoro rod), not an MPM scene")
    scene = load_scene(path)
    assert scene.simulation.duration > 0
