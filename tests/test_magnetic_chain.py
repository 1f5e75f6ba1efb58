"""The magnetic chain robot (scenes/magnetic_chain.toml, magsoro.robots.magnetic_chain): four magnetised blocks
joined by soft hinges close into a ring under their own attraction, with no applied field.

The closed forms the robot checks the engine against are tested here first, against independent sums: the field
of a uniformly magnetised polygon (edge charges) against a fine lattice of line dipoles, the line-dipole pair law
against finite differences of its energy and Newton's third law, and the polygon force and torque against the
lattice. Then a lone block's zero self-torque (the grid's spurious one removed at each refresh) and the preview
reproduction with its checks.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from magsoro.constants import MU0
from magsoro.robots import magnetic_chain as mc
from magsoro.robots.base import Context, read_csv, scene_data

M = 0.112 / MU0  # A/m, the blocks' magnetisation (|Br| = 112 mT)


def filled(vertices_center, size, angle, h):
    """Points of a fine square lattice (spacing h) inside a rectangle, each standing for h^2 of material."""
    hx, hy = size[0] / 2, size[1] / 2
    n = math.ceil(max(hx, hy) * 1.5 / h)
    g = (np.arange(-n, n) + 0.5) * h
    P = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    local = P @ np.array([[c, -s], [s, c]])  # rotate the lattice points into the rectangle's frame
    inside = (np.abs(local[:, 0]) < hx) & (np.abs(local[:, 1]) < hy)
    return P[inside] + np.asarray(vertices_center, float)


def lattice_H(points, sources, moment_per_point):
    out = np.zeros((len(points), 2))
    for i, p in enumerate(points):
        r = p - sources
        r2 = np.einsum("ij,ij->i", r, r)
        u = r / np.sqrt(r2)[:, None]
        out[i] = ((2 * (u @ moment_per_point)[:, None] * u - moment_per_point) / (2 * math.pi * r2[:, None])).sum(0)
    return out


def test_scene_parts_are_the_design():
    """scenes/magnetic_chain.toml holds the parts chain_parts() writes (its comments say so)."""
    parts = scene_data("magnetic_chain")["robot"]["parts"]
    ref = mc.chain_parts()
    assert [p["name"] for p in parts] == [p["name"] for p in ref]
    for p, r in zip(parts, ref):
        assert p["material"] == r["material"] and p["priority"] == r["priority"]
        assert p["shape"]["type"] == r["shape"]["type"]
        if p["shape"]["type"] == "rectangle":
            assert np.allclose(p["shape"]["center"], r["shape"]["center"], atol=1e-12)
            assert np.allclose(p["shape"]["size"], r["shape"]["size"], atol=1e-12)
            assert p["shape"]["angle"] == pytest.approx(r["shape"]["angle"], abs=1e-9)
            assert np.allclose(p["magnetization"]["direction"], r["magnetization"]["direction"], atol=1e-9)
            assert p["magnetic"] is True
        else:
            assert np.allclose(p["shape"]["vertices"], r["shape"]["vertices"], atol=1e-11)
    # the axis-aligned blocks sit on the particle lattice of both resolutions (0.0625 and 0.125 mm)
    for p in ref[:4]:
        c = np.asarray(p["shape"]["center"]) / 1.25e-4
        assert np.allclose(c, np.round(c), atol=1e-9)


def test_polygon_field_is_that_of_its_dipoles():
    """The edge-charge closed form of a uniformly magnetised, rotated square equals the sum over a fine lattice of
    line dipoles filling it (h = 5 um, 160000 dipoles) within 1e-4 at points outside it, one near a corner."""
    center, size, angle = np.array([0.4e-3, -0.2e-3]), (2e-3, 2e-3), 30.0
    Mv = M * np.array([math.cos(0.3), math.sin(0.3)])
    h = 5e-6
    src = filled(center, size, angle, h)
    pts = center + np.array([[2.5e-3, 0.3e-3], [-0.4e-3, 1.9e-3], [-3e-3, -3e-3], [1.3e-3, 1.0e-3]])
    ref = lattice_H(pts, src, Mv * h * h)
    H = mc.polygon_field(mc.rectangle_vertices(center, size, angle), Mv, pts)
    assert np.all(np.linalg.norm(H - ref, axis=1) <= 1e-4 * np.linalg.norm(ref, axis=1))
    # far away: the field of one line dipole of moment M A
    far = center + np.array([[0.2, 0.05]])
    r = far[0] - center
    u = r / np.linalg.norm(r)
    m = Mv * 4e-6
    dip = (2 * np.dot(m, u) * u - m) / (2 * math.pi * np.dot(r, r))
    assert mc.polygon_field(mc.rectangle_vertices(center, size, angle), Mv, far)[0] == pytest.approx(dip, rel=1e-4)


def test_line_dipole_pair_law():
    """Two line dipoles: the force is grad(m2 . mu0 H1) (central differences of the energy), the torque on 2 is
    m2 x mu0 H1, and the pair obeys Newton's third law and conserves angular momentum:
    F21 = -F12, tau_1 + tau_2 + (x2 - x1) x F12 = 0 (to 1e-12)."""
    depth = 5e-3
    x1, x2 = np.array([[0.0, 0.0]]), np.array([[1.3e-3, -0.7e-3]])
    m1, m2 = np.array([[0.3, -0.8]]) * 1e-3, np.array([[-0.5, 0.4]]) * 1e-3
    F12, T12 = mc.line_dipole_force_torque(x1, m1, x2, m2, depth, x2[0])   # on 2 about its own position
    F21, T21 = mc.line_dipole_force_torque(x2, m2, x1, m1, depth, x1[0])

    def energy(p2):
        r = p2 - x1[0]
        u = r / np.linalg.norm(r)
        H = (2 * np.dot(m1[0] / depth, u) * u - m1[0] / depth) / (2 * math.pi * np.dot(r, r))
        return -MU0 * np.dot(m2[0], H)

    e = 1e-9
    grad = np.array([(energy(x2[0] + e * d) - energy(x2[0] - e * d)) / (2 * e) for d in np.eye(2)])
    assert np.allclose(F12, -grad, rtol=1e-6)
    assert np.allclose(F21, -F12, rtol=1e-12, atol=0)
    r = x2[0] - x1[0]
    assert abs(T12 + T21 + (r[0] * F12[1] - r[1] * F12[0])) < 1e-12 * abs(T12)


def test_polygon_force_and_torque_are_those_of_the_dipoles():
    """Force and torque on one drawn square in the field of another (edge-charge closed form, Gauss-Legendre on
    the edges) against the direct line-dipole sum over fine lattices filling both (h = 40 um, each lattice
    carrying the square's total moment): within 0.5 % (measured 0.04 % force, 0.11 % torque on the |F| side/2
    scale; what is left is the tilted lattice's staircase outline, h / side = 2 % of the edge)."""
    depth, h = 5e-3, 40e-6
    a = {"center": np.array([0.0, 0.0]), "size": (2e-3, 2e-3), "angle": 0.0, "M": M * np.array([1.0, 0.0])}
    b = {"center": np.array([3.2e-3, 1.4e-3]), "size": (2e-3, 2e-3), "angle": 45.0, "M": M * np.array([0.6, 0.8])}
    Va = mc.rectangle_vertices(a["center"], a["size"], a["angle"])
    Vb = mc.rectangle_vertices(b["center"], b["size"], b["angle"])
    F, T = mc.polygon_force_torque(Vb, b["M"], lambda p: mc.polygon_field(Va, a["M"], p), b["center"])
    pa, pb = filled(a["center"], a["size"], a["angle"], h), filled(b["center"], b["size"], b["angle"], h)
    wa, wb = 4e-6 / len(pa), 4e-6 / len(pb)  # each lattice carries the square's area (4 mm^2)
    Fd, Td = mc.line_dipole_force_torque(pa, np.tile(a["M"] * wa * depth, (len(pa), 1)),
                                         pb, np.tile(b["M"] * wb * depth, (len(pb), 1)), depth, b["center"])
    assert np.linalg.norm(F * depth - Fd) <= 0.005 * np.linalg.norm(Fd)
    assert abs(T * depth - Td) <= 0.005 * np.linalg.norm(Fd) * 1e-3


SINGLE = """
name = "one_block"
[simulation]
dim = 2
dx = 2.5e-4
domain_lo = [-0.006, -0.006]
domain_hi = [0.006, 0.006]
duration = 0.001
depth = 5.0e-3
formulation = "updated"
magnetic_interaction = "dipole"
[[bodies]]
name = "block1"
shape = {{ type = "rectangle", center = [3.0e-5, 1.0e-5], size = [{sx}, {sy}], angle = 22.5 }}
material = "dragon-skin-10-ndfeb100"
magnetization = {{ type = "uniform", direction = [-0.382683432, 0.923879533, 0.0] }}
"""


def test_a_lone_block_feels_no_self_torque(tmp_path):
    """A body's own field must not turn it. The grid's lattice of dipoles alone gives a lone body a spurious
    self-torque that grows with its shape's anisotropy: at dx = 0.25 mm a 4 x 1 mm bar tilted 22.5 degrees and
    magnetised across gets 1.8e-2 mu0 M^2 V (measured; 0.9e-2 at dx = 0.125 mm), a 2 mm square (the chain's
    block) 6e-7 here. Each refresh removes it body by body (MagneticInteraction._remove_self_torque): required
    below 1e-7 mu0 M^2 V (float32 round-off of the gathered field; measured 4e-10 and 2e-10). Self-force: zero
    to round-off."""
    from magsoro.simulation import Simulation

    for name, (sx, sy) in {"square": (2e-3, 2e-3), "bar": (4e-3, 1e-3)}.items():
        path = tmp_path / f"{name}.toml"
        path.write_text(SINGLE.format(sx=sx, sy=sy))
        sim = Simulation.from_file(path)
        energy = MU0 * M * M * sx * sy * 5e-3  # mu0 M^2 V (J)
        sim.solver.interaction.correct_self_torque = False
        (_, raw), = mc.engine_block_loads(sim)
        sim.solver.interaction.correct_self_torque = True
        (force, torque), = mc.engine_block_loads(sim)
        assert abs(torque) < 1e-7 * energy
        assert np.linalg.norm(force) < 1e-6 * energy / sx
        if name == "bar":
            assert abs(raw) > 1e-2 * energy  # what the correction removes


@pytest.mark.slow
def test_preview_reproduction(tmp_path):
    """The CI reproduction (preview grid, ~20 s): every check passes, the chain folds (the outer hinges pass 90
    degrees) and closes (the end blocks' gap falls from 6.6 mm to below two cells), and the files are written."""
    res = mc.reproduce(Context(out=tmp_path, preview=True))
    assert res.passed, [r.as_dict() for r in res.rows if not r.passed]
    data = read_csv(res.csv)
    assert data["end_gap_mm"][0] == pytest.approx(6.6, abs=0.2)
    assert data["end_gap_mm"][-1] < 0.5
    assert max(data["hinge1_deg"]) > 90 and max(data["hinge3_deg"]) > 90
    assert np.all(np.abs(data["hinge1_deg"][:1] - 45.0) < 1e-6)
    assert res.png.is_file() and res.animation.is_file()
    assert res.info["interaction_refreshes"] >= res.info["steps"]


def test_full_resolution_loads_and_free_blocks():
    """At the full grid (dx = 0.125 mm, 4741 particles): the engine's initial loads match the direct pair sum
    within 1 % (measured 0.001 % force) and free blocks start moving at them within 2 % (measured 0.35 % force,
    0.27 % torque); ~5 s."""
    from pathlib import Path

    from magsoro.robots.base import simulation

    ctx = Context(out=Path("."), preview=False)
    sim = simulation("magnetic_chain")
    ef, et = mc._load_errors(mc.engine_block_loads(sim), mc.direct_block_loads(sim), 1e-3)
    assert ef < 0.01 and et < 0.01
    rates, direct, _ = mc.free_blocks_rates(scene_data("magnetic_chain"), ctx)
    ef, et = mc._load_errors(rates, direct, 1e-3)
    assert ef < 0.02 and et < 0.02
