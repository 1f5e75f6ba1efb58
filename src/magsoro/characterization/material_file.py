"""Material entries: the fitted hyperelastic law of a material, written as a small TOML file.

Format (documented in docs/characterization.md; the scene format reads such entries)::

    name = "ecoflex30_ndfeb100"        # material name, also the file stem
    model = "ogden3"                   # one of linear, neo-hookean, mooney-rivlin, yeoh, ogden3, polynomial5
    shear_modulus = 10075.0            # Pa, initial (small-strain) shear modulus of the fit
    density = 1070.0                   # kg/m^3, only when given
    source = "tensile.csv"             # the data file(s) the fit came from
    prony = [[0.3, 0.01], [0.2, 1.0]]  # optional: Prony terms [g_i, tau_i in s] (viscoelastic.py), 1..3 pairs

    [parameters]                       # moduli in Pa; Ogden exponents alpha_i dimensionless
    mu1 = -7000.0
    alpha1 = -6.2
    ...

Python's tomllib reads it back (:func:`read_material` also checks the keys); there is no TOML writer in the
standard library, and these files need only strings, floats, one array and one table, so they are written here.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from magsoro.characterization.errors import CharacterizationDataError
from magsoro.characterization.hyperelastic import MODEL_NAMES, ModelFit, get_model
from magsoro.characterization.viscoelastic import check_prony

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


def material_toml(
    name: str, fit: ModelFit, source: str, density: float | None = None, prony=None, prony_note: str | None = None
) -> str:
    """TOML text of a material entry for ``fit`` (see the module docstring for the keys and units).

    ``prony``: optional [[g_i, tau_i (s)], ...] (checked by :func:`~magsoro.characterization.viscoelastic.check_prony`),
    written as the top-level key ``prony``; ``prony_note`` a comment line above it (e.g. the fit's data and error).
    """
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
    if prony is not None:
        terms = check_prony(prony, "prony terms of the material entry")
        if prony_note:
            lines.append("# " + " ".join(prony_note.split()))
        pairs = ", ".join(f"[{_toml_float(g)}, {_toml_float(tau)}]" for g, tau in terms)
        lines.append(f"prony = [{pairs}]  # [g_i (fraction of the instantaneous shear modulus), tau_i (s)]")
    lines.append("")
    lines.append("[parameters]  # moduli in Pa; Ogden exponents (alpha_i) dimensionless")
    for key in model.param_names:
        unit = "" if key in model.dimensionless else "  # Pa"
        lines.append(f"{key} = {_toml_float(fit.params[key])}{unit}")
    return "\n".join(lines) + "\n"


def write_material(
    directory: str | Path,
    name: str,
    fit: ModelFit,
    source: str,
    density: float | None = None,
    prony=None,
    prony_note: str | None = None,
) -> Path:
    """Write ``directory/name.toml`` for ``fit`` (and optional ``prony`` terms) and return its path."""
    text = material_toml(name, fit, source, density, prony, prony_note)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def read_material(path: str | Path) -> dict:
    """Read a material entry back and check it: the dict of the TOML file, with ``prony`` (when present) as a list
    of [g_i, tau_i] float pairs.

    Checked: ``model`` (required, a string: a fit-material model or an engine law name), ``shear_modulus`` (Pa)
    and ``density`` (kg/m^3) finite and > 0 when present, ``name`` and ``source`` strings, ``[parameters]`` a table
    of finite numbers (or arrays of them) when present, and ``prony``: 1 to 3 pairs [g, tau] of finite numbers with
    g > 0, tau > 0 s and sum g < 1. Whether the parameters complete the model is left to the scene builder, which
    also reads hand-written entries in the engine's own parameter names. Other keys are kept as they are. Raises
    :class:`CharacterizationDataError` naming the file and the key.
    """
    from magsoro.io.files import read_toml_file

    path = Path(path)
    entry = read_toml_file(path, CharacterizationDataError, "material file")
    model = entry.get("model")
    if not isinstance(model, str):
        raise CharacterizationDataError(
            f"{path}: key 'model' must be a model name such as {', '.join(repr(m) for m in MODEL_NAMES)}, got {model!r}"
        )
    for key, unit in (("shear_modulus", "Pa"), ("density", "kg/m^3")):
        if key in entry:
            v = entry[key]
            if not (_is_number(v) and math.isfinite(v) and v > 0):
                raise CharacterizationDataError(f"{path}: key {key!r} must be a finite number > 0 ({unit}), got {v!r}")
    for key in ("name", "source"):
        if key in entry and not isinstance(entry[key], str):
            raise CharacterizationDataError(f"{path}: key {key!r} must be a string, got {entry[key]!r}")
    params = entry.get("parameters")
    if params is not None:
        if not isinstance(params, dict):
            raise CharacterizationDataError(f"{path}: key 'parameters' must be a table [parameters], got {params!r}")
        for key, v in params.items():
            items = v if isinstance(v, list) else [v]
            if not items or not all(_is_number(x) and math.isfinite(x) for x in items):
                raise CharacterizationDataError(
                    f"{path}: key 'parameters.{key}' must be a finite number (or an array of them), got {v!r}"
                )
    if "prony" in entry:
        entry["prony"] = [list(t) for t in check_prony(entry["prony"], f"{path}: key 'prony'")]
    return entry


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)
