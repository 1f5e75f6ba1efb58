"""``magsoro sweep SCENE.toml --param KEY=VALUES [...] --out DIR``: run a parameter sweep on dask.distributed."""

import sys
import time

from magsoro.errors import MagsoroError

EPILOG = """\
VALUES: a:b:n (n points from a to b) or a comma list of numbers, words or JSON values such as [0,0.01,0].
Several --param make a cartesian product; --zip pairs the i-th values instead.
KEY: dotted scene path; list entries by name or index, e.g. bodies.beam.material.shear_modulus, fields.0.B.
See docs/sweeps.md."""


def register(sub):
    import argparse

    p = sub.add_parser(
        "sweep",
        help="run a parameter sweep of a scene on dask.distributed",
        description="Run a scene once per parameter combination (a LocalCluster by default) and collect "
        "DIR/summary.csv and DIR/summary.parquet: parameters, status, error, wall time, final probe values.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUES", help="a swept scene key and its values (repeatable)")
    p.add_argument("--zip", action="store_true", help="pair the i-th values of every --param instead of taking all combinations")
    p.add_argument("--out", required=True, help="sweep directory (runs/, summary.csv, summary.parquet, sweep.json)")
    p.add_argument("--scheduler", metavar="HOST:PORT", help="connect to a running dask.distributed scheduler instead of starting a LocalCluster")
    p.add_argument("--workers", type=int, metavar="N", help="LocalCluster worker processes (default: one per core, or one per GPU with --device cuda); 0 runs them in this process without Dask")
    p.add_argument("--resume", action="store_true", help="continue a sweep in --out: skip runs whose run.json says completed or failed")
    p.add_argument("--device", help="cpu, cuda or cuda:N for every run (overrides simulation.device); 'cuda' gives worker k GPU k")
    p.add_argument("--no-particles", action="store_true", help="do not write the particle series of each run (saves disk)")
    p.add_argument("--dry-run", action="store_true", help="validate and list the runs, run nothing")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--allow-large", action="store_true",
                   help="plan more than 1,000 runs (up to 100,000), and let runs estimated to need more than 90 %% of "
                        "the available memory or more than 1e8 time steps go ahead (without it they fail at once, "
                        "naming the key)")
    p.set_defaults(func=run)


def _clock(epoch: float) -> str:
    return time.strftime("%H:%M:%S", time.localtime(epoch))


def run(args) -> int:
    from magsoro.sweep import make_plan, run_sweep
    from magsoro.sweep.params import format_value

    if args.workers is not None and args.workers < 0:
        raise MagsoroError(f"--workers: must be >= 0, got {args.workers}")
    if args.workers is not None and args.scheduler:
        raise MagsoroError("--workers sets the size of a LocalCluster; with --scheduler the cluster's own workers run the sweep")
    if args.device is not None and not (args.device == "cpu" or args.device.startswith("cuda")):
        raise MagsoroError(f"--device: '{args.device}' is not allowed; use cpu, cuda or cuda:N")
    allow_large = getattr(args, "allow_large", False)
    plan = make_plan(args.scene, args.param, zipped=args.zip, allow_large=allow_large)  # every scene validated first
    if args.dry_run:
        for r in plan.runs:
            print(f"{r.name}: " + ", ".join(f"{k}={format_value(v)}" for k, v in r.params.items()))
        print(f"{len(plan.runs)} runs; all scenes valid")
        return 0

    def progress(state):
        if args.quiet:
            return
        rec = state.last
        eta = state.eta
        when = f", finish ~{_clock(eta)} (in {max(0.0, eta - time.time()):.0f} s)" if eta is not None and state.done < state.total else ""
        tail = f": {rec['error']}" if rec["status"] == "failed" else ""
        print(f"[{state.done}/{state.total} done, {state.failed} failed{when}] {rec['run']} {rec['status']}{tail}", file=sys.stderr, flush=True)

    from magsoro.sweep.extra import parquet_note, require_distributed

    if args.workers != 0 or args.scheduler:
        require_distributed()  # the cluster needs the sweep extra: one line naming it, before anything runs
    if not args.quiet and parquet_note():
        print(f"magsoro sweep: note: {parquet_note()}", file=sys.stderr)
    if not args.quiet:
        where = (f"scheduler {args.scheduler}" if args.scheduler else "this process (--workers 0)" if args.workers == 0
                 else (f"a LocalCluster ({args.workers} worker{'s' if args.workers != 1 else ''})" if args.workers
                  else "a LocalCluster (one worker per core)"))
        print(f"magsoro sweep: {len(plan.runs)} runs on {where}; results in {args.out}", file=sys.stderr, flush=True)
    try:
        result = run_sweep(
            plan, args.out, scheduler=args.scheduler, workers=args.workers, resume=args.resume, device=args.device,
            particles=False if args.no_particles else None, progress=progress, allow_large=allow_large,
        )
    except KeyboardInterrupt as exc:
        print(f"magsoro sweep: interrupted; finished runs are kept, continue with --resume --out {args.out}", file=sys.stderr)
        return 128 + getattr(exc, "signum", 2)  # 143 after SIGTERM (a Terminated), 130 after Ctrl-C
    n_failed = len(result.failed)
    unfinished = len(result.records) - len(result.completed) - n_failed
    rest = f", {unfinished} not finished (run again with --resume)" if unfinished else ""
    print(f"{len(result.completed)} completed, {n_failed} failed{rest} of {len(result.records)} runs in {result.wall_time:.1f} s; summary in {result.out_dir / 'summary.csv'}")
    return 1 if n_failed or unfinished else 0
