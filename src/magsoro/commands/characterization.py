"""``magsoro fit-material`` and ``magsoro fit-magnetization``: the material characterisation tools of seed 001.

See docs/characterization.md for a walk-through. Heavy imports (scipy, matplotlib) happen inside the commands so
building the parser stays cheap.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from magsoro.errors import MagsoroError


def register(sub) -> None:
    _register_fit_material(sub)


# ----------------------------------------------------------------------------------------------------------------
# fit-material


def _register_fit_material(sub) -> None:
    p = sub.add_parser(
        "fit-material",
        help="fit hyperelastic models to uniaxial tensile data",
        description=(
            "Fit the incompressible uniaxial forms of linear, Neo-Hookean, Mooney-Rivlin, Yeoh, Ogden (3 terms) and "
            "polynomial (5 coefficients) models to tensile data by nonlinear least squares, and report parameters, "
            "initial shear modulus and MAPE as in seed 001 Table II. Data: CSV with header columns 'strain' "
            "(engineering, dimensionless) and 'stress' (nominal, Pa), optionally 'specimen'."
        ),
    )
    p.add_argument("data", nargs="+", metavar="DATA.csv", help="tensile CSV file(s); several files = several specimens")
    p.add_argument(
        "--models",
        default="linear,neo-hookean,mooney-rivlin,yeoh,ogden3,polynomial5",
        help="comma-separated models to fit (default: all six)",
    )
    p.add_argument("--max-strain", type=float, metavar="S", help="fit only points with strain <= S (e.g. 1.0 = 100%%)")
    p.add_argument(
        "--weighting",
        choices=("relative", "absolute"),
        default="relative",
        help="least-squares residual: stress error divided by measured stress (default) or plain stress error",
    )
    p.add_argument("--json", action="store_true", help="print {\"models\": {...}} as JSON instead of a table")
    p.add_argument("--out", metavar="DIR", help="write fit_material.png and fit_material.json here")
    p.add_argument("--save-material", metavar="NAME", help="write DIR/NAME.toml with the chosen fit (DIR: --out or .)")
    p.add_argument("--material-model", metavar="M", help="model saved by --save-material (default: lowest MAPE)")
    p.add_argument("--density", type=float, metavar="RHO", help="density in kg/m^3 stored in the material entry")
    p.set_defaults(func=run_fit_material)


def _parse_models(text: str) -> list[str]:
    from magsoro.characterization.hyperelastic import MODEL_NAMES

    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise MagsoroError("--models: give at least one model")
    bad = [n for n in names if n not in MODEL_NAMES]
    if bad:
        raise MagsoroError(f"--models: unknown model(s) {', '.join(bad)}; choose from {', '.join(MODEL_NAMES)}")
    return list(dict.fromkeys(names))


def _format_params(model, params: dict) -> str:
    from magsoro.characterization.hyperelastic import get_model

    dimless = get_model(model).dimensionless
    return "  ".join(f"{k}={v:.4g}" if k in dimless else f"{k}={v:.4g} Pa" for k, v in params.items())


def run_fit_material(args) -> int:
    import numpy as np

    from magsoro.characterization.hyperelastic import (
        best_model,
        fit_model,
        fit_models,
        read_tensile_csv,
        youngs_modulus_per_specimen,
    )
    from magsoro.characterization.material_file import write_material

    models = _parse_models(args.models)
    if args.max_strain is not None and not args.max_strain > 0:
        raise MagsoroError(f"--max-strain: must be > 0, got {args.max_strain}")
    if args.material_model is not None and args.material_model not in models:
        raise MagsoroError(f"--material-model: {args.material_model!r} is not among --models ({', '.join(models)})")
    if args.density is not None and not args.density > 0:
        raise MagsoroError(f"--density: must be > 0 kg/m^3, got {args.density}")
    data = read_tensile_csv(args.data)
    fits = fit_models(data, models, max_strain=args.max_strain, weighting=args.weighting)
    result = {"models": {name: fit.to_json() for name, fit in fits.items()}}

    out_dir = Path(args.out) if args.out else None
    written = []
    if out_dir is not None:
        from magsoro.characterization.plotting import plot_tensile_fits

        out_dir.mkdir(parents=True, exist_ok=True)
        sources = ", ".join(Path(s).name for s in data.sources)
        written.append(plot_tensile_fits(data.select(args.max_strain), fits, out_dir / "fit_material.png", title=sources))
        (out_dir / "fit_material.json").write_text(json.dumps(result, indent=2) + "\n")
        written.append(out_dir / "fit_material.json")
    if args.save_material:
        chosen = args.material_model or best_model(fits)
        written.append(
            write_material(out_dir or Path("."), args.save_material, fits[chosen], ", ".join(data.sources), args.density)
        )

    if args.json:
        print(json.dumps(result, indent=2))
        return 0

    sub = data.select(args.max_strain)
    print(
        f"fit-material: {len(data.specimens)} specimen(s), {sub.strain.size} points fitted, strain "
        f"{sub.strain.min():g} .. {sub.strain.max():g}, {args.weighting} residuals"
    )
    print(f"{'model':<14} {'MAPE [%]':>9} {'mu0 [kPa]':>10}  parameters")
    for name, fit in fits.items():
        print(f"{name:<14} {fit.mape:9.2f} {fit.initial_shear_modulus / 1e3:10.3f}  {_format_params(name, fit.params)}")
    print(f"lowest MAPE: {best_model(fits)}")
    # seed 001 Table II reports E from a linear fit up to 100 % strain, mean and std over specimens
    if np.any((data.strain > 0) & (data.strain <= 1.0)):
        per = youngs_modulus_per_specimen(data, 1.0, weighting=args.weighting)
        vals = np.array(list(per.values()))
        pooled = fit_model(data, "linear", max_strain=1.0, weighting=args.weighting).params["E"]
        spread = f", {vals.mean() / 1e3:.2f} +- {vals.std(ddof=1) / 1e3:.2f} kPa over {len(vals)} specimens" if len(vals) > 1 else ""
        print(f"Young's modulus, linear fit up to 100% strain: E = {pooled / 1e3:.2f} kPa (all specimens){spread}")
    for path in written:
        print(f"wrote {path}")
    return 0
