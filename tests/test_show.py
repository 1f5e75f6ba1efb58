"""`magsoro show` renders every example scene (small images) without running it."""

from pathlib import Path

import pytest

from magsoro.cli import main

SCENES = sorted(p for p in (Path(__file__).resolve().parents[1] / "scenes").glob("*.toml") if not p.name.startswith("rod"))  # rod_*: rod-model files


@pytest.mark.parametrize("scene", SCENES, ids=[p.stem for p in SCENES])
def test_show_renders_png(tmp_path, capsys, scene):
    out = tmp_path / f"{scene.stem}.png"
    assert main(["show", str(scene), "--out", str(out), "--size", "3", "--dpi", "40", "--arrows", "30"]) == 0
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 2000
    assert "particles" in capsys.readouterr().out


def test_show_refuses_bad_input(tmp_path, capsys):
    assert main(["show", str(tmp_path / "absent.toml"), "--out", str(tmp_path / "x.png")]) == 2
    assert "not found" in capsys.readouterr().err
    assert main(["show", str(SCENES[0]), "--out", str(tmp_path / "x.jpg")]) == 2
    assert "--out" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_clamp_regions_are_the_particles_the_engine_holds():
    """`magsoro show` marks what the engine holds: clamped bodies and the particles inside [[clamps]] regions
    (scenes/cantilever_2d.toml has only a region)."""
    from magsoro.scene import load_scene
    from magsoro.scene.build import build, fill_bodies, held_particles

    scene = load_scene(Path(__file__).resolve().parents[1] / "scenes" / "cantilever_2d.toml")
    particles = fill_bodies(scene)
    held = held_particles(scene, particles)
    assert not particles.clamped.any() and held.sum() > 0
    assert (held == build(scene).model.host["clamped"]).all()
