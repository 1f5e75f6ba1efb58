"""magsoro.robots.base.run_jobs: a reproduction's independent simulations in worker processes."""

from __future__ import annotations

import os

import pytest

from magsoro.robots import base
from magsoro.robots.base import Context, Job, RobotError, run_jobs


def _facts(ctx: Context, value: float, note: str = ""):
    """A job: where it ran and what it got (and a scene note, as a simulation leaves one)."""
    if note:
        base._run_notes.append([note])
    ctx.log(f"job {value}")
    return {"value": 2.0 * value, "pid": os.getpid(), "threads": os.environ.get("MAGSORO_THREADS"),
            "blas": os.environ.get("OPENBLAS_NUM_THREADS"), "workers": ctx.workers, "preview": ctx.preview}


def _waits(ctx: Context, k: int, together: int):
    """A job that marks its start in ctx.out and waits (up to 60 s) until ``together`` jobs have started; returns
    how many had."""
    import time

    (ctx.out / f"started_{k}").touch()
    t0 = time.monotonic()
    while len(list(ctx.out.glob("started_*"))) < together and time.monotonic() - t0 < 60.0:
        time.sleep(0.05)
    return {"started": len(list(ctx.out.glob("started_*")))}


class _Unpicklable(Exception):
    def __init__(self, a, b):  # pickling rebuilds it with one argument: it cannot travel
        super().__init__(f"{a} {b}")


def _fails(ctx: Context, kind: str):
    if kind == "value":
        raise ValueError("the job's own message")
    raise _Unpicklable("cannot", "travel")


def test_serial_runs_here_in_order(tmp_path):
    base.scene_notes()
    lines = []
    ctx = Context(out=tmp_path, log=lines.append)
    out = run_jobs(ctx, [Job(_facts, ctx, (1.0, "a")), Job(_facts, ctx, (3.0,), {"note": "b"})])
    assert [o["value"] for o in out] == [2.0, 6.0]
    assert {o["pid"] for o in out} == {os.getpid()}
    assert lines == ["job 1.0", "job 3.0"]
    assert base.scene_notes() == ["a", "b"]


def test_workers_run_jobs_in_their_own_processes_in_order(tmp_path, capfd):
    base.scene_notes()
    ctx = Context(out=tmp_path, workers=2, log=lambda msg: None)  # a logger that cannot travel stays here
    jobs = [Job(_facts, ctx, (float(k),), {"note": f"note {k % 2}"}, label=f"job {k}") for k in range(3)]
    jobs.append(Job(_facts, Context(out=tmp_path, preview=True), (9.0,), label="preview"))
    out = run_jobs(ctx, jobs)
    assert [o["value"] for o in out] == [0.0, 2.0, 4.0, 18.0]
    pids = [o["pid"] for o in out]
    assert os.getpid() not in pids and len(set(pids)) == 4  # each job in a fresh process
    assert all(o["threads"] == str(max(1, len(os.sched_getaffinity(0)) // 2)) and o["blas"] == "1" for o in out)
    assert [o["workers"] for o in out] == [1, 1, 1, 1] and [o["preview"] for o in out] == [False] * 3 + [True]
    assert sorted(base.scene_notes()) == ["note 0", "note 1"]
    assert "[job 2] job 2.0" in capfd.readouterr().err  # the worker's progress, prefixed with its label


def test_the_environment_is_restored(tmp_path, monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "7")
    monkeypatch.delenv("MAGSORO_THREADS", raising=False)
    ctx = Context(out=tmp_path, workers=2)
    run_jobs(ctx, [Job(_facts, ctx, (1.0,)), Job(_facts, ctx, (2.0,))])
    assert os.environ["OPENBLAS_NUM_THREADS"] == "7" and "MAGSORO_THREADS" not in os.environ


def test_a_failing_job_raises_its_exception_with_the_workers_traceback(tmp_path):
    ctx = Context(out=tmp_path, workers=2)
    with pytest.raises(ValueError, match="the job's own message") as info:
        run_jobs(ctx, [Job(_facts, ctx, (1.0,)), Job(_fails, ctx, ("value",), label="bad")])
    assert any("worker process of 'bad'" in n and "_fails" in n for n in info.value.__notes__)
    with pytest.raises(RobotError, match="travel: failed in a worker process") as info:
        run_jobs(ctx, [Job(_fails, ctx, ("other",), label="travel"), Job(_facts, ctx, (1.0,))])
    assert "_Unpicklable: cannot travel" in str(info.value)


def test_balanced_jobs_run_all_at_once_up_to_twice_the_workers(tmp_path):
    ctx = Context(out=tmp_path, workers=2)
    out = run_jobs(ctx, [Job(_waits, ctx, (k, 4)) for k in range(5)], balanced=True)
    # the first four wait for each other (with two processes they would wait in vain); the fifth starts after them
    assert all(o["started"] >= 4 for o in out[:4])
    assert out[4]["started"] == 5
    ctx1 = Context(out=tmp_path, workers=1)
    assert {o["pid"] for o in run_jobs(ctx1, [Job(_facts, ctx1, (1.0,)), Job(_facts, ctx1, (2.0,))], balanced=True)} == {
        os.getpid()}


def test_one_job_or_one_worker_runs_here(tmp_path):
    ctx = Context(out=tmp_path, workers=4)
    assert run_jobs(ctx, [Job(_facts, ctx, (1.0,))])[0]["pid"] == os.getpid()
