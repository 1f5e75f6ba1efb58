"""Hertz contact (3D): an elastic hemisphere resting on its curved side on a rigid, frictionless plane.

Hertz's law for an elastic sphere of radius R on a rigid plane: F = 4/3 E* R^(1/2) d^(3/2), with
E* = E / (1 - nu^2), E = 2 G (1 + nu) and nu = (3 K - 2 G) / (2 (3 K + G)) from the shear and bulk moduli G, K.

Set-up. A solid hemisphere (radius R = 5 mm, flat face up, G = 300 kPa, K = 20 G so nu = 0.475 and
E* = 3.81 G, 1100 kg/m^3) rests on a fixed half-space collider ("slip": frictionless) and is loaded by its own
weight only: one run per load level, gravity g_k chosen so that the weight F_k = M g_k is Hertz's force at
d / R = 0.025, 0.05, 0.075, 0.1. Grid damping c = c_s / R (c_s the shear wave speed; 0.5-0.7 of critical for
the bounce on the contact) settles it in 14 R / c_s; the approach delta_k is how far the centre of mass (the
mean particle position; uniform density) has come down. R = 16 dx, 2 particles per cell per axis, float32, and
simulation.formulation = "updated" named in the scene (the form whose colliders this case checks).
Why this design:

* The force is known exactly: at rest the contact force is the weight M g of the simulated particles. No
  stress has to be read back, and the collider stays where it is.
* The plane does not move. The engine's collider acts on the grid nodes at or below its plane (updated
  Lagrangian form), so the plane matters only through the node layer it cuts: runs with the plane 0.55 and 0.95
  cells below the sphere are bit-identical, and a plate moved along a path would load in steps of a cell. With a
  fixed plane the contact sits at one node layer for every load, and the engine's contact offset delta_0 is
  fitted:
  delta_k - delta_fb(F_k) = delta_0 + c F_k^(2/3), where Hertz says c = (3 / (4 E* R^(1/2)))^(2/3); the local
  indentation of level k is d_k = delta_k - delta_fb(F_k) - delta_0.
* A hemisphere resting on its round side is stable against rocking (its centre of mass, 3/8 R below the flat
  face, lies below the centre of curvature) and costs half the particles of a sphere. Symmetry planes made from
  slip walls or colliders (a quarter body) were not used: the builder keeps bodies two cells away from domain
  walls, so a wall acts half a cell or more outside a cut face, and slip contact holds no tension, while the
  hemisphere's meridian planes carry tensile hoop stress in its upper half (up to 0.12 p0 in the model below).

What the approach means (delta_fb). Hertz's d is the approach of the plane to points far away in a half-space.
Any finite body adds a term from the far field that is linear in F (elasticity of the body as a whole; the
point-load displacement a distance R away is already of order F / (E* R)), and how large it is depends on the
body, the load and the point whose approach is measured, so a full sphere would need it as well. Here:
delta_cm(F) = d_H(F) + delta_fb(F) with delta_fb ~ kappa F / (E* R). It is computed by an independent,
axisymmetric linear-elastic finite-element model of the same hemisphere (quadratic triangles, mesh graded to
a few thousandths of R at the contact, frictionless unilateral contact by an active set, the same body force;
:class:`HemisphereFE`): kappa = -0.61 at d = 0.005 R and -0.58 at d = 0.1 R for nu = 0.475, i.e. the centre
of mass comes down 13 % (d = 0.025 R) to 24 % (d = 0.1 R) less than Hertz's d: compared with Hertz through its
centre of mass, an engine that solved the continuum exactly would be 1/0.76^1.5 - 1 = 52 % off at d = 0.1 R. The model is checked here against Hertz's limit (its approach tends
to Hertz's d as F -> 0, with a correction linear in F), against Boussinesq's far field, and for mesh
convergence (0.1 % from the default mesh to one with half the element size): tests/test_hertz.py.

Rows: per level, the weight F_k against Hertz's force at the local indentation d_k (tolerance 10 %), and the
fitted Hertz constant a = c^(-3/2) against 4/3 E* R^(1/2) (10 %). Hertz and the model are small-strain
theories; the engine is finite-strain Neo-Hookean, which differs by a few per cent at d = 0.1 R.

Measured (float32, updated Lagrangian, 2 CPU threads; ``compare(s, measure(s))`` with ``s = HertzSetup(cells=N)``):

=========  =========  ==========================================  ======================  =========
R / dx     particles  force error at d_k / R                      Hertz constant a / a_H  wall time
=========  =========  ==========================================  ======================  =========
12         28,900     11.4, 16.7, 15.6, 14.1 % (0.027 - 0.111)     0.852                   2.5 min
16 (case)  68,700     5.3, 12.4, 10.2, 9.0 % (0.026 - 0.107)       0.903                   4.9 min
20         134,000    3.6, 9.1, 7.3, 6.4 % (0.026 - 0.105)         0.931                   9.7 min
=========  =========  ==========================================  ======================  =========

The engine is softer than Hertz (the weights lie below Hertz's force at the measured indentation) and
converges at first order in dx (extrapolated a / a_H about 1.04, within the finite-strain difference). Where it
comes from: the contact offset delta_k - d_H(F_k) - delta_fb(F_k) is not constant but grows with the load,
0.20, 0.26, 0.27, 0.29 cells at R = 16 dx and 0.20, 0.26, 0.27, 0.28 cells at R = 20 dx, the same in cells at
both resolutions, most of it between the two smallest loads (contact radius 2.5 and 3.5 cells at R = 16 dx):
an extra compliance of the node-based contact of about a tenth of a cell, which is a smaller part of d at finer
grids. At R = 16 dx two of the four levels miss 10 % (tests/test_hertz.py marks the test xfail with these
numbers); at R = 20 dx every row passes. With nu = 0.3 (K = 2.17 G) the engine is softer still (R = 12 dx:
a / a_H = 0.75).
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from magsoro.validation.registry import CaseResult, Context, Row, register

#: Hertz indentations d / R of the load levels (the weights are Hertz's forces at these).
LEVELS = (0.025, 0.05, 0.075, 0.1)
TOLERANCE = 0.10


# -- closed forms ---------------------------------------------------------------------------------------------
def elastic_moduli(shear_modulus: float, bulk_modulus: float) -> tuple[float, float, float]:
    """(nu, E, E*) of an isotropic solid from G and K (Pa): nu = (3K - 2G) / (2 (3K + G)), E = 2 G (1 + nu),
    E* = E / (1 - nu^2) (contact with a rigid body)."""
    G, K = float(shear_modulus), float(bulk_modulus)
    nu = (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))
    E = 2.0 * G * (1.0 + nu)
    return nu, E, E / (1.0 - nu * nu)


def hertz_force(d, radius: float, e_star: float):
    """Hertz's force (N) of a sphere of ``radius`` (m) pressed by ``d`` (m) onto a rigid plane, E* in Pa."""
    return 4.0 / 3.0 * e_star * math.sqrt(radius) * np.asarray(d, dtype=np.float64) ** 1.5


