"""``magsoro fit-material`` and ``magsoro fit-magnetization``: the material characterisation tools of seed 001.

See docs/characterization.md for a walk-through. Heavy imports (scipy, matplotlib) happen inside the commands so
building the parser stays cheap.
"""

from __future__ import annotations

import json
from pathlib import Path

from magsoro.errors import MagsoroError


def register(sub) -> None:
    _register_fit_material(sub)
    _register_fit_magnetization(sub)


# ----------------------------------------------------------------------------------------------------------------
# fit-material


def _register_fit_material(sub) -> None:
    p = sub.add_parser(
        "fit-material",
        help="fit hyperelastic models to tensile data and Prony terms to relaxation or frequency-sweep data",
        description=(
            "Fit the incompressible uniaxial forms of linear, Neo-Hookean, Mooney-Rivlin, Yeoh, Ogden (3 terms) and "
            "polynomial (5 coefficients) models to tensile data by nonlinear least squares, and report parameters, "
            "initial shear modulus and MAPE as in seed 001 Table II. Data: CSV with header columns 'strain' "
            "(engineering, dimensionless) and 'stress' (nominal, Pa), optionally 'specimen'. With --relaxation or "
            "--frequency-sweep, also (or only) fit a Prony series G(t) = G0 (g_inf + sum g_i exp(-t/tau_i))."
        ),
    )
    p.add_argument(
        "data", nargs="*", metavar="DATA.csv",
        help="tensile CSV file(s); several files = several specimens (optional with --relaxation/--frequency-sweep)",
    )
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
    p.add_argument(
        "--relaxation", metavar="FILE.csv",
        help="stress-relaxation CSV: 'time' (s) and 'shear_modulus' (Pa), 'tensile_modulus' (Pa) or 'stress' (Pa) "
        "with 'strain'; fits Prony terms",
    )
    p.add_argument(
        "--frequency-sweep", metavar="FILE.csv",
        help="frequency-sweep CSV: 'frequency' (Hz), 'storage_modulus' and 'loss_modulus' (Pa); fits Prony terms",
    )
    p.add_argument("--prony-terms", type=int, metavar="N", help="number of Prony terms, 1..3 (default 3)")
    p.add_argument(
        "--json", action="store_true",
        help="print {\"models\": {...}} (tensile) and/or {\"prony\": {...}} as JSON instead of a table",
    )
    p.add_argument(
        "--out", metavar="DIR", help="write fit_material.png, fit_prony.png and fit_material.json here (as fitted)"
    )
    p.add_argument(
        "--save-material", metavar="NAME",
        help="write DIR/NAME.toml with the chosen fit, and the Prony terms when fitted (DIR: --out or .); needs "
        "tensile data",
    )
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


def _check_fit_material_args(args) -> None:
    viscous = args.relaxation is not None or args.frequency_sweep is not None
    if not args.data and not viscous:
        raise MagsoroError(
            "no data: give tensile DATA.csv file(s), --relaxation FILE.csv or --frequency-sweep FILE.csv"
        )
    if args.relaxation is not None and args.frequency_sweep is not None:
        raise MagsoroError("--relaxation and --frequency-sweep: give one of them, not both")
    if args.prony_terms is not None:
        if not viscous:
            raise MagsoroError("--prony-terms: needs --relaxation or --frequency-sweep")
        if not 1 <= args.prony_terms <= 3:
            raise MagsoroError(f"--prony-terms: must be 1, 2 or 3, got {args.prony_terms}")
    if args.save_material and not args.data:
        raise MagsoroError(
            "--save-material: a material entry needs a hyperelastic law (model, shear_modulus, [parameters]) from "
            "tensile data; give the tensile DATA.csv file(s) in the same command, e.g. magsoro fit-material "
            "tensile.csv --relaxation relax.csv --save-material NAME"
        )
    if args.max_strain is not None and not args.max_strain > 0:
        raise MagsoroError(f"--max-strain: must be > 0, got {args.max_strain}")
    if args.density is not None and not args.density > 0:
        raise MagsoroError(f"--density: must be > 0 kg/m^3, got {args.density}")


