"""What a Dask worker does for one run of a sweep, and how a finished run directory is read back.

``execute_run`` is shipped to the workers by pickling a reference to this module, so it must stay a plain
top-level function with JSON-like arguments. It never raises for a run that goes wrong: the error is written
to the run's run.json (status 'failed') and returned, so one bad run does not stop the sweep.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import time
import traceback
from pathlib import Path

from magsoro.warp_setup import quiet_warp

FINISHED = ("completed", "failed")

# Environment of LocalCluster worker processes: one thread each, because Dask already runs one process per
# core and nested BLAS/OpenMP threads would make the workers fight over the same cores.
SINGLE_THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMEXPR_NUM_THREADS": "1",
    "VECLIB_MAXIMUM_THREADS": "1",
    "MAGSORO_THREADS": "1",  # the engine's own CPU threads (magsoro.mpm.runtime.resolve_threads)
}


def _worker_device(device: str | None) -> str | None:
    """'cuda' on a multi-GPU LocalCluster: worker k takes GPU k mod count, so each GPU gets one worker."""
    if device != "cuda":
        return device
    try:
        from distributed import get_worker

        name = get_worker().name
    except (ImportError, ValueError):
        return device
    import warp as wp

    count = wp.get_cuda_device_count()
    if count > 1 and isinstance(name, int):
        return f"cuda:{name % count}"
    return device


def execute_run(run: dict, run_dir: str, scene_file: str, device: str | None = None, particles: bool | None = None,
                allow_large: bool = False) -> dict:
    """Run one scene of a sweep into ``run_dir`` with the outputs of ``magsoro run``; return its summary row.

    ``run`` holds index, name, params and the full scene dict; relative files in the scene resolve against the
    directory of ``scene_file``. A run estimated to need more memory or steps than :mod:`magsoro.limits` allows
    fails at once, naming the key, unless ``allow_large``.
    """
    for key, value in SINGLE_THREAD_ENV.items():
        os.environ.setdefault(key, value)
    wall0 = time.perf_counter()
    out = Path(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    sweep_info = {"index": run["index"], "name": run["name"], "params": run["params"], "scene_file": scene_file}
    writer = None
    try:
        quiet_warp()
        import warp as wp

        from magsoro.io.files import atomic_write_json
        from magsoro.io.recorder import RunWriter
        from magsoro.limits import check_memory, check_steps
        from magsoro.scene import parse_scene
        from magsoro.simulation import Simulation

        # a worker's first run pays the imports and Warp's start-up; the run's own wall time starts after them
        wp.init()
        wall0, cpu0 = time.perf_counter(), time.process_time()
        source = f"{scene_file} [run {run['name']}]"
        scene = parse_scene(json.loads(json.dumps(run["scene"])), source, Path(scene_file).parent)
        check_memory(scene, source, allow_large)
        sim = Simulation(scene, device=_worker_device(device), source=source)
        check_steps(sim, scene.simulation.duration, source, allow_large)
        writer = RunWriter(out, sim, run["scene"], particles=scene.output.particles if particles is None else particles)
        writer.info["sweep"] = sweep_info
        atomic_write_json(out / "run.json", writer.info)
        result = sim.run(record=writer.record, record_every=scene.output.every)
        writer.finish(result, time.perf_counter() - wall0)
        # CPU time next to wall time tells a slow run from a run starved by other processes on the machine
        writer.info["sweep"]["cpu_time_s"] = time.process_time() - cpu0
        atomic_write_json(out / "run.json", writer.info)
    except Exception as exc:  # noqa: BLE001 - any error of one run is that run's result, not the sweep's
        _write_failure(out, run, sweep_info, exc, time.perf_counter() - wall0, writer)
    return read_record(out, run)


def _write_failure(out: Path, run: dict, sweep_info: dict, exc: BaseException, wall: float, writer=None) -> None:
    """run.json with status 'failed' for an error outside the stepping loop (build, recorder, a bug)."""
    from magsoro._version import __version__
    from magsoro.errors import MagsoroError
    from magsoro.io.files import atomic_write_json

    message = str(exc) if isinstance(exc, MagsoroError) else f"{type(exc).__name__}: {exc}"
    info = dict(writer.info) if writer is not None else {
        "magsoro_version": __version__,
        "python": platform.python_version(),
        "machine": platform.node(),
        "scene": run["scene"],
        "sweep": sweep_info,
    }
    info.update(
        status="failed",
        message=message.splitlines()[0] if message else type(exc).__name__,
        traceback=traceback.format_exception(exc),
        wall_time_total=wall,
        finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    )
    atomic_write_json(out / "run.json", info)


def record_failure(run_dir, run: dict, message: str) -> dict:
    """Mark a run failed from outside (its worker died, Dask gave up on the task) and return its row."""
    out = Path(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    from magsoro.io.files import atomic_write_json

    info = {}
    try:
        info = json.loads((out / "run.json").read_text())
    except (OSError, ValueError):
        info = {"scene": run["scene"], "sweep": {"index": run["index"], "name": run["name"], "params": run["params"]}}
    info.update(status="failed", message=message, finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    atomic_write_json(out / "run.json", info)
    return read_record(out, run)


def run_status(run_dir) -> str | None:
    """Status in run_dir/run.json ('running', 'completed', 'failed', 'interrupted'), None when absent/unreadable."""
    try:
        return json.loads((Path(run_dir) / "run.json").read_text()).get("status")
    except (OSError, ValueError):
        return None


def run_signal(run_dir) -> int | None:
    """The signal that stopped the run in run_dir (run.json ``signal``: 15 after SIGTERM), None when none did."""
    try:
        value = json.loads((Path(run_dir) / "run.json").read_text()).get("signal")
    except (OSError, ValueError, AttributeError):
        return None
    return value if isinstance(value, int) and not isinstance(value, bool) and 0 < value < 128 else None


def final_probes(run_dir) -> dict[str, float]:
    """Last row of metrics.csv (the values at the end of the run), without the time column."""
    path = Path(run_dir) / "metrics.csv"
    header = last = None
    try:
        with path.open(newline="", encoding="utf-8") as fh:  # a stream: only the header and the last row are kept
            for row in csv.reader(fh):
                if header is None:
                    header = row
                else:
                    last = row
    except (OSError, UnicodeDecodeError, csv.Error):  # not a metrics.csv of ours: no final values
        return {}
    if header is None or last is None:
        return {}
    out = {}
    for k, v in zip(header, last):
        if k != "time":
            try:
                out[k] = float(v)
            except ValueError:
                out[k] = None
    return out


def read_record(run_dir, run: dict) -> dict:
    """Summary row of one run from its directory: params, status, error, wall time, final probe values.

    Probe values are given for completed runs only; a failed run's last row is not a result.
    """
    out = Path(run_dir)
    try:
        info = json.loads((out / "run.json").read_text())
    except (OSError, ValueError):
        info = {}
    status = info.get("status") or "pending"
    wall = info.get("wall_time_total")
    return {
        "index": run["index"],
        "run": run["name"],
        "params": dict(run["params"]),
        "status": status,
        "error": info.get("message", "") if status != "completed" else "",
        "wall_time_s": float(wall) if isinstance(wall, (int, float)) and math.isfinite(wall) else None,
        "cpu_time_s": (info.get("sweep") or {}).get("cpu_time_s"),
        "steps": info.get("steps"),
        "sim_time_s": info.get("time"),
        "probes": final_probes(out) if status == "completed" else {},
    }
