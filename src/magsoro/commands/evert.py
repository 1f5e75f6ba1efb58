"""``magsoro evert``: eversion mechanics of a magnetoelastic growing robot (seed 004 eqs 1-13, docs/actuation.md)."""

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "evert",
        help="pressure and tip force of an everting magnetoelastic tube; minimum field for pressure-free growth",
        description=(
            "Internal pressure P (eq 10) and tip force N (eqs 11-13) of an everting Neo-Hookean magnetoelastic "
            "tube described by DESIGN.toml, plotted against the everted inner radius for several axial fields "
            "(as seed 004 Fig. 2), and the smallest field for pressure-free growth at the design's operating "
            "point. Writes DIR/eversion.csv, DIR/eversion.png and DIR/summary.json. See docs/actuation.md."
        ),
    )
    p.add_argument("design", metavar="DESIGN.toml", help="eversion design (TOML)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: out/<DESIGN stem>)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=run_evert)


def run_evert(args) -> int:
    import json

    from magsoro.actuation.config import ActuationInputError, EversionDesign, load
    from magsoro.actuation.eversion import write_report

    design = load(EversionDesign, args.design)
    out = Path(args.out) if args.out else Path("out") / Path(args.design).stem
    try:
        summary = write_report(design, out)
    except ValueError as exc:
        raise ActuationInputError(f"{args.design}: {exc}") from None
    if args.json:
        print(json.dumps(summary))
        return 0
    b_min = summary["minimum_growth_field_T"]
    print(f"pressure-free radius a0     : {1e3 * summary['pressure_free_radius_m']:.6g} mm")
    print(f"operating radius            : {1e3 * summary['operating_radius_m']:.6g} mm "
          f"(contact pressure {summary['contact_pressure_Pa']:.6g} Pa)")
    print(f"tip force at zero field     : {1e3 * summary['pressure_free_tip_force_at_zero_field_N']:.6g} mN")
    if b_min is None:
        print(f"minimum growth field        : none up to {1e3 * summary['max_field_searched_T']:g} mT")
    else:
        print(f"minimum growth field        : {1e3 * b_min:.6g} mT (lambda_z = {summary['axial_stretch']:g})")
    b0 = summary["minimum_growth_field_without_friction_T"]
    print("  without friction          : " + (f"{1e3 * b0:.6g} mT" if b0 is not None else
                                              f"none up to {1e3 * summary['max_field_searched_T']:g} mT"))
    if summary["remanence_T"] > 0:
        print(f"tail remanence (flip term)  : {summary['remanence_T']:.6g} T, "
              f"{summary['flip_force_per_tesla_N_per_T']:.6g} mN per mT against it (N/T)")
    for front, what in (("full", "pi a^2"), ("gap", "pi (a^2 - B^2)")):
        P = summary[f"growth_pressure_{front}_front_Pa"]
        print("growth pressure, no field   : " + (f"{P:.6g} Pa" if P is not None else "none below the inflation limit")
              + f" (front area {what})")
    if "implied_friction_coefficient" in summary:
        mu = summary["implied_friction_coefficient"]
        print("friction for measured field : " + (f"mu_k = {mu:.4g} at {1e3 * summary['measured_growth_field_T']:g} mT"
              if mu is not None else f"none makes {1e3 * summary['measured_growth_field_T']:g} mT the threshold"))
    print(f"wrote {out / 'eversion.csv'}, {out / 'eversion.png'}, {out / 'summary.json'}")
    return 0
