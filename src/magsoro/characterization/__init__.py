"""Material characterisation tools (seed 001): hyperelastic fits of tensile data and the magnetic moment of a
sample from force/torque measurements near a large cylindrical magnet.

Hyperelastic part::

    from magsoro.characterization import read_tensile_csv, fit_models
    data = read_tensile_csv("tensile.csv")          # strain (dimensionless), stress (Pa)
    fits = fit_models(data, ["neo-hookean", "ogden3"])
    fits["ogden3"].params, fits["ogden3"].initial_shear_modulus, fits["ogden3"].mape
"""

from magsoro.characterization.errors import CharacterizationDataError
from magsoro.characterization.hyperelastic import (
    MODEL_NAMES,
    MODELS,
    HyperelasticModel,
    ModelFit,
    TensileData,
    best_model,
    fit_model,
    fit_models,
    get_model,
    mape,
    read_tensile_csv,
    uniaxial_stress,
    youngs_modulus_per_specimen,
)
from magsoro.characterization.material_file import material_toml, write_material

__all__ = [
    "CharacterizationDataError",
    "MODEL_NAMES",
    "MODELS",
    "HyperelasticModel",
    "ModelFit",
    "TensileData",
    "best_model",
    "fit_model",
    "fit_models",
    "get_model",
    "mape",
    "read_tensile_csv",
    "uniaxial_stress",
    "youngs_modulus_per_specimen",
    "material_toml",
    "write_material",
]