def run_fit_material(args) -> int:
    _check_fit_material_args(args)
    models = _parse_models(args.models)
    if args.material_model is not None and args.material_model not in models:
        raise MagsoroError(f"--material-model: {args.material_model!r} is not among --models ({', '.join(models)})")

    data = fits = None
    result: dict = {}
    if args.data:
        from magsoro.characterization.hyperelastic import fit_models, read_tensile_csv

        data = read_tensile_csv(args.data)
        fits = fit_models(data, models, max_strain=args.max_strain, weighting=args.weighting)
        result["models"] = {name: fit.to_json() for name, fit in fits.items()}
    prony = None
    if args.relaxation is not None or args.frequency_sweep is not None:
        from magsoro.characterization.viscoelastic import fit_prony, read_frequency_sweep_csv, read_relaxation_csv

        if args.relaxation is not None:
            vdata = read_relaxation_csv(args.relaxation)
        else:
            vdata = read_frequency_sweep_csv(args.frequency_sweep)
        prony = fit_prony(vdata, 3 if args.prony_terms is None else args.prony_terms)
        result["prony"] = prony.to_json()

    out_dir = Path(args.out) if args.out else None
    written = []
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        if fits is not None:
            from magsoro.characterization.plotting import plot_tensile_fits

            sources = ", ".join(Path(s).name for s in data.sources)
            fitted = data.select(args.max_strain)
            written.append(plot_tensile_fits(fitted, fits, out_dir / "fit_material.png", title=sources))
        if prony is not None:
            from magsoro.characterization.viscoelastic import plot_prony_fit

            title = f"{Path(prony.data.source).name}: {prony.kind}"
            written.append(plot_prony_fit(prony, out_dir / "fit_prony.png", title=title))
            result["prony"]["plot"] = "fit_prony.png"
        (out_dir / "fit_material.json").write_text(json.dumps(result, indent=2) + "\n")
        written.append(out_dir / "fit_material.json")
    if args.save_material:
        from magsoro.characterization.hyperelastic import best_model
        from magsoro.characterization.material_file import write_material

        chosen = args.material_model or best_model(fits)
        source = ", ".join(data.sources)
        note = None
        if prony is not None:
            source += f", {prony.data.source}"
            note = (
                f"prony: {prony.kind} fit of {prony.data.source}, G0 {prony.shear_modulus:.6g} Pa, g_inf "
                f"{prony.g_inf:.4g}, relative RMS error {prony.rms_error:.2f} %"
            )
        written.append(
            write_material(
                out_dir or Path("."), args.save_material, fits[chosen], source, args.density,
                prony=prony.prony if prony is not None else None, prony_note=note,
            )
        )

    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    if fits is not None:
        _print_tensile(args, data, fits)
    if prony is not None:
        _print_prony(prony)
        if fits is not None:
            from magsoro.characterization.hyperelastic import best_model

            chosen = args.material_model or best_model(fits)
            mu0 = fits[chosen].initial_shear_modulus
            print(
                f"note: in a material entry the g_i scale the hyperelastic law ({chosen}: mu0 = {mu0 / 1e3:.4g} kPa "
                f"from the tensile data); the Prony fit's instantaneous G0 = {prony.shear_modulus / 1e3:.4g} kPa "
                f"(mu0 {100 * (mu0 / prony.shear_modulus - 1):+.1f} %)"
            )
    for path in written:
        print(f"wrote {path}")
    return 0


