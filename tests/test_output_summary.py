"""What `magsoro run` prints: a closing summary (final probe values with units, whether the run settled, notes,
wall time), nothing with --quiet, Warp's start-up and module-load lines only with -v, plain progress lines (no
redraws) when stderr is not a terminal, one line per level for --static; and `magsoro report` of a --static run
plots the probes against the level."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ROOT / "scenes" / "cantilever_2d.toml"


def _magsoro(*args, **kw):
    return subprocess.run([sys.executable, "-m", "magsoro", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, **kw)


def _cantilever(tmp_path, *extra, duration="0.02", name="out"):
    return _magsoro("run", CANTILEVER, "--out", tmp_path / name, "--duration", duration, *extra)


def test_run_ends_with_the_tip_and_whether_it_settled(tmp_path):
    """Two records (every 10 ms) of the ramp: the beam is still moving, and the summary's last lines say where the
    tip is (with units), that it has not settled and by which criterion; run.json keeps the verdict."""
    run = _cantilever(tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.strip().splitlines()
    assert lines[-3].startswith("final probe values at t = 0.02 s")
    tip = lines[-2].strip()
    assert tip.startswith("tip: x ") and tip.count(" m") == 2, tip
    assert lines[-1].startswith("settled: no"), lines[-1]
    assert "kinetic energy" in lines[-1] and "settled means" in lines[-1]
    assert any(ln.startswith("wall time ") and "0 notes" in ln for ln in lines)
    metrics = (tmp_path / "out" / "metrics.csv").read_text().strip().splitlines()
    assert f"{float(metrics[-1].split(',')[1]):.6g}" in tip  # the last row of metrics.csv
    info = json.loads((tmp_path / "out" / "run.json").read_text())
    assert info["settled"]["settled"] is False


def test_quiet_prints_nothing_on_success(tmp_path):
    run = _cantilever(tmp_path, "--quiet", duration="0.002")
    assert run.returncode == 0
    assert run.stdout == "" and run.stderr == ""


def test_warp_lines_only_with_verbose(tmp_path):
    """Without -v no Warp line (its banner, 'Module ... load on device', its no-driver CUDA warning); -v shows
    the banner and the module lines."""
    plain = _cantilever(tmp_path, duration="0.002", name="a")
    assert plain.returncode == 0, plain.stderr[-2000:]
    both = (plain.stdout + plain.stderr).splitlines()
    assert not [ln for ln in both if ln.startswith("Warp ") or "Module " in ln], both
    verbose = _cantilever(tmp_path, "-v", duration="0.002", name="b")
    assert verbose.returncode == 0, verbose.stderr[-2000:]
    assert "Warp " in verbose.stdout and "initialized" in verbose.stdout
    assert "Module " in verbose.stdout + verbose.stderr


def test_progress_into_a_pipe_is_lines_not_redraws(tmp_path):
    """stderr is a pipe here: progress comes as whole lines (at most one every few seconds), no carriage return."""
    run = _cantilever(tmp_path, duration="0.03")
    assert run.returncode == 0, run.stderr[-2000:]
    assert "\r" not in run.stderr and "\r" not in run.stdout
    progress = [ln for ln in run.stderr.splitlines() if ln.startswith("t = ")]
    assert progress and all(" of 0.03 s (" in ln for ln in progress)
    assert "%|" not in run.stderr  # no progress bar


def _static_scene(tmp_path) -> Path:
    scene = tmp_path / "cantilever_static.toml"
    scene.write_text(CANTILEVER.read_text().replace("[output]", "[static]\nlevels = [0.5, 1.0]\n\n[output]"))
    return scene


def test_static_prints_each_level_then_the_summary(tmp_path):
    run = _magsoro("run", _static_scene(tmp_path), "--static", "--out", tmp_path / "s")
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.strip().splitlines()
    levels = [ln for ln in lines if ln.startswith("level ")]
    assert [ln.split(":")[0] for ln in levels] == ["level 0.5", "level 1"]
    assert all("Newton iteration" in ln and "|R|" in ln for ln in levels)
    assert lines[-3] == "probe values at level 1 (the last):"
    assert lines[-2].strip().startswith("tip: x ") and lines[-2].count(" m") == 2
    assert lines[-1].startswith("equilibrium: converged at every level (2)")


def test_verbose_shows_each_newton_iteration(tmp_path):
    """-v: each load increment's Newton iterations on stderr, one line each with |R| and the step (no colliders
    here: no contact counts); as many lines per increment as the level's summary line counts iterations."""
    run = _magsoro("run", _static_scene(tmp_path), "--static", "-v", "--out", tmp_path / "s")
    assert run.returncode == 0, run.stderr[-2000:]
    blocks = [b.splitlines()[1:] for b in run.stderr.split("increment to ")[1:]]
    newton = [[ln.strip() for ln in b if ln.strip().startswith("newton ")] for b in blocks]
    assert len(newton) == 2 and all(newton)
    assert all("|R| " in ln and " cells" in ln and "contacts" not in ln for b in newton for ln in b)
    counts = [int(ln.split(" Newton iteration")[0].split()[-1]) for ln in run.stdout.splitlines()
              if ln.startswith("level ")]
    assert [len(b) for b in newton] == counts


def test_report_of_a_static_run_plots_the_levels(tmp_path):
    from magsoro.viz.report import run_content

    out = tmp_path / "s"
    run = _magsoro("run", _static_scene(tmp_path), "--static", "--quiet", "--out", out)
    assert run.returncode == 0, run.stderr[-2000:]
    content = run_content(out)
    charts = content["charts"]
    assert charts and charts[0]["title"] == "probe tip"
    assert charts[0]["xlabel"].startswith("field level")
    assert charts[0]["series"][0]["x"] == [0.0, 0.5, 1.0]
    facts = dict(content["facts"])
    assert "steps" not in facts and facts["levels"].startswith("2 solved")
    assert content["viewer"]["stamp"] == "level"
    rep = _magsoro("report", out)
    assert rep.returncode == 0, rep.stderr
    assert "No probe data" not in (out / "report.html").read_text()
