"""Grid convergence studies: the Richardson estimate against exact power laws, ``magsoro converge`` on the aligned
2D cantilever against the Kirchhoff rod, the thin-part note of ``magsoro run`` and ``magsoro run --set``."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from magsoro.cli import main
from magsoro.convergence.richardson import estimate, observed_order

ROOT = Path(__file__).resolve().parents[1]
ALIGNED = ROOT / "scenes" / "cantilever_2d_aligned.toml"
THICKNESS = 0.8e-3


# -- Richardson ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("p", [1.0, 2.0, 2.7])
def test_richardson_recovers_an_exact_power_law_on_unequal_ratios(p):
    """f = 3 + 0.7 h^p at h = t/2, t/3, t/4, t/6 (ratios 1.5, 1.33, 1.5): the order and f0 to round-off; the grid
    convergence index bounds the finest value's error (it is 1.25 times it)."""
    h = THICKNESS / np.array([2.0, 3.0, 4.0, 6.0])
    f = 3.0 + 0.7 * (h / THICKNESS) ** p
    e = estimate(h, f)
    assert e.behaviour == "monotone"
    assert e.order == pytest.approx(p, abs=1e-8)
    assert e.extrapolated == pytest.approx(3.0, abs=1e-12)
    assert e.uncertainty == pytest.approx(1.25 * abs(f[-1] - 3.0), rel=1e-6)
    assert [t.order for t in e.triples] == pytest.approx([p, p], abs=1e-8)
    assert observed_order(h[::-1][:3], f[::-1][:3]) == pytest.approx(p, abs=1e-8)  # any order of the inputs


def test_richardson_oscillating_two_spacings_and_round_off():
    """Differences that change sign give no order and a band of half the finest three's spread; two spacings give
    the change (and an extrapolation only with an assumed order); values equal to round-off are converged."""
    e = estimate([4.0, 3.0, 2.0], [1.0, 0.9, 0.95])
    assert e.behaviour == "oscillating" and e.order is None and e.extrapolated is None
    assert e.value == 0.95 and e.uncertainty == pytest.approx(0.05)
    two = estimate([2.0, 1.0], [1.0, 1.1])
    assert two.behaviour == "two spacings" and two.order is None and two.value == 1.1
    assumed = estimate([2.0, 1.0], [1.0, 1.1], order=2.0)
    assert assumed.extrapolated == pytest.approx(1.1 + 0.1 / 3.0) and assumed.assumed_order == 2.0
    assert estimate([3.0, 2.0, 1.0], [5.0, 5.0, 5.0]).behaviour == "converged"
    with pytest.raises(ValueError, match="two or more"):
        estimate([1.0], [1.0])
    with pytest.raises(ValueError, match="finite"):
        estimate([2.0, 1.0], [1.0, float("nan")])



def test_components_zero_by_symmetry_are_reported_as_zero_not_fitted():
    """A probe's component that stays at round-off while another is millimetres (the cross's centre x and y at
    1e-14 to 7e-10 m against its z at 7 mm, benchmarks/results/*-cross-rise-converge.json) is zero by symmetry: no
    order (those values gave 10.8), no panel; a component at a thousandth of the scale is still fitted."""
    from magsoro.convergence.study import probe_scale

    h = [0.002, 0.001, 0.0005]
    points = {"centre_x": list(zip(h, [-2.97e-14, -4.52e-13, -7.32e-10])),
              "centre_z": list(zip(h, [9.47e-3, 6.81e-3, 6.77e-3])), "force": list(zip(h, [1.0, 2.0, 3.0]))}
    assert probe_scale("centre_x", points) == pytest.approx(9.47e-3)
    assert probe_scale("force", points) is None
    zero = estimate(h, [v for _, v in points["centre_x"]], scale=9.47e-3)
    assert zero.behaviour == "zero" and zero.value == 0.0 and zero.uncertainty == pytest.approx(7.32e-10)
    assert zero.order is None and "zero by symmetry" in zero.summary()
    assert estimate(h, [v for _, v in points["centre_x"]]).behaviour != "zero"  # no scale, no judgement
    small = estimate(h, [1.0e-5, 1.2e-5, 1.25e-5], scale=9.47e-3)
    assert small.behaviour == "monotone" and small.order == pytest.approx(2.0)

# -- magsoro converge on the cantilever ---------------------------------------------------------------------------