def hertz_indentation(force, radius: float, e_star: float):
    """Inverse of :func:`hertz_force`: the indentation (m) under ``force`` (N)."""
    return (0.75 * np.asarray(force, dtype=np.float64) / (e_star * math.sqrt(radius))) ** (2.0 / 3.0)


# -- finite-element reference: the hemisphere's far-field term -------------------------------------------------
# Axisymmetric (r, z) small-strain elasticity on the meridian quarter disc r >= 0, -1 <= z <= 0 of the unit
# hemisphere (flat face z = 0 up, pole (0, -1) on the plane z = -1), 6-node triangles, 6-point rule.
_QA, _QB = 0.445948490915965, 0.091576213509771
_QP = np.array([[_QA, _QA], [1 - 2 * _QA, _QA], [_QA, 1 - 2 * _QA], [_QB, _QB], [1 - 2 * _QB, _QB], [_QB, 1 - 2 * _QB]])
_QW = np.array([0.223381589678011] * 3 + [0.109951743655322] * 3) * 0.5


def _t6(xi: float, eta: float):
    """Shape functions (6,) and their derivatives (6, 2) of the 6-node triangle at (xi, eta); corners 0-2, then
    the mid-side nodes of edges 01, 12, 20."""
    L = (1.0 - xi - eta, xi, eta)
    dL = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
    N = np.array([L[0] * (2 * L[0] - 1), L[1] * (2 * L[1] - 1), L[2] * (2 * L[2] - 1), 4 * L[0] * L[1], 4 * L[1] * L[2], 4 * L[2] * L[0]])
    dN = np.zeros((6, 2))
    for i in range(3):
        dN[i] = (4 * L[i] - 1) * dL[i]
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        dN[3 + k] = 4 * (L[i] * dL[j] + L[j] * dL[i])
    return N, dN


