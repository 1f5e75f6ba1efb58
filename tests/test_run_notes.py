"""Notes on what a scene may not mean (run.json ``notes``, one stderr line each).

The domain walls' reach (Simulation.check_wall_reach): a body that moves into the band where the domain walls act
is noted, naming the wall and its scene key; a body that starts there (a robot on the domain's floor) is not.
scenes/cantilever_2d.toml once had its domain's top 12 mm up: the bent tip rested on that wall, 15 % of the length
from its free shape, and nothing said so.

The particle lattice: a body whose particles fill more than 2 % more or less than its shape's volume is noted (the
same scene's 0.84 mm beam was 8 rows 0.1 mm apart, 0.8 mm, with 2.8 % of the length between its tip and a 0.84 mm
rod's)."""

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
    # without --quiet: the notes go to stderr (with --quiet only run.json keeps them)
    run = subprocess.run([sys.executable, "-m", "magsoro", "run", str(scene), "--out", str(out)],
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


def test_a_body_the_lattice_rounds_is_noted(tmp_path):
    """4.4 mm across at particle spacing 0.5 mm: 8 columns fill 4 mm, 9.1 % less than the 4.4 x 4 mm shape's
    area; 4 x 4 mm is filled exactly and not noted."""
    from magsoro.scene import parse_scene
    from magsoro.scene.load import read_scene_toml
    from magsoro.simulation import Simulation

    path = tmp_path / "b.toml"
    path.write_text(SCENE.format(y=0.012).replace("size = [0.004, 0.004]", "size = [0.0044, 0.004]"))
    notes = [n for n in Simulation(parse_scene(read_scene_toml(path))).notes if "shape's volume" in n]
    assert len(notes) == 1 and notes[0].startswith("body 'block': its particles fill 9.1 % less than its shape's volume")
    assert "simulation.dx" in notes[0]
    path.write_text(SCENE.format(y=0.012))
    assert not [n for n in Simulation(parse_scene(read_scene_toml(path))).notes if "shape's volume" in n]


def test_reproduce_collects_the_scene_notes_of_its_runs():
    """magsoro reproduce writes the scene notes of the simulations a robot made into result.json: continuum_discrete's
    3 mm rods at particle spacing 0.5 mm fill 32 of the 36 sites of their section's square, 13.2 % more than the
    circle (a documented coarse robot), one note for the eight rods; the record is cleared once read."""
    from magsoro.robots.base import scene_notes, simulation

    scene_notes()
    simulation("continuum_discrete", preview=True)
    notes = scene_notes()
    fill = [n for n in notes if "shapes' volumes" in n]
    assert len(fill) == 1 and "their particles fill 13.2 % more than their shapes' volumes" in fill[0]
    assert fill[0].startswith("bodies 'corrected_plain1', 'corrected_mag1', ") and "'theoretical_mag2'" in fill[0]
    # and the rods, 2.8 cells across, are one piece noted as thin
    thin = [n for n in notes if "thinnest part" in n]
    assert len(thin) == 1 and thin[0].startswith("the piece of 8 bonded bodies (all of them): its thinnest part is about 2.8 cells")
    assert len(notes) == 2 and scene_notes() == []


def test_run_quiet_keeps_warp_off_stdout(tmp_path):
    """`magsoro run --quiet` prints nothing on stdout: Warp's start-up banner and its per-module load lines are
    turned off before Warp starts (they went to stdout even with --quiet)."""
    path = tmp_path / "b.toml"
    path.write_text(SCENE.format(y=0.012).replace("duration = 0.03", "duration = 0.002").replace("every = 0.01", "every = 0.001"))
    run = subprocess.run([sys.executable, "-m", "magsoro", "run", str(path), "--out", str(tmp_path / "o"), "--quiet"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout == ""