def _print_tensile(args, data, fits) -> None:
    import numpy as np

    from magsoro.characterization.hyperelastic import best_model, fit_model, youngs_modulus_per_specimen

    sub = data.select(args.max_strain)
    print(
        f"fit-material: {len(data.specimens)} specimen(s), {sub.strain.size} points in the fitted range, strain "
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
        spread = ""
        if len(vals) > 1:
            spread = f", {vals.mean() / 1e3:.2f} +- {vals.std(ddof=1) / 1e3:.2f} kPa over {len(vals)} specimens"
        print(f"Young's modulus, linear fit up to 100% strain: E = {pooled / 1e3:.2f} kPa (all specimens){spread}")


def _print_prony(fit) -> None:
    d = fit.data
    if fit.kind == "relaxation":
        axis, unit = d.time, "s"
        what = {"shear_modulus": "G(t)", "tensile_modulus": "E(t)/3", "stress": "stress/(lam - lam^-2)"}[d.column]
    else:
        axis, unit = d.frequency, "Hz"
        what = "G', G''" if d.column == "storage_modulus" else "E'/3, E''/3"
    print(
        f"prony: {fit.kind} {d.source}, {axis.size} points, {axis[0]:g} .. {axis[-1]:g} {unit}, fitted {what}; "
        f"{fit.n_terms} term(s)" + (f" of {fit.n_terms_requested} asked" if fit.n_terms < fit.n_terms_requested else "")
    )
    print(f"{'term':<6} {'g_i':>10} {'tau_i [s]':>12}")
    for i, (g, tau) in enumerate(zip(fit.g, fit.tau), start=1):
        print(f"{i:<6} {g:10.5f} {tau:12.5g}")
    print(
        f"G0 = {fit.shear_modulus / 1e3:.5g} kPa (instantaneous shear modulus), g_inf = {fit.g_inf:.5f} "
        f"(G_inf = {fit.long_term_shear_modulus / 1e3:.5g} kPa)"
    )
    print(f"relative RMS error {fit.rms_error:.3f} %, MAPE {fit.mape:.3f} % ({fit.method})")
    print("prony = [" + ", ".join(f"[{g:.6g}, {tau:.6g}]" for g, tau in zip(fit.g, fit.tau)) + "]")
    for note in fit.notes:
        print(f"note: {note}")


# ----------------------------------------------------------------------------------------------------------------
# fit-magnetization


def _floats(text: str, n: int, option: str) -> list[float]:
    try:
        vals = [float(t) for t in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != n:
        raise MagsoroError(f"{option}: expected {n} comma-separated numbers, got {text!r}")
    return vals


def _register_fit_magnetization(sub) -> None:
    p = sub.add_parser(
        "fit-magnetization",
        help="fit a sample's magnetic moment to force/torque data near a cylinder magnet",
        description=(
            "Fit the moment m of a small magnetised sample (point dipole: F = (grad B)^T m, tau = m x B) to forces "
            "and torques measured at several positions near a large axially magnetised cylinder (seed 001 sec IV, "
            "eqs 7 and 10). CSV columns: x,y,z (sample centre, m), fx,fy,fz (N), tx,ty,tz (N m), optional "
            "orientation (integer id) and repetition (integer id)."
        ),
    )
    p.add_argument("data", metavar="DATA.csv", help="force/torque CSV file")
    p.add_argument(
        "--magnet", required=True, metavar="DIAMETER,LENGTH,REMANENCE",
        help="reference cylinder magnet: diameter (m), length (m), remanence (T), e.g. 0.1016,0.1016,1.48",
    )
    p.add_argument("--magnet-position", default="0,0,0", metavar="X,Y,Z", help="magnet centre, m (default 0,0,0)")
    p.add_argument(
        "--magnet-axis", default="1,0,0", metavar="AX,AY,AZ",
        help="magnetisation axis of the magnet (default 1,0,0: orthogonal to the z scan line, as in seed 001)",
    )
    p.add_argument(
        "--field-model", choices=("multipole", "exact"), default="multipole",
        help="cylinder field model (default multipole, seed 001 eqs 3-4)",
    )
    p.add_argument("--order", type=int, default=17, help="highest multipole order n (default 17, seed 001)")
    p.add_argument(
        "--orientations", metavar="ID:AXIS:DEG[,...]",
        help="rotation (sample frame -> global) of each orientation id other than 0, e.g. 1:y:90 (seed 001 eq 10)",
    )
    p.add_argument("--torque-only", action="store_true", help="fit torques only (needs two orientations)")
    p.add_argument("--volume", type=float, metavar="V", help="sample volume, m^3: reports |m|/V and Br = mu0 |m|/V")
    p.add_argument(
        "--force-noise", type=float, metavar="N",
        help="std of one force reading, N (default 1/320 N: assumed ATI Nano17 resolution)",
    )
    p.add_argument(
        "--torque-noise", type=float, metavar="NM",
        help="std of one torque reading, N m (default 1/64 N mm: assumed ATI Nano17 resolution)",
    )
    p.add_argument(
        "--zero-quiet-axes", type=float, nargs="?", const=1.0 / 3.0, metavar="FRACTION",
        help="seed 001 filter 1: zero axes whose mean change between consecutive positions is < FRACTION "
        "(default 1/3) of the largest",
    )
    p.add_argument(
        "--drop-noisy-points", type=float, nargs="?", const=1.0 / 3.0, metavar="RATIO",
        help="seed 001 filter 2: drop points whose std over repetitions exceeds RATIO (default 1/3) of the mean",
    )
    p.add_argument("--paper-filters", action="store_true", help="both seed 001 filters with their 1/3 thresholds")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--out", metavar="DIR", help="write fit_magnetization.png and fit_magnetization.json here")
    p.set_defaults(func=run_fit_magnetization)


def run_fit_magnetization(args) -> int:
    import numpy as np

    from magsoro.characterization.magnetization import (
        NANO17_FORCE_RESOLUTION,
        NANO17_TORQUE_RESOLUTION,
        fit_magnetization,
        parse_orientations,
        read_force_torque_csv,
    )
    from magsoro.fields.cylinder import CylinderMagnet

    diameter, length, remanence = _floats(args.magnet, 3, "--magnet")
    if not (diameter > 0 and length > 0):
        raise MagsoroError(f"--magnet: diameter and length must be > 0 m, got {args.magnet!r}")
    position = _floats(args.magnet_position, 3, "--magnet-position")
    axis = _floats(args.magnet_axis, 3, "--magnet-axis")
    if not np.linalg.norm(axis) > 0:
        raise MagsoroError("--magnet-axis: must be a non-zero vector")
    if not 1 <= args.order <= 17:
        raise MagsoroError(f"--order: must be in 1..17, got {args.order}")
    if args.volume is not None and not args.volume > 0:
        raise MagsoroError(f"--volume: must be > 0 m^3, got {args.volume}")
    force_noise = NANO17_FORCE_RESOLUTION if args.force_noise is None else args.force_noise
    torque_noise = NANO17_TORQUE_RESOLUTION if args.torque_noise is None else args.torque_noise
    if not (force_noise > 0 and torque_noise > 0):
        raise MagsoroError("--force-noise and --torque-noise must be > 0")
    orientations = parse_orientations(args.orientations)
    zero_fraction = args.zero_quiet_axes
    std_ratio = args.drop_noisy_points
    if args.paper_filters:
        zero_fraction = 1.0 / 3.0 if zero_fraction is None else zero_fraction
        std_ratio = 1.0 / 3.0 if std_ratio is None else std_ratio
    magnet = CylinderMagnet(
        diameter, length, remanence, position=position, axis=axis, model=args.field_model, order=args.order
    )
    data = read_force_torque_csv(args.data, require_force=not args.torque_only)
    fit = fit_magnetization(
        data,
        magnet,
        orientations,
        torque_only=args.torque_only,
        volume=args.volume,
        force_noise=force_noise,
        torque_noise=torque_noise,
        zero_quiet_fraction=zero_fraction,
        max_relative_std=std_ratio,
    )
    result = fit.to_json()
    written = []
    if args.out:
        from magsoro.characterization.plotting import plot_force_torque_fit

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        written.append(plot_force_torque_fit(fit, out / "fit_magnetization.png", position, Path(args.data).name))
        (out / "fit_magnetization.json").write_text(json.dumps(result, indent=2) + "\n")
        written.append(out / "fit_magnetization.json")
    if args.json:
        print(json.dumps(result, indent=2))
        return 0

    d = fit.data
    field = f"multipole field to n = {args.order}" if args.field_model == "multipole" else "exact field"
    print(
        f"fit-magnetization: {len(d.position)} averaged points ({len(set(d.orientation.tolist()))} orientation(s), "
        f"up to {int(d.count.max())} repetition(s)); fitted {fit.n_force} force and {fit.n_torque} torque components"
    )
    print(
        f"reference magnet: cylinder D = {diameter * 1e3:g} mm, L = {length * 1e3:g} mm, Br = {remanence:g} T, "
        f"centre {tuple(position)} m, axis {tuple(axis)}, {field}"
    )
    std = np.sqrt(np.diag(fit.moment_cov))
    print(
        "moment (sample frame): m = ("
        + ", ".join(f"{v:.5g} +- {s:.2g}" for v, s in zip(fit.moment, std))
        + ") A m^2"
    )
    print(
        f"|m| = {fit.moment_norm:.5g} +- {fit.moment_norm_std:.2g} A m^2, direction ("
        + ", ".join(f"{v:.4f}" for v in fit.direction)
        + f") +- {fit.direction_std_deg:.2g} deg"
    )
    if fit.volume is not None:
        print(f"magnetisation |m|/V = {fit.magnetization:.5g} +- {fit.magnetization_std:.2g} A/m")
        print(f"remanence Br = mu0 |m|/V = {fit.remanence:.4f} +- {fit.remanence_std:.4f} T")
    rms = f"torque {fit.rms_torque * 1e6:.3g} uN m" + (
        f", force {fit.rms_force * 1e3:.3g} mN" if fit.rms_force is not None else ""
    )
    print(f"MAPE model vs data (driven components): {fit.mape:.2f} %; residual RMS: {rms}")
    for path in written:
        print(f"wrote {path}")
    return 0