def _fe_mesh(h0: float, grow: float, hmax: float):
    """Nodes (n, 2), 6-node triangles (e, 6) and the flag of nodes on the spherical surface, for the meridian
    quarter disc of the unit hemisphere; element size h0 + grow * (distance from the pole), at most hmax."""
    from scipy.spatial import Delaunay

    pole = np.array([0.0, -1.0])

    def size(p):
        return np.minimum(h0 + grow * np.linalg.norm(np.atleast_2d(p) - pole, axis=1), hmax)

    pts = []
    z, axis = -1.0, []  # the axis r = 0, from the pole up
    while z < 0.0:
        axis.append(z)
        z += size((0.0, z))[0]
    axis = [z for z in axis if z < -0.5 * size((0.0, 0.0))[0]] + [0.0]
    pts += [(0.0, z) for z in axis]
    phi, arc = 0.0, []  # the spherical surface, polar angle from the pole
    while True:
        phi += size((math.sin(phi), -math.cos(phi)))[0]
        if phi >= math.pi / 2 - 0.5 * hmax:
            break
        arc.append(phi)
    arc.append(math.pi / 2)
    pts += [(math.sin(a), -math.cos(a)) for a in arc]
    r = 0.0
    while True:  # the flat face z = 0
        r += size((r, 0.0))[0]
        if r > 1.0 - 0.5 * size((1.0, 0.0))[0]:
            break
        pts.append((r, 0.0))
    rho = 0.0
    while rho < math.sqrt(2.0):  # interior: rings about the pole, kept clear of the boundary
        rho += size(pole + (0.0, rho))[0]
        h = size(pole + (0.0, rho))[0]
        n = max(int(math.ceil(rho * math.pi / 2 / h)), 1)
        psi = (np.arange(n) + 0.5) / n * math.pi / 2
        P = pole + rho * np.stack([np.sin(psi), np.cos(psi)], axis=1)
        hh = size(P)
        ok = (P[:, 0] > 0.6 * hh) & (-P[:, 1] > 0.6 * hh) & (1.0 - np.linalg.norm(P, axis=1) > 0.6 * hh)
        pts += [tuple(p) for p in P[ok]]
    pts = np.array(pts)
    tri = Delaunay(pts).simplices
    a = pts[tri]
    area = 0.5 * ((a[:, 1, 0] - a[:, 0, 0]) * (a[:, 2, 1] - a[:, 0, 1]) - (a[:, 2, 0] - a[:, 0, 0]) * (a[:, 1, 1] - a[:, 0, 1]))
    tri = tri[np.abs(area) > 1e-14]
    area = area[np.abs(area) > 1e-14]
    tri[area < 0] = tri[area < 0][:, [0, 2, 1]]
    on_sphere = np.abs(np.linalg.norm(pts, axis=1) - 1.0) < 1e-12
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    uniq, inv = np.unique(edges, axis=0, return_inverse=True)
    mid = 0.5 * (pts[uniq[:, 0]] + pts[uniq[:, 1]])
    curved = on_sphere[uniq[:, 0]] & on_sphere[uniq[:, 1]]
    mid[curved] /= np.linalg.norm(mid[curved], axis=1)[:, None]  # mid-side nodes of surface edges on the sphere
    conn = np.concatenate([tri, inv.reshape(3, len(tri)).T + len(pts)], axis=1)
    return np.concatenate([pts, mid]), conn, np.concatenate([on_sphere, curved])


