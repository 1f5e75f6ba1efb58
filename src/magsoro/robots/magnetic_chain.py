"""A chain of magnetised blocks that closes into a ring under its own attraction, with no applied field (issue
"Magnetic interaction"; seed 000 sec 5 leaves "the field created by distinct magnetic segments" to future work).

Four stiff magnetic blocks (squares in 2D plane strain) are joined by soft, non-magnetic hinge strips and laid out
as an open "C" (each hinge bent 45 degrees). Every block is magnetised along the chain (head to tail), so each
pair of neighbours attracts and, once folded, lies side by side with opposite magnetisations, which in 2D attract
as strongly as head to tail. Only ``simulation.magnetic_interaction = "dipole"`` moves it: the blocks' own field
(m = F Br V / mu0 per particle, line dipoles of the plane-strain slab) is the only load.

What the reproduction reports (``docs/robots/magnetic_chain``): the three hinge angles and the distance between the
two end blocks over time, the GIF of the folding, and these checks:

1. the interaction force and torque on every block before any motion against an independent closed form: the
   direct sum over all particle pairs of the 2D line-dipole law H = (2 (m.u) u - m) / (2 pi r^2) (no grid, no
   FFT), for the same particles;
2. the same blocks without their hinges: their initial rates of change of momentum and angular momentum in the
   engine against that force and torque (the engine turns the interaction into motion);
3. no external force: the centre of mass stays put while the blocks move by millimetres;
4. with ``magnetic_interaction = "none"`` nothing moves;
5. the ring closes: the end blocks end less than two cells apart (they meet on the grid).

The gap to reality is stated in the summary and in ``info``: the blocks are filled on the particle lattice, so
the tilted blocks are stair-stepped and every block sits up to half a particle spacing off its drawn centre; the
closed form for the drawn squares (uniformly magnetised polygons, edge charges) differs from the particle sets'
by 1.3 % in force on the full grid, 3.5 % on the preview grid (``info["drawn_squares_force_error"]``). The grid's
lattice of dipoles does not conserve angular momentum exactly: each block's own spurious torque is removed at
every refresh, the grid's error in the torques between blocks is not, and the closed ring may turn slowly as a
whole (``info["spurious_spin"]``). The path of the fold depends on the grid: on the full grid neighbours first snap
face to face in pairs (outer hinges near 180 degrees) before the pairs close the ring; the preview's 2-cell
hinges never fold that far. Touching blocks share one velocity field (they stick; no contact law between them).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from magsoro.constants import MU0
from magsoro.robots.base import (
    Context,
    FrameRecorder,
    ReproduceResult,
    Robot,
    RobotError,
    scene_data,
    simulation,
    write_csv,
)

NAME = "magnetic_chain"


# -- the design (scenes/magnetic_chain.toml is written from it; tests/test_magnetic_chain.py compares) --------
@dataclass(frozen=True)
class ChainDesign:
    """The chain's layout in the scene plane (m, degrees). Our design: the issue gives no dimensions."""

    blocks: int = 4                  # magnetic blocks
    side: float = 2.0e-3             # square blocks: a square has no preferred axis, so the grid's lattice of
                                     # dipoles has little spurious self-torque to remove (a 4:1 bar has more)
    gap: float = 2.0e-3              # hinge length between the facing block faces (= side: room to fold 90 deg)
    hinge_thickness: float = 0.5e-3  # a quarter of the face: soft in bending, 4 cells thick at full resolution
    bend: float = 45.0               # each hinge's initial bend (the open "C"), degrees
    inset: float = 0.25e-3           # the hinge strip reaches this far into each block (the block keeps the overlap)
    snap: float = 1.25e-4            # block centres on this lattice: the axis-aligned blocks fill exactly


DESIGN = ChainDesign()
BLOCK_MATERIAL = "dragon-skin-10-ndfeb100"
HINGE_MATERIAL = "ecoflex-00-30"


