"""``magsoro run SCENE.toml --out DIR``: run a scene and write its results."""

import math
import sys
import time

from magsoro.errors import SceneError


def register(sub):
    p = sub.add_parser("run", help="run a scene file and write results", description="Run a scene and write run.json, metrics.csv, a ParaView particle series and final.npz.")
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("--out", required=True, help="output directory: new, empty, or a previous run with --overwrite")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the previous run in --out (all of it: frames, report, everything)")
    p.add_argument("--device", choices=None, help="cpu, cuda or cuda:N (overrides simulation.device)")
    p.add_argument("--duration", type=float, help="simulated time in s (overrides simulation.duration)")
    p.add_argument("--preview", action="store_true",
                   help="use the scene's [preview] settings (coarser grid, shorter run) for a quick look")
    p.add_argument("--equilibrium", action="store_true",
                   help="instead of the motion, find the static equilibrium under the loads at the end of the scene "
                        "(fields and collider paths at t = duration) by dynamic relaxation with kinetic damping; "
                        "writes the initial and the relaxed state")
    p.add_argument("--static", action="store_true",
                   help="instead of the motion, solve the static equilibria by Newton's method (float64, total-Lagrangian "
                        "form) under the loads at t = duration, the fields scaled by each of [static] levels; writes one "
                        "metrics row and frame per level (first column 'level'); or, with [static] times, the equilibria along the "
                        "scene's paths at those times (first column 'time'); rigid colliders, no contact between bodies yet")
    p.add_argument("--quiet", action="store_true", help="no progress bar, and no Warp start-up banner or kernel-load lines")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.io.outdir import prepare_output_dir
    from magsoro.io.recorder import RunWriter
    from magsoro.scene import load_scene
    from magsoro.scene.load import read_scene_toml
    from magsoro.simulation import Simulation, check_run_length

    if args.quiet:
        from magsoro.warp_setup import quiet_warp

        quiet_warp()  # before Warp starts: its banner and per-module load lines go to stdout
    if args.device is not None and not (args.device == "cpu" or args.device.startswith("cuda")):
        raise SceneError(f"--device: '{args.device}' is not allowed; use cpu, cuda or cuda:N")
    if args.duration is not None and not (args.duration > 0 and math.isfinite(args.duration)):
        raise SceneError(f"--duration: must be a finite number > 0 s, got {args.duration}")
    wall0 = time.perf_counter()
    preview = getattr(args, "preview", False)
    scene = load_scene(args.scene, preview=preview)  # every check happens before the output folder is touched
    static = getattr(args, "static", False)
    if static:
        if getattr(args, "equilibrium", False):
            raise SceneError("--static and --equilibrium: give one of them")
        if scene.simulation.formulation == "updated":
            raise SceneError(f"{args.scene}: simulation.formulation: --static solves the total-Lagrangian form; set it to 'auto' or 'total'")
        scene.simulation.precision = "float64"
        scene.simulation.formulation = "total"
    sim = Simulation(scene, device=args.device, source=args.scene)
    if static:
        from magsoro.errors import SimulationError
        from magsoro.mpm.static import check_supported

        try:
            check_supported(sim)
        except SimulationError as exc:
            raise SceneError(f"{args.scene}: --static: {exc}") from None
    if sim.integrator == "implicit" and not static and not getattr(args, "equilibrium", False):
        from magsoro.errors import SimulationError
        from magsoro.mpm.implicit import check_implicit_supported

        try:
            check_implicit_supported(sim)
        except SimulationError as exc:
            raise SceneError(f"{args.scene}: {exc}") from None
    echo = read_scene_toml(args.scene)
    if preview:
        from magsoro.scene.load import apply_preview

        echo = apply_preview(echo, args.scene)
    duration = args.duration if args.duration is not None else scene.simulation.duration
    check_run_length(duration, scene.output.every)  # before the output folder is touched
    prepare_output_dir(args.out, overwrite=getattr(args, "overwrite", False))
    writer = RunWriter(args.out, sim, echo, particles=scene.output.particles)
    if getattr(args, "equilibrium", False):
        return _relax(args, sim, writer, duration, wall0)
    if static:
        return _static(args, sim, writer, wall0)
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=duration, unit="s sim", file=sys.stderr, bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}{postfix}]")
    last = [time.perf_counter(), 0]

    def progress(s):
        if bar is not None:
            now = time.perf_counter()
            rate = (s.steps - last[1]) / max(now - last[0], 1e-9)
            last[0], last[1] = now, s.steps
            bar.n = min(s.time, duration)
            if s.integrator == "implicit":
                bar.set_postfix_str(f"dt={s.dt:.3g} s, {getattr(s, 'last_newton_iterations', 0)} Newton its")
            else:
                bar.set_postfix_str(f"{rate:.0f} steps/s, dt={s.dt:.3g} s")
            bar.refresh()

    try:
        result = sim.run(duration, heartbeat=writer.beat, record=writer.record, record_every=scene.output.every,
                         progress=progress)
    except Exception as exc:  # a fault of ours: run.json says 'failed' with it, then the traceback for the report
        from magsoro.simulation import RunResult

        writer.finish(RunResult("failed", sim.steps, sim.time, time.perf_counter() - wall0,
                                f"internal error: {type(exc).__name__}: {exc}"), time.perf_counter() - wall0)
        raise
    finally:
        if bar is not None:
            bar.close()
    writer.finish(result, time.perf_counter() - wall0)
    _print_notes(sim, "magsoro run")
    if result.status != "completed":
        print(f"magsoro run: {result.status}: {result.message}", file=sys.stderr)
        print(f"results so far in {args.out} (run.json status '{result.status}')", file=sys.stderr)
        return 1 if result.status == "failed" else _interrupted_status(result.signal)
    if not args.quiet:
        print(f"{result.steps} steps in {result.wall_time:.1f} s ({result.steps / max(result.wall_time, 1e-9):.0f} steps/s), dt {sim.dt_min:.3g}-{sim.dt_max:.3g} s; results in {args.out}")
    return 0