class HemisphereFE:
    """Axisymmetric linear-elastic finite elements of a unit hemisphere (R = 1, E* = 1, Poisson ratio ``nu``)
    resting on its curved side on a rigid frictionless plane under its own uniform weight.

    :meth:`rest` gives, for a weight F (in units of E* R^2), the approach of the centre of mass to the plane
    (in R) measured from the unloaded sphere touching the plane, the contact radius and the contact reaction.
    Mesh: element size ``h0`` + ``grow`` x distance from the pole, at most ``hmax`` (units of R).
    """

    def __init__(self, nu: float, h0: float = 0.002, grow: float = 0.06, hmax: float = 0.03):
        import scipy.sparse as sp

        self.nu = float(nu)
        self.nodes, self.conn, self.surface = _fe_mesh(h0, grow, hmax)
        E = 1.0 - nu * nu  # so that E* = 1
        lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
        D = np.array([[lam + 2 * mu, lam, lam, 0], [lam, lam + 2 * mu, lam, 0], [lam, lam, lam + 2 * mu, 0], [0, 0, 0, mu]])
        X = self.nodes[self.conn]
        ne = len(self.conn)
        Ke = np.zeros((ne, 12, 12))
        weights = np.zeros((ne, 6))
        for (xi, eta), w in zip(_QP, _QW):
            N, dN = _t6(xi, eta)
            J = np.einsum("nka,kb->nab", X, dN)
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
            dNx = np.einsum("kb,nba->nka", dN, np.linalg.inv(J))
            r = X[:, :, 0] @ N
            B = np.zeros((ne, 4, 12))  # strains rr, zz, theta-theta, rz
            B[:, 0, 0::2] = dNx[:, :, 0]
            B[:, 1, 1::2] = dNx[:, :, 1]
            B[:, 2, 0::2] = N[None, :] / r[:, None]
            B[:, 3, 0::2] = dNx[:, :, 1]
            B[:, 3, 1::2] = dNx[:, :, 0]
            dv = 2 * math.pi * r * det * w
            Ke += np.einsum("nia,ij,njb->nab", B, D, B) * dv[:, None, None]
            weights += N[None, :] * dv[:, None]
        dofs = np.stack([2 * self.conn, 2 * self.conn + 1], axis=2).reshape(ne, 12)
        n = 2 * len(self.nodes)
        self.K = sp.csr_matrix((Ke.ravel(), (np.repeat(dofs, 12, axis=1).ravel(), np.tile(dofs, (1, 12)).ravel())), shape=(n, n))
        self.mass_weight = np.zeros(len(self.nodes))  # integral of N_i over the volume: lumps the body force
        np.add.at(self.mass_weight, self.conn.ravel(), weights.ravel())
        self.volume = float(self.mass_weight.sum())

    def rest(self, force: float) -> dict:
        """The hemisphere under its weight ``force`` (units of E* R^2) on the plane z = -1: centre-of-mass
        approach ``approach`` (R), ``contact_radius`` (R) and ``reaction`` (the plane's force, equal to the weight)."""
        f = np.zeros(2 * len(self.nodes))
        f[1::2] = -force / self.volume * self.mass_weight
        u, reaction, act = self._contact(f, {}, 0.5 * (0.75 * force) ** (2 / 3))
        return {
            "approach": float(-(self.mass_weight @ u[1::2]) / self.volume),
            "contact_radius": float(self.nodes[act, 0].max()),
            "reaction": float(reaction[2 * act + 1].sum()),
            "u": u,
        }

    def pressed(self, approach: float) -> dict:
        """The hemisphere held by its flat face z = 0 (clamped: no radial motion) and moved down by ``approach``
        (units of R) onto the plane z = -1, no body force: the plane's ``reaction`` (units of E* R^2) and the
        ``contact_radius`` (R)."""
        top = np.flatnonzero(np.abs(self.nodes[:, 1]) < 1e-12)
        held = {2 * i: 0.0 for i in top}
        held.update({2 * i + 1: -float(approach) for i in top})
        u, reaction, act = self._contact(np.zeros(2 * len(self.nodes)), held, 0.5 * float(approach))
        return {"reaction": float(reaction[2 * act + 1].sum()), "contact_radius": float(self.nodes[act, 0].max()), "u": u}

    def _contact(self, f, held: dict, reach: float):
        """Frictionless unilateral contact with the plane z = -1 by an active set, under the nodal loads ``f`` and
        the prescribed components ``held`` (dof -> value); the first set takes the surface nodes within ``reach``
        of the plane. Returns (u, reaction K u - f, the contact nodes)."""
        import scipy.sparse.linalg as spla

        nodes, n = self.nodes, len(self.nodes)
        axis = np.flatnonzero(np.abs(nodes[:, 0]) < 1e-12)
        cand = np.flatnonzero(self.surface & (nodes[:, 1] < -0.3))
        gap0 = nodes[cand, 1] + 1.0
        active = set(cand[gap0 < reach].tolist()) or {int(cand[np.argmin(gap0)])}
        for _ in range(100):
            fixed = {2 * i: 0.0 for i in axis}
            fixed.update(held)
            fixed.update({2 * i + 1: -1.0 - nodes[i, 1] for i in active})
            pres = np.array(sorted(fixed))
            vals = np.array([fixed[k] for k in pres])
            free = np.setdiff1d(np.arange(2 * n), pres)
            u = np.zeros(2 * n)
            u[pres] = vals
            u[free] = spla.spsolve(self.K[free][:, free].tocsc(), f[free] - self.K[free][:, pres] @ vals)
            reaction = self.K @ u - f
            act = np.array(sorted(active))
            keep = set(act[reaction[2 * act + 1] > 0].tolist())  # compressive contact only
            keep |= set(cand[nodes[cand, 1] + u[2 * cand + 1] < -1.0 - 1e-12].tolist())  # no penetration
            if keep == active:
                break
            active = keep
        else:
            raise RuntimeError("HemisphereFE: the contact active set did not settle")
        return u, reaction, np.array(sorted(active))