def _rot(angle: float, v) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def chain_parts(design: ChainDesign = DESIGN) -> list[dict]:
    """The robot parts ([[robot.parts]] tables) of the chain: ``blocks`` squares, block k turned by k * bend and
    magnetised along its own axis (head to tail), joined by hinge strips (polygons) between the centres of
    facing faces, the whole centred on the origin, block centres rounded to multiples of ``snap``."""
    d = design
    angles = [math.radians(k * d.bend) for k in range(d.blocks)]
    centres = [np.zeros(2)]
    for k in range(d.blocks - 1):
        face = centres[k] + _rot(angles[k], (d.side / 2, 0.0))
        mid = 0.5 * (angles[k] + angles[k + 1])
        nxt = face + d.gap * np.array([math.cos(mid), math.sin(mid)])
        centres.append(nxt + _rot(angles[k + 1], (d.side / 2, 0.0)))
    mean = np.mean(centres, axis=0)
    centres = [np.round((c - mean) / d.snap) * d.snap for c in centres]
    parts = []
    for k, (c, a) in enumerate(zip(centres, angles)):
        parts.append({
            "name": f"block{k + 1}",
            "shape": {"type": "rectangle", "center": [float(c[0]), float(c[1])], "size": [d.side, d.side],
                      "angle": math.degrees(a)},
            "material": BLOCK_MATERIAL,
            "magnetization": {"type": "uniform", "direction": [*(float(v) for v in _rot(a, (1.0, 0.0))), 0.0]},
            "magnetic": True,
            "priority": 2,
        })
    for k in range(d.blocks - 1):
        ends = []
        for c, a, x in ((centres[k], angles[k], d.side / 2 - d.inset), (centres[k + 1], angles[k + 1], -d.side / 2 + d.inset)):
            ends.append([c + _rot(a, (x, y)) for y in (-d.hinge_thickness / 2, d.hinge_thickness / 2)])
        verts = [ends[0][0], ends[1][0], ends[1][1], ends[0][1]]
        parts.append({
            "name": f"hinge{k + 1}",
            "shape": {"type": "polygon", "vertices": [[float(p[0]), float(p[1])] for p in verts]},
            "material": HINGE_MATERIAL,
            "priority": 1,
        })
    return parts


# -- closed forms ------------------------------------------------------------------------------------------
def line_dipole_force_torque(x_src, m_src, x_dst, m_dst, depth: float, centre, chunk: int = 256):
    """Force (N) and torque (N m, about ``centre``) on the particles ``x_dst`` (m, (n, 2)) with moments ``m_dst``
    (A m^2, in-plane) in the field of the particles ``x_src`` with moments ``m_src``, in 2D plane strain: a
    particle of a slab of thickness ``depth`` (m) is a line dipole of moment m / depth per unit length, whose field
    is H = (2 (m.u) u - m) / (2 pi r^2). Direct sum over every pair (no grid): per pair the force on dipole 2 is
    mu0 grad(m2 . H1) and its torque m2 x mu0 H1, summed over the targets' particles with their lever arms."""
    xs = np.asarray(x_src, dtype=np.float64)
    ms = np.asarray(m_src, dtype=np.float64) / depth
    xd = np.asarray(x_dst, dtype=np.float64)
    md = np.asarray(m_dst, dtype=np.float64)
    force = np.zeros(2)
    torque = 0.0
    c = np.asarray(centre, dtype=np.float64)
    for j in range(0, len(xd), chunk):
        r = xd[j:j + chunk, None, :] - xs[None]          # (n, k, 2) from source to target
        r2 = np.einsum("nki,nki->nk", r, r)
        inv2 = 1.0 / r2
        m1r = np.einsum("ki,nki->nk", ms, r)              # m_src . r
        m2r = np.einsum("ni,nki->nk", md[j:j + chunk], r)  # m_dst . r
        m12 = np.einsum("ki,ni->nk", ms, md[j:j + chunk])
        H = (2.0 * m1r[..., None] * r * inv2[..., None] - ms[None]) * (inv2[..., None] / (2.0 * math.pi))
        # grad_c (m2 . H) = [2 (m2.r) m1_c + 2 (m1.r) m2_c + 2 (m1.m2) r_c - 8 (m1.r)(m2.r) r_c / r^2] / (2 pi r^4)
        g = (2.0 * m2r[..., None] * ms[None] + 2.0 * m1r[..., None] * md[j:j + chunk, None, :]
             + 2.0 * m12[..., None] * r - 8.0 * (m1r * m2r * inv2)[..., None] * r) * (inv2 * inv2 / (2.0 * math.pi))[..., None]
        f = MU0 * g.sum(axis=1)
        Hp = H.sum(axis=1)
        arm = xd[j:j + chunk] - c
        force += f.sum(axis=0)
        torque += float(np.sum(arm[:, 0] * f[:, 1] - arm[:, 1] * f[:, 0]))
        mm = md[j:j + chunk]
        torque += float(MU0 * np.sum(mm[:, 0] * Hp[:, 1] - mm[:, 1] * Hp[:, 0]))
    return force, torque


