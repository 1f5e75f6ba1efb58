"""A careless or hostile user (issue "Reliability III"): nothing lost with --overwrite, no silent hangs, limits
stated before they bite. One test (or more) per numbered finding, named after it."""

import copy
import json
import os
import platform
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from magsoro.cli import main

SCENE = """
[simulation]
dim = 2
dx = 1e-3
domain_lo = [0.0, 0.0]
domain_hi = [0.02, 0.02]
duration = 0.004

[[bodies]]
name = "block"
shape = { type = "rectangle", center = [0.01, 0.01], size = [0.004, 0.004] }
material = { density = 1000.0, shear_modulus = 1e5 }
magnetization = [0.1, 0.0, 0.0]

[output]
every = 0.001
"""

BASE = {
    "simulation": {"dim": 2, "dx": 1e-3, "domain_lo": [0.0, 0.0], "domain_hi": [0.02, 0.02], "duration": 0.004},
    "bodies": [{"name": "b", "shape": {"type": "rectangle", "center": [0.01, 0.01], "size": [0.004, 0.004]},
                "material": {"density": 1000.0, "shear_modulus": 1e5}, "magnetization": [0.1, 0.0, 0.0]}],
}


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "block.toml"
    path.write_text(SCENE)
    return path


def _write_scene(tmp_path, text: str, name: str = "scene.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _one_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err[-3000:]
    return lines[0]


def _run(scene, out, *extra) -> int:
    return main(["run", str(scene), "--out", str(out), "--quiet", *extra])


def _run_bounded(scene, out, *extra, timeout: float = 60.0) -> tuple[int, str]:
    """``magsoro run`` in a child process that may not take longer than ``timeout`` s (the findings of a run that
    hangs must fail, not hang the tests): (exit status, stderr without Warp's CUDA line)."""
    try:
        proc = subprocess.run([sys.executable, "-m", "magsoro", "run", str(scene), "--out", str(out), "--quiet", *extra],
                              capture_output=True, text=True, timeout=timeout, env={**os.environ, "MAGSORO_THREADS": "1"})
    except subprocess.TimeoutExpired:
        pytest.fail(f"magsoro run {scene.name} was still running after {timeout:g} s")
    err = "\n".join(ln for ln in proc.stderr.splitlines() if "CUDA" not in ln)
    return proc.returncode, err


# ---------------------------------------------------------------------------------------------------- finding 1
def test_overwrite_keeps_foreign_files(scene, tmp_path, capsys):
    """--overwrite removes only what the run wrote (run.json's files); a folder holding anything else is refused,
    naming the first foreign entry, and nothing in it is touched."""
    out = tmp_path / "project"
    assert _run(scene, out) == 0
    info = json.loads((out / "run.json").read_text())
    assert "metrics.csv" in info["files"] and "frames/frame_*.vtp" in info["files"]
    (out / "report.html").write_text("old report")  # magsoro report's default page: the run's
    (out / "block.toml").write_text(SCENE)  # --out . in a project folder: the scene beside the results
    (out / "data").mkdir()
    (out / "data" / "measured.csv").write_text("t,x\n0,1\n")
    (out / "frames" / "notes.txt").write_text("precious")
    capsys.readouterr()
    assert _run(scene, out, "--overwrite") == 2
    line = _one_line(capsys.readouterr().err)
    assert "'block.toml'" in line and "did not write" in line
    assert (out / "block.toml").read_text() == SCENE and (out / "data" / "measured.csv").exists()
    assert (out / "frames" / "notes.txt").read_text() == "precious"
    assert (out / "metrics.csv").exists() and (out / "report.html").exists()  # refused: nothing removed
    for foreign in ("block.toml", "data/measured.csv"):
        (out / foreign).unlink()
    (out / "data").rmdir()
    assert _run(scene, out, "--overwrite") == 2
    assert "'frames/notes.txt'" in _one_line(capsys.readouterr().err)
    (out / "frames" / "notes.txt").unlink()
    (out / "frames" / ".frame_00001.vtp.abc123.tmp").write_text("left by a killed write")
    assert _run(scene, out, "--overwrite") == 0
    assert not (out / "report.html").exists() and not (out / "frames" / ".frame_00001.vtp.abc123.tmp").exists()
    assert json.loads((out / "run.json").read_text())["status"] == "completed"


def test_overwrite_does_not_trust_a_widened_file_list(scene, tmp_path, capsys):
    """run.json is only a file: a list naming everything ('*') does not let --overwrite remove other files."""
    out = tmp_path / "out"
    assert _run(scene, out) == 0
    info = json.loads((out / "run.json").read_text())
    info["files"] = ["*", "notes.txt"]
    (out / "run.json").write_text(json.dumps(info))
    (out / "notes.txt").write_text("keep")
    capsys.readouterr()
    assert _run(scene, out, "--overwrite") == 2
    assert "did not write" in _one_line(capsys.readouterr().err)
    assert (out / "notes.txt").read_text() == "keep"


# ---------------------------------------------------------------------------------------------------- finding 2
NAN_FIELD = SCENE + """
[[fields]]
type = "cylinder_magnet"
diameter = 0.01
length = 1e300
remanence = 1.3
position = [0.01, -0.03, 0.0]
axis = [0.0, 1.0, 0.0]
"""


def test_non_finite_time_step_is_refused_naming_the_field(tmp_path, capsys):
    """length = 1e300 made the field, so the time step, NaN: the run sat at t = 0 for ever. Now one line naming
    the source, before the output folder is touched."""
    path = _write_scene(tmp_path, NAN_FIELD)
    code, err = _run_bounded(path, tmp_path / "out", timeout=30)
    line = _one_line(err)
    assert code == 2 and "fields[0] (cylinder_magnet)" in line and "not finite" in line and str(path) in line
    assert not (tmp_path / "out").exists()


def test_every_computed_time_step_is_checked_for_being_finite():
    """A step that comes out NaN mid-run (here: the wave speed spoilt) ends the run 'failed' at once, naming
    the cause, instead of looping at the same time for ever."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(copy.deepcopy(BASE)))
    sim._wave_speed = float("nan")
    calls = []

    def guard(s):  # a step after every call: a run that does not end within 10,000 of them is stuck
        calls.append(s.time)
        if len(calls) > 10_000:
            raise RuntimeError(f"still stepping after 10,000 steps at t = {s.time}")

    result = sim.run(0.004, callback=guard)
    assert result.status == "failed" and "time step is not a finite positive number" in result.message
    assert not calls


def test_step_count_limit_names_the_key_and_allow_large_goes_ahead(tmp_path, capsys, monkeypatch):
    """density = 1e-30 gave steps of 1e-21 s and a run that never ended, without a word: now refused in one line
    naming the key and the flag; under a (here lowered) limit --allow-large runs anyway."""
    light = _write_scene(tmp_path, SCENE.replace("density = 1000.0", "density = 1e-30"), "light.toml")
    code, err = _run_bounded(light, tmp_path / "light", timeout=30)
    line = _one_line(err)
    assert code == 2 and "bodies[0].material.density = 1e-30" in line and "time steps" in line
    assert "--allow-large" in line
    strong = _write_scene(tmp_path, SCENE + '\n[[fields]]\ntype = "uniform"\nB = [0.0, 1e30, 0.0]\n', "strong.toml")
    code, err = _run_bounded(strong, tmp_path / "strong", timeout=30)
    assert code == 2 and "fields[0] (uniform)" in err and "time steps" in err
    import magsoro.limits as limits

    monkeypatch.setattr(limits, "MAX_STEPS", 5.0)
    path = _write_scene(tmp_path, SCENE)
    assert _run(path, tmp_path / "limited") == 2
    assert "more than 5e+00" in _one_line(capsys.readouterr().err)
    assert _run(path, tmp_path / "limited", "--allow-large") == 0
    assert json.loads((tmp_path / "limited" / "run.json").read_text())["status"] == "completed"
    from magsoro.cli import build_parser

    assert "--allow-large" in build_parser()._subparsers._group_actions[0].choices["run"].format_help()
    assert "--allow-large" in (Path(__file__).parents[1] / "README.md").read_text().split("## Using it")[1][:3000]


def test_scheduler_that_never_answers_times_out(scene, tmp_path):
    """Something listens at --scheduler but never answers: the sweep ends with one line within its overall
    timeout instead of hanging for minutes."""
    from magsoro.sweep import make_plan, run_sweep
    from magsoro.sweep import runner
    from magsoro.sweep.params import SweepError

    pytest.importorskip("distributed")
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)  # the kernel completes connections; nothing reads or writes on them
    port = server.getsockname()[1]
    plan = make_plan(scene, ["bodies.block.material.shear_modulus=1e5"])
    old = getattr(runner, "SCHEDULER_TIMEOUT_S", None)
    runner.SCHEDULER_TIMEOUT_S = 2.0
    box = {}

    def attempt():
        try:
            run_sweep(plan, tmp_path / "sweep", scheduler=f"127.0.0.1:{port}")
        except BaseException as exc:  # noqa: BLE001
            box["error"] = exc

    try:
        t0 = time.perf_counter()
        thread = threading.Thread(target=attempt, daemon=True)
        thread.start()
        thread.join(20.0)
        assert not thread.is_alive(), "the sweep still waits for the scheduler after 20 s"
        assert time.perf_counter() - t0 < 20.0
        exc = box.get("error")
        assert isinstance(exc, SweepError) and f"127.0.0.1:{port}" in str(exc) and "\n" not in str(exc), exc
    finally:
        runner.SCHEDULER_TIMEOUT_S = old
        server.close()


# ---------------------------------------------------------------------------------------------------- finding 3
@pytest.mark.parametrize("value", ["abc", "-1", "0", "1e3"])
def test_magsoro_threads_is_validated(value, scene, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MAGSORO_THREADS", value)
    assert _run(scene, tmp_path / "out") == 2
    line = _one_line(capsys.readouterr().err)
    assert "MAGSORO_THREADS" in line and ">= 1" in line and repr(value) in line


def test_magsoro_threads_is_capped_at_the_usable_cores_with_a_note(monkeypatch):
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    scene = copy.deepcopy(BASE)
    scene["bodies"][0]["shape"]["size"] = [0.012, 0.012]  # 576 particles: room for many threads
    monkeypatch.setenv("MAGSORO_THREADS", "99999")
    sim = Simulation(parse_scene(scene))
    assert sim.solver.threads <= cores
    notes = [n for n in sim.notes if "MAGSORO_THREADS" in n]
    assert notes and "99999" in notes[0] and f"{cores} usable" in notes[0]
    assert notes[0] in sim.scene_notes  # printed by magsoro run, kept in run.json


# ---------------------------------------------------------------------------------------------------- finding 4
def test_memory_estimate_refuses_before_building(tmp_path, capsys, monkeypatch):
    """Three bodies each under the 1e8-site cap, together about 2.6e8 particles (hundreds of GB): refused from
    the shapes alone, in one line naming simulation.dx and the flag, before any lattice is filled."""
    import magsoro.limits as limits
    import magsoro.scene.build as build

    def no_filling(*args, **kw):
        raise AssertionError("a lattice was filled before the memory check")

    monkeypatch.setattr(build, "fill_lattice", no_filling)
    monkeypatch.setattr(limits, "available_memory", lambda: (64e9, "test"))
    boxes = "\n".join(
        f'[[bodies]]\nname = "b{k}"\nshape = {{ type = "box", center = [{0.015 + 0.025 * k}, 0.015, 0.015], '
        f'size = [0.022, 0.022, 0.022] }}\nmaterial = {{ density = 1000.0, shear_modulus = 1e5 }}\n' for k in range(3))
    text = ("[simulation]\ndim = 3\ndx = 1e-4\ndomain_lo = [0.0, 0.0, 0.0]\ndomain_hi = [0.09, 0.03, 0.03]\n"
            "duration = 0.001\n\n" + boxes)
    path = _write_scene(tmp_path, text)
    t0 = time.perf_counter()
    assert _run(path, tmp_path / "out") == 2
    line = _one_line(capsys.readouterr().err)
    assert "simulation.dx" in line and "GB" in line and "--allow-large" in line and "particles" in line
    assert time.perf_counter() - t0 < 10 and not (tmp_path / "out").exists()
    need, particles, _ = limits.estimate_memory(__import__("magsoro.scene", fromlist=["load_scene"]).load_scene(path))
    assert 2e8 < particles < 3e8 and need > 64e9


# ---------------------------------------------------------------------------------------------------- finding 5
def test_sweep_of_too_many_runs_is_refused_before_planning(scene, tmp_path, capsys, monkeypatch):
    """Three 1,000-value parameters (10^9 runs) ran out of memory while planning: now refused before a run is
    made; more than 1,000 runs need --allow-large, more than 100,000 are refused in any case."""
    import magsoro.sweep.plan as plan_module

    real = plan_module.combine

    def guarded(params, zipped=False):
        assert np.prod([len(p.values) for p in params]) <= 10_000, "planning started on a sweep that is too large"
        return real(params, zipped)

    monkeypatch.setattr(plan_module, "combine", guarded)
    params = [f"bodies.block.material.{k}=1:2:1000" for k in ("shear_modulus", "density", "bulk_modulus")]
    argv = ["sweep", str(scene), *sum((["--param", p] for p in params), []), "--out", str(tmp_path / "s"), "--dry-run"]
    t0 = time.perf_counter()
    assert main(argv) == 2
    line = _one_line(capsys.readouterr().err)
    assert "1,000,000,000 runs" in line and "--allow-large" in line and time.perf_counter() - t0 < 10
    assert main(argv + ["--allow-large"]) == 2
    assert "more than 100,000" in _one_line(capsys.readouterr().err)
    from magsoro.sweep.params import SweepError, check_run_count, parse_param

    two = [parse_param("bodies.block.material.density=1:2:40"), parse_param("bodies.block.material.shear_modulus=1:2:40")]
    with pytest.raises(SweepError, match="1,600 runs"):
        check_run_count(two)
    assert check_run_count(two, allow_large=True) == 1600
    with pytest.raises(SweepError, match="range count"):
        parse_param("bodies.block.material.density=1:2:1e12")


# ---------------------------------------------------------------------------------------------------- finding 6
def _laughs(levels: int) -> str:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ",".join([f"*a{k - 1}"] * 9) + "]")
    return "\n".join(lines) + f"\nsegments: *a{levels - 1}\nremenance: 0.1\n"


@pytest.mark.parametrize("levels", [6, 9])
def test_yaml_nested_anchors_are_refused_in_one_short_line(levels, tmp_path, capsys):
    """A few hundred bytes of nested anchors made a 4 MB error line (6 levels: 531,441 values) or 3 GB and a
    MemoryError (9 levels); now one short line, from the composed document, without building the expansion."""
    robot = tmp_path / "robot.yaml"
    robot.write_text(_laughs(levels))
    assert len(robot.read_bytes()) < 1000
    t0 = time.perf_counter()
    assert main(["import-magneticmpm", str(robot), "--out", str(tmp_path / "robot.toml")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert len(line) < 300 and str(robot) in line and "aliases" in line
    assert time.perf_counter() - t0 < 10


def test_yaml_anchors_used_sparingly_still_load(tmp_path):
    from magsoro.scene.magneticmpm import _load_yaml

    data = _load_yaml(tmp_path / "x.yaml", "base: &b {density: 1000}\nsegments: [*b, *b]\n")
    assert data["segments"] == [{"density": 1000}, {"density": 1000}]


# ---------------------------------------------------------------------------------------------------- finding 7
def test_stale_heartbeat_with_a_live_pid_reads_stale(scene, tmp_path, capsys):
    """A run.json whose process id was given to another process (containers reuse small ids) blocked its folder
    for good, even with --overwrite, although its heartbeat was 45 minutes old."""
    from magsoro.io import outdir
    from magsoro.io.outdir import run_state

    out = tmp_path / "out"
    assert _run(scene, out) == 0
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        info = json.loads((out / "run.json").read_text())
        info.update(status="running", pid=other.pid, machine=platform.node(), heartbeat_unix=time.time() - 2700)
        state, why = run_state(info)
        assert state == "stale" and "45 minutes" not in why and "2700 s" in why and str(other.pid) in why
        assert run_state({**info, "heartbeat_unix": time.time() - 5})[0] == "running"
        assert run_state({**info, "heartbeat_unix": time.time() - outdir.STALE_ALIVE_AFTER_S + 30})[0] == "running"
        assert run_state({**info, "pid": os.getpid(), "heartbeat_unix": time.time() - 300})[0] == "stale"  # our id now
        (out / "run.json").write_text(json.dumps(info))
        capsys.readouterr()
        assert _run(scene, out, "--overwrite") == 0
        assert json.loads((out / "run.json").read_text())["status"] == "completed"
    finally:
        other.kill()
        other.wait()


def test_a_static_solve_keeps_beating():
    """The heartbeat that tells a working run from a reused process id goes on while a static level solves."""
    from magsoro.io import recorder

    beats = []

    class Writer:
        beating = recorder.RunWriter.beating

        def beat(self, sim=None, force=False):
            beats.append(force)

    old = recorder.HEARTBEAT_S
    recorder.HEARTBEAT_S = 0.05
    try:
        with Writer().beating():
            time.sleep(0.5)
    finally:
        recorder.HEARTBEAT_S = old
    assert len(beats) >= 3 and all(beats)


# ---------------------------------------------------------------------------------------------------- finding 8
def _messages_cases(tmp_path):
    kf = tmp_path / "kf.csv"
    kf.write_text("t,Bx,By,Bz\n0,0,0.01,0\n0.1,nan,0.01,0\n")
    mat = tmp_path / "mat.toml"
    mat.write_text("this is not = = toml\n")
    stl = tmp_path / "mag.stl"
    stl.write_text("solid x\nfacet normal 0 0 1\n outer loop\n vertex 0 0 0\n endloop\nendfacet\nendsolid\n")
    csv_bad = tmp_path / "mag.csv"
    csv_bad.write_text("x,y,z,Brx,Bry,Brz\nfacet normal 0 0 1\n")
    bow = ("[simulation]\ndim = 3\ndx = 1e-3\ndomain_lo = [0.0, 0.0, 0.0]\ndomain_hi = [0.02, 0.02, 0.02]\n"
           "duration = 0.004\n\n[[bodies]]\nname = \"bow\"\nshape = { type = \"extrusion\", vertices = [[0,0],"
           "[0.004,0.004],[0.004,0],[0,0.004]], thickness = 0.002, position = [0.01,0.01,0.01] }\n"
           "material = { density = 1000.0, shear_modulus = 1e5 }\n")
    return {
        "keyframe_nan": (SCENE + '\n[[fields]]\ntype = "keyframes"\nfile = "kf.csv"\n',
                         ["fields[0].file", str(kf), "line 3", "Bx", "not finite"]),
        "material_not_toml": (SCENE.replace('material = { density = 1000.0, shear_modulus = 1e5 }',
                                            'material = { file = "mat.toml" }'),
                              ["bodies[0].material.file", str(mat), "not valid TOML"]),
        "magnetisation_stl": (SCENE.replace("magnetization = [0.1, 0.0, 0.0]",
                                            'magnetization = { type = "file", file = "mag.stl" }'),
                              ["bodies[0].magnetization.file", str(stl), ".csv"]),
        "magnetisation_csv_of_text": (SCENE.replace("magnetization = [0.1, 0.0, 0.0]",
                                                    'magnetization = { type = "file", file = "mag.csv" }'),
                                      ["bodies[0].magnetization.file", str(csv_bad), "not a CSV of numbers"]),
        "self_intersecting_extrusion": (bow, ["bodies[0].shape", "vertices", "edges 0 and 2", "cross"]),
    }


@pytest.mark.parametrize("case", ["keyframe_nan", "material_not_toml", "magnetisation_stl",
                                  "magnetisation_csv_of_text", "self_intersecting_extrusion"])
def test_messages_name_the_file_and_field(case, tmp_path, capsys):
    text, wanted = _messages_cases(tmp_path)[case]
    path = _write_scene(tmp_path, text)
    assert _run(path, tmp_path / "out") == 2
    line = _one_line(capsys.readouterr().err)
    assert str(path) in line, line
    for w in wanted:
        assert w in line, (w, line)


def test_report_names_a_metrics_file_that_is_not_utf8(scene, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(scene, out) == 0
    (out / "metrics.csv").write_bytes(b"time,c\n0,\xff\xfe\n")
    capsys.readouterr()
    assert main(["report", str(out), "--out", str(tmp_path / "r.html")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert str(out / "metrics.csv") in line and "UTF-8" in line


# ---------------------------------------------------------------------------------------------------- finding 9
def test_report_survives_wrong_types_in_run_json(scene, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(scene, out) == 0
    good = json.loads((out / "run.json").read_text())
    for key, value in (("notes", 5), ("scene", "beam"), ("sweep", {"params": [1, 2]}), ("bodies", 3)):
        (out / "run.json").write_text(json.dumps({**good, key: value}))
        capsys.readouterr()
        assert main(["report", str(out), "--out", str(tmp_path / "r.html")]) == 2, key
        line = _one_line(capsys.readouterr().err)
        assert str(out / "run.json") in line and f"'{'params' if key == 'sweep' else key}'" in line, line


def test_report_survives_a_sweep_json_without_params(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    (sweep / "runs").mkdir(parents=True)
    base = {"scene_file": "x.toml", "params": [{"key": "fields.0.B", "values": [1, 2]}], "mode": "product",
            "runs": [{"index": 0, "name": "000-B=1", "params": {"fields.0.B": 1}}]}
    for broken in ({k: v for k, v in base.items() if k != "params"},
                   {**base, "runs": [{"index": 0, "name": "000-B=1"}]},
                   {**base, "runs": [{"index": 0, "name": "000-B=1", "params": {}}]},
                   {**base, "params": [{"values": [1]}]}):
        (sweep / "sweep.json").write_text(json.dumps(broken))
        capsys.readouterr()
        assert main(["report", str(sweep), "--out", str(tmp_path / "r.html")]) == 2
        line = _one_line(capsys.readouterr().err)
        assert str(sweep / "sweep.json") in line and ("params" in line or "runs" in line), line


def test_report_caps_the_metrics_rows_it_embeds(scene, tmp_path, capsys):
    from magsoro.viz import report

    MAX_METRIC_ROWS = getattr(report, "MAX_METRIC_ROWS", 10_000)

    out = tmp_path / "out"
    assert _run(scene, out) == 0
    header = (out / "metrics.csv").read_text().splitlines()[0]
    n = 5 * MAX_METRIC_ROWS + 3
    t = np.arange(n) * 1e-6
    body = "\n".join(f"{v:.9g}" for v in t)
    (out / "metrics.csv").write_text("time\n" + body + "\n")
    assert header.startswith("time")
    page = tmp_path / "r.html"
    assert main(["report", str(out), "--out", str(page)]) == 0
    text = page.read_text()
    assert f"of the {n:,} rows of metrics.csv" in text
    # the run has no probe columns here, so no curve; with one, the embedded curve is capped
    (out / "metrics.csv").write_text("time,c_x\n" + "\n".join(f"{v:.9g},{2 * v:.9g}" for v in t) + "\n")
    assert main(["report", str(out), "--out", str(page)]) == 0
    text = page.read_text()
    data = json.loads(re.search(r'<script type="application/json" id="report-data">(.*?)</script>', text, re.S).group(1))
    xs = data["charts"][0]["series"][0]["x"]
    assert len(xs) <= MAX_METRIC_ROWS and xs[0] == 0.0 and xs[-1] == pytest.approx(t[-1])
    assert len(text) < 2_000_000


# --------------------------------------------------------------------------------------------------- finding 10
def test_implausible_field_and_remanence_are_warned():
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    scene = copy.deepcopy(BASE)
    scene["bodies"][0]["magnetization"] = [5.0, 0.0, 0.0]
    scene["fields"] = [{"type": "uniform", "B": [0.0, 20.0, 0.0]}]
    sim = Simulation(parse_scene(scene))
    field = [n for n in sim.scene_notes if n.startswith("fields[0]")]
    remanence = [n for n in sim.scene_notes if n.startswith("bodies[0].magnetization")]
    assert field and "20 T" in field[0] and "above 2 T" in field[0]
    assert remanence and "5 T" in remanence[0] and "above 1.6 T" in remanence[0]
    scene = copy.deepcopy(BASE)
    scene["fields"] = [{"type": "uniform", "B": [0.0, 0.02, 0.0]}]
    assert not [n for n in Simulation(parse_scene(scene)).scene_notes if "tesla" in n]  # 20 mT, 0.1 T: no note


def test_implausible_values_are_printed_before_the_run(tmp_path, capsys):
    path = _write_scene(tmp_path, SCENE.replace("[0.1, 0.0, 0.0]", "[5.0, 0.0, 0.0]"))
    # without --quiet (which prints nothing but errors: the note then lives in run.json only)
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert err.count("|Br| = 5 T") == 1
    assert any("|Br| = 5 T" in n for n in json.loads((tmp_path / "out" / "run.json").read_text())["notes"])


# --------------------------------------------------------------------------------------------------- finding 11
def _static_scene(tmp_path) -> Path:
    return _write_scene(tmp_path, SCENE + '\n[[fields]]\ntype = "uniform"\nB = [0.0, 0.01, 0.0]\n', "static.toml")


def test_static_run_interrupted_prints_like_a_dynamic_one(tmp_path, capsys, monkeypatch):
    from magsoro.errors import Terminated
    from magsoro.simulation import Simulation

    def stopped(self, *args, **kw):
        raise Terminated(signal.SIGTERM)

    monkeypatch.setattr(Simulation, "solve_static", stopped)
    out = tmp_path / "out"
    assert _run(_static_scene(tmp_path), out, "--static") == 128 + signal.SIGTERM
    err = capsys.readouterr().err
    assert "magsoro run --static: interrupted: terminated by SIGTERM" in err and "results so far in" in err
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "interrupted" and info["signal"] == signal.SIGTERM


def test_sigterm_after_a_static_run_completes_keeps_exit_code_and_run_json_consistent(tmp_path, capsys, monkeypatch):
    """SIGTERM just after the closing run.json ('completed') used to exit 143; now the signal waits until the
    outcome is recorded, and the exit status is the one run.json gives."""
    from magsoro.io.recorder import RunWriter
    from magsoro.mpm.newton.static import StaticResult
    from magsoro.simulation import Simulation

    monkeypatch.setattr(Simulation, "solve_static", lambda self, *a, **kw: StaticResult(True, message="1 level(s) converged"))
    real_finish = RunWriter.finish

    def finish_then_signal(self, result, wall):
        real_finish(self, result, wall)
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(RunWriter, "finish", finish_then_signal)
    out = tmp_path / "out"
    code = _run(_static_scene(tmp_path), out, "--static")
    status = json.loads((out / "run.json").read_text())["status"]
    assert (status, code) == ("completed", 0)
    assert signal.getsignal(signal.SIGTERM) not in (signal.SIG_IGN, None)  # the handler is back


SWEEP_SCENE = SCENE.replace("duration = 0.004", "duration = 100.0").replace("every = 0.001", "every = 0.002\nparticles = false")


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigterm_to_a_sweep_with_workers_0_exits_143(tmp_path):
    scene = _write_scene(tmp_path, SWEEP_SCENE)
    out = tmp_path / "sweep"
    proc = subprocess.Popen([sys.executable, "-m", "magsoro", "sweep", str(scene), "--param",
                             "bodies.block.material.shear_modulus=1e5", "--workers", "0", "--out", str(out), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "MAGSORO_THREADS": "1"})
    deadline = time.time() + 60
    metrics = None
    while time.time() < deadline:
        found = list(out.glob("runs/*/metrics.csv"))
        if found and len(found[0].read_text().splitlines()) > 3:
            metrics = found[0]
            break
        time.sleep(0.2)
    assert metrics is not None and proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "Traceback" not in err and "--resume" in err
    assert json.loads((metrics.parent / "run.json").read_text())["status"] == "interrupted"