def rod_tip():
    """The Kirchhoff rod (plane-strain modulus) of the aligned scene's beam at arc length 17.0 mm (the tip probe's
    centroid): (x, y) in m, clamp face at x = 0. The normalised field from the scene's own numbers."""
    import tomllib

    from magsoro.constants import MU0
    from magsoro.validation.beam import BeamSetup, rod_reference

    scene = tomllib.loads(ALIGNED.read_text())
    body = scene["bodies"][0]
    G, K = body["material"]["shear_modulus"], body["material"]["bulk_modulus"]
    br, b = body["magnetization"][0], scene["fields"][0]["B"][1]
    setup = BeamSetup(dim=2, thickness=THICKNESS, length=17.2e-3, shear_modulus=G, bulk_ratio=K / G, remanence=br)
    dx, dy = rod_reference(setup, [br * b / (MU0 * G)], 90.0, 17.0e-3, 17.2e-3)
    return 17.0e-3 + dx[0] * 17.2e-3, dy[0] * 17.2e-3


def test_converge_cantilever_extrapolates_to_the_rod(tmp_path, capsys):
    """magsoro converge --static at t/dx = 6, 8, 12, 16: the tip's extrapolated deflection within 1 % of the rod
    (measured +0.23 %: the continuum plane-strain beam against the rod, L/t = 21.5) at an order between 1 and 3
    (measured 2.10; 1.79 for the tip's x); the table, converge.json, converge.csv and the figure are written."""
    dxs = [THICKNESS / n for n in (6, 8, 12, 16)]
    out = tmp_path / "study"
    code = main(["converge", str(ALIGNED), "--static", "--dx", ",".join(repr(d) for d in dxs), "--out", str(out),
                 "--probe", "tip", "--quiet"])
    assert code == 0
    info = json.loads((out / "converge.json").read_text())
    assert info["status"] == "completed" and info["mode"] == "static"
    assert [r["status"] for r in info["runs"]] == ["completed"] * 4
    rx, ry = rod_tip()
    ey, ex = info["estimates"]["tip_y"], info["estimates"]["tip_x"]
    assert ey["behaviour"] == "monotone" and 1.0 <= ey["order"] <= 3.0
    assert abs(ey["extrapolated"] - ry) <= 0.01 * abs(ry)
    assert ex["behaviour"] == "monotone" and 1.0 <= ex["order"] <= 3.0
    assert abs(ex["extrapolated"] - rx) <= 0.01 * abs(ry)  # x measured against the deflection's scale
    # the extrapolated value lies within the finest run's uncertainty band of it
    assert abs(ey["extrapolated"] - ey["values"][-1]) <= ey["uncertainty"]
    rows = (out / "converge.csv").read_text().splitlines()
    assert rows[0] == "dx,status,wall_time_s,tip_x,tip_y" and len(rows) == 5
    assert (out / "converge.png").stat().st_size > 10_000
    assert all((out / f"dx_{i}" / "run.json").is_file() for i in range(1, 5))
    printed = capsys.readouterr().out
    assert "tip_y: extrapolated" in printed and "order 2.1" in printed


def test_converge_coarse_cantilever_is_pre_asymptotic(tmp_path):
    """At t/dx = 2, 3, 4, 6 the tip does not yet follow one power of dx: 2 cells are 0.6 % too soft, then the
    values at 3, 4 and 6 cells differ by 0.05 % up and down. converge says so (oscillating, no order) and gives the
    finest value with half the spread of the finest three as its band; that value is within 1 % of the rod."""
    dxs = [THICKNESS / n for n in (2, 3, 4, 6)]
    out = tmp_path / "coarse"
    assert main(["converge", str(ALIGNED), "--static", "--dx", ",".join(repr(d) for d in dxs), "--out", str(out),
                 "--probe", "tip_y", "--quiet"]) == 0
    e = json.loads((out / "converge.json").read_text())["estimates"]["tip_y"]
    assert list(json.loads((out / "converge.json").read_text())["estimates"]) == ["tip_y"]
    assert e["behaviour"] == "oscillating" and e["order"] is None
    _, ry = rod_tip()
    assert abs(e["value"] - ry) <= 0.01 * abs(ry)
    assert e["uncertainty"] <= 0.001 * abs(ry)