def rectangle_vertices(center, size, angle_deg: float) -> np.ndarray:
    """Counter-clockwise corners (4, 2) of a rectangle turned by ``angle_deg`` about its centre."""
    hx, hy = size[0] / 2, size[1] / 2
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return np.array([np.asarray(center, float) + _rot(math.radians(angle_deg), p) for p in local])


def polygon_field(vertices, magnetization, points) -> np.ndarray:
    """H (A/m, (n, 2)) at ``points`` (m) of a uniformly magnetised polygon in 2D (counter-clockwise
    ``vertices``, ``magnetization`` M in A/m): the field of its edge charges sigma = M . n, for each straight edge
    P0 -> P1 with tangent t and nu = z x t, H = sigma / (2 pi) [ln(|r - P0| / |r - P1|) t + phi nu], phi the signed
    angle the edge subtends at r. Exact (closed form), valid outside the polygon."""
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    V = np.asarray(vertices, dtype=np.float64)
    M = np.asarray(magnetization, dtype=np.float64)
    H = np.zeros_like(pts)
    for i in range(len(V)):
        p0, p1 = V[i], V[(i + 1) % len(V)]
        t = (p1 - p0) / np.linalg.norm(p1 - p0)
        sigma = float(M[0] * t[1] - M[1] * t[0])  # M . outward normal (t_y, -t_x)
        if sigma == 0.0:
            continue
        d0, d1 = pts - p0, pts - p1
        phi = np.arctan2(d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0], np.einsum("ij,ij->i", d0, d1))
        log = np.log(np.linalg.norm(d0, axis=1) / np.linalg.norm(d1, axis=1))
        H += sigma / (2.0 * math.pi) * (log[:, None] * t + phi[:, None] * np.array([-t[1], t[0]]))
    return H


def polygon_force_torque(vertices, magnetization, field, centre, pieces: int = 32, order: int = 16):
    """Force per unit depth (N/m) and torque per unit depth (N, about ``centre``) on a uniformly magnetised polygon
    in the external field ``field(points) -> H`` (A/m): mu0 times the integrals of sigma H and (s - centre) x sigma H
    over its edge charges (composite Gauss-Legendre, ``pieces`` x ``order`` points per edge). For a rigid magnet in
    a curl-free external field this equals the dipole form (m . grad) B and m x B summed over its volume."""
    V = np.asarray(vertices, dtype=np.float64)
    M = np.asarray(magnetization, dtype=np.float64)
    xg, wg = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(0.0, 1.0, pieces + 1)
    u = ((edges[:-1, None] + edges[1:, None]) / 2 + np.diff(edges)[:, None] / 2 * xg[None]).ravel()
    w = (np.diff(edges)[:, None] / 2 * wg[None]).ravel()
    force, torque = np.zeros(2), 0.0
    c = np.asarray(centre, dtype=np.float64)
    for i in range(len(V)):
        p0, p1 = V[i], V[(i + 1) % len(V)]
        length = float(np.linalg.norm(p1 - p0))
        t = (p1 - p0) / length
        sigma = float(M[0] * t[1] - M[1] * t[0])
        if sigma == 0.0:
            continue
        s = p0 + u[:, None] * (p1 - p0)
        H = field(s)
        force += MU0 * sigma * length * (w[:, None] * H).sum(axis=0)
        arm = s - c
        torque += MU0 * sigma * length * float(np.sum(w * (arm[:, 0] * H[:, 1] - arm[:, 1] * H[:, 0])))
    return force, torque


# -- measuring the engine -------------------------------------------------------------------------------------
def _blocks(sim) -> list[int]:
    names = list(sim.built.body_names)
    return [i for i, n in enumerate(names) if n.startswith("block")]


def _engine_particle_loads(sim):
    """Positions x (m), moments m = F Br V / mu0 (A m^2), interaction field B (T) and force f (N) of every
    particle now, from a refresh of the solver's interaction (the bodies' own fields included, as applied)."""
    inter = sim.solver.interaction
    if inter is None:
        raise RobotError(f"{NAME}: the scene has no magnetic interaction")
    inter.refresh(sim.state.x, sim.state.F)
    h, dim = sim.model.host, sim.model.dim
    x = sim.state.x.numpy().astype(np.float64)
    F = sim.state.F.numpy().astype(np.float64)
    m = np.einsum("pij,pj->pi", F, h["remanence"][:, :dim]) * h["volumes"][:, None] / MU0
    B = inter.B.numpy().astype(np.float64)[:, :dim]
    G = inter.grad_B.numpy().astype(np.float64)[:, :dim, :dim]
    return x, m, B, np.einsum("pac,pa->pc", G, m)


