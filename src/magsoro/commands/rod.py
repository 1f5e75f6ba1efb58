"""``magsoro rod``: static equilibrium of a magnetic Cosserat rod clamped at one end (docs/rod.md)."""

from __future__ import annotations

import json
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "rod",
        help="static Cosserat-rod equilibrium of a clamped magnetic rod",
        description=(
            "Solve the static Cosserat rod (seed 003 eqs 1-5) described by ROD.toml under a uniform field, write "
            "DIR/centreline.csv (s, x, y, z in m and the unit tangent tx, ty, tz) and DIR/centreline.png, and "
            "print the tip position. See docs/rod.md for the file format."
        ),
    )
    p.add_argument("scene", metavar="ROD.toml", help="rod description (TOML)")
    p.add_argument("--field", nargs=3, type=float, metavar=("BX", "BY", "BZ"),
                   help="uniform applied field in tesla (overrides `field` in the file)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: out/<ROD stem>)")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.set_defaults(func=run_rod)


def run_rod(args) -> int:
    import numpy as np

    from magsoro.rod.config import load_rod_config
    from magsoro.rod.output import plot_centreline, write_centreline_csv

    config = load_rod_config(args.scene)
    field = np.array(args.field if args.field is not None else config.field, dtype=np.float64)
    rod = config.build()
    solution = rod.solve(field, perturbation=config.perturbation)
    out = Path(args.out) if args.out else Path("out") / Path(args.scene).stem
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_centreline_csv(solution, out / "centreline.csv")
    png_path = plot_centreline(solution, out / "centreline.png", title=f"{Path(args.scene).name}: "
                               f"B = [{', '.join(f'{1e3 * b:.4g}' for b in field)}] mT")
    tip = solution.tip_position
    if args.json:
        print(json.dumps({
            "scene": str(args.scene),
            "field_T": field.tolist(),
            "tip_position_m": tip.tolist(),
            "tip_tangent": solution.tangents[-1].tolist(),
            "clamp_force_N": solution.clamp_force.tolist(),
            "clamp_moment_Nm": solution.clamp_moment.tolist(),
            "residual": solution.residual,
            "files": [str(csv_path), str(png_path)],
        }))
    else:
        print(f"tip position: x = {tip[0]:.6e} m, y = {tip[1]:.6e} m, z = {tip[2]:.6e} m")
        print(f"wrote {csv_path} and {png_path}")
    return 0
