"""``magsoro reproduce`` and the ``scenes/<name>/reproduce.py`` scripts: run robots of the library and write
the curve the paper plots (CSV, PNG with the paper's values), an animation and the acceptance checks."""

from __future__ import annotations

import argparse
import json
import sys
import time


def add_arguments(p: argparse.ArgumentParser, names: bool = True) -> None:
    if names:
        p.add_argument("names", nargs="*", metavar="NAME", help="robot names (see --list)")
        p.add_argument("--list", action="store_true", help="list the robots and exit")
        p.add_argument("--all", action="store_true", help="reproduce every robot")
    p.add_argument("--preview", action="store_true",
                   help="coarse and short runs (the scenes' [preview] tables): a quick look, not the paper's curve")
    p.add_argument("--out", metavar="DIR",
                   help="output folder (default runs/reproduce/NAME[-preview]; with several robots: DIR/NAME)")
    p.add_argument("--device", help="cpu, cuda or cuda:N (default: the scene's)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="processes a robot's independent simulations (speeds, resolutions) run in at once "
                        "(default: one per usable core on the CPU, 1 on CUDA)")
    p.add_argument("--json", action="store_true", help="print the results (files, summary, checks) as JSON")


def run_reproduce(args) -> int:
    from pathlib import Path

    from magsoro.robots import ROBOTS, RobotError, get, reproduce

    if getattr(args, "list", False):
        for r in ROBOTS.values():
            print(f"{r.name:20s} {r.source:22s} {r.quantity}")
        return 0
    names = list(ROBOTS) if getattr(args, "all", False) else list(args.names)
    if not names:
        print("magsoro reproduce: error: name a robot (magsoro reproduce --list) or give --all", file=sys.stderr)
        return 2
    try:
        for n in names:
            get(n)
    except RobotError as exc:
        print(f"magsoro reproduce: error: {exc}", file=sys.stderr)
        return 2
    workers = getattr(args, "workers", None)
    if workers is not None and workers < 1:
        print(f"magsoro reproduce: error: --workers {workers}: give a whole number of processes, 1 or more",
              file=sys.stderr)
        return 2
    if workers is None:
        from magsoro.mpm.runtime import usable_cores

        workers = 1 if (args.device or "cpu").startswith("cuda") else usable_cores()
    from magsoro.console import configure_warp

    configure_warp()  # Warp's banner and module-load lines off stdout (--json prints there), as in magsoro run
    results, ok = [], True
    for n in names:
        out = None
        if args.out:
            out = Path(args.out) / n if len(names) > 1 else Path(args.out)
        t0 = time.perf_counter()
        res = reproduce(n, out=out, preview=args.preview, device=args.device, workers=workers)
        wall = time.perf_counter() - t0
        ok &= res.passed
        results.append((res, wall))
        if not args.json:
            print(f"{n}: {res.summary}")
            for row in res.rows:
                mark = "pass" if row.passed else "FAIL"
                print(f"  {row.quantity}: {row.value:.4g} (reference {row.reference:.4g}, error {row.error:.3g}, "
                      f"tolerance {row.tolerance:.3g}) {mark}")
            files = [res.csv, res.png] + ([res.animation] if res.animation else [])
            print(f"  files: {', '.join(str(f) for f in files)}  ({wall:.0f} s)")
    if args.json:
        print(json.dumps([{
            "name": res.name, "summary": res.summary, "wall_s": round(wall, 1), "preview": bool(args.preview),
            "csv": str(res.csv), "png": str(res.png), "animation": str(res.animation) if res.animation else None,
            "info": res.info, "checks": [r.as_dict() for r in res.rows], "passed": res.passed,
        } for res, wall in results], indent=1))
    return 0 if ok else 1


def main(argv=None) -> int:
    """Entry point of ``scenes/<name>/reproduce.py``: ``main([name, *sys.argv[1:]])``."""
    from magsoro.errors import MagsoroError

    argv = list(sys.argv[1:] if argv is None else argv)
    name, rest = argv[0], argv[1:]
    p = argparse.ArgumentParser(prog=f"python scenes/{name}/reproduce.py",
                                description=f"Reproduce the {name} robot's curve (see docs/robots.md).")
    add_arguments(p, names=False)
    args = p.parse_args(rest)
    args.names, args.list, args.all = [name], False, False
    try:
        return run_reproduce(args)
    except MagsoroError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