def _torque(arm, f, m, B) -> float:
    """sum of arm x f + m x B (2D, z component)."""
    return float(np.sum(arm[:, 0] * f[:, 1] - arm[:, 1] * f[:, 0]) + np.sum(m[:, 0] * B[:, 1] - m[:, 1] * B[:, 0]))


def engine_block_loads(sim) -> list[tuple[np.ndarray, float]]:
    """(force N, torque N m about the block's centroid) of the magnetic interaction on every block now, as the
    engine computes it (FFT lattice of dipoles; the block's own field included)."""
    x, m, B, f = _engine_particle_loads(sim)
    body = sim.model.host["body"]
    out = []
    for b in _blocks(sim):
        sel = body == b
        out.append((f[sel].sum(axis=0), _torque(x[sel] - x[sel].mean(axis=0), f[sel], m[sel], B[sel])))
    return out


def lattice_total_torque(sim) -> float:
    """Total torque (N m) of the interaction on every particle now, about the origin: zero in physics (a system's
    own field exerts no net torque on it); what the grid's lattice of dipoles leaves."""
    x, m, B, f = _engine_particle_loads(sim)
    return _torque(x, f, m, B)


def direct_block_loads(sim) -> list[tuple[np.ndarray, float]]:
    """The same loads from :func:`line_dipole_force_torque`: every block in the field of the other blocks'
    particles, now (current positions and moments)."""
    h, dim = sim.model.host, sim.model.dim
    x = sim.state.x.numpy().astype(np.float64)
    F = sim.state.F.numpy().astype(np.float64)
    m = np.einsum("pij,pj->pi", F, h["remanence"][:, :dim]) * h["volumes"][:, None] / MU0
    blocks = _blocks(sim)
    depth = sim.solver.settings.depth
    out = []
    for b in blocks:
        sel = h["body"] == b
        src = np.isin(h["body"], [o for o in blocks if o != b])
        out.append(line_dipole_force_torque(x[src], m[src], x[sel], m[sel], depth, x[sel].mean(axis=0)))
    return out


def drawn_block_loads(parts: list[dict], depth: float) -> list[tuple[np.ndarray, float]]:
    """The loads on the drawn squares (exact uniformly magnetised polygons, :func:`polygon_force_torque`), each
    in the field of the others, times ``depth``; magnetisation |Br| / mu0 along each block's direction."""
    from magsoro.materials import get_material

    blocks = [p for p in parts if p["name"].startswith("block")]
    polys, mags, centres = [], [], []
    for p in blocks:
        s = p["shape"]
        polys.append(rectangle_vertices(s["center"], s["size"], s.get("angle", 0.0)))
        d = np.asarray(p["magnetization"]["direction"][:2], dtype=np.float64)
        br = p["magnetization"].get("magnitude") or get_material(p["material"]).remanence
        mags.append(br / MU0 * d / np.linalg.norm(d))
        centres.append(np.asarray(s["center"], dtype=np.float64))
    out = []
    for k in range(len(blocks)):
        others = [j for j in range(len(blocks)) if j != k]

        def field(pts, others=others):
            return sum(polygon_field(polys[j], mags[j], pts) for j in others)

        f, t = polygon_force_torque(polys[k], mags[k], field, centres[k])
        out.append((f * depth, t * depth))
    return out


def block_momenta(sim) -> list[tuple[np.ndarray, float]]:
    """Momentum (kg m/s) and angular momentum about its centroid (kg m^2/s) of every block now; the angular
    momentum includes the particles' own APIC part m dx^2/4 (C_yx - C_xy) (quadratic B-splines)."""
    h = sim.model.host
    x = sim.state.x.numpy().astype(np.float64)
    v = sim.state.v.numpy().astype(np.float64)
    C = sim.state.C.numpy().astype(np.float64)
    mass = h["mass"]
    q = sim.model.dx ** 2 / 4
    out = []
    for b in _blocks(sim):
        sel = h["body"] == b
        arm = x[sel] - x[sel].mean(axis=0)
        ms = mass[sel]
        L = np.sum(ms * (arm[:, 0] * v[sel, 1] - arm[:, 1] * v[sel, 0])) + np.sum(ms * q * (C[sel, 1, 0] - C[sel, 0, 1]))
        out.append(((ms[:, None] * v[sel]).sum(axis=0), float(L)))
    return out


