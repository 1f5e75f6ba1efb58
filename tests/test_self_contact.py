"""Self-contact: a strip folded onto itself by its field (magsoro.validation.self_contact).

Quick: the measures on synthetic configurations and the scene's magnetisation. Slow: the folding strip with
``self_contact = true`` against the acceptance, and the no-contact control that shows the measure can fail.
"""

import numpy as np
import pytest

from magsoro.validation.self_contact import (
    MIN_CELLS,
    TORN_CELLS,
    TOUCH_CELLS,
    UNFOLDED,
    FoldSetup,
    acceptance_failures,
    end_to_end,
    far_pair_distance,
    fold_scene,
    largest_stretch,
    neighbour_pairs,
    run_fold,
)

DX = 0.25e-3
H = DX / 2  # particle spacing at 2 particles per cell


def _strip(length=10e-3, thickness=1e-3, h=H):
    """Reference lattice of a strip along x centred on the origin (cell-centred, spacing h)."""
    xs = np.arange(-0.5 * length + 0.5 * h, 0.5 * length, h)
    ys = np.arange(-0.5 * thickness + 0.5 * h, 0.5 * thickness, h)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


def _folded(X, gap, thickness=1e-3):
    """The right half turned under the left half (mirrored about x = 0 and y = 0), its top particle layer
    ``gap`` + one particle spacing below the left half's bottom layer, particles aligned in x."""
    x = X.copy()
    right = X[:, 0] > 0
    x[right, 0] = -X[right, 0]
    x[right, 1] = -X[right, 1] - thickness - gap
    return x


def test_undeformed_and_rigidly_moved_strip_has_no_close_far_pairs():
    X = _strip()
    assert far_pair_distance(X, X, DX) == (3.0, 0)  # no pair > 3 dx apart comes within the 3-cell search
    c, s = np.cos(0.7), np.sin(0.7)
    x = X @ np.array([[c, s], [-s, c]]) + [1e-3, -2e-3]
    d, n = far_pair_distance(x, X, DX)
    assert d == pytest.approx(3.0) and n == 0


@pytest.mark.parametrize("gap_cells, expect_cells, expect_close", [(0.5, 1.0, 0), (0.2, 0.7, 0), (-0.4, 0.1, True)])
def test_folded_layers_closest_far_pair_is_the_layer_gap(gap_cells, expect_cells, expect_close):
    """Folded exactly: the closest reference-far pair is one particle spacing plus the gap between the layers
    (h + gap); pairs near the fold, close in the reference configuration, do not count."""
    X = _strip()
    d, n = far_pair_distance(_folded(X, gap_cells * DX), X, DX)
    assert d == pytest.approx(expect_cells, abs=1e-9)
    assert (n > 0) == bool(expect_close)


def test_reference_near_pairs_do_not_count_even_when_squeezed():
    """A strip squeezed to 0.3 of its size: pairs within 3 dx in the reference configuration come to 0.15 cells
    but are ignored; the closest reference-far pair is 0.3 x (just over 3 cells)."""
    X = _strip()
    d, n = far_pair_distance(0.3 * X, X, DX)
    assert n == 0 and 0.9 < d < 1.0


def test_end_to_end_and_neighbour_stretch():
    L = 10e-3
    X = _strip(L)
    assert end_to_end(X, X, DX, L) == pytest.approx((L - DX) / L)  # end regions' centroids half a cell in
    assert end_to_end(_folded(X, 0.0), X, DX, L) == pytest.approx(1e-3 / L)  # ends one thickness apart
    pairs = neighbour_pairs(X, H)
    assert largest_stretch(X, pairs, DX) == pytest.approx(np.sqrt(2) * 0.5)  # a diagonal at rest
    x = X.copy()
    x[X[:, 0] > 0, 0] += DX  # cut through the middle, opened by a cell
    assert largest_stretch(x, pairs, DX) > TORN_CELLS - 0.1


def test_fold_scene_magnetisation_arms_taper_and_hinge():
    from magsoro.scene import parse_scene
    from magsoro.scene.build import build

    s = FoldSetup()
    model = build(parse_scene(fold_scene(s))).model
    X = model.host["positions"]
    Br = model.host["remanence"]
    a = np.radians(s.overfold)
    arm = s.remanence * np.array([np.cos(a), -np.sin(a), 0.0])
    mirror = np.array([-1.0, 1.0, 1.0])
    edge = 0.5 * s.hinge + s.taper
    left, right = X[:, 0] < -edge, X[:, 0] > edge
    assert np.allclose(Br[left], arm) and np.allclose(Br[right], mirror * arm)
    assert np.allclose(Br[np.abs(X[:, 0]) < 0.5 * s.hinge], 0.0)
    taper = (X[:, 0] > 0.5 * s.hinge) & (X[:, 0] < edge)  # linear from zero to the arm's vector
    frac = (X[taper, 0] - 0.5 * s.hinge) / s.taper
    assert np.allclose(Br[taper], frac[:, None] * mirror * arm)
    assert len(X) == round(s.length / H) * round(s.thickness / H)
    assert s.field * s.remanence / (4e-7 * np.pi * s.shear_modulus) == pytest.approx(s.field_ratio, rel=1e-6)
    assert FoldSetup(taper=0.0).field == s.field and fold_scene(FoldSetup(taper=0.0))["bodies"][0][
        "magnetization"]["interpolation"] == "step"


