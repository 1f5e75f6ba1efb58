"""Contact between bodies: the [contact] table, contact groups and the two-field grid contact (docs/engine.md)."""

import copy

import numpy as np
import pytest

from magsoro.errors import SceneError
from magsoro.scene import parse_scene
from magsoro.scene.build import build
from magsoro.simulation import Simulation
from magsoro.validation.contact import DX, G_EARTH, acceleration, block_track, slope_reference, slope_scene


# -- scene interface and contact groups -------------------------------------------------------------------------
def _two_blocks(gap_sites: int, **contact) -> dict:
    """Two 2D blocks side by side along x, ``gap_sites`` empty lattice sites apart (dx 0.5 mm, 2 particles/cell)."""
    dx, h = 5e-4, 2.5e-4
    left = {"name": "a", "shape": {"type": "rectangle", "center": [-1e-3, 0.0], "size": [2e-3, 2e-3]}, "material": {"density": 1000.0, "shear_modulus": 1e5}}
    right = copy.deepcopy(left)
    right["name"] = "b"
    right["shape"]["center"] = [1e-3 + gap_sites * h, 0.0]
    return {"simulation": {"dim": 2, "dx": dx, "domain_lo": [-0.01, -0.01], "domain_hi": [0.01, 0.01], "duration": 1e-3},
            "bodies": [left, right], "contact": contact, "output": {"particles": False}}


def test_touching_bodies_are_in_contact_unless_the_scene_bonds_them():
    """Separate bodies are never bonded by default, touching or not, and run.json's notes say what happens to the
    touching ones; contact.bonded = 'touching' or a pair's bonded = true glues them into one piece."""
    touching = build(parse_scene(_two_blocks(0, friction=0.3)))
    assert touching.model.host["contact_group"].tolist() == touching.model.host["body"].tolist()
    assert touching.settings.contact.active(2)
    assert len(touching.notes) == 1 and "'a'-'b'" in touching.notes[0] and "in contact" in touching.notes[0]
    assert "friction 0.3" in touching.notes[0]
    for contact in ({"bonded": "touching"}, {"pairs": [{"bodies": ["a", "b"], "bonded": True}]}):
        glued = build(parse_scene(_two_blocks(0, **contact)))
        assert set(glued.model.host["contact_group"].tolist()) == {0}, contact
        assert len(glued.notes) == 1 and "bonded into one piece" in glued.notes[0], contact
    # a bonded pair is one piece wherever its bodies are; 'touching' glues only bodies that touch
    assert set(build(parse_scene(_two_blocks(1, pairs=[{"bodies": ["a", "b"], "bonded": True}]))).model.host["contact_group"].tolist()) == {0}
    far = build(parse_scene(_two_blocks(1, bonded="touching")))
    assert far.model.host["contact_group"].tolist() == far.model.host["body"].tolist() and not far.notes
    apart = build(parse_scene(_two_blocks(1, friction=0.3)))
    groups = apart.model.host["contact_group"]
    body = apart.model.host["body"]
    assert np.all(groups == body)
    table = apart.settings.contact.friction
    assert table.shape == (2, 2) and np.allclose(table, 0.3)


def test_contact_pairs_override_and_sticky():
    scene = _two_blocks(1, friction=0.3, pairs=[{"bodies": ["a", "b"], "friction": "sticky"}])
    built = build(parse_scene(scene))
    c = built.settings.contact
    assert c.friction[0, 1] < 0 and c.friction[1, 0] < 0
    assert not c.active(2)  # a sticky pair shares one velocity field: no contact pass at all
    scene = _two_blocks(1, pairs=[{"bodies": ["a", "b"], "friction": 0.5}])
    assert build(parse_scene(scene)).settings.contact.friction[0, 1] == 0.5


