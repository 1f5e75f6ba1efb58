"""``magsoro report``: the HTML page's content for a run and for a sweep (the browser checks are in
test_report_browser.py)."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

# A 2D clamped strip in a uniform field: 176 particles, 1 ms of simulated time, about half a second of CPU.
TINY_SCENE = """\
name = "tiny"
[simulation]
dim = 2
dx = 5.0e-4
domain_lo = [0.0, -0.006]
domain_hi = [0.014, 0.006]
duration = 0.001
damping = 100.0
depth = 5.0e-3

[[bodies]]
name = "beam"
shape = { type = "rectangle", center = [0.0065, 0.0], size = [0.011, 0.001] }
material = { density = 1030.0, shear_modulus = 3.0e5 }
magnetization = [0.1, 0.0, 0.0]

[[clamps]]
region = { type = "rectangle", center = [0.0012, 0.0], size = [0.0014, 0.003] }

[[fields]]
type = "uniform"
B = [0.0, 0.02, 0.0]

[[probes]]
type = "tip"
name = "tip"
body = "beam"
region = { type = "rectangle", center = [0.0115, 0.0], size = [0.001, 0.003] }

[output]
every = 0.0002
"""


def write_scene(folder: Path, text: str = TINY_SCENE) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "tiny.toml"
    path.write_text(text)
    return path


def make_run_dir(out: Path) -> Path:
    """A run directory as ``magsoro run`` writes it (in this process)."""
    from magsoro.commands.run import run as run_command

    scene = write_scene(out.parent / "scene")

    class Args:
        pass

    args = Args()
    args.scene, args.out, args.device, args.duration, args.quiet = str(scene), str(out), None, None, True
    assert run_command(args) == 0
    return out


def make_sweep_dir(out: Path) -> Path:
    """A 3-run sweep run in this process (workers=0): two completed time steps and one too large to be stable."""
    from magsoro.sweep import make_plan, run_sweep

    scene = write_scene(out.parent / "scene")
    plan = make_plan(scene, ["simulation.dt=2e-6,3e-6,4e-4"])
    result = run_sweep(plan, out, workers=0)
    assert [r["status"] for r in result.records] == ["completed", "completed", "failed"]
    return out


def make_bending_run_dir(out: Path, field=None) -> Path:
    """A 3D run folder written by hand (no simulation): a strip along x, 1 mm thin in z, magnetised along x and
    clamped at x = 0, whose free end bends up in z over 6 frames: a bend in the x-z plane, which a view down z
    cannot show. ``field``: the scene echo's uniform field (T), or none (the motion alone tells the plane)."""
    from magsoro.io.vtk import write_pvd, write_vtp

    g = np.linspace
    x, y, z = np.meshgrid(g(0.0, 0.01, 21), g(-0.002, 0.002, 5), g(-0.0005, 0.0005, 3), indexing="ij")
    x0 = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    n = len(x0)
    (out / "frames").mkdir(parents=True)
    entries = []
    for k in range(6):
        t = k * 2e-4
        pts = x0.copy()
        pts[:, 2] += 3.0e4 * t * x0[:, 0] ** 2  # the tip rises 3 mm by the last frame
        name = f"frames/frame_{k:05d}.vtp"
        write_vtp(out / name, pts, {"velocity": np.zeros((n, 3), np.float32), "body": np.zeros(n, np.int32),
                                    "clamped": (x0[:, 0] < 1e-3).astype(np.uint8), "J": np.ones(n, np.float32),
                                    "magnetization_direction": np.tile(np.float32([1.0, 0.0, 0.0]), (n, 1))})
        entries.append((t, name))
    write_pvd(out / "particles.pvd", entries)
    scene = {"name": "bending", "simulation": {"dim": 3}, "fields": [] if field is None else [{"type": "uniform", "B": list(field)}]}
    (out / "run.json").write_text(json.dumps({"status": "completed", "dim": 3, "n_particles": n, "time": 1e-3, "steps": 10,
                                              "scene": scene, "bodies": [{"body": "strip"}]}))
    return out


def embedded(page: Path) -> dict:
    text = page.read_text()
    return json.loads(text.split('id="report-data">', 1)[1].split("</script>", 1)[0])


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    return make_run_dir(tmp_path_factory.mktemp("report") / "run")


