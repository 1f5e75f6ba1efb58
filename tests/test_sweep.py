"""``magsoro sweep``: the --param grammar, dotted scene paths, planning and validation, a sweep on a Dask
LocalCluster with a failing run, and --resume after an interruption."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from magsoro.sweep import SweepError, make_plan, parse_param, run_sweep, set_path
from magsoro.sweep.params import combine
from test_report import TINY_SCENE, write_scene

B_VALUES = "[0,0.01,0],[0,0.02,0],[0,0.03,0],[0,0.04,0],[0,0.05,0],[0,0.06,0]"
# the last run's fixed time step is ~160x the stable one: it blows up in its first step
DT_VALUES = "2e-6,2e-6,2e-6,2e-6,2e-6,4e-4"


def read_csv(path: Path) -> list[dict]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------------------------------------------ grammar
def test_param_grammar():
    p = parse_param("fields.coil.magnitude=0:0.05:11")
    assert p.key == "fields.coil.magnitude" and len(p.values) == 11
    assert p.values[0] == 0.0 and p.values[-1] == 0.05 and p.values[5] == pytest.approx(0.025)
    assert parse_param("a.b=1e5, 2e5,4e5").values == [1e5, 2e5, 4e5]
    assert parse_param("a.b=3:3:1").values == [3.0]
    assert parse_param("bodies.tail.material=ecoflex-00-30-ndfeb100,dragon-skin-10-ndfeb100").values == [
        "ecoflex-00-30-ndfeb100", "dragon-skin-10-ndfeb100"]
    assert parse_param("fields.0.B=[0,0.01,0],[0, 0.02, 0]").values == [[0, 0.01, 0], [0, 0.02, 0]]
    assert parse_param('x.y="a,b",c,true,.5,{"type":"ramp","duration":0.1}').values == [
        "a,b", "c", True, 0.5, {"type": "ramp", "duration": 0.1}]
    assert parse_param('x.y="a:b:c",cuda:0').values == ["a:b:c", "cuda:0"]
    assert parse_param("x.y=7").values == [7] and isinstance(parse_param("x.y=7").values[0], int)
    bad = {
        "x.y=0:1:0": "range count must be a whole number >= 1",
        "x.y=0:1:2.5": "range count must be a whole number >= 1",
        "x.y=a:1:3": "range start 'a' is not a number",
        "x.y=[0,1": "unclosed bracket",
        "x.y=1,,2": "empty value",
        "x.y=[0,1,]": "looks like JSON but does not parse",
        "x.y": "expected KEY=VALUES",
        "x..y=1": "dotted scene path",
        "x.y=nan": "must be finite",
    }
    for spec, message in bad.items():
        with pytest.raises(SweepError) as err:
            parse_param(spec)
        assert str(err.value).startswith(f"--param {spec}: ") and message in str(err.value), str(err.value)


def test_set_path_by_name_index_and_errors():
    scene = {"bodies": [{"name": "beam", "material": {"shear_modulus": 1.0}}, {"name": "tail", "material": "x"}],
             "fields": [{"type": "uniform", "B": [0, 0, 0]}, {"type": "loop", "name": "coil", "current": 1.0}]}
    set_path(scene, "bodies.beam.material.shear_modulus", 2.0)
    set_path(scene, "bodies.1.material", "dragon-skin-10")
    set_path(scene, "fields.0.B", [0, 0.01, 0])
    set_path(scene, "fields.coil.current", 5.0)  # any list entry with a matching 'name', fields included
    set_path(scene, "fields.-1.radius", 0.02)  # a new last key is allowed: the schema check decides
    assert scene["bodies"][0]["material"]["shear_modulus"] == 2.0 and scene["bodies"][1]["material"] == "dragon-skin-10"
    assert scene["fields"][0]["B"] == [0, 0.01, 0] and scene["fields"][1]["current"] == 5.0 and scene["fields"][1]["radius"] == 0.02
    errors = {
        "bodies.head.material": "bodies has no entry named 'head' (indices 0..1, names beam, tail)",
        "fields.7.B": "fields has no entry 7 (indices 0..1, names coil)",
        "bodies.beam.shape.center": "bodies.beam has no key 'shape' (keys material, name)",
        "bodies.tail.material.density": "bodies.tail.material is a str = 'dragon-skin-10', it has no 'density' inside",
        "probes.tip.name": "the scene has no key 'probes' (keys bodies, fields)",
    }
    for key, message in errors.items():
        with pytest.raises(SweepError) as err:
            set_path(scene, key, 1, f"{key}=1")
        assert str(err.value) == f"--param {key}=1: {message}"


def test_combine_product_and_zip():
    a, b = parse_param("a=1,2"), parse_param("b=x,y,z")
    product = combine([a, b])
    assert product == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 1, "b": "z"},
                       {"a": 2, "b": "x"}, {"a": 2, "b": "y"}, {"a": 2, "b": "z"}]
    assert combine([parse_param("a=1,2,3"), b], zipped=True) == [{"a": 1, "b": "x"}, {"a": 2, "b": "y"}, {"a": 3, "b": "z"}]
    with pytest.raises(SweepError, match=r"--zip needs the same number of values in every --param \(a: 2, b: 3\)"):
        combine([a, b], zipped=True)
    with pytest.raises(SweepError, match="given more than once"):
        combine([a, parse_param("a=3")])


# ----------------------------------------------------------------------------------------------- planning
def test_plan_builds_and_names_every_run(tmp_path):
    scene = write_scene(tmp_path)
    plan = make_plan(scene, ["bodies.beam.material.shear_modulus=1e5:3e5:3", "fields.0.B=[0,0.01,0],[0,0.02,0]"])
    assert len(plan.runs) == 6
    names = [r.name for r in plan.runs]
    assert len(set(names)) == 6 and names[0] == "000-shear_modulus=100000_B=0-0.01-0"
    assert all(n[:3] == f"{i:03d}" for i, n in enumerate(names))
    last = plan.runs[-1].scene
    assert last["bodies"][0]["material"]["shear_modulus"] == 3e5 and last["fields"][0]["B"] == [0, 0.02, 0]
    assert plan.base["fields"][0]["B"] == [0.0, 0.02, 0.0] and plan.runs[0].scene["fields"][0]["B"] == [0, 0.01, 0]
    # library materials by name, as strings
    plan = make_plan(scene, ["bodies.beam.material=ecoflex-00-30-ndfeb100,dragon-skin-10-ndfeb100"])
    assert [r.scene["bodies"][0]["material"] for r in plan.runs] == ["ecoflex-00-30-ndfeb100", "dragon-skin-10-ndfeb100"]


def test_bad_param_fails_before_any_run(tmp_path, capsys):
    from magsoro.cli import main

    scene = write_scene(tmp_path)
    with pytest.raises(SweepError) as err:
        make_plan(scene, ["fields.0.B=[0,0.01,0]", "bodies.beam.material.shear_modlus=1e5,2e5"])
    msg = str(err.value)
    assert msg.startswith("--param bodies.beam.material.shear_modlus=1e5,2e5: value 100000 makes the scene invalid")
    assert "unknown key 'shear_modlus'" in msg and "\n" not in msg
    with pytest.raises(SweepError, match=r"^--param simulation.dx=0.001,-1: value -1 makes the scene invalid: .*simulation.dx"):
        make_plan(scene, ["simulation.dx=0.001,-1"])
    with pytest.raises(SweepError, match=r"^--param bodies.head.material=x: bodies has no entry named 'head'"):
        make_plan(scene, ["bodies.head.material=x"])
    with pytest.raises(SweepError, match=r"^--param bodies.beam.material=no-such-material: value no-such-material makes the scene invalid"):
        make_plan(scene, ["bodies.beam.material=no-such-material"])
    out = tmp_path / "never"
    assert main(["sweep", str(scene), "--param", "simulation.dx=-1", "--out", str(out), "--quiet"]) == 2
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert len(err_lines) == 1 and err_lines[0].startswith("magsoro sweep: error: --param simulation.dx=-1:")
    assert not out.exists()
    assert main(["sweep", str(scene), "--param", "fields.0.B=[0,0.01,0],[0,0.02,0]", "--out", str(out), "--dry-run"]) == 0
    assert "2 runs; all scenes valid" in capsys.readouterr().out and not out.exists()


def test_worker_records_an_error_outside_the_stepping_loop(tmp_path):
    """A scene that breaks while being built is recorded as failed with its message; nothing is raised."""
    from magsoro.sweep.worker import execute_run

    bad = {"index": 3, "name": "003-bad", "params": {"x": 1}, "scene": {"simulation": {"dim": 2}}}
    rec = execute_run(bad, str(tmp_path / "003-bad"), str(tmp_path / "scene.toml"))
    assert rec["status"] == "failed" and "simulation.dx: required key is missing" in rec["error"]
    info = json.loads((tmp_path / "003-bad" / "run.json").read_text())
    assert info["status"] == "failed" and info["sweep"]["params"] == {"x": 1} and info["traceback"]


# ------------------------------------------------------------------------------------------- running on Dask
def test_sweep_on_local_cluster_records_the_failing_run(tmp_path):
    """6 runs on a 2-worker LocalCluster reached through its scheduler address (the --scheduler path; the
    sweep's own LocalCluster is exercised by the --resume test below), one of them failing."""
    from distributed import LocalCluster

    from magsoro.sweep.worker import SINGLE_THREAD_ENV

    scene = write_scene(tmp_path)
    plan = make_plan(scene, [f"fields.0.B={B_VALUES}", f"simulation.dt={DT_VALUES}"], zipped=True)
    seen = []
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, env=SINGLE_THREAD_ENV) as cluster:
        result = run_sweep(plan, tmp_path / "sweep", scheduler=cluster.scheduler_address,
                           progress=lambda s: seen.append((s.done, s.failed, s.eta)))
    assert result.workers == 2
    rows = read_csv(tmp_path / "sweep" / "summary.csv")
    assert [int(r["index"]) for r in rows] == list(range(6))
    assert list(rows[0])[:4] == ["index", "run", "fields.0.B", "simulation.dt"]
    assert [r["status"] for r in rows] == ["completed"] * 5 + ["failed"]
    failed = rows[5]
    assert failed["error"].startswith("step 1, t = 0.0002 s:") and "time step too large" in failed["error"]
    assert failed["tip_y"] == "" and failed["simulation.dt"] == "0.0004"
    assert json.loads((tmp_path / "sweep" / "runs" / failed["run"] / "run.json").read_text())["status"] == "failed"
    for r in rows[:5]:
        assert r["error"] == "" and float(r["wall_time_s"]) > 0 and int(r["steps"]) > 0
        metrics = read_csv(tmp_path / "sweep" / "runs" / r["run"] / "metrics.csv")
        assert float(r["tip_y"]) == pytest.approx(float(metrics[-1]["tip_y"]), rel=1e-8)
        assert float(metrics[-1]["time"]) == pytest.approx(0.001)
    # the tip deflects further in a stronger field (small deflection: about linear in B)
    tips = [float(r["tip_y"]) for r in rows[:5]]
    assert all(b > a for a, b in zip(tips, tips[1:]))
    assert tips[1] / tips[0] == pytest.approx(2.0, rel=0.05)
    # the Parquet copy holds the same table, numeric columns as numbers
    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "sweep" / "summary.parquet").to_pydict()
    assert table["status"] == [r["status"] for r in rows] and table["fields.0.B"][0] == "[0,0.01,0]"
    assert table["tip_y"][:5] == pytest.approx(tips) and table["tip_y"][5] is None
    # progress after every run: done counts up, the failure is counted, an estimated finish time is given
    assert [s[0] for s in seen] == list(range(1, 7)) and seen[-1][1] == 1
    assert all(s[2] is not None and s[2] > time.time() - 60 for s in seen)


