"""The public API and the package as installed: ``magsoro.__all__``, a cheap ``import magsoro``, the static
solver's precision rule shared by the API and the command line, run results with their metrics table, the sweep
extra's one-line message, and the repository folders the wheel ships (scenes/, examples/)."""

import csv
import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import magsoro
from magsoro import bundled

ROOT = Path(__file__).resolve().parents[1]
STRIP = ROOT / "examples" / "tutorial" / "strip.toml"


# -- the API -----------------------------------------------------------------------------------------------
def test_all_lists_the_public_names_and_each_resolves():
    public = {"Simulation", "RunResult", "StaticRun", "RelaxResult", "prepare_static", "Scene", "load_scene",
              "parse_scene", "MU0", "MagsoroError", "SceneError", "SimulationError", "OutputError", "__version__"}
    assert public <= set(magsoro.__all__), public - set(magsoro.__all__)
    assert len(magsoro.__all__) == len(set(magsoro.__all__))
    for name in magsoro.__all__:
        assert getattr(magsoro, name) is not None, name
        assert name in dir(magsoro), name
    from magsoro.simulation import Simulation

    assert magsoro.Simulation is Simulation
    with pytest.raises(AttributeError, match="no attribute 'Simulaton'"):
        magsoro.Simulaton  # noqa: B018


def test_import_magsoro_loads_neither_warp_nor_the_sweep_packages():
    code = ("import sys, magsoro; print(sorted(m for m in ('warp', 'numpy', 'scipy', 'dask', 'distributed', "
            "'pyarrow') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_prepare_static_is_float64_and_total_and_refuses_updated():
    from magsoro.errors import SceneError
    from magsoro.simulation import prepare_static

    scene = magsoro.load_scene(STRIP)
    assert scene.simulation.precision == "float32"
    notes = prepare_static(scene)
    assert (scene.simulation.precision, scene.simulation.formulation) == ("float64", "total")
    assert len(notes) == 1 and "float64" in notes[0]
    assert prepare_static(scene) == []  # already float64: nothing to note
    scene = magsoro.load_scene(STRIP)
    scene.simulation.formulation = "updated"
    with pytest.raises(SceneError, match="total-Lagrangian"):
        prepare_static(scene)


def _cli_static(tmp_path, monkeypatch):
    """``magsoro run STRIP --static`` in this process, recording the calls of the shared precision rule."""
    import magsoro.simulation as simulation
    from magsoro.cli import main

    calls = []
    rule = simulation.prepare_static

    def recording(scene):
        calls.append(scene.simulation.precision)
        return rule(scene)

    monkeypatch.setattr(simulation, "prepare_static", recording)
    assert main(["run", str(STRIP), "--static", "--quiet", "--out", str(tmp_path / "cli")]) == 0
    with open(tmp_path / "cli" / "metrics.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return calls, rows


def test_solve_static_converges_on_the_tutorial_strip_as_the_command_line_does(tmp_path, monkeypatch):
    calls, rows = _cli_static(tmp_path, monkeypatch)
    assert calls == ["float32"]  # the command line went through the shared rule
    sim = magsoro.Simulation.from_file(STRIP, device="cpu")
    assert sim.model.np_scalar == np.float32  # the scene's own precision until the static solve
    res = sim.solve_static()
    assert res.converged, res.message
    assert sim.model.np_scalar == np.float64 and sim.solver.settings.formulation == "total"
    assert any("float64" in n for n in sim.notes)
    assert res.metrics.dtype.names == ("level", "tip_x", "tip_y")
    assert res.metrics["level"].tolist() == [1.0]
    last = rows[-1]
    assert float(last["level"]) == 1.0
    for col in ("tip_x", "tip_y"):
        assert res.metrics[col][-1] == pytest.approx(float(last[col]), rel=1e-6, abs=1e-9), col
    assert res.metrics["tip_y"][-1] > 1e-3  # bent up by the field: mm, not round-off


def test_run_result_carries_the_metrics_table_and_static_after_steps_is_refused():
    sim = magsoro.Simulation.from_file(STRIP, device="cpu")
    res = sim.run(duration=0.002, record_every=0.001)
    assert res.status == "completed", res.message
    table = res.metrics
    assert isinstance(table, np.ndarray) and table.dtype.names == ("time", *sim.probe_columns())
    assert table.dtype.names == ("time", "tip_x", "tip_y")
    np.testing.assert_allclose(table["time"], [0.0, 0.001, 0.002], atol=1e-12)
    now = sim.probe_values()
    assert table["tip_x"][-1] == now["tip_x"] and table["tip_y"][-1] == now["tip_y"]
    assert table["tip_x"][0] == pytest.approx(0.00995, abs=1e-4)  # the probe's start, not a placeholder
    try:
        import pandas  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="pandas"):
            res.dataframe()
    else:
        assert list(res.dataframe().columns) == ["time", "tip_x", "tip_y"]
    with pytest.raises(magsoro.SimulationError, match="float64"):
        sim.solve_static()


# -- the sweep extra --------------------------------------------------------------------------------------------
def test_pyproject_keeps_the_sweep_packages_in_extras():
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]

    def names(reqs):
        return {r.split("[")[0].split(">")[0].split("<")[0].split("=")[0].strip().lower() for r in reqs}

    sweep = {"dask", "pyarrow"}
    assert not sweep & names(project["dependencies"])
    assert sweep <= names(project["optional-dependencies"]["sweep"])
    assert sweep <= names(project["optional-dependencies"]["test"])  # CI still tests sweeps