@pytest.mark.parametrize(
    "contact, message",
    [
        ({"pairs": [{"bodies": ["a", "nope"], "friction": 0.2}]}, "contact.pairs[0].bodies: no body named 'nope'"),
        ({"friction": -0.1}, "contact.friction: must be a finite Coulomb coefficient >= 0 or 'sticky'"),
        ({"friction": float("nan")}, "contact.friction: must be a finite Coulomb coefficient >= 0 or 'sticky'"),
        ({"friction": "glue"}, "contact.friction"),
        ({"frction": 0.2}, "frction"),
        ({"pairs": [{"bodies": ["a", "b"]}]}, "friction is required"),
        ({"pairs": [{"bodies": ["a", "b"], "friction": 0.2, "bonded": True}]}, "not both"),
        ({"bonded": "always"}, "contact.bonded"),
    ],
)
def test_contact_input_errors_name_the_key(contact, message):
    with pytest.raises(SceneError) as err:
        build(parse_scene(_two_blocks(1, **contact)))
    assert message in str(err.value)


def test_friction_pair_of_bonded_bodies_is_refused():
    with pytest.raises(SceneError, match=r"contact.pairs\[0\].bodies: bodies 'a' and 'b' move as one piece: contact.bonded"):
        build(parse_scene(_two_blocks(0, bonded="touching", pairs=[{"bodies": ["a", "b"], "friction": 0.2}])))
    # without bonding, a friction pair for touching bodies is what it says
    assert build(parse_scene(_two_blocks(0, pairs=[{"bodies": ["a", "b"], "friction": 0.2}]))).settings.contact.friction[0, 1] == 0.2


def test_auto_formulation_runs_contact_scenes_in_the_updated_form():
    scene = _two_blocks(1)
    assert build(parse_scene(scene)).settings.formulation == "updated"
    scene["contact"] = {"friction": "sticky"}
    assert build(parse_scene(scene)).settings.formulation == "total"  # one velocity field: nothing to resolve


# -- physics ------------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_total_form_contact_pass_lets_a_block_slide_and_keeps_it_out_of_the_slab():
    """formulation = "total" with contact (the contact pass on a grid of the current configuration, bodies kept
    apart on the reference grid): the coarse frictionless block slides down the slab, measured 4.68 m/s^2 against
    g sin 30 = 4.905 (-4.6 %, sinking 0.22 cells; the updated form -0.05 % at the finer grid); with 'sticky' the two share the reference
    grid's nodes and the block stays glued (the reference configuration has them one cell apart)."""
    scene = slope_scene(0.0, "slab", dx=5e-4)
    scene["simulation"]["formulation"] = "total"
    ts, xs, sim = block_track(scene, 0.015)
    assert sim.solver._tcontact
    a = acceleration(ts, xs, 0.004)
    assert 0.85 * G_EARTH * 0.5 < a < 1.01 * G_EARTH * 0.5
    assert xs[-1, 1] - xs[0, 1] > -0.5 * 5e-4  # does not sink into the slab by half a cell
    scene["contact"] = {"friction": "sticky"}
    ts, xs, _ = block_track(scene, 0.015)
    assert abs(xs[-1, 0] - xs[0, 0]) < 0.1 * 5e-4


def test_frictionless_block_slides_on_a_body_and_a_sticky_one_does_not():
    """Coarse (dx 0.5 mm) block on a clamped slab, 30 degree slope, 15 ms: frictionless it accelerates at g sin 30
    within 3 % (the coarse grid's leading-edge drag); with the old single velocity field ('sticky') it does not
    move along the slope (less than a tenth of a cell)."""
    ts, xs, _ = block_track(slope_scene(0.0, "slab", dx=5e-4), 0.015)
    a = acceleration(ts, xs, 0.004)
    assert a == pytest.approx(G_EARTH * 0.5, rel=0.03)
    ts, xs, _ = block_track(slope_scene("sticky", "slab", dx=5e-4), 0.015)
    assert abs(xs[-1, 0] - xs[0, 0]) < 0.1 * 5e-4


@pytest.mark.slow
@pytest.mark.parametrize("support", ["collider", "slab"])
def test_block_on_slope_friction_02_slides_at_coulomb_rate(support):
    """g (sin 30 - 0.2 cos 30) = 3.206 m/s^2: within 2 % on the collider, 5 % on the elastic slab (measured
    +0.17 % and -0.17 % in `magsoro validate contact_slope`; fitted over 10-40 ms after the block has settled)."""
    ts, xs, _ = block_track(slope_scene(0.2, support), 0.04)
    a_ref = slope_reference(0.2)
    assert acceleration(ts, xs, 0.01) == pytest.approx(a_ref, rel=0.02 if support == "collider" else 0.05)


