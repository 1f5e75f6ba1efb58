"""``magsoro run SCENE.toml --out DIR``: run a scene and write its results."""

import contextlib
import math
import signal
import sys
import threading
import time

from magsoro.errors import SceneError


def register(sub):
    p = sub.add_parser("run", help="run a scene file and write results", description="Run a scene and write run.json, metrics.csv, a ParaView particle series and final.npz.")
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("--out", required=True, help="output directory: new, empty, or a previous run with --overwrite")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the previous run in --out: removes the files that run wrote (run.json's files: "
                        "results, frames, its report); a folder holding anything else is refused, naming it")
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
    p.add_argument("--allow-large", action="store_true",
                   help="run even when the scene is estimated to need more than 90 %% of the available memory, or more "
                        "than 1e8 time steps (without it such a run is refused before it starts, naming the key that "
                        "causes it)")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.io.outdir import prepare_output_dir
    from magsoro.io.recorder import RunWriter
    from magsoro.limits import check_memory, check_steps
    from magsoro.scene import load_scene
    from magsoro.scene.load import read_scene_toml
    from magsoro.simulation import Simulation, check_run_length, prepare_static

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
        try:
            prepare_static(scene)  # float64, total form: the rule Simulation.solve_static follows
        except SceneError as exc:
            raise SceneError(f"{args.scene}: {exc}") from None
    allow_large = getattr(args, "allow_large", False)
    check_memory(scene, args.scene, allow_large)  # before anything is allocated
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
    if not static and not getattr(args, "equilibrium", False):
        check_steps(sim, duration, args.scene, allow_large)
    prepare_output_dir(args.out, overwrite=getattr(args, "overwrite", False))
    writer = RunWriter(args.out, sim, echo, particles=scene.output.particles)
    shown = _print_notes(sim, "magsoro run")  # what the scene may not mean, before the run rather than after it
    if getattr(args, "equilibrium", False):
        return _relax(args, sim, writer, duration, wall0, shown)
    if static:
        return _static(args, sim, writer, wall0, shown)
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
    with _signals_deferred():  # run.json's status and the exit status must agree
        writer.finish(result, time.perf_counter() - wall0)
        _print_notes(sim, "magsoro run", shown)
        return _report_run(args, sim, result)


def _report_run(args, sim, result) -> int:
    """The closing lines of a dynamic run, and its exit status."""
    if result.status != "completed":
        print(f"magsoro run: {result.status}: {result.message}", file=sys.stderr)
        print(f"results so far in {args.out} (run.json status '{result.status}')", file=sys.stderr)
        return 1 if result.status == "failed" else _interrupted_status(result.signal)
    if not args.quiet:
        print(f"{result.steps} steps in {result.wall_time:.1f} s ({result.steps / max(result.wall_time, 1e-9):.0f} steps/s), dt {sim.dt_min:.3g}-{sim.dt_max:.3g} s; results in {args.out}")
    return 0


def _relax(args, sim, writer, t_loads: float, wall0: float, shown: int = 0) -> int:
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
    with _signals_deferred():
        writer.finish(result, time.perf_counter() - wall0)
        _print_notes(sim, "magsoro run --equilibrium", shown)
        return _report_relax(args, status, message, signum, wall)


def _report_relax(args, status: str, message: str, signum, wall: float) -> int:
    if status != "completed":
        print(f"magsoro run --equilibrium: {status}: {message}", file=sys.stderr)
        return 1 if status == "failed" else _interrupted_status(signum)
    if not args.quiet:
        print(f"{message} in {wall:.1f} s; results in {args.out}")
    return 0


def _static(args, sim, writer, wall0: float, shown: int = 0) -> int:
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
        with writer.beating():  # a level's Newton iterations can take minutes between records
            res = sim.solve_static(on_level=on_level)
        status, message, wall = ("completed" if res.converged else "failed"), res.message, res.wall_time
        writer.info["static"] = {"converged": res.converged, "levels": [asdict(r) for r in res.levels],
                                 "residual_evaluations": res.residual_evaluations, "wall_time": res.wall_time,
                                 "t_loads": sim.time, "times": sim.scene.static.times}
    except SimulationError as exc:
        status, message, wall = "failed", str(exc), time.perf_counter() - wall0
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", None)
        cfg = sim.scene.static
        done = len(writer.rows) - (0 if along_paths else 1)  # rows recorded: the unloaded one, then one per level
        total = len(cfg.times if along_paths else cfg.levels)
        message = f"{str(exc) or 'interrupted by the user'} after {max(done, 0)} of {total} {'time' if along_paths else 'level'}s"
        with _signals_deferred():
            writer.finish(RunResult("interrupted", 0, sim.time, time.perf_counter() - wall0, message, signum),
                          time.perf_counter() - wall0)
            _print_notes(sim, "magsoro run --static", shown)
            print(f"magsoro run --static: interrupted: {message}", file=sys.stderr)
            print(f"results so far in {args.out} (run.json status 'interrupted')", file=sys.stderr)
            return _interrupted_status(signum)
    with _signals_deferred():
        writer.finish(RunResult(status, 0, sim.time, wall, message), time.perf_counter() - wall0)
        _print_notes(sim, "magsoro run --static", shown)
        return _report_static(args, status, message, wall, res if status == "completed" else None)


def _report_static(args, status: str, message: str, wall: float, res) -> int:
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


def _print_notes(sim, prefix: str, shown: int = 0) -> int:
    """The run's notes on what the scene may not mean (a body in the domain walls' reach, a body the particle
    lattice rounds, a field or remanence out of the plausible range) from the ``shown``-th on, one stderr line
    each; returns how many there are. run.json's ``notes`` holds them with the others."""
    for note in sim.scene_notes[shown:]:
        print(f"{prefix}: note: {note}", file=sys.stderr)
    return len(sim.scene_notes)


@contextlib.contextmanager
def _signals_deferred():
    """While the closing run.json is written and the last lines printed, SIGTERM and Ctrl-C are held: one arriving
    then would leave run.json and the exit status disagreeing (run.json 'completed', exit 143; or run.json still
    'running'). The run's outcome is recorded by then, so a signal held is dropped: the process ends in a moment."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = (signal.SIGTERM, signal.SIGINT)
    previous = {s: signal.getsignal(s) for s in held}
    for s in held:
        signal.signal(s, lambda signum, frame: None)
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _interrupted_status(signum: int | None) -> int:
    """Exit status of an interrupted run: 128 + the signal that stopped it (143 after SIGTERM), 130 (128 + SIGINT)
    after Ctrl-C."""
    return 128 + signum if signum is not None else 130
