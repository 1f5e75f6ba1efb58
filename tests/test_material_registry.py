"""Material registry (magsoro.mpm.laws.elastic): the scene schema, the scene builder and the engine Model take their
model names and codes from the registry. Each law's stress against its energy and its initial shear modulus are
tested for every registered law in tests/test_stress.py."""

import typing

import numpy as np
import pytest
import warp as wp
from pydantic import ValidationError

from magsoro.mpm.laws.elastic import (DEFAULT_LAW, FIT_MODEL_LAWS, LAW_NAMES, LAW_PARAM_COUNT, LAWS, PARAMETER_KEYS,
                                   describe_codes, make_material_functions)

LAW_LIST = list(LAWS.values())


def _example(law):
    return {p.key: list(p.example) if p.terms else p.example for p in law.parameters}


EXAMPLES = {p.key: list(p.example) if p.terms else p.example for law in LAW_LIST for p in law.parameters}


def test_registry_shape():
    assert sorted(law.code for law in LAW_LIST) == list(range(len(LAW_LIST)))
    assert DEFAULT_LAW in LAWS
    for law in LAW_LIST:
        assert law.required and set(law.required) <= set(law.keys)
        assert len(law.pack(_example(law))) == LAW_PARAM_COUNT
        assert law.initial_shear_modulus(_example(law)) > 0
        assert law.problem(_example(law)) is None
    for dim in (2, 3):
        for scalar in (wp.float32, wp.float64):
            assert set(make_material_functions(dim, scalar)["laws"]) == set(LAWS)
    assert describe_codes() == "0 (Neo-Hookean), 1 (Mooney-Rivlin), 2 (Yeoh), 3 (Ogden) or 4 (polynomial)"


def test_every_fit_material_model_has_a_law():
    from magsoro.characterization.hyperelastic import MODEL_NAMES

    assert set(FIT_MODEL_LAWS) == set(MODEL_NAMES)
    assert set(FIT_MODEL_LAWS.values()) <= set(LAWS)


def test_schema_takes_the_registry_names():
    from magsoro.scene.schema import Material

    allowed = tuple(a for a in typing.get_args(Material.model_fields["model"].annotation) if a is not type(None))
    assert allowed == (typing.Literal[LAW_NAMES],)
    assert typing.get_args(allowed[0]) == LAW_NAMES == ("neo-hookean", "mooney-rivlin", "yeoh", "ogden", "polynomial")
    for key in PARAMETER_KEYS:  # a law's new parameter key needs its Material field
        assert key in Material.model_fields, key
    for law in LAW_LIST:
        assert f"'{law.name}'" in Material.__doc__  # named in the docs/scenes.md text
        required = {k: v for k, v in _example(law).items() if k in law.required}
        assert Material(density=1000.0, model=law.name, **required).model == law.name
        Material(density=1000.0, model=law.name, **_example(law))
        others = [k for k in PARAMETER_KEYS if k not in law.keys]
        if others:
            with pytest.raises(ValidationError, match=f"model '{law.name}' does not use {others[0]}"):
                Material(density=1000.0, model=law.name, **required, **{others[0]: EXAMPLES[others[0]]})
        missing = dict(required)
        missing.pop(law.required[0])
        with pytest.raises(ValidationError, match=f"model '{law.name}' needs {law.required[0]}"):
            Material(density=1000.0, model=law.name, **missing)
    with pytest.raises(ValidationError, match=r"mooney-rivlin needs C10 \+ C01 > 0"):
        Material(density=1000.0, model="mooney-rivlin", C10=1.0e4, C01=-1.0e4)


def test_unknown_model_lists_the_registry_names():
    import copy

    from magsoro.errors import SceneError
    from magsoro.scene import parse_scene
    from magsoro.scene.schema import Material
    from tests.test_scene_cli import BASE

    with pytest.raises(ValidationError) as err:
        Material(density=1000.0, model="ogden3", C10=1.0e4)
    assert "Input should be 'neo-hookean', 'mooney-rivlin', 'yeoh', 'ogden' or 'polynomial'" in str(err.value)
    d = copy.deepcopy(BASE)
    d["bodies"][0]["material"] = {"density": 1000.0, "model": "ogden3", "C10": 1.0e4}
    with pytest.raises(SceneError) as err:
        parse_scene(d)
    message = str(err.value)
    assert "bodies[0].material.model" in message and all(f"'{name}'" in message for name in LAW_NAMES), message


@pytest.mark.parametrize("law", LAW_LIST, ids=lambda law: law.name)
def test_scene_and_engine_use_the_registry(law):
    from magsoro.mpm.model import Model
    from magsoro.scene.build import resolve_material
    from magsoro.scene.schema import Material

    mat = resolve_material(Material(density=1000.0, model=law.name, **_example(law)), None, "bodies[0].material")
    G = law.initial_shear_modulus(_example(law))
    assert mat["model"] == law.code and mat["shear_modulus"] == G and mat["params"] == law.pack(_example(law))
    assert mat["bulk_modulus"] == 20.0 * G
    assert Model.MATERIAL_MODELS[law.name] == law.code


def test_model_refuses_unknown_codes():
    from magsoro.mpm.model import Model

    with pytest.raises(ValueError, match=r"material_model must be 0 \(Neo-Hookean\), 1 \(Mooney-Rivlin\), 2 \(Yeoh\), "
                                         r"3 \(Ogden\) or 4 \(polynomial\)"):
        Model(np.zeros((1, 2)), 1e-6, 1000.0, 1e5, 2e6, np.zeros(3), 0, False, dx=1e-3, domain_lo=(-0.01, -0.01),
              domain_hi=(0.01, 0.01), material_model=len(LAWS))