def test_a_sweep_without_dask_says_the_extra_in_one_line(tmp_path, monkeypatch, capsys):
    from magsoro.cli import main
    from magsoro.sweep import SweepError, make_plan, run_sweep
    from magsoro.sweep.extra import require_distributed

    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` raises ImportError
    with pytest.raises(SweepError) as exc:
        require_distributed()
    message = str(exc.value)
    assert "\n" not in message and "pip install 'magsoro[sweep]'" in message and "dask.distributed" in message
    plan = make_plan(ROOT / "scenes" / "cantilever_2d.toml", ["simulation.damping=1,2"])
    with pytest.raises(SweepError, match=r"magsoro\[sweep\]"):
        run_sweep(plan, tmp_path / "lib", workers=2)
    assert not (tmp_path / "lib").exists()  # refused before anything was written
    capsys.readouterr()
    rc = main(["sweep", str(ROOT / "scenes" / "cantilever_2d.toml"), "--param", "simulation.damping=1,2",
               "--out", str(tmp_path / "cli")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "pip install 'magsoro[sweep]'" in err[0], err
    assert not (tmp_path / "cli").exists()


def test_the_sweep_modules_import_without_dask_and_parquet_names_the_extra():
    # the report reads sweep folders through magsoro.sweep: it must import on a core install
    code = ("import sys\n"
            "for m in ('dask', 'distributed', 'pyarrow'): sys.modules[m] = None\n"
            "import magsoro.sweep, magsoro.sweep.summary, magsoro.sweep.worker, magsoro.sweep.runner\n"
            "from magsoro.sweep.extra import parquet_note\n"
            "print(parquet_note())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "pip install 'magsoro[sweep]'" in out.stdout and "pyarrow" in out.stdout


# -- package data -----------------------------------------------------------------------------------------------
def _tracked(folders) -> list[Path] | None:
    try:
        out = subprocess.run(["git", "ls-files", "-z", *folders], cwd=ROOT, capture_output=True, timeout=60)
    except OSError:
        return None
    if out.returncode != 0:
        return None
    return sorted(Path(p) for p in out.stdout.decode().split("\0") if p and (ROOT / p).is_file())


def test_manifest_and_bundle_cover_every_tracked_file_of_the_shipped_folders():
    lines = [line.split() for line in (ROOT / "MANIFEST.in").read_text().splitlines()
             if line.strip() and not line.startswith("#")]
    for folder in bundled.FOLDERS:
        assert ["graft", folder] in lines, f"MANIFEST.in does not graft {folder}/ (the sdist would lack it)"
    files = bundled.bundled_files(ROOT)
    assert any(p.parts[0] == "scenes" for p in files) and any(p.parts[0] == "examples" for p in files)
    tracked = _tracked(bundled.FOLDERS)
    if tracked is None:
        pytest.skip("not a git checkout: the tracked files cannot be listed")
    missing = sorted(set(tracked) - set(files))
    assert not missing, f"tracked but not shipped in the wheel: {missing[:10]}"


def test_setup_build_py_copies_the_bundle_into_the_built_package(tmp_path, monkeypatch):
    """setup.py's build_py, run as the wheel build runs it: the package and every bundled file end up in
    build_lib, and the files the robot library and the tutorial read are among them."""
    import runpy

    setuptools = pytest.importorskip("setuptools", reason="setup.py's build hook needs setuptools in this venv")
    from setuptools.dist import Distribution

    monkeypatch.setattr(setuptools, "setup", lambda **kw: kw)
    namespace = runpy.run_path(str(ROOT / "setup.py"))
    command = namespace["BuildPyWithBundle"]
    monkeypatch.chdir(ROOT)
    dist = Distribution({"name": "magsoro", "package_dir": {"": "src"},
                         "packages": setuptools.find_packages("src"), "package_data": {"magsoro": ["data/*"]}})
    dist.script_name = str(ROOT / "setup.py")
    cmd = command(dist)
    cmd.build_lib = str(tmp_path / "lib")
    cmd.ensure_finalized()
    cmd.run()
    package = tmp_path / "lib" / "magsoro"
    assert (package / "simulation.py").is_file() and (package / "data" / "materials.toml").is_file()
    shipped = package / bundled.BUNDLE_DIR
    for rel in bundled.bundled_files(ROOT):
        assert (shipped / rel).is_file(), f"{rel} is not in the built package"

    from magsoro.robots import ROBOTS
    from magsoro.robots.growing_retroflexion import PLAN

    needed = [Path("scenes") / f"{name}.toml" for name in ROBOTS] + [PLAN, Path("scenes") / "meshes"]
    needed += [STRIP.relative_to(ROOT), *(p.relative_to(ROOT) for p in (ROOT / "examples" / "tutorial").glob("*.toml"))]
    for rel in needed:
        assert (shipped / rel).exists(), f"{rel} (read by the robot library or the tutorial) is not shipped"


def test_shipped_paths_resolve_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scene = magsoro.load_scene("scenes/cantilever_2d.toml")
    assert Path(scene.source_path).is_file() and Path(scene.source_path).is_relative_to(bundled.data_root())
    assert bundled.resolve_data_path("examples/tutorial/strip.toml").is_file()
    with pytest.raises(magsoro.SceneError, match="scenes/no_such_scene.toml"):
        magsoro.load_scene("scenes/no_such_scene.toml")
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "cantilever_2d.toml").write_text((ROOT / "scenes" / "cantilever_2d.toml").read_text())
    assert bundled.resolve_data_path("scenes/cantilever_2d.toml") == Path("scenes/cantilever_2d.toml")  # a local file wins


def test_an_installed_bundle_is_preferred_to_the_checkout(tmp_path, monkeypatch):
    for folder in bundled.FOLDERS:
        (tmp_path / folder).mkdir()
    monkeypatch.setattr(bundled, "_INSTALLED", tmp_path)
    monkeypatch.delenv("MAGSORO_SCENES", raising=False)
    robots_base = importlib.import_module("magsoro.robots.base")
    assert bundled.data_root() == tmp_path and robots_base.scenes_dir() == tmp_path / "scenes"
    monkeypatch.setattr(bundled, "_INSTALLED", tmp_path / "absent")
    assert bundled.data_root() == ROOT and robots_base.scenes_dir() == ROOT / "scenes"
    monkeypatch.setattr(bundled, "_CHECKOUT", tmp_path / "absent")
    with pytest.raises(robots_base.RobotError, match="MAGSORO_SCENES"):
        robots_base.scenes_dir()