def total_angular_momentum(sim) -> float:
    """Angular momentum (kg m^2/s) of every particle about the centre of mass, APIC part included."""
    h = sim.model.host
    x = sim.state.x.numpy().astype(np.float64)
    v = sim.state.v.numpy().astype(np.float64)
    C = sim.state.C.numpy().astype(np.float64)
    mass = h["mass"]
    arm = x - (mass[:, None] * x).sum(axis=0) / mass.sum()
    q = sim.model.dx ** 2 / 4
    return float(np.sum(mass * (arm[:, 0] * v[:, 1] - arm[:, 1] * v[:, 0])) + np.sum(mass * q * (C[:, 1, 0] - C[:, 0, 1])))


def block_rotations(X0: np.ndarray, x: np.ndarray, body: np.ndarray, blocks: list[int]) -> np.ndarray:
    """Rotation (rad) of every block from its reference shape: the least-squares (Kabsch) angle in 2D."""
    out = []
    for b in blocks:
        sel = body == b
        D = X0[sel] - X0[sel].mean(axis=0)
        d = x[sel] - x[sel].mean(axis=0)
        out.append(math.atan2(float(np.sum(D[:, 0] * d[:, 1] - D[:, 1] * d[:, 0])), float(np.sum(D[:, 0] * d[:, 0] + D[:, 1] * d[:, 1]))))
    return np.array(out)


def end_gap(x: np.ndarray, body: np.ndarray, first: int, last: int, spacing: float) -> float:
    """Clear distance (m) between the first and last block: closest particle centres less one particle spacing
    (so touching blocks give about 0)."""
    from scipy.spatial import cKDTree

    a, b = x[body == first], x[body == last]
    dist, _ = cKDTree(b).query(a)
    return float(dist.min() - spacing)


# -- checks that need runs of their own -------------------------------------------------------------------------
#: free blocks: sampled over the first FREE_TIME s (full, preview) at FREE_SAMPLES times; the slope at t = 0 of
#: momentum and angular momentum (a quadratic fit through the origin) is the initial force and torque. The window
#: is shorter than the blocks' ringing under their own field (period ~0.3 ms, measured), which changes the loads.
FREE_TIME = (2e-4, 2e-4)
FREE_SAMPLES = 8
#: without interaction: run this long (full, preview), s, and expect no motion at all
STILL_TIME = (0.01, 0.005)


def free_blocks_rates(data: dict, ctx: Context):
    """The chain's blocks without their hinges (same particles, same grid): (initial force, initial torque) per
    block as the slopes at t = 0 of their momentum and angular momentum, and the direct-sum loads at t = 0."""
    import copy

    free = copy.deepcopy(data)
    free["robot"]["parts"] = [p for p in free["robot"]["parts"] if p["name"].startswith("block")]
    # the blocks stay apart (closest corners ~1.2 mm, 5 cells) for the short run: one shared velocity field
    free["contact"] = {"friction": "sticky"}
    mode = 1 if ctx.preview else 0
    free.pop("probes", None)
    sim = simulation(NAME, free, preview=ctx.preview, device=ctx.device)
    direct = direct_block_loads(sim)
    times, P, L = [], [], []
    for k in range(1, FREE_SAMPLES + 1):
        sim.advance_to(FREE_TIME[mode] * k / FREE_SAMPLES)
        mom = block_momenta(sim)
        times.append(sim.time)
        P.append([p for p, _ in mom])
        L.append([l for _, l in mom])
    t = np.array(times)
    A = np.stack([t, t * t], axis=1)
    P, L = np.array(P), np.array(L)  # (samples, blocks, 2), (samples, blocks)
    rates = []
    for b in range(P.shape[1]):
        fx = np.linalg.lstsq(A, P[:, b, 0], rcond=None)[0][0]
        fy = np.linalg.lstsq(A, P[:, b, 1], rcond=None)[0][0]
        tq = np.linalg.lstsq(A, L[:, b], rcond=None)[0][0]
        rates.append((np.array([fx, fy]), float(tq)))
    return rates, direct, sim


