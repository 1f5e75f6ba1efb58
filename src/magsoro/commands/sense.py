"""``magsoro sense``: robot centreline from Hall-sensor readings of magnetic markers (seed 004 eqs 17-23)."""

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "sense",
        help="reconstruct the robot centreline from Hall-sensor readings of magnetic markers",
        description=(
            "Read a stream of sensor readings (CSV: a time column and one H_z column per station, in tesla), "
            "invert the marker dipole model of seed 004 (eqs 18-22) for each station's bend angle and chain "
            "constant-curvature segments (eq 23). Writes DIR/centreline.csv (t, s, x, y, z in s and m), "
            "DIR/angles.csv, DIR/centreline.png and DIR/summary.json; with --truth, the RMSE against a "
            "ground-truth centreline CSV of the same format. See docs/actuation.md."
        ),
    )
    p.add_argument("readings", metavar="READINGS.csv", help="sensor readings (CSV with header)")
    p.add_argument("--calib", metavar="CALIB.toml", required=True, help="station calibration (TOML)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: out/<READINGS stem>)")
    p.add_argument("--truth", metavar="TRUTH.csv", help="ground-truth centrelines (t, s, x, y, z) for the RMSE")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=run_sense)


def run_sense(args) -> int:
    import json

    from magsoro.actuation.config import SensingCalibration, load
    from magsoro.actuation.sensing import sense

    calib = load(SensingCalibration, args.calib)
    out = Path(args.out) if args.out else Path("out") / Path(args.readings).stem
    summary = sense(args.readings, calib, out, args.truth)
    if args.json:
        print(json.dumps(summary))
        return 0
    lo, hi = summary["bend_angle_range_rad"]
    print(f"{summary['samples']} samples, {len(summary['stations'])} stations, robot length "
          f"{1e3 * summary['robot_length_m']:.6g} mm, bend angles {lo:.4g} .. {hi:.4g} rad ({summary['inverse']} inverse)")
    if "rmse_m" in summary:
        print(f"RMSE against {summary['truth']}: {1e3 * summary['rmse_m']:.4g} mm "
              f"(tip RMSE {1e3 * summary['tip_rmse_m']:.4g} mm, largest tip error {1e3 * summary['tip_max_error_m']:.4g} mm, "
              f"{summary['matched_samples']} samples)")
    elif args.truth:
        print(f"no sample time of {args.truth} matches the readings")
    print(f"wrote {', '.join(str(out / f) for f in summary['files'])}")
    return 0
