"""Per-body constitutive models in the engine: Mooney-Rivlin and Yeoh, inline or from a fit-material entry."""

import copy

import numpy as np
import pytest

from magsoro.errors import SceneError
from magsoro.scene import parse_scene
from magsoro.simulation import Simulation
from tests.test_scene_cli import BASE


def _run(material, duration=1e-3):
    d = copy.deepcopy(BASE)
    d["bodies"][0]["material"] = material
    d["simulation"]["duration"] = duration
    d["simulation"]["precision"] = "float64"
    sim = Simulation(parse_scene(d))
    assert sim.run().status == "completed"
    return sim.particles()["x"]


def test_reduced_models_reproduce_neo_hookean():
    """Mooney-Rivlin with C01 = 0 and Yeoh with C20 = C30 = 0 are Neo-Hookean with G = 2 C10: same trajectory."""
    x_nh = _run({"density": 1000.0, "shear_modulus": 5e4})
    x_mr = _run({"density": 1000.0, "model": "mooney-rivlin", "C10": 2.5e4, "C01": 0.0})
    x_yeoh = _run({"density": 1000.0, "model": "yeoh", "C10": 2.5e4})
    scale = np.abs(x_nh).max()
    assert np.abs(x_mr - x_nh).max() < 1e-12 * scale
    assert np.abs(x_yeoh - x_nh).max() < 1e-12 * scale


def test_mooney_rivlin_c01_changes_response():
    """Same initial shear modulus split between C10 and C01: a different large-strain path, same small-strain stiffness."""
    x_nh = _run({"density": 1000.0, "shear_modulus": 5e4})
    x_mr = _run({"density": 1000.0, "model": "mooney-rivlin", "C10": 1.5e4, "C01": 1.0e4})
    diff = np.abs(x_mr - x_nh).max()
    assert 0 < diff < 0.05 * np.abs(x_nh - np.asarray(x_nh).mean(0)).max()


def test_material_from_fit_material_entry(tmp_path):
    from magsoro.characterization.material_file import write_material
    from magsoro.characterization import fit_model, TensileData

    strain = np.linspace(0.01, 2.0, 60)
    stretch = 1 + strain
    C10, C20, C30 = 2.5e4, -300.0, 40.0
    I1 = stretch**2 + 2 / stretch
    dW = C10 + 2 * C20 * (I1 - 3) + 3 * C30 * (I1 - 3) ** 2
    stress = 2 * (stretch - stretch**-2) * dW
    fit = fit_model(TensileData.from_arrays(strain, stress), "yeoh")
    path = write_material(tmp_path, "silicone_a", fit, source="synthetic", density=1000.0)
    d = copy.deepcopy(BASE)
    d["bodies"][0]["material"] = {"file": path.name}
    scene = parse_scene(d, base_dir=tmp_path)
    sim = Simulation(scene)
    assert sim.model.host["material_model"][0] == 2
    assert sim.model.host["shear_modulus"][0] == pytest.approx(2 * C10, rel=1e-3)
    assert sim.model.host["material_params"][0] == pytest.approx([C10, C20, C30, 0.0, 0.0, 0.0], rel=1e-2)


@pytest.mark.parametrize(
    "material,key,hint",
    [
        ({"density": 1000.0, "model": "mooney-rivlin", "C10": 1e4}, "bodies[0].material", "needs C01"),
        ({"density": 1000.0, "model": "yeoh", "C10": 1e4, "shear_modulus": 2e4}, "bodies[0].material", "does not use shear_modulus"),
        ({"density": 1000.0, "model": "ogden3", "C10": 1e4}, "bodies[0].material.model", "neo-hookean"),
        ({"file": "missing.toml"}, "bodies[0].material.file", "not found"),
    ],
)
def test_bad_materials(material, key, hint, tmp_path):
    d = copy.deepcopy(BASE)
    d["bodies"][0]["material"] = material
    with pytest.raises(SceneError) as err:
        Simulation(parse_scene(d, base_dir=tmp_path))
    assert key in str(err.value) and hint in str(err.value)