def test_converge_refuses_bad_input_in_one_line(tmp_path, capsys):
    """A bad --dx, an unknown --probe (naming the columns there are), a folder holding something else, and a
    second study into the same folder without --resume: exit 2, one line each; --resume reuses completed runs."""
    scene = str(ALIGNED)
    for argv, text in [
        (["--dx", "2e-4"], "at least two spacings"),
        (["--dx", "2e-4,abc"], "give grid spacings in m"),
        (["--dx", "2e-4,-1e-4"], "must be a finite number > 0"),
        (["--dx", "2e-4,2e-4"], "given twice"),
    ]:
        assert main(["converge", scene, "--static", "--out", str(tmp_path / "x"), *argv]) == 2
        err = capsys.readouterr().err
        assert text in err and len(err.strip().splitlines()) == 1
    out = tmp_path / "s"
    assert main(["converge", scene, "--static", "--dx", "4e-4,2e-4", "--probe", "nope", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--probe nope" in err and "tip_x, tip_y" in err and len(err.strip().splitlines()) == 1
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert main(["converge", scene, "--static", "--dx", "4e-4,2e-4", "--out", str(other)]) == 2
    assert "holds no convergence study" in capsys.readouterr().err
    done = tmp_path / "done"
    assert main(["converge", scene, "--static", "--dx", "4e-4,2e-4", "--out", str(done), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["converge", scene, "--static", "--dx", "4e-4,2e-4", "--out", str(done), "--quiet"]) == 2
    assert "add --resume" in capsys.readouterr().err
    assert main(["converge", scene, "--static", "--dx", "4e-4,2e-4", "--out", str(done), "--resume", "--quiet"]) == 0
    runs = json.loads((done / "converge.json").read_text())["runs"]
    assert [r["message"] for r in runs] == ["reused (--resume)"] * 2
    assert "finest" in capsys.readouterr().out  # two spacings: the change, no order


# -- magsoro run --set, and the thin-part note ---------------------------------------------------------------------

def test_run_set_changes_a_key_and_run_json_says_so(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["run", str(ALIGNED), "--static", "--set", "simulation.dx=4e-4", "--set",
                 "bodies.beam.material.shear_modulus=2e5", "--out", str(out), "--quiet"]) == 0
    info = json.loads((out / "run.json").read_text())
    assert info["scene"]["simulation"]["dx"] == 4e-4
    assert info["scene"]["bodies"][0]["material"]["shear_modulus"] == 2e5
    # the beam is 2 cells thick at that spacing: the thin-part note, naming the cells and the dx for 3 cells
    (note,) = [n for n in info["notes"] if "thinnest part" in n]
    assert note.startswith("body 'beam': its thinnest part is about 2 cells through (0.0008 m at simulation.dx 0.0004 m)")
    assert "refine simulation.dx to 0.000267 m" in note
    for argv, text in [(["--set", "simulaton.dx=1e-4"], "--set simulaton.dx=1e-4: the scene has no key 'simulaton'"),
                       (["--set", "simulation.dx"], "expected KEY=VALUE"),
                       (["--set", "bodies.arm.material.shear_modulus=1"], "has no entry named 'arm'")]:
        assert main(["run", str(ALIGNED), "--static", "--out", str(tmp_path / "bad"), *argv]) == 2
        err = capsys.readouterr().err
        assert text in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "bad").exists()


def test_thin_parts_measures_plates_hinges_and_tilted_plates():
    """Plates of 1 to 8 rows read their thickness exactly (either parity of rows); a 3-row hinge between 10-row
    plates is thin and the plates are not; a 4-row plate tilted 30 degrees reads 4 rows."""
    from magsoro.geometry.thickness import thin_parts

    h = 0.1

    def rect(nx, ny, x0=0, y0=0):
        i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        return np.c_[(i.ravel() + x0 + 0.5) * h, (j.ravel() + y0 + 0.5) * h]

    for n in range(1, 9):
        r = thin_parts(rect(60, n), h, limit=6 * h)
        assert r.thinnest == pytest.approx(n * h, abs=1e-12)
        assert r.thin_particles == (60 * n if n < 6 else 0)
    hinge = np.r_[rect(30, 10), rect(10, 3, 30, 0), rect(30, 10, 40, 0)]
    r = thin_parts(hinge, h, 6 * h)
    assert r.thinnest == pytest.approx(3 * h) and 0 < r.thin_particles <= 30
    assert not r.thin[:300].any() and not r.thin[330:].any()
    grid = rect(400, 400, -200, -200)
    th = math.radians(30.0)
    normal, along = np.array([-math.sin(th), math.cos(th)]), np.array([math.cos(th), math.sin(th)])
    tilted = grid[(np.abs(grid @ normal) < 0.2) & (np.abs(grid @ along) < 5.0)]
    assert thin_parts(tilted, h, 6 * h).thinnest == pytest.approx(0.4, abs=0.5 * h)
    assert thin_parts(rect(5, 5) + 0.03, h, 6 * h) is None  # not on the lattice: no measure


def test_thin_note_for_pieces_not_for_thick_bodies():
    """scenes/cantilever_2d.toml at its own dx (4 cells through the beam): no thin-part note; the cross robot (2 mm
    plates at dx 1 mm) gets one note for its piece of five bonded bodies."""
    from magsoro.scene import load_scene
    from magsoro.simulation import Simulation

    sim = Simulation(load_scene(ROOT / "scenes" / "cantilever_2d.toml"))
    assert not [n for n in sim.notes if "thinnest part" in n]
    sim = Simulation(load_scene(ROOT / "scenes" / "cross.toml"))
    (note,) = [n for n in sim.scene_notes if "thinnest part" in n]
    assert note.startswith("the piece of 5 bonded bodies (all of them): its thinnest part is about 2 cells through")
