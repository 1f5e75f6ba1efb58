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
