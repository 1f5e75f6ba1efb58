"""``magsoro converge SCENE.toml --dx A,B,C --out DIR``: run a scene at several grid spacings and estimate its
grid-independent results (Richardson extrapolation)."""

from magsoro.convergence.study import FEATURES


def register(sub):
    import argparse

    p = sub.add_parser(
        "converge",
        help="run a scene at several grid spacings and estimate its converged results",
        description="Run the scene once per grid spacing (each a complete magsoro run in DIR/dx_1 ... dx_N, coarsest "
                    "first), tabulate its probe values and estimate from the finest three the grid-independent value, "
                    "the order of convergence and the uncertainty of the finest result (Richardson extrapolation). "
                    "Writes DIR/converge.csv, converge.json and converge.png.",
        epilog="The runs are dynamic or implicit as the scene's simulation.integrator says, or static with --static. "
               "See docs/how-to/convergence.md.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("--dx", required=True, metavar="A,B,C", help="grid spacings in m, comma-separated (two or more; "
                   "three or more to measure the order), e.g. 4e-4,2.67e-4,2e-4")
    p.add_argument("--out", required=True, help="study folder: new or empty (or an earlier study with --resume)")
    p.add_argument("--probe", action="append", default=[], metavar="NAME",
                   help="a probe (all its columns) or a metrics column (e.g. tip_y) to follow (repeatable); default: "
                        "every probe column")
    p.add_argument("--feature", choices=FEATURES, default="final",
                   help="which value of each column: the last (default; with --static the last level or time), or "
                        "the largest, smallest or largest in magnitude over the run")
    p.add_argument("--static", action="store_true", help="solve the static equilibria (as magsoro run --static)")
    p.add_argument("--order", type=float, metavar="P", help="assume this order of convergence instead of measuring "
                   "it (needed to extrapolate from two spacings)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="change a scene key in every run (repeatable), as magsoro run --set")
    p.add_argument("--duration", type=float, help="simulated time in s of every run (overrides simulation.duration)")
    p.add_argument("--preview", action="store_true", help="use the scene's [preview] settings other than dx")
    p.add_argument("--device", help="cpu, cuda or cuda:N (overrides simulation.device)")
    p.add_argument("--resume", action="store_true", help="continue a study in --out: reuse its completed runs")
    p.add_argument("--allow-large", action="store_true", help="as magsoro run --allow-large, for every run")
    p.add_argument("--quiet", action="store_true", help="print only the table and the estimates")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.convergence.study import study

    return study(args)
