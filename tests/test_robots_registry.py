"""The robot library as a whole (issue 7): every robot the seeds describe is registered with a scene, a
[preview] table and a reproduce script; the CLI lists them; the gallery page is current."""

import subprocess
import sys
from pathlib import Path

import pytest

from magsoro.errors import SceneError
from magsoro.robots import ROBOTS, RobotError, get, scenes_dir
from magsoro.robots.base import scene, scene_data

ROOT = Path(__file__).resolve().parents[1]

#: seed 000 sec 4.3-4.5, seed 002 sec 4-5, seed 001 sec V
EXPECTED = {
    "strip_magnet", "obstacle_beam", "tentacle", "walker", "gripper",
    "triangle", "cross", "pentagram", "pentahedron", "hexahedron", "arch",
    "continuum_soft", "continuum_discrete",
}


def test_every_seed_robot_is_registered():
    assert EXPECTED <= set(ROBOTS), sorted(EXPECTED - set(ROBOTS))


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_robot_has_scene_preview_and_script(name):
    robot = get(name)
    assert robot.scene_path == scenes_dir() / f"{name}.toml" and robot.scene_path.is_file()
    assert "preview" in scene_data(name), f"scenes/{name}.toml has no [preview] table"
    assert (scenes_dir() / name / "reproduce.py").is_file()
    assert robot.source.startswith("seed 00") and robot.sentence and robot.quantity
    full, prev = scene(name), scene(name, preview=True)
    assert prev.simulation.dx >= full.simulation.dx
    assert prev.simulation.duration <= full.simulation.duration


def test_reproduce_cli_lists_and_refuses_unknown_names():
    out = subprocess.run([sys.executable, "-m", "magsoro", "reproduce", "--list"], capture_output=True, text=True)
    assert out.returncode == 0
    listed = {line.split()[0] for line in out.stdout.splitlines() if line.strip()}
    assert listed == set(ROBOTS)
    bad = subprocess.run([sys.executable, "-m", "magsoro", "reproduce", "no_such_robot"], capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "unknown robot 'no_such_robot'" in bad.stderr
    with pytest.raises(RobotError, match="known:"):
        get("no_such_robot")
    zero = subprocess.run([sys.executable, "-m", "magsoro", "reproduce", "walker", "--workers", "0"],
                          capture_output=True, text=True)
    assert zero.returncode == 2 and zero.stderr.strip().splitlines() == [
        "magsoro reproduce: error: --workers 0: give a whole number of processes, 1 or more"]


def test_validate_lists_a_case_per_robot():
    from magsoro.validation import CASES, select_cases

    assert {f"robot-{n}" for n in ROBOTS} <= set(CASES)
    default = {c.name for c in select_cases()}
    everything = {c.name for c in select_cases(all_cases=True)}
    assert not any(n.startswith("robot-") for n in default)
    assert {f"robot-{n}" for n in ROBOTS} <= everything


def test_gallery_page_covers_every_robot():
    """docs/robots.md (python scripts/make_robot_gallery.py) has a section and the reproduce command for
    every registered robot, and no section for a robot that is not registered."""
    import re

    from magsoro.robots.gallery import gallery_markdown

    page = (ROOT / "docs" / "robots.md").read_text()
    sections = set(re.findall(r"^## (\w+)$", page, flags=re.M))
    assert sections == set(ROBOTS), "docs/robots.md is stale: run python scripts/make_robot_gallery.py"
    for name in ROBOTS:
        assert f"`magsoro reproduce {name}`" in page
    assert sections == set(re.findall(r"^## (\w+)$", gallery_markdown(ROOT / "docs"), flags=re.M))


def test_preview_needs_a_preview_table(tmp_path):
    from magsoro.scene import load_scene

    path = tmp_path / "s.toml"
    path.write_text("""
[simulation]
dim = 2
dx = 1e-3
domain_lo = [0, 0]
domain_hi = [0.02, 0.02]
duration = 0.01
[[bodies]]
name = "b"
shape = { type = "rectangle", center = [0.01, 0.01], size = [0.004, 0.002] }
material = "ecoflex-00-30"
""")
    with pytest.raises(SceneError, match=r"s.toml: preview: --preview needs a \[preview\] table"):
        load_scene(path, preview=True)
    path.write_text(path.read_text() + "[preview]\ndx = 2e-3\nsteps = 3\n")
    with pytest.raises(SceneError, match=r"preview.steps: unknown key 'steps'; allowed keys here: cfl, duration, dx"):
        load_scene(path, preview=True)
    path.write_text(path.read_text().replace("steps = 3\n", "duration = 0.005\n"))
    sc = load_scene(path, preview=True)
    assert sc.simulation.dx == 2e-3 and sc.simulation.duration == 0.005
    assert load_scene(path).simulation.dx == 1e-3


def test_write_csv_pads_shorter_columns_with_empty_cells(tmp_path):
    """Runs sampled at their own steps go side by side in one CSV: the shorter columns end in empty cells, read
    back as nan (an arch_flip run with 1,107 samples beside longer ones stopped on an IndexError before)."""
    import numpy as np

    from magsoro.robots.base import read_csv, write_csv

    path = write_csv(tmp_path / "c.csv", {"a": [1.0, 2.0], "b": [1.0, 2.0, 3.0], "c": []})
    back = read_csv(path)
    assert back["b"].tolist() == [1.0, 2.0, 3.0]
    assert back["a"][:2].tolist() == [1.0, 2.0] and np.isnan(back["a"][2]) and np.isnan(back["c"]).all()
