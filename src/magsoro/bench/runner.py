"""Run benchmark scenes and report steps per second, particle-steps per second, phases and the reference ratio."""

import dataclasses
import datetime
import platform
import resource
import subprocess
import time
from pathlib import Path

import numpy as np
import warp as wp

from magsoro.bench.reference import ReferenceStep
from magsoro.bench.scenes import SCENES, build
from magsoro.mpm.solver import Solver

DEFAULT_STEPS = {"walker": 300, "walker_1m": 300, "walker_total": 300, "walker_dipole": 300, "beam2d": 1000, "block1m": 3, "sweep": 60}


#: Timed rounds per scene: engine and reference alternate, ``steps`` each, so both see the same machine; the
#: figures are medians over the rounds (a shared 2-core VM here changes speed by up to 1.7x from one second to
#: the next, which a single timing mistakes for a change of the code).
ROUNDS = 5
#: Steps per check window in the windowed timing (the scene default of simulation.check_every).
WINDOW = 200


def _timed_steps(solver, states: list, control, dt: float, steps: int, device: str) -> float:
    """Wall time (s) of ``steps`` checked steps of ``solver`` between the two ``states`` (swapped in place)."""
    a, b = states
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    for _ in range(steps):
        solver.step(a, b, control, dt)
        a, b = b, a
    wp.synchronize_device(device)
    states[:] = [a, b]
    return time.perf_counter() - t0