def finite_body_term(force, radius: float, e_star: float, fe: HemisphereFE) -> np.ndarray:
    """delta_fb (m): the model's centre-of-mass approach under ``force`` (N, each) less Hertz's d at that force."""
    out = []
    for F in np.atleast_1d(np.asarray(force, dtype=np.float64)):
        ratio = F / (e_star * radius**2)
        out.append(fe.rest(ratio)["approach"] * radius - float(hertz_indentation(F, radius, e_star)))
    return np.array(out)


# -- the MPM run ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class HertzSetup:
    """Hemisphere and numerics (SI). ``cells``: R / dx; ``damping``: grid damping in units of c_s / R (c_s the
    shear wave speed); ``settle``: simulated time per level in units of R / c_s; ``floor_gap``: cells between
    the hemisphere's lowest point and the plane at the start; ``formulation``: the engine's (simulation.formulation)."""

    radius: float = 5e-3
    cells: int = 16
    particles_per_cell: int = 2
    density: float = 1100.0
    shear_modulus: float = 3e5
    bulk_modulus: float = 6e6
    levels: tuple = LEVELS
    damping: float = 1.0
    settle: float = 14.0
    floor_gap: float = 0.75
    precision: str = "float32"
    formulation: str = "updated"

    @property
    def dx(self) -> float:
        return self.radius / self.cells

    @property
    def moduli(self) -> tuple[float, float, float]:
        return elastic_moduli(self.shear_modulus, self.bulk_modulus)

    @property
    def shear_wave_speed(self) -> float:
        return math.sqrt(self.shear_modulus / self.density)

    @property
    def continuum_mass(self) -> float:
        return self.density * 2.0 / 3.0 * math.pi * self.radius**3