def test_run_report_embeds_curves_and_frames(run_dir, tmp_path):
    from magsoro.io.vtk import read_vtp
    from magsoro.viz import build_report

    page = build_report(run_dir, tmp_path / "r.html")
    text = page.read_text()
    data = embedded(page)
    assert data["kind"] == "run"
    # one chart for the tip probe with its x and y columns, values equal to metrics.csv
    (chart,) = data["charts"]
    assert [s["name"] for s in chart["series"]] == ["tip_x", "tip_y"]
    rows = np.loadtxt(run_dir / "metrics.csv", delimiter=",", skiprows=1)
    assert np.allclose(chart["series"][1]["x"], rows[:, 0]) and np.allclose(chart["series"][1]["y"], rows[:, 2])
    assert data["expected_curves"] == 2
    # viewer: every frame (6 at 0.2 ms over 1 ms), every particle, positions within the 16-bit quantum
    v = data["viewer"]
    frames = sorted((run_dir / "frames").glob("frame_*.vtp"))
    assert v["frames"] == len(frames) == 6 and v["times"][0] == 0.0 and v["times"][-1] == pytest.approx(0.001)
    pts, fields = read_vtp(frames[-1])
    assert v["n"] == len(pts) == 176
    q = np.frombuffer(base64.b64decode(v["pos"]), dtype="<u2").reshape(v["frames"], v["n"], 3)
    decoded = np.asarray(v["lo"]) + q[-1] / 65535.0 * np.asarray(v["span"])
    assert np.abs(decoded - pts).max() <= 0.51 * max(v["span"]) / 65535
    assert v["flat_z"] is True
    body = np.frombuffer(base64.b64decode(v["body"]), dtype=np.uint8)
    assert np.array_equal(body, fields["body"]) and v["body_names"] == ["beam"]
    # self-contained: no script, style, image or link fetched from anywhere
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", text)
    assert "url(http" not in text and "@import" not in text
    assert '<div id="status"' in text
    # the scene table lists swept-style dotted keys
    assert "bodies.beam.material.shear_modulus" in text


def test_run_report_lists_the_run_notes(run_dir, tmp_path):
    """run.json's notes (a body that reached a domain wall, a body the lattice rounds, why steps left the check
    windows) appear in the report's facts, one row each."""
    import shutil

    from magsoro.viz import build_report

    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    info = json.loads((copy / "run.json").read_text())
    # the fixture's beam is 2 cells thick: its one note says so
    assert len(info["notes"]) == 1 and "thinnest part is about 2 cells" in info["notes"][0]
    note = "body 'beam' reached the domain wall at y = 0.012 m (simulation.domain_hi[1]) by t = 0.04 s"
    info["notes"] = [note]
    (copy / "run.json").write_text(json.dumps(info))
    import html

    text = build_report(copy, tmp_path / "n.html").read_text()
    assert "<th>note</th>" in text and html.escape(note) in text
    info["notes"] = []
    (copy / "run.json").write_text(json.dumps(info))
    assert "<th>note</th>" not in build_report(copy, tmp_path / "m.html").read_text()


def test_run_report_subsamples_particles_and_frames(run_dir, tmp_path):
    from magsoro.viz import build_report

    data = embedded(build_report(run_dir, tmp_path / "small.html", max_frames=3, max_particles=50))
    v = data["viewer"]
    assert v["n"] == 50 and v["n_total"] == 176
    assert v["frames"] == 3 and v["frames_total"] == 6
    assert v["times"][0] == 0.0 and v["times"][-1] == pytest.approx(0.001)  # first and last frame kept
    assert len(base64.b64decode(v["pos"])) == 3 * 50 * 3 * 2


def test_sweep_report_plots_final_values_against_the_parameter(tmp_path):
    from magsoro.sweep.summary import read_summary
    from magsoro.viz import build_report

    sweep = make_sweep_dir(tmp_path / "sweep")
    page = build_report(sweep)
    assert page == sweep / "report.html"
    data = embedded(page)
    titles = [c["title"] for c in data["charts"]]
    assert titles[:2] == ["final tip_x vs simulation.dt", "final tip_y vs simulation.dt"]
    _, rows = read_summary(sweep / "summary.csv")
    done = [r for r in rows if r["status"] == "completed"]
    final_y = data["charts"][1]["series"][0]
    assert final_y["x"] == [float(r["simulation.dt"]) for r in done]
    assert np.allclose(final_y["y"], [float(r["tip_y"]) for r in done])
    # the overlays hold every completed run's curve, not the failed one
    overlay = data["charts"][3]
    assert [s["name"] for s in overlay["series"]] == [r["run"] for r in done]
    assert data["expected_curves"] == 6 and data["viewer"] is None
    text = page.read_text()
    assert "failed" in text and "simulation.dt" in text
    failed = [r for r in rows if r["status"] == "failed"][0]
    assert failed["error"][:40] in text.replace("&#x27;", "'")


