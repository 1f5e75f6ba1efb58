"""Run a sweep plan on dask.distributed and keep DIR/summary.csv (and .parquet) current as runs finish.

Layout of DIR::

    sweep.json            the plan (scene file, params, runs); a --resume must match it
    summary.csv/.parquet  one row per planned run (see magsoro.sweep.summary)
    runs/<index>-<slug>/  the outputs of ``magsoro run`` for that run

A run counts as finished only when its run.json (written atomically by the run) says 'completed' or
'failed'; --resume skips those and runs everything else again from the start in the same directory.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from magsoro.errors import Terminated
from magsoro.io.files import atomic_write_json
from magsoro.sweep.extra import require_distributed
from magsoro.sweep.params import SweepError
from magsoro.sweep.plan import SweepPlan
from magsoro.sweep.summary import write_summary
from magsoro.sweep.worker import (FINISHED, SINGLE_THREAD_ENV, execute_run, read_record, record_failure, run_signal,
                                  run_status)


@dataclass
class Progress:
    """Where a sweep stands; passed to the progress callback after every finished run."""

    total: int
    done: int = 0  # finished runs, completed or failed, including those skipped by --resume
    failed: int = 0
    skipped: int = 0  # finished before this invocation (--resume)
    started: float = field(default_factory=time.time)
    last: dict | None = None  # the record of the run that just finished

    @property
    def eta(self) -> float | None:
        """Estimated wall-clock time (epoch s) when the sweep finishes: this invocation's rate so far."""
        ran = self.done - self.skipped
        if ran <= 0:
            return None
        elapsed = time.time() - self.started
        return time.time() + elapsed / ran * (self.total - self.done)


@dataclass
class SweepResult:
    """Outcome of :func:`run_sweep`: ``out_dir`` (the sweep folder), ``records`` (one dict per run, as in
    summary.csv: parameters, status, final probe values in SI units), ``workers`` and ``wall_time`` (s)."""

    out_dir: Path
    records: list[dict]
    workers: int
    wall_time: float

    @property
    def failed(self) -> list[dict]:
        """The records of the runs that failed."""
        return [r for r in self.records if r["status"] == "failed"]

    @property
    def completed(self) -> list[dict]:
        """The records of the runs that completed."""
        return [r for r in self.records if r["status"] == "completed"]


#: seconds to connect to a --scheduler and have it answer, all steps together: an address where something listens
#: but never answers (a wrong port, a firewall that swallows packets) must not hold the sweep for minutes
SCHEDULER_TIMEOUT_S = 30.0
#: seconds to wait for the first worker of a --scheduler cluster
WORKER_WAIT_S = 60.0


def connect(Client, scheduler: str, timeout: float | None = None):
    """A ``Client`` (dask.distributed's) of the scheduler at ``scheduler`` ('HOST:PORT' or a full address), or
    SweepError (one line) when it does not answer within ``timeout`` s (default SCHEDULER_TIMEOUT_S) in all: Dask's
    own connect timeout does not bound every step of its handshake, so the connection runs in a helper thread that
    is abandoned at the deadline."""
    import threading

    timeout = SCHEDULER_TIMEOUT_S if timeout is None else timeout
    address = scheduler if "://" in scheduler else f"tcp://{scheduler}"
    box: dict = {}

    def attempt():
        try:
            box["client"] = Client(address, timeout=timeout)
        except BaseException as exc:  # noqa: BLE001 - handed to the calling thread
            box["error"] = exc

    thread = threading.Thread(target=attempt, name="magsoro-scheduler-connect", daemon=True)
    thread.start()
    thread.join(timeout + 1.0)
    if thread.is_alive():
        raise SweepError(f"--scheduler {scheduler}: no answer within {timeout:g} s (something listens there but does "
                         f"not speak to a dask scheduler?); check the address and port")
    exc = box.get("error")
    if exc is not None:
        if isinstance(exc, (OSError, TimeoutError, ValueError)):
            raise SweepError(f"--scheduler {scheduler}: cannot connect ({type(exc).__name__}: {exc})") from None
        raise exc
    return box["client"]


# LocalCluster worker environment: single-threaded numerics, and no statistical profiler (it samples every
# worker's stack every 10 ms, CPU the runs can use; a sweep's tasks are opaque to it anyway).
WORKER_ENV = {**SINGLE_THREAD_ENV, "DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False"}