def write_hemisphere_mesh(path, radius: float, n_phi: int = 256, n_theta: int = 64) -> Path:
    """Closed triangle mesh (STL) of a solid hemisphere of ``radius`` (m): centre of the flat face at the origin,
    the curved side towards -z. Latitude rings every 90/``n_theta`` degrees, ``n_phi`` points per ring (the chord
    error is below 1e-4 R)."""
    import trimesh

    th = np.linspace(0.0, math.pi / 2, n_theta + 1)[1:]
    ph = np.linspace(0.0, 2 * math.pi, n_phi, endpoint=False)
    V = [[0.0, 0.0, -radius]]
    for t in th:
        V += [[radius * math.sin(t) * math.cos(p), radius * math.sin(t) * math.sin(p), -radius * math.cos(t)] for p in ph]
    V.append([0.0, 0.0, 0.0])
    centre = len(V) - 1

    def ring(j, i):
        return 1 + j * n_phi + i % n_phi

    F = [[0, ring(0, i + 1), ring(0, i)] for i in range(n_phi)]
    for j in range(n_theta - 1):
        for i in range(n_phi):
            a, b, c, d = ring(j, i), ring(j, i + 1), ring(j + 1, i), ring(j + 1, i + 1)
            F += [[a, b, d], [a, d, c]]
    F += [[centre, ring(n_theta - 1, i), ring(n_theta - 1, i + 1)] for i in range(n_phi)]
    path = Path(path)
    trimesh.Trimesh(np.array(V), np.array(F), process=False).export(path)
    return path


def hertz_scene(setup: HertzSetup, mesh_file, level: float) -> dict:
    """Scene dict: the hemisphere (flat face at z = 0, lowest point at z = -R) above a frictionless plane
    ``floor_gap`` cells below it, gravity such that its continuum weight is Hertz's force at d = ``level`` R.
    The hemisphere's axis lies on a grid line, so particles and nodes are symmetric about it."""
    R, dx = setup.radius, setup.dx
    _, _, e_star = setup.moduli
    g = float(hertz_force(level * R, R, e_star)) / setup.continuum_mass
    pad = 6 * dx
    return {
        "name": f"hertz_{level:g}",
        "simulation": {
            "dim": 3, "dx": dx, "particles_per_cell": setup.particles_per_cell,
            "domain_lo": [-R - pad, -R - pad, -R - pad], "domain_hi": [R + pad, R + pad, pad],
            "duration": setup.settle * R / setup.shear_wave_speed, "gravity": [0.0, 0.0, -g],
            "damping": setup.damping * setup.shear_wave_speed / R, "precision": setup.precision,
            "formulation": setup.formulation,
        },
        "bodies": [{"name": "hemisphere", "shape": {"type": "mesh", "file": str(mesh_file)},
                    "material": {"density": setup.density, "shear_modulus": setup.shear_modulus, "bulk_modulus": setup.bulk_modulus}}],
        "colliders": [{"type": "half_space", "point": [0.0, 0.0, -R - setup.floor_gap * dx], "normal": [0.0, 0.0, 1.0], "mode": "slip"}],
        "output": {"particles": False},
    }


@dataclass
class LevelResult:
    """One load level: ``force`` the weight M g of the particles (N), ``approach`` the fall of the centre of mass
    (m), ``drift`` its change over the last R / c_s (m), ``max_speed`` the largest particle speed at the end
    (m/s), and the run's ``steps``, ``wall_s``, ``particles``."""

    level: float
    force: float
    approach: float
    drift: float
    max_speed: float
    steps: int
    wall_s: float
    particles: int