def test_report_cli(run_dir, tmp_path, capsys):
    from magsoro.cli import main

    out = tmp_path / "x" / "page.html"
    assert main(["report", str(run_dir), "--out", str(out)]) == 0
    assert out.is_file() and "report written to" in capsys.readouterr().out
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "neither a run (run.json) nor a sweep (sweep.json) directory" in err
    assert main(["report", str(run_dir), "--max-frames", "0"]) == 2


def test_embedded_data_cannot_close_its_script_tag():
    from magsoro.viz.report import render_html

    evil = "</script><!--<script>"
    content = {"kind": "run", "title": evil, "subtitle": "s", "status": "completed", "facts": [("a", evil)], "sweep_params": [],
               "scene_rows": [], "viewer": None,
               "charts": [{"title": evil, "xlabel": "t", "ylabel": "y", "series": [{"name": evil, "x": [0.0, 1.0], "y": [1.0, 2.0]}]}]}
    page = render_html(content)
    assert page.count("</script>") == 2 and page.count("<script") == 2  # the data block and the code, nothing else
    data = json.loads(page.split('id="report-data">', 1)[1].split("</script>", 1)[0])
    assert data["charts"][0]["series"][0]["name"] == evil and data["expected_curves"] == 1


@pytest.mark.parametrize("field", [None, (0.0, 0.0, 0.01)])
def test_report_view_starts_looking_at_the_bend_plane(tmp_path, field):
    """A 3D run bending in x-z: the viewer starts looking along y (the plane's normal), with z up, not down z."""
    from magsoro.viz import build_report

    run_dir = make_bending_run_dir(tmp_path / "run", field)
    page = build_report(run_dir, tmp_path / "r.html")
    v = embedded(page)["viewer"]
    assert v["dim"] == 3 and v["flat_z"] is False
    view = v["view"]
    assert view["plane"] == "x-z" and view["towards"] == [0.0, -1.0, 0.0], view
    assert view["right"] == [1.0, 0.0, 0.0] and view["up"] == [0.0, 0.0, 1.0]
    assert view["why"] == "the plane of the magnetisation and the motion"
    assert "The view starts looking at the plane of the magnetisation and the motion." in page.read_text()


def test_report_view_from_motion_field_and_shape():
    from magsoro.viz.report import default_view

    g = np.random.default_rng(5)
    strip = g.uniform([0.0, -2e-3, -0.5e-3], [0.01, 2e-3, 0.5e-3], size=(400, 3))
    sag = strip.copy()
    sag[:, 2] -= 20.0 * strip[:, 0] ** 2  # a strip along x sagging in z under its weight
    frames = np.stack([strip, sag])
    # not magnetised: the plane of its length and its motion
    v = default_view(frames, 3, None, {"simulation": {"gravity": [0.0, 0.0, -9.81]}})
    assert v["towards"] == [0.0, -1.0, 0.0] and v["up"] == [0.0, 0.0, 1.0] and "length and the motion" in v["why"]
    # still: the magnetisation and the scene's uniform field (m along x, B along y: a bend in x-y, seen down z)
    v = default_view(np.stack([strip, strip]), 3, np.tile([1.0, 0, 0], (400, 1)),
                     {"fields": [{"type": "uniform", "B": [0.0, 0.01, 0.0]}]})
    assert v["plane"] == "x-y" and v["towards"] == [0.0, 0.0, 1.0] and "magnetisation and the field" in v["why"]
    # still, no field, no magnetisation: the plane of the longest and thinnest extents (x and z)
    assert default_view(strip[None], 3)["plane"] == "x-z"
    # 2D: down z
    assert default_view(frames, 2)["towards"] == [0.0, 0.0, 1.0]
