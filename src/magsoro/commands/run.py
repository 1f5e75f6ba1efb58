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
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="change one scene key for this run (repeatable): a dotted path as in magsoro sweep, e.g. "
                        "--set simulation.dx=1e-4 or --set bodies.beam.material.shear_modulus=2e5; run.json's scene "
                        "has the value used")
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
                        "scene's paths at those times (first column 'time'); rigid colliders, contact between bodies and self-contact")
    p.add_argument("--from", dest="from_run", metavar="RUN_DIR",
                   help="start from the final state of an earlier run (its folder or its final.npz): positions, "
                        "velocities, deformation gradients, Prony internal stresses and its time, which this run "
                        "continues for --duration (fields, paths and keyframes see the continued time); the bodies "
                        "must match. Overrides the scene's [initial] from")
    p.add_argument("--quiet", action="store_true",
                   help="print nothing when the run succeeds: no progress, notes (run.json keeps them) or summary; "
                        "errors and failures still go to stderr")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="also show each Newton iteration of the static solver and the implicit integrator (|R|, the "
                        "step in cells, the contacts held) and Warp's start-up banner, its devices and its kernel "
                        "compile and load lines (hidden by default)")
    p.add_argument("--allow-large", action="store_true",
                   help="run even when the scene is estimated to need more than 90 %% of the available memory, or more "
                        "than 1e8 time steps (without it such a run is refused before it starts, naming the key that "
                        "causes it)")
    p.set_defaults(func=run)