def settle_level(setup: HertzSetup, level: float, mesh_file) -> LevelResult:
    """Run one load level to rest and measure it."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    scene = hertz_scene(setup, mesh_file, level)
    t0 = time.perf_counter()
    sim = Simulation(parse_scene(scene))
    mass = sim.model.host["mass"]
    z0 = float(np.average(sim.state.x.numpy()[:, 2], weights=mass))
    t_end = scene["simulation"]["duration"]
    unit = setup.radius / setup.shear_wave_speed
    sim.advance_to(t_end - unit)
    z1 = float(np.average(sim.state.x.numpy()[:, 2], weights=mass))
    sim.advance_to(t_end)
    z2 = float(np.average(sim.state.x.numpy()[:, 2], weights=mass))
    v = sim.state.v.numpy()
    weight = float(mass.sum()) * -scene["simulation"]["gravity"][2]
    return LevelResult(level, weight, z0 - z2, z1 - z2, float(np.sqrt((v.astype(np.float64) ** 2).sum(axis=1).max())),
                       sim.steps, time.perf_counter() - t0, sim.model.n_particles)


def measure(setup: HertzSetup, log=None) -> list[LevelResult]:
    """Every load level of ``setup``, each a fresh run from rest."""
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        mesh_file = write_hemisphere_mesh(Path(tmp) / "hemisphere.stl", setup.radius)
        for level in setup.levels:
            res = settle_level(setup, level, mesh_file)
            if log is not None:
                log(f"  hertz d/R={level:g}: F={res.force:.4g} N, approach={res.approach / setup.dx:.4f} cells, "
                    f"drift={res.drift / setup.dx:.1e} cells, {res.steps} steps, {res.wall_s:.0f} s")
            out.append(res)
    return out


@dataclass
class HertzComparison:
    """Measured levels against Hertz. Lengths in m, forces in N. ``offset``: the fitted delta_0; ``constant``
    and ``hertz_constant``: a = c^(-3/2) fitted and 4/3 E* R^(1/2) (N/m^1.5); ``indentation``: local d_k;
    ``finite_body``: delta_fb(F_k); ``hertz``: F_H(d_k); ``error``: |F_k - F_H(d_k)| / F_H(d_k);
    ``contact_offset``: delta_k - d_H(F_k) - delta_fb(F_k), the engine's contact offset level by level (constant
    if the engine followed Hertz and the model exactly); ``plain``: the same fit without delta_fb (a bare Hertz
    comparison of the centre-of-mass approach)."""

    setup: HertzSetup
    levels: list
    finite_body: np.ndarray
    offset: float
    constant: float
    hertz_constant: float
    indentation: np.ndarray
    hertz: np.ndarray
    error: np.ndarray
    contact_offset: np.ndarray
    plain: dict = field(default_factory=dict)


def _fit(approach, force):
    """Least squares approach = offset + c force^(2/3): (offset, c)."""
    A = np.stack([np.ones_like(force), force ** (2.0 / 3.0)], axis=1)
    (offset, c), *_ = np.linalg.lstsq(A, approach, rcond=None)
    return float(offset), float(c)


def compare(setup: HertzSetup, levels: list[LevelResult], fe: HemisphereFE | None = None) -> HertzComparison:
    """Fit the offset and Hertz's constant to the measured levels (after removing the model's far-field term)."""
    nu, _, e_star = setup.moduli
    R = setup.radius
    fe = fe if fe is not None else HemisphereFE(nu)
    F = np.array([lv.force for lv in levels])
    delta = np.array([lv.approach for lv in levels])
    fb = finite_body_term(F, R, e_star, fe)
    offset, c = _fit(delta - fb, F)
    d = delta - fb - offset
    ref = hertz_force(np.maximum(d, 0.0), R, e_star)
    err = np.abs(F - ref) / ref
    p_off, p_c = _fit(delta, F)
    p_ref = hertz_force(np.maximum(delta - p_off, 0.0), R, e_star)
    plain = {"offset_cells": p_off / setup.dx, "constant_ratio": float(p_c ** -1.5 / (4 / 3 * e_star * math.sqrt(R))),
             "errors": [float(e) for e in np.abs(F - p_ref) / p_ref]}
    return HertzComparison(setup, levels, fb, offset, c ** -1.5, 4.0 / 3.0 * e_star * math.sqrt(R), d, ref, err,
                           delta - hertz_indentation(F, R, e_star) - fb, plain)


def rows_of(comp: HertzComparison, tolerance: float = TOLERANCE) -> list[Row]:
    """Rows of the case: the weight of each level against Hertz's force at its local indentation d_k (N), and the
    fitted Hertz constant a (N/m^1.5). The engine form and precision are in the case's info (``setup``)."""
    s = comp.setup
    base = {"R_over_dx": s.cells, "R_m": s.radius, "nu": round(s.moduli[0], 4)}
    rows = []
    for lv, d, ref, err in zip(comp.levels, comp.indentation, comp.hertz, comp.error):
        rows.append(Row("hertz", "contact_force_N", {"d_over_R": round(float(d / s.radius), 4), **base}, float(ref), lv.force,
                        float(err), tolerance))
    fitted = {"d_over_R": [round(float(d / s.radius), 4) for d in comp.indentation], **base}
    rows.append(Row("hertz", "hertz_constant_N_m1.5", fitted, comp.hertz_constant, comp.constant,
                    abs(comp.constant - comp.hertz_constant) / comp.hertz_constant, tolerance))
    return rows


