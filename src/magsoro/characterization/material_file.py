"""Material entries: the fitted hyperelastic law of a material, written as a small TOML file.

Format (documented in docs/characterization.md; the scene format reads such entries)::

    name = "ecoflex30_ndfeb100"        # material name, also the file stem
    model = "ogden3"                   # one of linear, neo-hookean, mooney-rivlin, yeoh, ogden3, polynomial5
    shear_modulus = 10075.0            # Pa, initial (small-strain) shear modulus of the fit
    density = 1070.0                   # kg/m^3, only when given
    source = "tensile.csv"             # the data file(s) the fit came from

    [parameters]                       # moduli in Pa; Ogden exponents alpha_i dimensionless
    mu1 = -7000.0
    alpha1 = -6.2
    ...

Python's tomllib reads it back; there is no TOML writer in the standard library, and these files need only
strings, floats and one table, so they are written here.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from magsoro.characterization.errors import CharacterizationDataError
from magsoro.characterization.hyperelastic import ModelFit, get_model

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def _toml_string(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_float(x: float) -> str:
    x = float(x)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return repr(x)  # Python's shortest round-trip repr is valid TOML (1e-05, 12000.0, ...)


def material_toml(name: str, fit: ModelFit, source: str, density: float | None = None) -> str:
    """TOML text of a material entry for ``fit`` (see the module docstring for the keys and units)."""
    if not _NAME_RE.match(name):
        raise CharacterizationDataError(
            f"material name {name!r} must start with a letter or digit and use only letters, digits, '_', '.', '-'"
        )
    model = get_model(fit.model)
    lines = [
        "# magsoro material entry written by `magsoro fit-material`",
        f"# fit: {fit.n_points} points up to strain {fit.max_strain:g}, {fit.weighting} residuals, "
        f"MAPE {fit.mape:.2f} %",
        f"name = {_toml_string(name)}",
        f"model = {_toml_string(fit.model)}",
        f"shear_modulus = {_toml_float(fit.initial_shear_modulus)}  # Pa, initial (small-strain)",
    ]
    if density is not None:
        if not (density > 0 and math.isfinite(density)):
            raise CharacterizationDataError(f"--density must be a positive number of kg/m^3, got {density!r}")
        lines.append(f"density = {_toml_float(density)}  # kg/m^3")
    lines.append(f"source = {_toml_string(source)}")
    lines.append("")
    lines.append("[parameters]  # moduli in Pa; Ogden exponents (alpha_i) dimensionless")
    for key in model.param_names:
        unit = "" if key in model.dimensionless else "  # Pa"
        lines.append(f"{key} = {_toml_float(fit.params[key])}{unit}")
    return "\n".join(lines) + "\n"


def write_material(directory: str | Path, name: str, fit: ModelFit, source: str, density: float | None = None) -> Path:
    """Write ``directory/name.toml`` for ``fit`` and return its path."""
    text = material_toml(name, fit, source, density)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path
