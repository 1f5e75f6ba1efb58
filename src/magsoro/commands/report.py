"""``magsoro report RUN_OR_SWEEP_DIR [--out report.html]``: one self-contained HTML page of a run or a sweep."""

import sys

from magsoro.errors import MagsoroError


def register(sub):
    p = sub.add_parser(
        "report",
        help="write a self-contained HTML report of a run or a sweep",
        description="Write one HTML page (inline data, JS and CSS; opens offline from a file:// URL): parameters, "
        "interactive probe curves, for a sweep the final probe values against each parameter and the run table, "
        "for a run a 3D particle viewer with a time slider.",
    )
    p.add_argument("directory", help="a run directory (run.json) or a sweep directory (sweep.json)")
    p.add_argument("--out", help="output HTML file (default: DIRECTORY/report.html)")
    p.add_argument("--max-frames", type=int, default=None, metavar="N", help="particle frames in the viewer (default 60, spread over the run)")
    p.add_argument("--max-particles", type=int, default=None, metavar="N", help="particles shown in the viewer (default 4000, a fixed random subset)")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.viz.report import MAX_FRAMES, MAX_PARTICLES, build_report

    for flag, value in (("--max-frames", args.max_frames), ("--max-particles", args.max_particles)):
        if value is not None and value < 1:
            raise MagsoroError(f"{flag}: must be >= 1, got {value}")
    out = build_report(
        args.directory, args.out,
        max_frames=args.max_frames or MAX_FRAMES, max_particles=args.max_particles or MAX_PARTICLES,
    )
    from pathlib import Path

    from magsoro.io.outdir import read_run_info, run_state

    info = read_run_info(Path(args.directory))
    if info is not None:
        state, why = run_state(info)
        if state in ("stale", "running"):
            print(f"magsoro report: note: the run is {state}: {why}", file=sys.stderr)
    print(f"report written to {out} ({out.stat().st_size / 1e6:.2f} MB); open file://{out.resolve()}")
    return 0