def plot_hertz(comp: HertzComparison, path) -> Path:
    """Weight against local indentation d_k / R, with Hertz's law (PNG at ``path``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = comp.setup
    R = s.radius
    _, _, e_star = s.moduli
    d = np.linspace(0.0, 1.15 * max(float(comp.indentation.max()), 0.1 * R), 100)
    fig, ax = plt.subplots(figsize=(5, 3.6))
    ax.plot(d / R, hertz_force(d, R, e_star), "k-", label="Hertz 4/3 E* R^1/2 d^3/2")
    ax.plot(comp.indentation / R, [lv.force for lv in comp.levels], "o", label=f"MPM, R = {s.cells} dx (offset fitted)")
    ax.set_xlabel("local indentation d / R")
    ax.set_ylabel("contact force (weight), N")
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


@register("hertz", "elastic hemisphere on a rigid frictionless plane under its weight (3D, R = 16 dx): contact force vs Hertz "
          "at d = 0.025-0.1 R, far-field term from an axisymmetric FE model", quick=False, cost="~5 min")
def hertz_case(ctx: Context) -> CaseResult:
    setup = HertzSetup()
    levels = measure(setup, log=ctx.log)
    comp = compare(setup, levels)
    dx, R = setup.dx, setup.radius
    info = {
        "setup": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(setup).items()},
        "particles": levels[0].particles,
        "fitted_offset_cells": comp.offset / dx,
        "contact_offset_cells": [float(v / dx) for v in comp.contact_offset],
        "finite_body_over_R": [float(v / R) for v in comp.finite_body],
        "approach_cells": [lv.approach / dx for lv in levels],
        "drift_cells": [lv.drift / dx for lv in levels],
        "max_speed_m_s": [lv.max_speed for lv in levels],
        "steps": [lv.steps for lv in levels],
        "level_wall_s": [round(lv.wall_s, 1) for lv in levels],
        "without_finite_body_term": comp.plain,
    }
    figures = []
    if ctx.out is not None:
        figures.append(plot_hertz(comp, Path(ctx.out) / "hertz.png"))
    return CaseResult("hertz", rows_of(comp), figures, info)


__all__ = ["HemisphereFE", "HertzSetup", "LevelResult", "HertzComparison", "compare", "elastic_moduli", "finite_body_term",
           "hertz_force", "hertz_indentation", "hertz_scene", "measure", "plot_hertz", "rows_of", "settle_level",
           "write_hemisphere_mesh",
           "LEVELS", "TOLERANCE"]

