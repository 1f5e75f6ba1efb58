"""CPU threads of the engine's step: the walker bench scene on 1 and N threads, timed in alternating chunks
within one process so both see the same machine (this shared VM's second core does not always deliver).

    python benchmarks/thread_scaling.py [--threads 2] [--chunks 10] [--steps 150]

Writes benchmarks/results/thread_scaling-<date>-cpu-<commit>.json: ms per step of every chunk, medians and the
per-chunk speed-up (one thread's chunk over the N-thread chunk that follows it).
"""

import argparse
import datetime
import json
import time
from pathlib import Path

import numpy as np
import warp as wp

from magsoro.bench.runner import _commit, _cpu_model
from magsoro.bench.scenes import build
from magsoro.io.files import atomic_write_json
from magsoro.mpm.solver import Solver


def _solver(name: str, threads: int):
    model, control, settings = build(name, "cpu")
    settings.threads = threads
    solver = Solver(model, settings)
    states = [solver.new_state(), solver.new_state()]
    dt = solver.stable_dt(control)
    for _ in range(5):
        solver.step(states[0], states[1], control, dt)
        states.reverse()
    return solver, states, control, dt


def _chunk(run, steps: int) -> float:
    solver, states, control, dt = run
    t0 = time.perf_counter()
    for _ in range(steps):
        solver.step(states[0], states[1], control, dt)
        states.reverse()
    return 1e3 * (time.perf_counter() - t0) / steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="walker")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--chunks", type=int, default=10)
    ap.add_argument("--steps", type=int, default=150)
    args = ap.parse_args()
    wp.config.quiet = True
    one, many = _solver(args.scene, 1), _solver(args.scene, args.threads)
    ms_one, ms_many = [], []
    for _ in range(args.chunks):
        ms_one.append(_chunk(one, args.steps))
        ms_many.append(_chunk(many, args.steps))
    speedup = np.array(ms_one) / np.array(ms_many)
    result = {
        "scene": args.scene,
        "n_particles": one[0].model.n_particles,
        "threads": args.threads,
        "steps_per_chunk": args.steps,
        "ms_per_step_1_thread": ms_one,
        f"ms_per_step_{args.threads}_threads": ms_many,
        "median_ms_1_thread": float(np.median(ms_one)),
        f"median_ms_{args.threads}_threads": float(np.median(ms_many)),
        "speedup_per_chunk": speedup.tolist(),
        "median_speedup": float(np.median(speedup)),
        "commit": _commit(),
        "cpu_model": _cpu_model(),
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "warp_version": wp.config.version,
    }
    out = Path(__file__).parent / "results" / f"thread_scaling-{result['date'][:10]}-cpu-{result['commit']}.json"
    atomic_write_json(out, result)
    print(f"{args.scene}: 1 thread {result['median_ms_1_thread']:.2f} ms/step, {args.threads} threads "
          f"{result[f'median_ms_{args.threads}_threads']:.2f} ms/step (medians), median speed-up {result['median_speedup']:.2f}x; "
          f"per chunk {np.round(speedup, 2).tolist()}; wrote {out}")


if __name__ == "__main__":
    main()
