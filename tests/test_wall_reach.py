"""The domain walls' reach (Simulation.check_wall_reach): a body that moves into the band where the domain walls
act gets a note in run.json and on stderr, naming the wall and its scene key; a body that starts there (a robot
on the domain's floor) does not. scenes/cantilever_2d.toml once had its domain's top 12 mm up: the bent tip rested
on that wall, 15 % of the length from its free shape, and nothing said so."""

import json
import subprocess
import sys

SCENE = """
name = "falling_block"

[simulation]
dim = 2
dx = 1.0e-3
particles_per_cell = 2
domain_lo = [0.0, 0.0]
domain_hi = [0.02, 0.03]
duration = 0.03
gravity = [0.0, -100.0]
depth = 1.0e-3

[[bodies]]
name = "block"
shape = {{ type = "rectangle", center = [0.01, {y}], size = [0.004, 0.004] }}
material = {{ density = 1000.0, shear_modulus = 1.0e5 }}

[output]
every = 0.01
particles = false
"""


def _run(tmp_path, y):
    scene = tmp_path / f"block_{y}.toml"
    scene.write_text(SCENE.format(y=y))
    out = tmp_path / f"out_{y}"
    run = subprocess.run([sys.executable, "-m", "magsoro", "run", str(scene), "--out", str(out), "--quiet"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    info = json.loads((out / "run.json").read_text())
    return run.stderr, [n for n in info["notes"] if "domain wall" in n]


def test_a_body_that_falls_onto_the_domain_floor_is_noted(tmp_path):
    """Dropped from 12 mm (its underside 10 cells up) under 100 m/s^2 it reaches the floor in about 14 ms."""
    stderr, notes = _run(tmp_path, 0.012)
    assert len(notes) == 1
    assert "body 'block' reached the domain wall at y = 0 m (simulation.domain_lo[1])" in notes[0]
    assert notes[0] in stderr


def test_a_body_that_starts_on_the_floor_is_not_noted(tmp_path):
    """Its underside starts 2.5 cells from the face (bodies may not start closer than 2), within the walls' reach:
    the floor is part of the scene."""
    _, notes = _run(tmp_path, 0.0045)
    assert notes == []