def run_scene(name: str, device: str = "cpu", steps: int | None = None, threads: int | None = None, rounds: int = ROUNDS) -> dict:
    """Time ``name``. ``threads``: CPU threads of the engine's step (None: its automatic choice); the reference
    kernel always runs on one thread, so on CPU the ratio also carries the engine's threading."""
    steps = steps or DEFAULT_STEPS[name]
    model, control, settings = build(name, device)
    settings.threads = threads
    solver = Solver(model, settings)
    a, b = solver.new_state(), solver.new_state()
    dt = solver.stable_dt(control)
    for _ in range(5):  # kernel load and first grid fit
        solver.step(a, b, control, dt)
        a, b = b, a
    h = model.host
    ref = ReferenceStep(h["positions"], h["volumes"], h["mass"], float(h["shear_modulus"][0]), float(h["bulk_modulus"][0]), model.dx, dt, device)
    engine_s, window_s, ref_s, off_s = [], [], [], []
    reads = {}
    off = None
    if settings.magnetic_interaction != "none":
        # the same scene without the interaction, timed in the same rounds: the cost ratio of the interaction
        off = Solver(model, dataclasses.replace(settings, magnetic_interaction="none"))
        off_states = [off.new_state(), off.new_state()]
        _timed_steps(off, off_states, control, dt, 5, device)
    states = [a, b]
    window_loop = "plain" if solver.graph_refusal(control) is not None else "drive tables"
    for _ in range(rounds):
        if off is not None:
            off_s.append(_timed_steps(off, off_states, control, dt, steps, device))
        reads0 = solver.host_reads
        engine_s.append(_timed_steps(solver, states, control, dt, steps, device))
        reads["checked"] = (solver.host_reads - reads0) / steps
        a, b = states
        # the same steps in check windows (the loop Simulation.run uses): one host read per WINDOW steps, the steps
        # from drive tables (Solver.run_window; captured as graphs on CUDA) where the scene allows it
        reads0 = solver.host_reads
        t0 = time.perf_counter()
        for k0 in range(0, steps, WINDOW):
            n_win = min(WINDOW, steps - k0)
            reach = 2.0 * WINDOW * dt * solver.last_max_speed() + model.dx  # as Simulation._window
            if window_loop == "drive tables":
                solver.start_window(a, reach)
                if solver.run_window(a, b, control, [dt] * n_win) is not a:
                    a, b = b, a
            else:
                for _ in range(n_win):
                    solver.step(a, b, control, dt, check=False, reach=reach)
                    a, b = b, a
            problem = solver.close_window()
            if problem is not None:  # a run would go back and redo the window step by step
                raise RuntimeError(f"bench {name}: a check window failed ({problem}); lower WINDOW")
        wp.synchronize_device(device)
        window_s.append(time.perf_counter() - t0)
        states[:] = [a, b]
        reads["window"] = (solver.host_reads - reads0) / steps
        ref_s.append(ref.time(steps))
    # phase split from a separate, synchronised pass (timing each phase adds synchronisation)
    solver.enable_phase_timing(True)
    n_phase = max(1, steps // 4)
    for _ in range(n_phase):
        solver.step(a, b, control, dt)
        a, b = b, a
    phases = {k: 1e3 * v / n_phase for k, v in solver.phase_times.items()}
    n = model.n_particles
    wall = float(np.median(engine_s))
    ref_wall = float(np.median(ref_s))
    ratios = [r / e for e, r in zip(engine_s, ref_s)]  # each round against the reference timed right after it
    out = {
        "name": name,
        "n_particles": n,
        "dim": model.dim,
        "threads": solver.threads,
        "reference_threads": 1,
        "steps": steps,
        "rounds": rounds,
        "dt": dt,
        "ms_per_step": 1e3 * wall / steps,
        "ms_per_step_rounds": [1e3 * e / steps for e in engine_s],
        "window_steps": WINDOW,
        "window_ms_per_step": 1e3 * float(np.median(window_s)) / steps,
        "window_ms_per_step_rounds": [1e3 * e / steps for e in window_s],
        "window_loop": window_loop,
        "graph_captures": solver.graph_captures,
        "host_reads_per_step": reads,
        "steps_per_s": steps / wall,
        "particle_steps_per_s": n * steps / wall,
        "reference_ms_per_step": 1e3 * ref_wall / steps,
        "reference_ms_per_step_rounds": [1e3 * r / steps for r in ref_s],
        "reference_particle_steps_per_s": n * steps / ref_wall,
        "ratio_to_reference": float(np.median(ratios)),
        "phases_ms": phases,
        "grid": solver.grid_info(),
    }
    if off is not None:
        out["interaction_every"] = settings.interaction_every
        out["interaction_off_ms_per_step"] = 1e3 * float(np.median(off_s)) / steps
        out["interaction_off_ms_per_step_rounds"] = [1e3 * e / steps for e in off_s]
        # each round's checked timing against the one without interaction run right before it
        out["interaction_cost_ratio"] = float(np.median([e / o for e, o in zip(engine_s, off_s)]))
    if name == "sweep":
        # the batch against the same copies run one after another: the walker timed in this call
        from magsoro.bench.scenes import SWEEP_FREQUENCIES_HZ

        single = run_scene("walker", device, None, threads, rounds)
        copies = len(SWEEP_FREQUENCIES_HZ)
        out["copies"] = copies
        out["sequential_ms_per_step"] = copies * single["ms_per_step"]
        out["batch_speedup"] = out["sequential_ms_per_step"] / out["ms_per_step"]
        # the same in check windows, the loop magsoro run uses (on CUDA: captured graphs)
        out["window_sequential_ms_per_step"] = copies * single["window_ms_per_step"]
        out["window_batch_speedup"] = out["window_sequential_ms_per_step"] / out["window_ms_per_step"]
    return out


#: implicit benchmark scenes: a scene file run for its whole duration by both integrators (name -> scene file,
#: duration s, implicit step s)
IMPLICIT_SCENES = {"implicit_beam2d": ("cantilever_2d.toml", 0.2, 0.005)}


def run_implicit_scene(name: str, device: str = "cpu") -> dict:
    """Time ``name`` (IMPLICIT_SCENES): the scene file's run by the implicit integrator and by the explicit engine
    (both float64, total form) in one call; their wall times, ratio, and the tip probe's end values."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    file, duration, dt = IMPLICIT_SCENES[name]
    from magsoro.robots.base import scenes_dir

    path = scenes_dir() / file
    out = {"name": name, "scene": f"scenes/{file}", "duration_s": duration, "implicit_dt": dt}
    for integrator in ("implicit", "explicit"):
        scene = load_scene(path)
        scene.simulation.precision, scene.simulation.formulation = "float64", "total"
        scene.simulation.integrator = integrator
        scene.implicit.dt = scene.implicit.dt_max = dt
        sim = Simulation(scene, device=device, source=str(path))
        sim.advance_to(min(dt, duration / 100))  # kernel loads, first factorisation
        t0 = time.perf_counter()
        sim.advance_to(duration)
        wall = time.perf_counter() - t0
        out[integrator] = {"wall_s": wall, "steps": sim.steps, "n_particles": sim.model.n_particles,
                           "probes": sim.probe_values(), "integrator": sim.integrator_info()}
    out["speedup"] = out["explicit"]["wall_s"] / out["implicit"]["wall_s"]
    return out


def run(names, device: str = "cpu", steps: int | None = None, threads: int | None = None) -> dict:
    scenes = [run_implicit_scene(n, device) if n in IMPLICIT_SCENES else run_scene(n, device, steps, threads)
              for n in names]
    if device == "cpu":
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    else:
        peak = None
    return {
        "device": device,
        "device_name": wp.get_device(device).name,
        "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(), "cpu_count": __import__("os").cpu_count(), "cpu_model": _cpu_model()},
        "warp_version": wp.config.version,
        "commit": _commit(),
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "peak_memory_bytes": peak,
        "scenes": scenes,
    }


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _commit() -> str:
    """The checkout's short commit; MAGSORO_COMMIT where the tree has no git history (a copy sent to another
    machine)."""
    import os

    if os.environ.get("MAGSORO_COMMIT"):
        return os.environ["MAGSORO_COMMIT"]
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=Path(__file__).parent, timeout=10)
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def provenance() -> dict:
    """What a benchmark result file records about its run: the date (UTC), the checkout's commit and the machine."""
    import os

    return {"date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), "commit": _commit(),
            "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(),
                        "cpu_count": os.cpu_count()}}


def names_or_all(names):
    unknown = [n for n in names if n not in SCENES and n not in IMPLICIT_SCENES]
    if unknown:
        from magsoro.errors import MagsoroError

        raise MagsoroError(f"unknown benchmark scene(s) {unknown}; available: {', '.join([*SCENES, *IMPLICIT_SCENES])}")
    return list(names) or ["walker", "walker_total", "walker_dipole", "walker_1m", "beam2d", "block1m", "sweep"]