@pytest.mark.slow
@pytest.mark.parametrize(
    "support",
    [
        "collider",
        pytest.param("slab", marks=pytest.mark.xfail(strict=True, reason=(
            "open (issue 'Engine 2.0'): on the elastic slab the block slides 1.3 cells in 40 ms at friction 0.7, "
            "against less than a quarter cell asked. It starts outside the contact range, falls for about 3 ms and "
            "bounces (block and slab elastic, undamped); the landing's contact nodes stick, and the hops slide it "
            "down the slope. Started one empty site above (within range) it stays (0.14 cells) and friction 0.2 "
            "slides at the Coulomb rate (docs/engine.md, Contact)"))),
    ],
)
def test_block_on_slope_friction_07_stays(support):
    """tan 30 = 0.577 < 0.7: the block stays; it moves less than a quarter cell along the slope in 40 ms."""
    ts, xs, _ = block_track(slope_scene(0.7, support), 0.04)
    assert abs(xs[-1, 0] - xs[0, 0]) < 0.25 * DX


@pytest.mark.slow
@pytest.mark.parametrize("mu", [0.2, pytest.param(0.4, marks=pytest.mark.slow), 0.7])
def test_block_started_touching_the_slab_slides_by_coulomb(mu):
    """The block drawn resting on the slab (no gap: its bottom particle row one particle spacing above the slab's
    top row), 30 degree slope: separate bodies, in contact from the first step. Friction 0.2 and 0.4 slide at
    g (sin 30 - mu cos 30) within 3 % (measured -0.02 % both), 0.7 stays (under a quarter cell in 40 ms,
    measured 0.09). Before, the two bodies were bonded into one piece and did not move at any friction."""
    ts, xs, sim = block_track(slope_scene(mu, "slab", start_sites=0), 0.04)
    assert any("'block'-'slab'" in n and "in contact" in n for n in sim.notes)
    ref = slope_reference(mu)
    if ref > 0:
        assert acceleration(ts, xs, 0.01) == pytest.approx(ref, rel=0.03)
    else:
        assert abs(xs[-1, 0] - xs[0, 0]) < 0.25 * DX


@pytest.mark.slow
def test_no_adhesion_block_pulled_off_a_slab():
    """A magnetised block rests on an unmagnetised clamped slab (gravity, 10 ms), then a dipole brought above it
    (10-20 ms) pulls it up: by 25 ms it has left the slab (risen more than a cell) and the slab's top has lifted
    less than half a cell. With the old single velocity field ('sticky') the block stays glued to the slab.""" 
    dx, h = 2.5e-4, 1.25e-4
    # dipole 20 mm above the block at the end: gradient about 0.7 T/m, pull about 5 x the block's weight
    far, near = [-0.005, 0.5, 0.0], [-0.005, 0.0213, 0.0]
    scene = slope_scene(0.3, "slab", tilt_deg=0.0)
    scene["bodies"][0]["magnetization"] = [0.0, 0.1, 0.0]
    scene["fields"] = [{"type": "dipole", "moment": [0.0, 0.18, 0.0], "position": far,
                        "path": {"times": [0.0, 0.01, 0.02], "positions": [far, far, near]}}]

    def run(s):
        sim = Simulation(parse_scene(s))
        body = sim.model.host["body"]
        X = sim.model.host["positions"]
        top = (body == 1) & (X[:, 1] > -h)  # the slab's top particle layer
        y0_block = sim.state.x.numpy()[body == 0, 1].mean()
        sim.advance_to(0.025)
        x = sim.state.x.numpy()
        return x[body == 0, 1].mean() - y0_block, float(np.max(x[top, 1] - X[top, 1]))

    rise, lift = run(scene)
    assert rise > dx
    assert lift < 0.5 * dx
    sticky = copy.deepcopy(scene)
    sticky["contact"] = {"friction": "sticky"}
    rise_sticky, _ = run(sticky)
    assert rise_sticky < 0.1 * dx  # glued to the clamped slab