@pytest.mark.slow
def test_folded_strip_self_contact_keeps_layers_apart_and_unfolds():
    """30 x 1 mm strip, dx 0.25 mm, folded at its hinge by Br B/(mu0 G) = 0.2 (20 ms ramp, 10 ms hold, 5 ms down,
    50 ms off), self-contact frictionless, float32. Measured: closest pair > 3 dx apart in the reference
    configuration 0.91 cells (first impact, 7.9 ms), 1.13 cells during the hold, none under half a cell; end-to-end
    0.04 L folded and 0.97 L at the end; largest neighbour distance 1.16 cells; about 45 s on one core."""
    track = run_fold(FoldSetup())
    s = track.summary()
    assert acceptance_failures(track) == [], s
    assert s["far_min_cells"] >= MIN_CELLS and s["far_close_max"] == 0
    assert s["far_min_hold_cells"] <= TOUCH_CELLS  # the arms really touch: the check above can fail
    assert s["end_to_end_hold"] < 0.1  # folded
    assert s["end_to_end_end"] >= UNFOLDED and s["arm_gap_end_cells"] > 10  # released, not stuck
    assert s["stretch_max_cells"] <= TORN_CELLS  # in one piece throughout


@pytest.mark.slow
def test_without_contact_the_folded_arms_pass_through_each_other():
    """Control: the total-Lagrangian form has no contact, so the same fold drives the arms through each other
    (measured: closest reference-far pair 0.0002 cells, up to 352 pairs under half a cell; 23 s): the measure of
    the test above sees interpenetration when there is some."""
    s = run_fold(FoldSetup(self_contact=False, formulation="total")).summary()
    assert s["far_min_cells"] < MIN_CELLS and s["far_close_max"] > 0, s


def test_self_contact_with_a_second_body_runs_and_classifies_only_reached_nodes():
    """Self-contact beside contact between two bodies (a ring with a disc inside it): the classify pass used to
    treat nodes no particle reaches as self-contact candidates and index the friction table with an overflowed
    group number, which crashed the step as soon as there were two contact groups. The disc, pushed into the
    ring, must stay inside it (contact holds) and every node of the split classes must carry mass."""
    from magsoro.mpm.kernels.contact import BODIES, FOLD
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    scene = parse_scene({
        "name": "ring_and_disc",
        "simulation": {"dim": 2, "dx": 2.5e-4, "particles_per_cell": 2, "domain_lo": [-4e-3, -4e-3],
                       "domain_hi": [4e-3, 4e-3], "duration": 2e-3, "damping": 0.0},
        "bodies": [
            {"name": "ring", "shape": {"type": "arc", "center": [0.0, 0.0], "radius": 2.25e-3, "width": 5e-4,
                                       "start_angle": 0.0, "end_angle": 360.0},
             "material": {"density": 1000.0, "shear_modulus": 5e4}},
            {"name": "disc", "shape": {"type": "polygon", "vertices": [[-1e-3, -1e-3], [1e-3, -1e-3], [1e-3, 1e-3], [-1e-3, 1e-3]]},
             "material": {"density": 1000.0, "shear_modulus": 5e4}, "velocity": [0.5, 0.0]},
        ],
        "contact": {"friction": 0.3, "self_contact": True},
    }, "test")
    sim = Simulation(scene)
    res = sim.run(2e-3)
    assert res.status == "completed", res.message
    split = sim.solver._ct["split"].numpy()[: sim.solver.n_active]
    mass = sim.solver.grid_m.numpy()
    n = sim.solver.n_active
    node_mass = mass[:n] + mass[n: 2 * n]  # field 1 of node i sits at slot i + n (the active nodes)
    assert np.all(node_mass[(split == BODIES) | (split == FOLD)] > 0.0)
    assert (split == BODIES).any()  # the disc reached the ring: the two groups met
    x = sim.particles()["x"]
    body = sim.particles()["body"]
    r = np.hypot(x[body == 1, 0], x[body == 1, 1])
    # the disc (0.5 m/s for 2 ms: 1 mm of free flight, 0.5 mm to the ring's inner face) stays inside the bore
    assert r.max() < 2.0e-3 + 2.5e-4