def test_interrupted_sweep_resumes_without_duplicates_or_gaps(tmp_path):
    """Ctrl-C (SIGINT) half-way through `magsoro sweep`, then `--resume`: every run exactly once, and the runs
    finished before the interruption are not run again."""
    from magsoro.cli import main

    # runs long enough (0.01 s simulated, a few seconds each) that the interrupt lands while some are left even
    # on a busy machine, where the first runs wait for the worker's start and the later ones race through
    scene = write_scene(tmp_path, TINY_SCENE.replace("duration = 0.001", "duration = 0.01"))
    out = tmp_path / "sweep"
    args = ["sweep", str(scene), "--param", f"fields.0.B={B_VALUES}", "--out", str(out)]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # SIGINT back to its default in the child: a test run started in the background of a non-interactive shell
    # (`bash .ci/run &`) inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    proc = subprocess.Popen([sys.executable, "-m", "magsoro.cli", *args, "--workers", "1"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    done = 0
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "summary.csv").is_file():
            done = sum(r["status"] == "completed" for r in read_csv(out / "summary.csv"))
            if done >= 2:
                break
        time.sleep(0.05)
    assert proc.poll() is None, f"the sweep ended before it could be interrupted: {proc.communicate()}"
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "continue with --resume" in stderr
    before = {r["run"]: r["status"] for r in read_csv(out / "summary.csv")}
    finished_before = [name for name, s in before.items() if s == "completed"]
    assert 2 <= len(finished_before) < 6, before
    stamps = {n: (out / "runs" / n / "run.json").read_text() for n in finished_before}

    assert main(args + ["--quiet"]) == 2  # without --resume the folder is refused
    assert main(["sweep", str(scene), "--param", "fields.0.B=[0,0.07,0]", "--out", str(out), "--resume", "--quiet"]) == 2
    assert main(args + ["--resume", "--workers", "0", "--quiet"]) == 0

    rows = read_csv(out / "summary.csv")
    assert [int(r["index"]) for r in rows] == list(range(6))
    assert [r["status"] for r in rows] == ["completed"] * 6
    plan = json.loads((out / "sweep.json").read_text())
    assert sorted(p.name for p in (out / "runs").iterdir()) == [r["name"] for r in plan["runs"]]
    for n in finished_before:  # untouched: not run a second time
        assert (out / "runs" / n / "run.json").read_text() == stamps[n]
    for r in rows:
        metrics = read_csv(out / "runs" / r["run"] / "metrics.csv")
        times = [float(m["time"]) for m in metrics]
        assert times == sorted(times) and times[-1] == pytest.approx(0.01)  # one clean series per run
