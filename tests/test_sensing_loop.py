"""Closed shape-sensing loop in MPM (issue: "Sensing loop: the reconstructed tip position within 1 mm of the MPM
tip over bends of 0 to 90 degrees"): examples/sensing_loop/run_loop.py in its quick version.

A magnetic-tip robot (examples/sensing_loop/sensing_tip.toml, 2D, quick grid dx = 0.2 mm) is solved to static
equilibrium (the engine's Newton solver) at field levels giving bends of 0, 4, 15, 30, 45, 59, 74 and 89
degrees. At each bend the Hall sensor on the sliding camera cable reads the engine's field of the marker.
``magsoro sense`` (seed 004 eqs 17-23, run as the command) reconstructs a constant-curvature arc from the
readings, with the seed's operator calibration (B0 straight, lever arm from the 90 degree bend), and the
reconstructed tip is compared with the MPM tip. examples/sensing_loop/README.md has the numbers, the full
version (dx = 0.15 mm, bends every 10 degrees, 30 s) and the resolution study. This test takes about 12 s.
"""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "sensing_loop"


def _run_loop_module():
    spec = importlib.util.spec_from_file_location("sensing_run_loop", EXAMPLE / "run_loop.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    out = tmp_path_factory.mktemp("sensing_loop")
    module = _run_loop_module()
    summary = module.run(out, quick=True, log=lambda *a, **k: None)
    return module, summary, out


def test_reconstructed_tip_within_1_mm_over_0_to_90_degrees(loop):
    """The acceptance. The bends run from 0 to 90 degrees; the last level aims at 90 and is aimed again if it
    misses by more than 1 degree (measured 89.0). Bound: the issue's 1 mm.

    Measured tip errors, in mm: 0, 0.76, 0.39, 0.36, 0.46, 0.44, 0.50, 0.27. The 0.76 mm is the 4 degree bend in
    the sensor's dead zone (seed 004 sec V). There the grid's field error, +0.17 % of B0 at this resolution, is
    larger than the signal, -0.13 %: the reading comes out above B0, the bend is sensed as 0, and the error is
    the tip's whole deflection. A bend sensed as 0 stays within 1 mm for bends below 2/L = 5.7 degrees. At
    dx = 0.15 mm the same bend is sensed, with an error of 0.10 mm."""
    module, s, out = loop
    bends = s["bend_deg"]
    assert bends[0] == 0.0 and 0.0 < min(bends[1:]) < 10.0
    assert abs(max(bends) - 90.0) <= module.LAST_TOLERANCE_DEG
    assert s["max_tip_error_m"] <= module.TIP_BOUND
    # magsoro sense found the same largest tip error from truth.csv (--truth), independently of run_loop.py
    sensed = json.loads((out / "sense" / "summary.json").read_text())
    assert sensed["tip_max_error_m"] == pytest.approx(s["max_tip_error_m"], rel=1e-6, abs=1e-9)
    for name in ("readings.csv", "truth.csv", "calib.toml", "loop.csv", "loop.png", "sense/centreline.csv",
                 "sense_geometry/angles.csv"):
        assert (out / name).is_file(), name


def test_the_station_works_as_the_sensing_model_assumes(loop):
    """The mechanism behind seed 004 eqs 18-22, checked bend by bend in the MPM run.

    - B0: the straight reading is the field of a uniformly magnetised 0.6 x 0.3 mm slab at 0.75 mm, for which
      run_loop.StationGeometry has a closed form. Measured +0.03 % (+1.9 % at dx = 0.3 mm, where the sensor is
      2.5 cells from the marker). Bound 1 %.
    - slide: the cable moves d beta_S along the marker, with d = 0.75 mm (cable to neutral fibre) and beta_S the
      rotation of the marker's cross-section. Measured -2.8 % to +1.2 %. Bound 5 %.
    - gap: it stays at 0.75 mm within 2 %. Measured -1.1 % at 89 degrees, where the soft channel is squeezed.
    - control: a sensor glued to the body cannot slide, and its reading changes by less than a tenth of the
      sliding sensor's. Measured 0.025 against 0.43 at 89 degrees.
    - calibration: the lever arm of the operator's 90 degree calibration equals, within 3 %, the one it finds
      with exact mechanics and the closed-form 2D field. Measured +1.1 % (-0.4 % at dx = 0.15 mm). Both are
      about 9 % below the geometric h L_S / L_R because the slab's field falls off more slowly than eq 20.
    - constant curvature: the station bend over the tip bend is L_S / L_R. The station senses the first L_S,
      and the calibration extrapolates to L_R. Measured 3.6-6.8 % above it (0.8-3.6 % at dx = 0.15 mm),
      most at small bends, where the marker's own couple in the field adds to the moment. Bound 8 %.
    """
    module, s, out = loop
    assert s["peak_field_measured_T"] == pytest.approx(s["peak_field_2d_closed_form_T"], rel=0.01)
    slide, model = np.array(s["slide_m"][1:]), np.array(s["slide_model_m"][1:])
    assert np.all(np.abs(slide / model - 1.0) < 0.05)
    assert np.all(np.abs(np.array(s["gap_m"]) / s["gap_m"][0] - 1.0) < 0.02)
    q, glued = np.array(s["q"]), np.array(s["q_glued"])
    assert np.abs(glued - 1.0).max() < 0.1 * (1.0 - q.min())
    assert s["lever_arm_operator_m"] == pytest.approx(s["lever_arm_exact_mechanics_m"], rel=0.03)
    rows = np.genfromtxt(out / "loop.csv", delimiter=",", names=True)
    from magsoro.scene import load_scene

    geo = module.station_geometry(load_scene(EXAMPLE / "sensing_tip.toml"))
    ratio = rows["station_bend_deg"][1:] / rows["bend_deg"][1:]
    assert np.all(np.abs(ratio / (geo.cable_length / geo.robot_length) - 1.0) < 0.08)
