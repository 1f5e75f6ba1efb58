"""Material characterisation tools (seed 001): hyperelastic fits of tensile data and the magnetic moment of a
sample from force/torque measurements near a large cylindrical magnet.

Hyperelastic part::

    from magsoro.characterization import read_tensile_csv, fit_models
    data = read_tensile_csv("tensile.csv")          # strain (dimensionless), stress (Pa)
    fits = fit_models(data, ["neo-hookean", "ogden3"])
    fits["ogden3"].params, fits["ogden3"].initial_shear_modulus, fits["ogden3"].mape

Magnetic part::

    from magsoro.fields.cylinder import CylinderMagnet
    from magsoro.characterization import read_force_torque_csv, fit_magnetization, parse_orientations
    magnet = CylinderMagnet(0.1016, 0.1016, 1.48, axis=(1, 0, 0), model="multipole", order=17)
    fit = fit_magnetization(read_force_torque_csv("ft.csv"), magnet, parse_orientations("1:y:90"),
                            volume=6.35e-3**3)
    fit.moment, fit.remanence, fit.remanence_std, fit.mape
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
from magsoro.characterization.magnetization import (
    NANO17_FORCE_RESOLUTION,
    NANO17_TORQUE_RESOLUTION,
    AveragedData,
    ForceTorqueData,
    MagnetizationFit,
    average_repetitions,
    fit_magnetization,
    force_torque_matrices,
    parse_orientations,
    predict_force_torque,
    read_force_torque_csv,
    rotation_matrix,
    zero_quiet_axes,
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
    "NANO17_FORCE_RESOLUTION",
    "NANO17_TORQUE_RESOLUTION",
    "AveragedData",
    "ForceTorqueData",
    "MagnetizationFit",
    "average_repetitions",
    "fit_magnetization",
    "force_torque_matrices",
    "parse_orientations",
    "predict_force_torque",
    "read_force_torque_csv",
    "rotation_matrix",
    "zero_quiet_axes",
    "material_toml",
    "write_material",
]
