"""write_scene / Scene.to_toml: every scene of scenes/ and examples/ round-trips; edited and hand-built scenes do;
file names follow the file to another folder; values TOML cannot hold are refused in one line."""

import copy
import math
import tomllib
import typing
from pathlib import Path

import numpy as np
import pydantic
import pytest

from magsoro.errors import SceneError
from magsoro.io.tomlwrite import dumps
from magsoro.scene import Scene, load_scene, parse_scene, write_scene
from magsoro.scene.build import fill_bodies
from magsoro.scene.schema import CentroidProbe, Material
from magsoro.scene.write import PATH_KEYS

ROOT = Path(__file__).resolve().parents[1]
FILES = sorted(p.relative_to(ROOT).as_posix() for folder in ("scenes", "examples") for p in (ROOT / folder).rglob("*.toml"))


def _same(a: Scene, b: Scene) -> bool:
    """Equal to the bit: repr tells -0.0 from 0.0 and 1 from 1.0, which == does not."""
    return repr(a.model_dump()) == repr(b.model_dump())


def _load_or_skip(name):
    try:
        return load_scene(ROOT / name)
    except SceneError:
        pytest.skip("not a scene (a rod model, a design, a target, a calibration)")


@pytest.mark.parametrize("name", FILES)
def test_every_scene_file_round_trips(name, tmp_path):
    scene = _load_or_skip(name)
    # in place: the text, read against the scene's own folder, is the same scene to the bit
    again = parse_scene(tomllib.loads(scene.to_toml()), name, scene.base_dir)
    assert _same(scene, again)
    # to another folder: it loads there (its mesh and other files found) and writes the same text as the original
    moved = load_scene(write_scene(scene, tmp_path / "a" / "b" / "scene.toml"))
    assert moved.to_toml(relative_to=ROOT) == scene.to_toml(relative_to=ROOT)
    if scene.simulation.dim == 2:  # the builder fills the same particles (cheap in 2D)
        p, q = fill_bodies(scene, name), fill_bodies(moved, "moved")
        assert np.array_equal(p.positions, q.positions) and np.array_equal(p.remanence, q.remanence)


def test_the_repository_has_scenes_to_round_trip():
    loaded = 0
    for name in FILES:
        try:
            load_scene(ROOT / name)
            loaded += 1
        except SceneError:
            pass
    assert loaded >= 20


def test_a_scene_edited_in_python_round_trips(tmp_path):
    scene = load_scene(ROOT / "examples/tutorial/strip.toml")
    body = scene.bodies[0]
    body.material = Material(library=body.material, bulk_modulus=123456.789)  # a library entry with an override
    body.material.density = 1111.0
    scene.probes.append(CentroidProbe(type="centroid", name="centre", body=body.name))
    scene.simulation.damping = -0.0 + 2.5
    scene.simulation.plane_z = -0.0  # the sign of a zero survives too
    out = write_scene(scene, tmp_path / "edited.toml")
    back = load_scene(out)
    assert _same(scene, back)
    assert back.bodies[0].material.bulk_modulus == 123456.789 and back.probes[-1].name == "centre"
    assert math.copysign(1.0, back.simulation.plane_z) == -1.0


def test_a_scene_built_from_a_dict_with_robot_parts_round_trips(tmp_path):
    part = {"name": "beam", "shape": {"type": "rectangle", "center": [0.005, 0.003], "size": [0.006, 0.001]},
            "material": {"density": 1000.0, "shear_modulus": 3.0e4}, "magnetization": [0.0, 0.1, 0.0]}
    data = {"name": "a \"quoted\" title, 10 µm",
            "simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.01, 0.006],
                           "duration": 0.01},
            "robot": {"parts": [part]},
            "bodies": [dict(part, name="block", shape={"type": "rectangle", "center": [0.005, 0.0012], "size": [0.002, 0.0008]})],
            "contact": {"friction": 0.3, "pairs": [{"bodies": ["beam", "block"], "friction": "sticky"}]},
            "fields": [{"type": "uniform", "B": [0.0, 0.0, 0.01], "profile": {"type": "sine", "frequency": 5.0}}],
            "preview": {"dx": 1e-3}}
    scene = parse_scene(copy.deepcopy(data))
    text = scene.to_toml()
    assert text.count('name = "beam"') == 1  # a robot's part is written once, under [[robot.parts]]
    assert "[[contact.pairs]]" in text and "[preview]" in text
    back = load_scene(write_scene(scene, tmp_path / "built.toml"))
    assert _same(scene, back) and [b.name for b in back.bodies] == ["block", "beam"]
    assert _same(load_scene(tmp_path / "built.toml", preview=True), parse_scene(copy.deepcopy(data) | {
        "simulation": dict(data["simulation"], dx=1e-3)}))


