"""Material library: silicone / NdFeB composites with their sources, and the mixture rules behind them.

Entries come from the built-in ``magsoro/data/materials.toml`` and from user TOML files in the same format
(``[[materials]]`` tables, optional ``[particles]``). Every entry keeps which of its values were measured (by the
cited source) and which were estimated here, so `magsoro materials show NAME` can say so.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from magsoro.io.files import read_toml_file

# seed 003 (Supporting Note S1): NdFeB particle density 7.61 g/cm^3 and remanence 911 mT
NDFEB_DENSITY = 7610.0
NDFEB_REMANENCE = 0.911


class MaterialLibraryError(ValueError):
    """A library file or entry is malformed, or a name is not in the library."""


def ndfeb_volume_fraction(wt_percent: float, silicone_density: float, particle_density: float = NDFEB_DENSITY) -> float:
    """Volume fraction of NdFeB in a composite with ``wt_percent`` grams of NdFeB per 100 g of silicone.

    seed 001 sec II: the weight percentage is relative to the elastomer (150 wt% exists). Densities in kg/m^3.
    """
    w = wt_percent / 100.0
    return (w / particle_density) / (w / particle_density + 1.0 / silicone_density)


def mixture_density(wt_percent: float, silicone_density: float, particle_density: float = NDFEB_DENSITY) -> float:
    """Density (kg/m^3) of the composite by the mixture rule (volumes add): (1 + w) / (1/rho_s + w/rho_p)."""
    w = wt_percent / 100.0
    return (1.0 + w) / (1.0 / silicone_density + w / particle_density)


@dataclass
class MaterialEntry:
    """A library material. Moduli in Pa, density in kg/m^3, remanence in T (magnitude; the direction comes from
    the body's magnetisation)."""

    name: str
    title: str
    density: float
    shear_modulus: float
    remanence: float
    source: str
    measured: list[str]
    estimated: list[str]
    youngs_modulus: float | None = None
    youngs_modulus_std: float | None = None
    ndfeb_wt_percent: float | None = None
    volume_fraction: float | None = None
    remanence_estimate: float | None = None
    remanence_correction: float = 0.0
    notes: str = ""
    origin: str = "built-in"
    derivation: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The entry as a JSON-able dict (what ``magsoro materials show NAME --json`` prints), SI units."""
        keys = ["name", "title", "density", "shear_modulus", "youngs_modulus", "youngs_modulus_std", "remanence", "remanence_estimate",
                "remanence_correction", "ndfeb_wt_percent", "volume_fraction", "measured", "estimated", "source", "notes", "origin", "derivation"]
        return {k: getattr(self, k) for k in keys}


_KEYS = {"name", "title", "density", "silicone_density", "ndfeb_wt_percent", "youngs_modulus", "youngs_modulus_std", "shear_modulus", "remanence",
         "remanence_relative_to", "remanence_increment", "remanence_correction", "measured", "source", "notes"}


def _entries_from(data: dict, origin: str, known: dict) -> dict[str, MaterialEntry]:
    particles = data.get("particles", {})
    rho_p = float(particles.get("density", NDFEB_DENSITY))
    br_p = float(particles.get("remanence", NDFEB_REMANENCE))
    raw = data.get("materials", [])
    if not isinstance(raw, list):
        raise MaterialLibraryError(f"{origin}: 'materials' must be an array of tables ([[materials]])")
    out: dict[str, MaterialEntry] = {}
    pending = []
    for i, e in enumerate(raw):
        where = f"{origin}: materials[{i}]"
        unknown = set(e) - _KEYS
        if unknown:
            raise MaterialLibraryError(f"{where}: unknown key '{sorted(unknown)[0]}'; allowed keys: {', '.join(sorted(_KEYS))}")
        if "name" not in e or not isinstance(e["name"], str) or not e["name"]:
            raise MaterialLibraryError(f"{where}.name: required (a string)")
        if "source" not in e:
            raise MaterialLibraryError(f"{where}.source: required: cite where the values come from")
        pending.append((where, e))
    # entries whose remanence is relative to another one are resolved after their reference
    pending.sort(key=lambda we: "remanence_relative_to" in we[1])
    for where, e in pending:
        out[e["name"]] = _make_entry(e, where, origin, rho_p, br_p, {**known, **out})
    return {e["name"]: out[e["name"]] for _, e in sorted(pending, key=lambda we: raw.index(we[1]))}  # file order


def _num(e, key, where, positive=True):
    v = e.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or (positive and v <= 0):
        raise MaterialLibraryError(f"{where}.{key}: must be a {'positive ' if positive else ''}number, got {v!r}")
    return float(v)


def _make_entry(e, where, origin, rho_p, br_p, known) -> MaterialEntry:
    measured = list(e.get("measured", []))
    estimated: list[str] = []
    derivation: dict[str, str] = {}
    wt = _num(e, "ndfeb_wt_percent", where, positive=False)
    if wt is not None and wt < 0:
        raise MaterialLibraryError(f"{where}.ndfeb_wt_percent: must be >= 0, got {wt}")
    rho_s = _num(e, "silicone_density", where)
    density = _num(e, "density", where)
    phi = None
    if wt is not None and rho_s is not None:
        phi = ndfeb_volume_fraction(wt, rho_s, rho_p)
    if density is None:
        if wt is None or rho_s is None:
            raise MaterialLibraryError(f"{where}.density: give density (kg/m^3), or silicone_density and ndfeb_wt_percent for the mixture rule")
        density = mixture_density(wt, rho_s, rho_p)
        estimated.append("density")
        derivation["density"] = f"mixture rule (1 + w)/(1/{rho_s:g} + w/{rho_p:g}), w = {wt / 100:g}"
    E = _num(e, "youngs_modulus", where)
    G = _num(e, "shear_modulus", where)
    if G is None:
        if E is None:
            raise MaterialLibraryError(f"{where}.shear_modulus: give shear_modulus or youngs_modulus (Pa)")
        G = E / 3.0
        estimated.append("shear_modulus")
        derivation["shear_modulus"] = "youngs_modulus / 3 (incompressible)"
    estimate = phi * br_p if phi is not None else None
    Br = _num(e, "remanence", where, positive=False)
    correction = 0.0
    if Br is None:
        ref = e.get("remanence_relative_to")
        if ref is not None:
            if ref not in known:
                raise MaterialLibraryError(f"{where}.remanence_relative_to: no entry named '{ref}' (defined before use or in the same file)")
            inc = _num(e, "remanence_increment", where, positive=False)
            if inc is None:
                raise MaterialLibraryError(f"{where}.remanence_increment: required with remanence_relative_to (T)")
            Br = known[ref].remanence + inc
            derivation["remanence"] = f"remanence of '{ref}' ({known[ref].remanence:.4g} T) {inc:+g} T (measured change with concentration)"
        elif estimate is not None:
            Br = estimate + (_num(e, "remanence_correction", where, positive=False) or 0.0)
            derivation["remanence"] = f"volume fraction {phi:.4g} x particle remanence {br_p:g} T" + (" + remanence_correction" if "remanence_correction" in e else "")
        else:
            Br = 0.0
        estimated.append("remanence")
        if estimate is not None:
            correction = Br - estimate
    if Br < 0:
        raise MaterialLibraryError(f"{where}: remanence comes out negative ({Br:.4g} T)")
    measured_known = {"density", "shear_modulus", "youngs_modulus", "remanence", "remanence_increment", "remanence_correction"}
    bad = [m for m in measured if m not in measured_known]
    if bad:
        raise MaterialLibraryError(f"{where}.measured: unknown value '{bad[0]}'; allowed: {', '.join(sorted(measured_known))}")
    for k in ("density", "shear_modulus", "youngs_modulus", "remanence"):
        if k in e and k not in measured and k not in estimated:
            estimated.append(k)  # given but not marked measured: treat as an estimate
    return MaterialEntry(
        name=e["name"], title=e.get("title", e["name"]), density=density, shear_modulus=G, remanence=Br, source=e["source"],
        measured=measured, estimated=estimated, youngs_modulus=E, youngs_modulus_std=_num(e, "youngs_modulus_std", where, positive=False),
        ndfeb_wt_percent=wt, volume_fraction=phi, remanence_estimate=estimate, remanence_correction=correction,
        notes=e.get("notes", ""), origin=origin, derivation=derivation,
    )


def _read_toml(path: Path, what: str) -> dict:
    return read_toml_file(path, MaterialLibraryError, what)


def builtin_library() -> dict[str, MaterialEntry]:
    """The entries of the built-in library (magsoro/data/materials.toml) by name."""
    text = resources.files("magsoro").joinpath("data/materials.toml").read_text()
    return _entries_from(tomllib.loads(text), "built-in", {})


def load_library(extra_files=()) -> dict[str, MaterialEntry]:
    """The built-in entries plus those of ``extra_files`` (user TOML files, later files override earlier names)."""
    lib = builtin_library()
    for f in extra_files:
        path = Path(f)
        lib.update(_entries_from(_read_toml(path, "material library"), str(path), lib))
    return lib


def get_material(name: str, library: dict[str, MaterialEntry] | None = None) -> MaterialEntry:
    """The entry ``name`` of ``library`` (default: the built-in one); MaterialLibraryError naming close matches
    when there is none."""
    lib = builtin_library() if library is None else library
    if name not in lib:
        import difflib

        close = difflib.get_close_matches(name, list(lib), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise MaterialLibraryError(f"unknown material '{name}'{hint} (known: {', '.join(sorted(lib))})")
    return lib[name]