def _relax(args, sim, writer, t_loads: float, wall0: float) -> int:
    """``--equilibrium``: relax under the loads at ``t_loads`` and write the start and the relaxed state."""
    from dataclasses import asdict

    from magsoro.errors import OutputError, SimulationError
    from magsoro.simulation import RunResult

    writer.record(sim)
    sim.state.time = t_loads
    if not args.quiet:
        print(f"relaxing under the loads at t = {t_loads:.6g} s ...", file=sys.stderr)
    signum = None
    try:
        relax = sim.relax(callback=writer.beat)
        # at the round-off floor the state is as static as the precision allows: a result, with the reason
        status = "completed" if relax.converged or relax.stalled else "failed"
        message = relax.message
        steps, wall = relax.steps, relax.wall_time
    except SimulationError as exc:
        relax, status = None, "failed"
        message = f"step {exc.step}: {exc}"
        steps, wall = sim.steps, time.perf_counter() - wall0
    except KeyboardInterrupt as exc:
        relax, status, message = None, "interrupted", str(exc) or "interrupted by the user"
        signum = getattr(exc, "signum", None)  # Terminated carries its signal
        steps, wall = sim.steps, time.perf_counter() - wall0
    if relax is not None:
        writer.info["equilibrium"] = asdict(relax)
        sim.check_wall_reach()
        try:
            writer.record(sim)
        except OutputError as exc:
            status, message = "failed", f"{message}; the relaxed state could not be recorded: {exc}"
    result = RunResult(status, steps, sim.time, wall, message, signum)
    writer.finish(result, time.perf_counter() - wall0)
    _print_notes(sim, "magsoro run --equilibrium")
    if status != "completed":
        print(f"magsoro run --equilibrium: {status}: {message}", file=sys.stderr)
        return 1 if status == "failed" else _interrupted_status(signum)
    if not args.quiet:
        print(f"{message} in {wall:.1f} s; results in {args.out}")
    return 0


def _static(args, sim, writer, wall0: float) -> int:
    """``--static``: the unloaded state (level 0), then the equilibrium at each level of [static] levels; or the
    equilibrium at each of [static] times along the scene's paths."""
    from dataclasses import asdict

    from magsoro.errors import SimulationError
    from magsoro.simulation import RunResult

    along_paths = sim.scene.static.times is not None
    if along_paths:  # [static] times: one row per time along the paths (first column the time)
        on_level = lambda s, lev: writer.record(s, stamp=lev.time)  # noqa: E731
    else:
        writer.columns[0] = "level"
        sim.field_scale = 0.0  # the unloaded row: field probes read no applied field
        writer.record(sim, stamp=0.0)
        on_level = lambda s, lev: writer.record(s, stamp=lev.level)  # noqa: E731
    try:
        res = sim.solve_static(on_level=on_level)
        status, message, wall = ("completed" if res.converged else "failed"), res.message, res.wall_time
        writer.info["static"] = {"converged": res.converged, "levels": [asdict(r) for r in res.levels],
                                 "residual_evaluations": res.residual_evaluations, "wall_time": res.wall_time,
                                 "t_loads": sim.time, "times": sim.scene.static.times}
    except SimulationError as exc:
        status, message, wall = "failed", str(exc), time.perf_counter() - wall0
    except KeyboardInterrupt as exc:
        writer.finish(RunResult("interrupted", 0, sim.time, time.perf_counter() - wall0, str(exc) or "interrupted by the user",
                                getattr(exc, "signum", None)), time.perf_counter() - wall0)
        return _interrupted_status(getattr(exc, "signum", None))
    writer.finish(RunResult(status, 0, sim.time, wall, message), time.perf_counter() - wall0)
    _print_notes(sim, "magsoro run --static")
    if status != "completed":
        print(f"magsoro run --static: failed: {message}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(f"{message} in {wall:.1f} s; results in {args.out}")
        turns = [f"{t:.4g}" for r in res.levels for t in r.limit_levels]
        if turns:
            print(f"the equilibrium path turned back (limit points, a snap-through at the first) at field level(s) "
                  f"{', '.join(turns)}: run.json static.levels[].limit_levels")
    return 0


def _print_notes(sim, prefix: str) -> None:
    """The run's notes on what the scene may not mean (a body in the domain walls' reach, a body the particle
    lattice rounds), one stderr line each; run.json's ``notes`` holds them with the others."""
    for note in sim.scene_notes:
        print(f"{prefix}: note: {note}", file=sys.stderr)


def _interrupted_status(signum: int | None) -> int:
    """Exit status of an interrupted run: 128 + the signal that stopped it (143 after SIGTERM), 130 (128 + SIGINT)
    after Ctrl-C."""
    return 128 + signum if signum is not None else 130