def _show_newton_iterations() -> None:
    """--verbose: the Newton solvers' per-iteration lines (the 'magsoro.static' logger, DEBUG) on stderr."""
    import logging

    log = logging.getLogger("magsoro.static")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("  %(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.DEBUG)
    log.propagate = False


def run(args) -> int:
    from magsoro.io.outdir import prepare_output_dir
    from magsoro.io.recorder import RunWriter
    from magsoro.limits import check_memory, check_steps
    from magsoro.scene import load_scene
    from magsoro.scene.load import read_scene_toml
    from magsoro.simulation import Simulation, check_run_length, prepare_relax, prepare_static

    from magsoro.console import configure_warp

    configure_warp(verbose=getattr(args, "verbose", False))  # before Warp starts: its banner and load lines
    if getattr(args, "verbose", False):
        _show_newton_iterations()
    if args.device is not None and not (args.device == "cpu" or args.device.startswith("cuda")):
        raise SceneError(f"--device: '{args.device}' is not allowed; use cpu, cuda or cuda:N")
    if args.duration is not None and not (args.duration > 0 and math.isfinite(args.duration)):
        raise SceneError(f"--duration: must be a finite number > 0 s, got {args.duration}")
    wall0 = time.perf_counter()
    preview = getattr(args, "preview", False)
    overrides = getattr(args, "overrides", None) or []
    scene = load_scene(args.scene, preview=preview, overrides=overrides)  # every check before the output folder is touched
    static = getattr(args, "static", False)
    if static:
        if getattr(args, "equilibrium", False):
            raise SceneError("--static and --equilibrium: give one of them")
        try:
            prepare_static(scene)  # float64, total form: the rule Simulation.solve_static follows
        except SceneError as exc:
            raise SceneError(f"{args.scene}: {exc}") from None
    relax_notes = prepare_relax(scene) if getattr(args, "equilibrium", False) and not static else []
    allow_large = getattr(args, "allow_large", False)
    check_memory(scene, args.scene, allow_large)  # before anything is allocated
    sim = Simulation(scene, device=args.device, source=args.scene)
    for text in relax_notes:
        sim.note(text)
    if static:
        from magsoro.errors import SimulationError
        from magsoro.mpm.newton.static import check_supported

        try:
            check_supported(sim)
        except SimulationError as exc:
            raise SceneError(f"{args.scene}: --static: {exc}") from None
    if sim.integrator == "implicit" and not static and not getattr(args, "equilibrium", False):
        from magsoro.errors import SimulationError
        from magsoro.mpm.newton.implicit import check_implicit_supported

        try:
            check_implicit_supported(sim)
        except SimulationError as exc:
            raise SceneError(f"{args.scene}: {exc}") from None
    _start(args, scene, sim)
    echo = read_scene_toml(args.scene)
    if preview:
        from magsoro.scene.load import apply_preview

        echo = apply_preview(echo, args.scene)
    if overrides:
        from magsoro.scene.load import apply_overrides

        echo = apply_overrides(echo, overrides)
    duration = args.duration if args.duration is not None else scene.simulation.duration
    check_run_length(duration, scene.output.every)  # before the output folder is touched
    if not static and not getattr(args, "equilibrium", False):
        check_steps(sim, duration, args.scene, allow_large)
    prepare_output_dir(args.out, overwrite=getattr(args, "overwrite", False))
    writer = RunWriter(args.out, sim, echo, particles=scene.output.particles)
    shown = _print_notes(sim, "magsoro run", quiet=args.quiet)  # what the scene may not mean, before the run rather than after it
    if getattr(args, "equilibrium", False):
        return _relax(args, sim, writer, sim.time + duration, wall0, shown)
    if static:
        return _static(args, sim, writer, wall0, shown)
    from magsoro.console import SettleWatch
    from magsoro.simulation import DriftWatch

    show = _DynamicProgress(duration, enabled=not args.quiet, t0=sim.time)
    settle = SettleWatch()
    drift = DriftWatch(sim.model.dx, sim.model.precision)

    def record(s):
        writer.record(s)
        settle.sample(s)
        drift.sample(s)

    def heartbeat(s):
        writer.beat(s)
        show.tick(s)

    try:
        result = sim.run(duration, heartbeat=heartbeat, record=record, record_every=scene.output.every,
                         progress=lambda s: show.tick(s, record=True))
    except Exception as exc:  # a fault of ours: run.json says 'failed' with it, then the traceback for the report
        from magsoro.simulation import RunResult

        writer.finish(RunResult("failed", sim.steps, sim.time, time.perf_counter() - wall0,
                                f"internal error: {type(exc).__name__}: {exc}"), time.perf_counter() - wall0)
        raise
    finally:
        show.close()
    settled, why = settle.verdict(sim.model.dx)
    writer.info["drift"], creep = drift.report()  # the precision report: bodies creeping while at rest
    if creep is not None:
        sim.note(creep, scene=True)
    writer.info["settled"] = {"settled": settled, "criterion": why, "kinetic_energy": settle.energies[-1:],
                              "max_speed": settle.speeds[-1:]}
    with _signals_deferred():  # run.json's status and the exit status must agree
        writer.finish(result, time.perf_counter() - wall0)
        _print_notes(sim, "magsoro run", shown, quiet=args.quiet)
        return _report_run(args, sim, result, time.perf_counter() - wall0, (settled, why))


def _start(args, scene, sim) -> None:
    """--from RUN_DIR, else the scene's [initial] from (relative to the scene file): start ``sim`` from that run's
    final state (:meth:`magsoro.simulation.Simulation.start_from`), refusing in one line what does not match."""
    from pathlib import Path

    if getattr(args, "from_run", None) is not None:
        sim.start_from(args.from_run, key="--from")
    elif scene.initial.from_ is not None:
        base = scene.base_dir
        path = Path(scene.initial.from_)
        path = path if path.is_absolute() or base is None else Path(base) / path
        sim.start_from(path, key=f"{args.scene}: initial.from")


class _DynamicProgress:
    """Progress of a dynamic run on stderr: a tqdm bar on a terminal, else a plain line every few seconds."""

    def __init__(self, duration: float, enabled: bool, t0: float = 0.0):
        from magsoro.console import Progress, is_terminal

        self.duration = duration
        self.t0 = t0  # the time the run starts at (--from: the earlier run's)
        self.wall0 = time.perf_counter()
        self.steps0 = None
        self.bar = None
        self.lines = None
        self.last_bar = 0.0
        if not enabled:
            return
        if is_terminal(sys.stderr):
            from tqdm import tqdm

            self.bar = tqdm(total=duration, unit="s sim", file=sys.stderr,
                            bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}{postfix}]")
        else:
            self.lines = Progress(sys.stderr)

    def tick(self, s, record: bool = False) -> None:
        """After a check window (heartbeat) or a record (``record``)."""
        if self.bar is None and self.lines is None:
            return
        now = time.perf_counter()
        if self.steps0 is None:
            self.steps0, self.wall0 = s.steps, now
        if s.steps <= self.steps0:
            return
        rate = (s.steps - self.steps0) / max(now - self.wall0, 1e-9)
        if s.integrator == "implicit":
            post = f"dt={s.dt:.3g} s, {getattr(s, 'last_newton_iterations', 0)} Newton its"
        else:
            post = f"{rate:.0f} steps/s, dt={s.dt:.3g} s"
        if self.bar is not None:
            if record or now - self.last_bar > 0.2:
                self.last_bar = now
                self.bar.n = min(s.time - self.t0, self.duration)
                self.bar.set_postfix_str(post, refresh=False)
                self.bar.refresh()
            return
        from magsoro.console import clock

        done = min((s.time - self.t0) / self.duration, 1.0) if self.duration > 0 else 1.0
        elapsed = now - self.wall0
        left = f", about {clock(elapsed * (1 - done) / done)} left" if done > 0 else ""
        self.lines.update(f"t = {s.time:.4g} of {self.t0 + self.duration:.4g} s ({100 * done:.0f} %), {post.replace('=', ' ')}, "
                          f"{clock(elapsed)} elapsed{left}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _report_run(args, sim, result, wall: float, settled) -> int:
    """The closing lines of a dynamic run (a summary ending with the final probe values and whether the run
    settled), and its exit status."""
    if result.status != "completed":
        print(f"magsoro run: {result.status}: {result.message}", file=sys.stderr)
        print(f"results so far in {args.out} (run.json status '{result.status}')", file=sys.stderr)
        return 1 if result.status == "failed" else _interrupted_status(result.signal)
    if not args.quiet:
        print(f"{result.steps} steps in {result.wall_time:.1f} s ({result.steps / max(result.wall_time, 1e-9):.0f} steps/s), dt {sim.dt_min:.3g}-{sim.dt_max:.3g} s; results in {args.out}")
        ok, why = settled
        verdict = {True: "yes", False: "no, still moving", None: "not judged"}[ok]
        _print_summary(sim, wall, result.metrics, f"final probe values at t = {result.time:.6g} s",
                       f"settled: {verdict} ({why})")
    return 0


def _print_summary(sim, wall: float, metrics, heading: str, last: str) -> None:
    """The closing block on stdout: notes and wall time, the probe values of the last metrics row, then ``last``."""
    from magsoro.console import clock, probe_lines

    notes = len(getattr(sim, "notes", []))
    print(f"wall time {clock(wall)}; {notes} note{'' if notes == 1 else 's'}"
          f"{' (run.json notes)' if notes else ''}")
    columns = list(metrics.dtype.names[1:]) if metrics is not None and metrics.dtype.names else []
    if columns and len(metrics):
        row = metrics[-1]
        print(f"{heading}:")
        for line in probe_lines({c: float(row[c]) for c in columns}, sim.probes):
            print(line)
    else:
        print(f"{heading}: no probes (the scene's [[probes]])")
    print(last)


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
        _print_notes(sim, "magsoro run --equilibrium", shown, quiet=args.quiet)
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
    watch = _NewtonProgress(sim, along_paths, enabled=not args.quiet)
    if not along_paths:
        writer.columns[0] = "level"
        sim.field_scale = 0.0  # the unloaded row: field probes read no applied field
        writer.record(sim, stamp=0.0)

    def on_level(s, lev):  # [static] times: one row per time along the paths (first column the time)
        writer.record(s, stamp=lev.time if along_paths else lev.level)
        watch.solved(lev)

    try:
        with writer.beating(), watch:  # a level's Newton iterations can take minutes between records
            # from an earlier run's state (--from) the loads are those at the end of this phase, t0 + duration
            t_loads = None if along_paths or sim.started_from is None else sim.time + sim.scene.simulation.duration
            res = sim.solve_static(on_level=on_level, watch=watch.attach, t=t_loads)
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
            _print_notes(sim, "magsoro run --static", shown, quiet=args.quiet)
            print(f"magsoro run --static: interrupted: {message}", file=sys.stderr)
            print(f"results so far in {args.out} (run.json status 'interrupted')", file=sys.stderr)
            return _interrupted_status(signum)
    with _signals_deferred():
        writer.finish(RunResult(status, 0, sim.time, wall, message), time.perf_counter() - wall0)
        _print_notes(sim, "magsoro run --static", shown, quiet=args.quiet)
        return _report_static(args, sim, status, message, wall, res if status == "completed" else None,
                              time.perf_counter() - wall0)


def _level_name(lev, along_paths: bool) -> str:
    return f"t = {lev.time:.6g} s" if along_paths else f"level {lev.level:.4g}"


class _NewtonProgress:
    """``--static`` output while it solves: one stdout line per converged level (its Newton iterations and
    residual) and, while a level solves, a stderr status line (a plain line every few seconds when stderr is not
    a terminal) with the Newton iterations and residual evaluations so far, read from the solver's counters by a
    helper thread."""

    def __init__(self, sim, along_paths: bool, enabled: bool):
        from magsoro.console import Progress

        cfg = sim.scene.static
        self.targets = list(cfg.times) if along_paths else list(cfg.levels)
        self.along_paths = along_paths
        self.enabled = enabled
        self.progress = Progress(sys.stderr, enabled=enabled)
        self.solver = None
        self.done = 0
        self.level_start = (time.perf_counter(), 0, 0)  # wall time, linear solves, residual evaluations
        self.stop = threading.Event()
        self.thread = None

    def attach(self, solver) -> None:
        self.solver = solver
        self.level_start = (time.perf_counter(), solver.linear_solves, solver.residual_evaluations)

    def solved(self, lev) -> None:
        self.done += 1
        if self.enabled:
            self.progress.line(f"{_level_name(lev, self.along_paths)}: converged in {lev.iterations} Newton iteration"
                               f"{'' if lev.iterations == 1 else 's'}, |R| {lev.residual:.2e} N ({lev.residual_relative:.1e} "
                               f"of the load's force scale), {lev.wall_time:.1f} s", stream=sys.stdout)
        if self.solver is not None:
            self.level_start = (time.perf_counter(), self.solver.linear_solves, self.solver.residual_evaluations)

    def status(self) -> str | None:
        solver = self.solver
        if solver is None or self.done >= len(self.targets):
            return None
        from magsoro.console import clock

        t0, solves0, evals0 = self.level_start
        target = self.targets[self.done]
        what = f"t = {target:.6g} s" if self.along_paths else f"level {target:.4g}"
        return (f"{what} ({self.done + 1} of {len(self.targets)}): {solver.linear_solves - solves0} Newton iterations, "
                f"{solver.residual_evaluations - evals0} residual evaluations, {clock(time.perf_counter() - t0)}")

    def __enter__(self):
        if self.enabled:
            def keep_showing():
                while not self.stop.wait(1.0):
                    text = self.status()
                    if text is not None:
                        self.progress.update(text)

            self.thread = threading.Thread(target=keep_showing, name="magsoro-newton-progress", daemon=True)
            self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        if self.thread is not None:
            self.thread.join()
        self.progress.close()
        return False


def _report_static(args, sim, status: str, message: str, wall: float, res, wall_total: float) -> int:
    if status != "completed":
        print(f"magsoro run --static: failed: {message}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(f"{message} in {wall:.1f} s; results in {args.out}")
        turns = [f"{t:.4g}" for r in res.levels for t in r.limit_levels]
        if turns:
            print(f"the equilibrium path turned back (limit points, a snap-through at the first) at field level(s) "
                  f"{', '.join(turns)}: run.json static.levels[].limit_levels")
        along_paths = sim.scene.static.times is not None
        last = res.levels[-1]
        worst = max(res.levels, key=lambda r: r.residual_relative)
        _print_summary(sim, wall_total, res.metrics, f"probe values at {_level_name(last, along_paths)} (the last)",
                       f"equilibrium: converged at every {'time' if along_paths else 'level'} ({len(res.levels)}), "
                       f"largest |R| {worst.residual_relative:.1e} of the load's force scale "
                       f"(tolerance {sim.scene.static.tolerance:g})")
    return 0


def _print_notes(sim, prefix: str, shown: int = 0, quiet: bool = False) -> int:
    """The run's notes on what the scene may not mean (a body in the domain walls' reach, a body the particle
    lattice rounds, a field or remanence out of the plausible range) from the ``shown``-th on, one stderr line
    each (none with ``quiet``); returns how many there are. run.json's ``notes`` holds them with the others."""
    for note in ([] if quiet else sim.scene_notes[shown:]):
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