def test_file_names_follow_the_scene_to_another_folder(tmp_path):
    src = tmp_path / "src"
    (src / "parts").mkdir(parents=True)
    (src / "lib.toml").write_text('[[materials]]\nname = "my-silicone"\ndensity = 1100.0\nshear_modulus = 2.0e4\n'
                                  'source = "test"\nmeasured = ["shear_modulus"]\n')
    (src / "parts" / "robot.toml").write_text(dumps({"parts": [{
        "name": "arm", "shape": {"type": "rectangle", "center": [0.004, 0.004], "size": [0.004, 0.001]},
        "material": "my-silicone"}], "material_library": ["../lib.toml"]}))
    (src / "m.csv").write_text("x,y,z,Brx,Bry,Brz\n0.005,0.005,0,0.1,0,0\n")
    (src / "keys.csv").write_text("t,Bx,By,Bz\n0,0,0,0\n0.01,0,0.01,0\n")
    (src / "mat.toml").write_text('model = "neo-hookean"\nshear_modulus = 1.0e4\ndensity = 1000.0\n')
    absolute = (src / "keys.csv").resolve().as_posix()
    data = {"simulation": {"dim": 2, "dx": 5e-4, "domain_lo": [0.0, 0.0], "domain_hi": [0.01, 0.01], "duration": 0.01},
            "robot": "parts/robot.toml", "material_library": ["lib.toml"],
            "bodies": [{"name": "tip", "shape": {"type": "rectangle", "center": [0.0075, 0.004], "size": [0.002, 0.001]},
                        "material": {"file": "mat.toml"}, "magnetization": {"type": "file", "file": "m.csv"}}],
            "fields": [{"type": "keyframes", "file": "keys.csv"}, {"type": "keyframes", "file": absolute}]}
    scene = parse_scene(data, "src/scene.toml", src)
    out = write_scene(scene, tmp_path / "elsewhere" / "deeper" / "scene.toml")
    written = tomllib.loads(out.read_text())
    new = out.parent
    assert written["robot"] == "../../src/parts/robot.toml"  # relative to the new file's folder
    assert (new / written["material_library"][0]).resolve() == (src / "lib.toml").resolve()
    assert (new / written["bodies"][0]["material"]["file"]).resolve() == (src / "mat.toml").resolve()
    assert (new / written["bodies"][0]["magnetization"]["file"]).resolve() == (src / "m.csv").resolve()
    assert written["fields"][1]["file"] == absolute  # absolute names stay absolute
    back = load_scene(out)  # the loader finds every file, the robot's own library included
    p, q = fill_bodies(scene, "src"), fill_bodies(back, "back")
    assert np.array_equal(p.positions, q.positions) and np.array_equal(p.remanence, q.remanence)
    assert np.array_equal(p.shear_modulus, q.shear_modulus)


def test_every_key_naming_a_file_is_rebased():
    """A key whose description says it is relative to the scene (or robot) file must be in PATH_KEYS."""
    seen, missing = set(), []

    def walk(model):
        if model in seen:
            return
        seen.add(model)
        for name, field in model.model_fields.items():
            if "relative to the" in (field.description or "") and (model, name) not in PATH_KEYS:
                missing.append(f"{model.__name__}.{name}")
            for sub in _models(field.annotation):
                walk(sub)

    walk(Scene)
    assert not missing, f"add these to magsoro.scene.write.PATH_KEYS: {missing}"


def _models(ann):
    if isinstance(ann, type) and issubclass(ann, pydantic.BaseModel):
        return [ann]
    return [m for a in typing.get_args(ann) for m in _models(a)]


@pytest.mark.parametrize("edit, message", [
    (lambda s: setattr(s.simulation, "dx", None), r"^simulation\.dx: None cannot be written to TOML, which has no null"),
    (lambda s: setattr(s.simulation, "duration", math.inf), r"^simulation\.duration: inf cannot be written"),
    (lambda s: setattr(s.bodies[0].shape, "center", [0.001, float("nan")]), r"^bodies\[0\]\.shape\.center\[1\]: nan"),
    (lambda s: setattr(s.simulation, "device", object()), r"^simulation\.device: a value of type object cannot be written to TOML"),
    (lambda s: s.set_magnetization(lambda X: 0 * X), r"^bodies strip: a magnetisation given by set_magnetization"),
])
def test_values_toml_cannot_hold_are_refused_in_one_line(tmp_path, edit, message):
    scene = load_scene(ROOT / "examples/tutorial/strip.toml")
    edit(scene)
    with pytest.raises(SceneError, match=message) as err:
        write_scene(scene, tmp_path / "x.toml")
    assert "\n" not in str(err.value) and not (tmp_path / "x.toml").exists()


def test_a_scene_that_would_not_load_is_refused_by_its_key(tmp_path):
    scene = load_scene(ROOT / "examples/tutorial/strip.toml")
    scene.simulation.duration = -1.0  # attribute assignment is not validated; writing checks
    with pytest.raises(SceneError, match=r"x\.toml: simulation\.duration: .*greater than 0") as err:
        write_scene(scene, tmp_path / "x.toml")
    assert "\n" not in str(err.value) and not (tmp_path / "x.toml").exists()
    write_scene(scene, tmp_path / "x.toml", check=False)  # on request it is written all the same
    assert tomllib.loads((tmp_path / "x.toml").read_text())["simulation"]["duration"] == -1.0


def test_dumps_writes_what_tomllib_reads_back():
    data = {"a": -0.0, "b": 1e-300, "c": 0.1 + 0.2, "big": 2**63 - 1, "s": 'q"\\\n\t\x7f é 😀', "weird key": True,
            "t": {"u": [1, 2], "inline": [{"x": 1}, [{"y": 2.5}]],
                  "rows": [{"k": 1, "sub": {"deep": "x"}, "more": [{"z": 0}]}, {"k": 2}]},
            "empty": [], "after": {"v": "w"}}
    back = tomllib.loads(dumps(data))
    assert back == data and math.copysign(1.0, back["a"]) == -1.0 and type(back["t"]["u"][0]) is int
    with pytest.raises(ValueError, match="64 bits"):
        dumps({"n": 2**63})