def still_run(data: dict, ctx: Context) -> float:
    """Largest particle displacement (m) of the chain run with magnetic_interaction = "none"."""
    import copy

    none = copy.deepcopy(data)
    none["simulation"]["magnetic_interaction"] = "none"
    mode = 1 if ctx.preview else 0
    none.pop("probes", None)
    sim = simulation(NAME, none, preview=ctx.preview, device=ctx.device)
    sim.advance_to(STILL_TIME[mode])
    x = sim.state.x.numpy().astype(np.float64)
    return float(np.abs(x - sim.model.host["positions"]).max())


def _load_errors(test, ref, arm: float):
    """Largest relative force error over the blocks, and largest torque error over |F| arm (the torques cancel
    nearly by symmetry, so they are compared on the scale of the forces' moments about a block's centre)."""
    ef = max(float(np.linalg.norm(f - fr) / np.linalg.norm(fr)) for (f, _), (fr, _) in zip(test, ref))
    et = max(abs(t - tr) / (float(np.linalg.norm(fr)) * arm) for (_, t), (fr, tr) in zip(test, ref))
    return ef, et


# -- the reproduction ------------------------------------------------------------------------------------------
def _plot(path, t_ms, gap_mm, centre_mm, hinges_deg):
    import os

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(5.2, 5.6), dpi=120, sharex=True)
    ax1.plot(t_ms, centre_mm, "-", label="end blocks' centres")
    ax1.plot(t_ms, gap_mm, "-", label="clear gap between end blocks")
    ax1.set_ylabel("distance (mm)")
    ax1.set_title("Magnetic chain closing into a ring (no applied field)\n"
                  "2D, 4 NdFeB-silicone blocks, soft hinges, dipole interaction", fontsize=9)
    ax1.grid(alpha=0.3)
    ax1.legend(fontsize=7)
    for k in range(hinges_deg.shape[1]):
        ax2.plot(t_ms, hinges_deg[:, k], "-", label=f"hinge {k + 1}")
    ax2.set_xlabel("time (ms)")
    ax2.set_ylabel("hinge angle (deg)")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=7)
    fig.tight_layout()
    path = os.fspath(path)
    tmp = path + ".tmp.png"
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.validation.registry import Row

    wall0 = time.perf_counter()
    data = scene_data(NAME)
    data.setdefault("output", {})["particles"] = False
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    if sim.solver.interaction is None:
        raise RobotError(f"{NAME}: the scene must set simulation.magnetic_interaction = 'dipole'")
    sc = sim.scene.simulation
    h = sim.model.host
    body, X0, mass = h["body"], h["positions"].astype(np.float64), h["mass"]
    blocks = _blocks(sim)
    spacing = sc.dx / sc.particles_per_cell
    side = float(data["robot"]["parts"][0]["shape"]["size"][0])
    ctx.log(f"{NAME}: {sim.model.n_particles} particles, dx = {sc.dx * 1e3:.3g} mm, dt = {sim.dt:.3g} s, "
            f"{sc.duration * 1e3:.0f} ms")

    # check 1: the loads before any motion, engine (FFT lattice of dipoles) against the direct pair sum; and the
    # drawn squares' closed form against the particle sets (the geometry gap, reported)
    engine0 = engine_block_loads(sim)
    direct0 = direct_block_loads(sim)
    drawn0 = drawn_block_loads(data["robot"]["parts"], sc.depth)
    static_f, static_t = _load_errors(engine0, direct0, side / 2)
    drawn_f, drawn_t = _load_errors(direct0, drawn0, side / 2)

    # the run
    every = float(sim.scene.output.every or sc.duration / 50)
    com0 = (mass[:, None] * X0).sum(axis=0) / mass.sum()
    rows_t, rots, gaps, centres, coms, spins, probe = [], [], [], [], [], [], []
    frames = FrameRecorder(axes=(0, 1), label=lambda s: f"t = {s.time * 1e3:.1f} ms")

    def record(s):
        x = s.state.x.numpy().astype(np.float64)
        frames.record(s)
        rows_t.append(s.time)
        rots.append(block_rotations(X0, x, body, blocks))
        gaps.append(end_gap(x, body, blocks[0], blocks[-1], spacing))
        ca = x[body == blocks[0]].mean(axis=0)
        cb = x[body == blocks[-1]].mean(axis=0)
        centres.append(float(np.linalg.norm(ca - cb)))
        coms.append(float(np.linalg.norm((mass[:, None] * x).sum(axis=0) / mass.sum() - com0)))
        spins.append(total_angular_momentum(s))
        vals = s.probe_values()
        probe.append(math.hypot(vals.get("centre_Bx", 0.0), vals.get("centre_By", 0.0)))

    result = sim.run(record=record, record_every=every)
    if result.status != "completed":
        raise RobotError(f"{NAME}: run {result.status}: {result.message}")
    t = np.array(rows_t)
    rot = np.unwrap(np.array(rots), axis=0)
    bend = np.diff(np.array([float(p["shape"].get("angle", 0.0)) for p in data["robot"]["parts"]
                             if p["name"].startswith("block")]))
    hinge = np.degrees(np.diff(rot, axis=1)) + bend[None]
    gap, centre, com, spin = np.array(gaps), np.array(centres), np.array(coms), np.array(spins)
    x_end = sim.state.x.numpy().astype(np.float64)
    motion = float(np.abs(x_end - X0).max())
    # spurious whole-body spin: total angular momentum over the chain's moment of inertia about its centre of mass
    arm = x_end - (mass[:, None] * x_end).sum(axis=0) / mass.sum()
    inertia = float(np.sum(mass * np.einsum("ij,ij->i", arm, arm)))
    end_loads = engine_block_loads(sim)
    lattice_torque = lattice_total_torque(sim)
    ctx.log(f"{NAME}: run {result.wall_time:.0f} s, {sim.steps} steps; free blocks and a run without interaction next")

    # check 2: free blocks, the engine's initial rates against the direct sum
    rates, direct_free, _free_sim = free_blocks_rates(scene_data(NAME), ctx)
    dyn_f, dyn_t = _load_errors(rates, direct_free, side / 2)
    # check 4: without interaction (check 3, the centre of mass, is read from the run above)
    still = still_run(scene_data(NAME), ctx)

    out = ctx.out
    csv = write_csv(out / f"{NAME}.csv", {
        "t_ms": t * 1e3,
        "end_centres_mm": centre * 1e3,
        "end_gap_mm": gap * 1e3,
        **{f"hinge{k + 1}_deg": hinge[:, k] for k in range(hinge.shape[1])},
        "com_drift_m": com,
        "angular_momentum_kg_m2_s": spin,
        "B_centre_mT": np.array(probe) * 1e3,
    })
    png = out / f"{NAME}.png"
    _plot(png, t * 1e3, gap * 1e3, centre * 1e3, hinge)
    allx = np.concatenate([f[0] for f in frames.frames]) * 1e3
    lo, hi = allx.min(axis=0) - 0.5, allx.max(axis=0) + 0.5
    gif = frames.write_gif(out / f"{NAME}.gif", title="magnetic_chain: four magnets close into a ring", fps=12,
                           lims=((lo[0], hi[0]), (lo[1], hi[1])))

    case = f"robot-{NAME}"
    inp = {"dx_mm": round(sc.dx * 1e3, 4), "blocks": len(blocks), "side_mm": side * 1e3,
           "interaction_every": sc.interaction_every, "precision": sc.precision}
    rows = [
        # the method's near-field error (tests/test_magnetic_interaction.py: 0.15 % at 3 sphere radii, 0.01 % at 6)
        # is below 1 % for blocks at least 5 cells apart
        Row(case, "initial interaction force on each block: engine (FFT lattice) vs direct line-dipole pair sum, "
            "largest relative error", inp, 0.0, static_f, static_f, 0.01),
        Row(case, "initial interaction torque on each block: engine vs direct pair sum, largest error / (|F| side/2)",
            inp, 0.0, static_t, static_t, 0.01),
        # the blocks ring under their own field (strain ~ mu0 M^2 / E' = 2 %, period ~0.3 ms), so the loads
        # drift by up to 4 % within the fitted 0.2 ms (measured in the engine); the quadratic fit follows that
        # drift, and 2 % allows half of it
        Row(case, "free blocks: initial rate of momentum vs direct-sum force, largest relative error", inp,
            0.0, dyn_f, dyn_f, 0.02),
        Row(case, "free blocks: initial rate of angular momentum vs direct-sum torque, largest error / (|F| side/2)",
            inp, 0.0, dyn_t, dyn_t, 0.02),
        # momentum: the interaction's self-force is an odd convolution (zero to round-off) refreshed every step,
        # the grid damping -c p conserves a zero total; what is left is float32 round-off of positions (6e-8 of
        # |x| ~ 5 mm per step, 4e4 steps: ~1e-5 of the motion as a random walk)
        Row(case, "no external force: largest centre-of-mass drift / largest particle displacement", inp, 0.0,
            float(com.max() / motion), float(com.max() / motion), 1e-4),
        # nothing but float32 round-off of the elastic stress at F = I is left to move anything
        Row(case, "magnetic_interaction = 'none': largest displacement / that with 'dipole'", inp, 0.0,
            still / motion, still / motion, 1e-6),
        # the ring closes: the end blocks meet on the grid (particles of two bodies share grid nodes when their
        # centres are within 3 cells, i.e. a clear gap below about 2 cells)
        Row(case, "ring closed: clear gap between the end blocks at the end / dx", inp, 0.0,
            float(gap[-1] / sc.dx), float(gap[-1] / sc.dx), 2.0),
    ]
    summary = (f"Without any applied field the four blocks fold under their own attraction: the end blocks' gap "
               f"closes from {gap[0] * 1e3:.1f} mm to {max(gap[-1], 0.0) * 1e3:.2f} mm in "
               f"{t[np.argmax(gap <= 2 * sc.dx)] * 1e3 if np.any(gap <= 2 * sc.dx) else float('nan'):.0f} ms and the chain "
               f"ends as a closed ring (hinges {', '.join(f'{a:.0f}' for a in hinge[-1])} deg). The engine's "
               f"interaction loads before any motion match the direct line-dipole pair sum to {static_f:.1e} "
               f"(relative, force), free blocks start moving at those loads within {100 * dyn_f:.2g} % and "
               f"the centre of mass drifts {com.max() / motion:.1e} of the motion. Gaps to reality: the "
               f"particle-filled blocks differ from the drawn squares by up to {100 * drawn_f:.1f} % in initial force, "
               f"and the grid's lattice of dipoles does not conserve angular momentum exactly: the closed ring "
               f"turns as a whole at {spin[-1] / inertia:.2g} rad/s at the end (lattice torque "
               f"{lattice_torque:.2g} N m).")
    info = {
        "particles": sim.model.n_particles, "steps": sim.steps, "dx_m": sc.dx, "dt_min_s": sim.dt_min,
        "dt_max_s": sim.dt_max, "sim_wall_s": round(result.wall_time, 1), "wall_s": round(time.perf_counter() - wall0, 1),
        "interaction_refreshes": sim.solver.interaction.refreshes, "damping": sc.damping,
        "initial_force_N": [f.tolist() for f, _ in direct0], "initial_torque_Nm": [tq for _, tq in direct0],
        "engine_initial_force_N": [f.tolist() for f, _ in engine0], "engine_initial_torque_Nm": [tq for _, tq in engine0],
        "free_block_force_rate_N": [f.tolist() for f, _ in rates], "free_block_torque_rate_Nm": [tq for _, tq in rates],
        "drawn_squares_force_N": [f.tolist() for f, _ in drawn0], "drawn_squares_torque_Nm": [tq for _, tq in drawn0],
        "drawn_squares_force_error": drawn_f, "drawn_squares_torque_error": drawn_t,
        "largest_displacement_m": motion, "com_drift_max_m": float(com.max()), "still_displacement_m": still,
        "spurious_spin": {"angular_momentum_end_kg_m2_s": float(spin[-1]), "inertia_kg_m2": inertia,
                          "rate_end_rad_s": float(spin[-1] / inertia), "lattice_torque_end_Nm": lattice_torque,
                          "largest_block_torque_end_Nm": float(max(abs(tq) for _, tq in end_loads))},
        "end_gap_m": [float(gap[0]), float(gap[-1])], "hinge_end_deg": hinge[-1].tolist(),
    }
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info)


ROBOT = Robot(
    name=NAME,
    title="Magnetic chain closing into a ring",
    source="seed 000 sec 5",
    quantity="hinge angles and end-block gap vs time (no applied field)",
    sentence=("Four 2 mm NdFeB-silicone blocks, magnetised head to tail and joined by soft silicone hinges, are "
              "laid out as an open C with no applied field: their mutual attraction (magnetic_interaction = "
              "'dipole') folds the hinges and closes the chain into a ring."),
    reproduce=reproduce,
    in_ci=True,  # tests/test_magnetic_chain.py runs the preview (~20 s)
)
