"""Robot everting_tube (seed 004's growing robot everted by an axial field, axisymmetric, implicit): the starting
shape its scene draws, the reduced model's numbers it is compared with, the growth-speed reading, and (slow) the
held tail's front force against the flip term's closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from magsoro.constants import MU0
from magsoro.robots import everting_tube as et

RHO = 0.3125e-3 / math.pi  # the fold's mid-radius as the scene draws it, m (its initial_displacement expressions)
TOP = 2.5e-3  # the fold starts there, m


@pytest.fixture(scope="module")
def started():
    from magsoro.robots.base import simulation

    sim = simulation(et.NAME, preview=True)
    X = sim.model.host["positions"].astype(np.float64)
    return sim, X, sim.state.x.numpy().astype(np.float64), sim.state.F.numpy().astype(np.float64)


def test_the_tube_starts_partly_everted(started):
    """The scene draws the tube straight (r from A to B) and starts it partly everted: the tail where it is drawn,
    a half-circle fold of mid-radius 0.0995 mm over the top (0.3125 mm of tube), and the everted wall running back down outside the tail,
    turned inside out (the tail's outer face now the wall's inner one), its end on the floor; F invertible
    everywhere."""
    sim, X, x, F = started
    h = sim.model.spacing
    assert X[:, 0].min() > et.A and X[:, 0].max() < et.B
    tail = X[:, 1] <= TOP
    np.testing.assert_allclose(x[tail], X[tail], atol=1e-12)
    wall = X[:, 1] >= TOP + math.pi * RHO
    # inside out: r = 2 (R_mid + rho) - R, so the wall's inner face (from R = B) stands 2 rho - (B - A) clear
    np.testing.assert_allclose(x[wall, 0], 2.0 * (0.5 * (et.A + et.B) + RHO) - X[wall, 0], rtol=1e-12)
    gap = x[wall, 0].min() - x[tail, 0].max()
    assert gap == pytest.approx(2.0 * RHO - (et.B - et.A) + h, rel=1e-9)
    assert 0.0 < x[wall, 1].min() <= 0.5 * h + 1e-12  # the base on the floor (z = 0), its lowest row within reach
    assert x[:, 1].max() == pytest.approx(TOP + RHO + 0.5 * (et.B - et.A) - 0.5 * h, abs=h)
    assert np.linalg.det(F).min() > 0.0
    assert np.allclose(F[wall], -np.eye(2)[None], atol=1e-6)  # reversed along the axis and through the wall


def test_reduced_model_numbers():
    """The numbers the robot is compared with: magsoro evert's frictionless growth field for this tube (20.26 mT,
    docs/actuation.md) and the flip term's slope 2 |Br| pi (B^2 - A^2) / mu0."""
    model = et.reduced_model(0.1123, 120.0333e3)
    assert model.minimum_growth_field() == pytest.approx(0.0202596, rel=1e-4)
    assert model.flip_force_per_tesla() == pytest.approx(2 * 0.1123 * math.pi * (et.B ** 2 - et.A ** 2) / MU0, rel=1e-12)


def test_growth_speed_reads_the_middle_of_the_advance():
    t = np.linspace(0.0, 10.0, 101)
    front = np.clip(t - 2.0, 0.0, 4.0) * 0.5  # at rest, then 0.5 per unit time for 4 units, then at rest
    assert et.growth_speed(t, front) == pytest.approx(0.5, rel=1e-9)
    assert et.growth_speed(t, -0.1 * t) == pytest.approx(-0.1)  # retreating


def test_the_fields_load_on_the_clamped_end_is_the_flip_terms_half():
    """With the remanence carried by F the field's energy density -B . F Br / mu0 has the constant first
    Piola-Kirchhoff stress -B (x) Br / mu0, so its node forces act only where the reference body ends: on the held
    tail's end, |Br| B pi (B^2 - A^2) / mu0 (1.9091 mN at 40 mT), half the flip term, and the opposite on the
    everted end. Preview grid, at the starting state, to 1e-9."""
    from magsoro.robots.base import scene_data, simulation

    data = et._with_field(scene_data("everting_tube"), 0.04)
    data["fields"][0].pop("profile", None)  # the whole field at once
    data["output"]["particles"] = False
    end, rows = et._tail_end(data), et.CLAMP_ROWS * float(data["preview"]["dx"]) / 2.0
    data["clamps"] = [{"body": "tube", "region": {"type": "rectangle", "center": [0.5 * (et.A + et.B), end + rows / 2.0],
                                                  "size": [2.0 * (et.B - et.A), rows]}}]
    sim = simulation("everting_tube", data, preview=True)
    sim.advance_to(1e-9)
    integ = sim.implicit
    u = integ.u_nodes
    field_part = integ.node_forces(u, 1.0, 0.0) - integ.node_forces(u, 0.0, 0.0)
    expected = 0.1123 * 0.04 / MU0 * np.pi * (et.B**2 - et.A**2)
    assert -field_part[integ.held_nodes, 1].sum() == pytest.approx(-expected, rel=1e-9)
    assert abs(field_part[:, 1].sum()) < 1e-9 * expected  # no net force in a uniform field


@pytest.mark.slow
def test_held_tail_front_force_follows_the_flip_term(tmp_path):
    """Preview resolution (4 cells through the wall), the tail's end held, at 0 and 40 mT: the front's push
    N = -2 F_clamp is the held shape's elastic push N_el plus the flip term (to 1e-9: the field loads the held ends
    only), N_el is the same at both fields within 1 % (measured 1e-5: the field does not move the held shape), and
    at zero field the front pulls back (N < 0: the elastic wall would retract it)."""
    from magsoro.robots.base import Context

    ctx = Context(out=tmp_path, preview=True, log=lambda msg: None)
    zero, strong = et.held_tail(ctx, 0.0), et.held_tail(ctx, 0.04)
    flip = et.reduced_model(0.1123, 120.0333e3).flip_force_per_tesla()
    assert strong["N"] - strong["N_el"] == pytest.approx(flip * 0.04, rel=1e-9)
    assert zero["N"] == pytest.approx(zero["N_el"], rel=1e-12)
    assert strong["N_el"] == pytest.approx(zero["N_el"], rel=0.01)
    assert zero["N"] < 0.0