def default_workers(device: str | None = None) -> int:
    """One worker per GPU for ``device='cuda'`` (one for 'cuda:N'), else one per core this process may use."""
    if device is not None and device.startswith("cuda"):
        if device != "cuda":
            return 1
        import warp as wp

        return max(1, wp.get_cuda_device_count())
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def _prepare(plan: SweepPlan, out: Path, resume: bool) -> None:
    description = plan.describe()
    sweep_json = out / "sweep.json"
    if sweep_json.is_file():
        if not resume:
            raise SweepError(f"--out {out}: already holds a sweep (sweep.json); add --resume to finish it, or choose another --out")
        try:
            previous = json.loads(sweep_json.read_text())
        except ValueError:
            previous = None
        # compare through JSON so tuples/lists and ints/floats read back the same way
        if previous is None or json.loads(json.dumps(description["runs"])) != previous.get("runs"):
            raise SweepError(f"--resume: the runs planned now differ from those in {sweep_json}; resume with the same scene and --param values, or choose another --out")
    elif (out / "runs").is_dir() and any((out / "runs").iterdir()):
        raise SweepError(f"--out {out}: holds runs/ but no sweep.json; choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    (out / "runs").mkdir(exist_ok=True)
    description["created"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    if not sweep_json.is_file():
        atomic_write_json(sweep_json, description)


def run_sweep(
    plan: SweepPlan,
    out_dir,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    resume: bool = False,
    device: str | None = None,
    particles: bool | None = None,
    progress: Callable[[Progress], None] | None = None,
    allow_large: bool = False,
) -> SweepResult:
    """Run every run of ``plan`` not yet finished in ``out_dir``.

    ``scheduler`` ('HOST:PORT' or a full address) connects to a running dask.distributed cluster whose
    workers have magsoro installed and see ``out_dir`` and the scene's files at the same paths; otherwise a
    LocalCluster with ``workers`` single-threaded worker processes (default: one per core) is started and
    closed; ``workers=0`` runs them one after the other in this process, without Dask. Ctrl-C cancels the runs
    in flight and raises KeyboardInterrupt; their run.json stays 'running', so a later ``resume=True`` runs
    them again. ``allow_large``: runs estimated to need more memory or steps than :mod:`magsoro.limits` allows
    go ahead instead of failing.
    """
    wall0 = time.perf_counter()
    # before anything is written: a cluster needs the sweep extra (workers=0 runs without it)
    distributed = None if workers == 0 and not scheduler else require_distributed()
    out = Path(out_dir).resolve()
    _prepare(plan, out, resume)
    param_keys = [p.key for p in plan.params]
    specs = {r.index: {"index": r.index, "name": r.name, "params": r.params, "scene": r.scene} for r in plan.runs}
    run_dirs = {r.index: out / "runs" / r.name for r in plan.runs}
    records = {i: read_record(run_dirs[i], specs[i]) for i in specs}
    pending = [i for i in specs if run_status(run_dirs[i]) not in FINISHED]
    state = Progress(total=len(specs))
    state.skipped = state.done = len(specs) - len(pending)
    state.failed = sum(1 for r in records.values() if r["status"] == "failed")
    write_summary(out, list(records.values()), param_keys)
    if not pending:
        return SweepResult(out, [records[i] for i in sorted(records)], 0, time.perf_counter() - wall0)

    def finished(i: int, rec: dict) -> None:
        records[i] = rec
        state.done += 1
        state.failed += rec["status"] == "failed"
        state.last = rec
        write_summary(out, list(records.values()), param_keys)
        if progress is not None:
            progress(state)

    if workers == 0 and not scheduler:
        # in this process, one run after the other, no Dask: for debugging (pdb, profilers) and small sweeps
        for i in pending:
            rec = execute_run(specs[i], str(run_dirs[i]), str(plan.scene_path), device, particles, allow_large)
            if rec["status"] == "interrupted":  # Simulation.run turned Ctrl-C or SIGTERM into a status: stop the sweep
                records[i] = rec
                write_summary(out, list(records.values()), param_keys)
                signum = run_signal(run_dirs[i])  # 143 after SIGTERM, as magsoro run
                raise Terminated(signum) if signum is not None else KeyboardInterrupt
            finished(i, rec)
        return SweepResult(out, [records[i] for i in sorted(records)], 0, time.perf_counter() - wall0)

    Client, LocalCluster, as_completed = distributed.Client, distributed.LocalCluster, distributed.as_completed

    cluster = None
    if scheduler:
        client = connect(Client, scheduler)
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT_S)  # a scheduler without workers would leave the sweep waiting
        except TimeoutError:
            client.close()
            raise SweepError(f"--scheduler {scheduler}: no worker joined the cluster within {WORKER_WAIT_S:g} s") from None
        n_workers = len(client.nthreads())
    else:
        n_workers = max(1, min(workers or default_workers(device), len(pending)))
        # processes, not threads: a run holds the GIL in its Python stepping loop
        cluster = LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            env=WORKER_ENV,
        )
        client = Client(cluster)
    futures = {}
    try:
        for i in pending:
            # a unique key per submission, so a resumed sweep never picks up a stale result of the same name
            fut = client.submit(
                execute_run, specs[i], str(run_dirs[i]), str(plan.scene_path), device, particles, allow_large,
                key=f"magsoro-run-{i}-{time.time_ns()}", pure=False, retries=0,
            )
            futures[fut] = i
        for fut in as_completed(list(futures)):
            i = futures[fut]
            try:
                rec = fut.result()
            except Exception as exc:  # noqa: BLE001 - the worker died or Dask gave up: this run failed
                rec = record_failure(run_dirs[i], specs[i], f"worker error: {type(exc).__name__}: {exc}")
            finished(i, rec)
    except BaseException:
        for fut in futures:
            fut.cancel()
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return SweepResult(out, [records[i] for i in sorted(records)], n_workers, time.perf_counter() - wall0)
