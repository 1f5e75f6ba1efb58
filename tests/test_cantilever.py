"""A clamped magnetic cantilever in a perpendicular uniform field settles, and its tip deflection converges
with grid refinement towards the Kirchhoff-rod solution (magsoro.rod, an independent model).

2D plane strain: the rod's bending stiffness uses the plane-strain modulus E' = E / (1 - nu^2) with E and nu
from the engine's G and K. The normalised field Br B / (mu0 G) = 0.003 and L/t = 8 give a tip rotation of
about 20 degrees, well into the geometrically nonlinear range.
"""

import numpy as np
import pytest

from magsoro import MU0
from magsoro.scene import parse_scene
from magsoro.simulation import Simulation

L, T, G, BR, BN, RHO = 8e-3, 1e-3, 303e3, 0.258, 0.003, 1030.0
B = BN * MU0 * G / BR


def cantilever_scene(t_over_dx: int, duration: float = 0.04, precision: str = "float32") -> dict:
    dx = T / t_over_dx
    omega1 = 3.516 * np.sqrt(3 * G * T**2 / (12 * RHO)) / L**2  # first bending mode (rad/s)
    return {
        "simulation": {
            "dim": 2, "dx": dx, "domain_lo": [-0.002, -0.006], "domain_hi": [L + 0.002, 0.01],
            "duration": duration, "damping": omega1, "precision": precision,
        },
        "bodies": [{
            "name": "beam",
            "shape": {"type": "rectangle", "center": [L / 2 - 0.0005, 0.0], "size": [L + 0.001, T]},
            "material": {"density": RHO, "shear_modulus": G},
            "magnetization": [BR, 0.0, 0.0],
        }],
        "clamps": [{"region": {"type": "rectangle", "center": [-0.0005, 0.0], "size": [0.001, 2 * T]}}],
        "fields": [{"type": "uniform", "B": [0.0, B, 0.0], "profile": {"type": "ramp", "duration": duration / 4}}],
        "probes": [{"type": "tip", "name": "tip", "body": "beam",
                    "region": {"type": "rectangle", "center": [L - 0.25 * dx, 0.0], "size": [0.5 * dx, 2 * T]}}],
    }


def rod_tip_deflection() -> float:
    from magsoro.rod import CrossSection, Rod

    K = 20 * G
    nu = (3 * K - 2 * G) / (2 * (3 * K + G))
    E_plane_strain = 2 * G * (1 + nu) / (1 - nu**2)
    rod = Rod(L, CrossSection.rectangle(5e-3, T), youngs_modulus=E_plane_strain, magnetisation=(0.0, 0.0, BR))
    return float(rod.solve(field=(0.0, 0.0, B)).tip_position[2])


def run_tip_history(t_over_dx: int, duration: float = 0.04):
    sim = Simulation(parse_scene(cantilever_scene(t_over_dx, duration)))
    hist = []
    sim.run(record=lambda s: hist.append((s.time, s.probe_values()["tip_y"])), record_every=duration / 8)
    return np.array(hist), sim


@pytest.fixture(scope="module")
def reference():
    return rod_tip_deflection()


def test_cantilever_settles_and_converges_to_rod(reference):
    errors = []
    for r in (3, 4):
        hist, _ = run_tip_history(r)
        tip = hist[:, 1]
        # settled: over the last quarter of the run (after the ramp and 3 damping times) the tip moves < 2 %
        assert abs(tip[-1] - tip[-3]) < 0.02 * abs(tip[-1]), tip
        errors.append(abs(tip[-1] - reference) / reference)
    # The scene default runs the total form, whose clamp holds the nodes up to the clamped face: measured 3.4 %
    # and 1.5 % (stiff side). In the updated form the nodes held by the clamped particles reach about one cell
    # past the face, shortening the free beam by ~dx: 11.3 % and 8.0 %, first order in dx (docs/engine.md).
    assert errors[1] < errors[0]
    assert errors[1] < 0.025, errors


@pytest.mark.slow
def test_float32_loaded_cantilever_tracks_float64():
    """A float32 cantilever held under a constant field stays with the float64 run of the same scene. With the
    deformation-gradient update written as (I + dt C) F, float32 rounding of 1 + dt C_ii dropped the small
    increments of the settling state and the tip crept along the field: 1.6 % above the float64 tip at 0.32 s
    (measured with that form restored); F + (dt C) F keeps them: 0.1 %. (Both precisions still move by about
    0.2 % per 80 ms late in the hold: the engine's slow drift of docs/validation.md, finding 4, which is not a
    float32 effect; an earlier form of this test asked for a settled float32 tip and failed on it.)"""
    tips = {}
    for precision in ("float32", "float64"):
        d = cantilever_scene(3, 0.32, precision=precision)
        d["fields"][0]["profile"]["duration"] = 0.01
        sim = Simulation(parse_scene(d))
        sim.advance_to(0.32)
        tips[precision] = sim.probe_values()["tip_y"]
    assert abs(tips["float32"] - tips["float64"]) < 5e-3 * abs(tips["float64"]), tips


@pytest.mark.parametrize("mode, low, high", [("remap", -0.02, 0.02), ("grid", 0.08, 0.25)])
def test_loaded_slender_beam_does_not_creep_with_the_remap(mode, low, high):
    """The Zhao beam (L/t = 20.5, t/dx = 2, float64) under a perpendicular field Br B/(mu0 G) = 0.0005, held
    for 6/omega_1 after a 1.5/omega_1 ramp, against the Kirchhoff rod (docs/engine.md, "Why the remap").
    With the velocity-gradient remap the tip is within 2 % of the rod (measured +0.03 %). The cheaper "grid"
    F update lets the loaded beam creep: measured +13.9 %; the band checks that the test tells them apart."""
    from magsoro.validation.beam import BeamSetup, rod_reference, run_sweep

    s = BeamSetup(t_over_dx=2, velocity_gradient=mode, formulation="updated")  # the F update of the updated form
    r = run_sweep(s, (0.0005,), 90.0)
    ref = rod_reference(s, (0.0005,), 90.0, r.tip_s, r.free_length)[1][0]
    assert low < r.tip_dy[0] / ref - 1.0 < high
