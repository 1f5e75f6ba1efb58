"""Bistable clamped arch snapped through by a field step (issue 25): the smallest step level that snaps it and
the snap time against the level, MPM against an independent planar elastica of the same strip.

The strip of scenes/bistable_arch.toml is clamped at both ends, pre-buckled by an axial eigenstrain (stimulus
stretch lambda along x: stress-free length lambda L between clamp faces L apart) and magnetised along its length,
+x on its left half and -x on its right half. In a uniform field the magnetic energy -(1/mu0) B . F Br dV0 of each
half integrates to -(1/mu0) |Br| t w B . (chord of the half), so the field's whole action is a point force
2 |Br| t w B / mu0 on the mid cross-section (seed 000 eq 13 with Zhao's F law; exact at any shape).

Reproduction:
1. pre-buckle: the eigenstrain ramps with a small upward bias field, then dynamic relaxation (Simulation.relax)
   brings the arch to rest in its upper state; that state is kept;
2. field steps: from the kept state, the scene's step field (its rise time and tilted direction) at a level,
   held for HOLD s; the crown (mean height of the mid cross-section) is read every READ_EVERY s. A level snaps
   the arch when the crown ends below the mid-plane y = 0. The snap time is from the start of the step to the
   first crossing of y = 0; the settling time to the last time the crown is farther than SETTLE_BAND x the
   pre-buckled crown height from its value at the end of the hold;
3. threshold: a bracket [lo, hi] (lo does not snap, hi snaps within the hold) verified by runs and halved by
   bisection; then levels above it give the snap time against the level. One snap, with the field switched off
   again afterwards (the arch must stay down: bistable), is the GIF.

Independent reference (:class:`ArchElastica`): the same strip as a discrete planar elastica (extensible, plane-
strain modulus E' = E / (1 - nu^2) from the engine's G and K, natural length lambda L, clamped tangents at the
clamp faces), with the magnetic energy of its segments written out (not the point-force shortcut), lumped masses
and the engine's mass-proportional damping. It gives (a) the static threshold: the level where the upper
equilibrium, followed by Newton continuation in the level, loses stability (smallest Hessian eigenvalue through
zero: the asymmetric bifurcation of a high arch); (b) the dynamic threshold and snap times for the same field
step, by explicit integration. The MPM threshold is checked against (b); the gap to (a) is reported.
"""

from __future__ import annotations

import math
import time

import numpy as np

from magsoro.actuation.planning import plane_strain_modulus
from magsoro.constants import MU0
from magsoro.robots.base import (Context, FrameRecorder, ReproduceResult, Robot, RobotError, scene_data,
                                 simulation, write_csv)

NAME = "bistable_arch"
HOLD = 0.15            # s of field after the step starts: long enough for the slow snaps near the threshold
READ_EVERY = 5e-4      # s between crown reads (the snap takes ~15-70 ms)
SETTLE_BAND = 0.10     # settled: within this fraction of the pre-buckled crown height of the end value
SETTLE_KEEP = 0.02     # s: ... and staying there at least this long before the end of the hold (else not settled)
RELEASE = 0.05         # s after the field is switched off again (GIF run): the arch must stay down
BRACKET = (0.75, 1.25)  # first bracket, times the elastica's dynamic threshold (then verified and widened by runs)
BISECTIONS = {True: 3, False: 4}      # preview: bracket 1/16 of the threshold wide; full: 1/32
SWEEP = {True: (1.4, 2.0), False: (1.2, 1.4, 2.0, 2.6)}  # snap-time levels, times the bracket's upper end
GIF_LEVEL = 1.4        # the GIF's level, times the bracket's upper end
ELASTICA_NODES = 40    # segments of the reference elastica (thresholds within 0.6 % of 80 segments)
# tolerances of the checks
THRESHOLD_TOL = 0.10   # MPM threshold vs the elastica's dynamic threshold (relative)
CROWN_TOL = 0.05       # pre-buckled crown height vs the elastica (relative)
SNAP_TIME_TOL = 0.15   # snap time at the sweep's levels vs the elastica (relative, mean)


# -- the reference: a discrete planar elastica ---------------------------------------------------------------
class ArchElastica:
    """A strip clamped at x = -span/2 and +span/2 (tangent along +x at both), ``n`` straight segments of natural
    length lambda span / n, extensible (E' t w) and bending (E' w t^3 / 12), magnetised along its length with
    |Br| (T), +x on the left half and -x on the right half (Zhao's law: a segment's moment is |Br| t w / mu0 times
    its current chord). SI units; forces and energies for the width ``width``."""

    def __init__(self, span: float, stretch: float, thickness: float, width: float, youngs_modulus: float,
                 density: float, remanence: float, n: int = ELASTICA_NODES):
        if n % 2:
            raise ValueError("n must be even (the magnetisation flips at the middle node)")
        self.span, self.stretch, self.n = float(span), float(stretch), int(n)
        self.axial = youngs_modulus * thickness * width                   # E' A, N
        self.bending = youngs_modulus * width * thickness**3 / 12.0       # E' I, N m^2
        self.seg = stretch * span / n                                     # natural segment length, m
        self.moment = remanence * thickness * width / MU0                 # moment per length of chord, A m
        self.sign = np.where(np.arange(n) < n // 2, 1.0, -1.0)
        self.mass = np.full(n + 1, density * thickness * width * span / n)  # the reference volume's mass
        self.mass[[0, -1]] *= 0.5
        # bending weights: E'I / l per interior node; 2 E'I / l at a clamp (half a segment to the clamp face)
        self.weights = np.full(n + 1, self.bending / self.seg)
        self.weights[[0, -1]] *= 2.0
        node = np.arange(2 * (n - 1)) // 2
        self._node = node

    # geometry ---------------------------------------------------------------------------------------------
    def nodes(self, q: np.ndarray) -> np.ndarray:
        p = np.empty((self.n + 1, 2))
        p[0] = (-0.5 * self.span, 0.0)
        p[-1] = (0.5 * self.span, 0.0)
        p[1:-1] = np.asarray(q).reshape(-1, 2)
        return p

    def crown(self, q: np.ndarray) -> float:
        return float(self.nodes(q)[self.n // 2, 1])

    def cosine_arch(self, up: float = 1.0) -> np.ndarray:
        """First buckling mode y = H/2 (1 + cos 2 pi x / L) with the inextensible height H = (2/pi) sqrt(L dL)."""
        x = np.linspace(-0.5 * self.span, 0.5 * self.span, self.n + 1)
        height = 2.0 / math.pi * math.sqrt(self.span * max(self.stretch - 1.0, 1e-6) * self.span)
        y = up * 0.5 * height * (1.0 + np.cos(2.0 * math.pi * x / self.span))
        return np.stack([x, y], axis=1)[1:-1].ravel()

    # energy -----------------------------------------------------------------------------------------------
    def energy_gradient(self, q: np.ndarray, B) -> tuple[float, np.ndarray]:
        """Energy (J) and its gradient over the free node coordinates at uniform field ``B`` (Bx, By) in T."""
        p = self.nodes(q)
        s = np.diff(p, axis=0)
        length = np.hypot(s[:, 0], s[:, 1])
        theta = np.arctan2(s[:, 1], s[:, 0])
        turn = np.empty(self.n + 1)
        turn[0] = theta[0]
        turn[1:-1] = (np.diff(theta) + math.pi) % (2.0 * math.pi) - math.pi
        turn[-1] = -theta[-1]
        b = np.asarray(B, dtype=np.float64)[:2]
        energy = (0.5 * self.axial * np.sum((length - self.seg) ** 2) / self.seg + 0.5 * np.sum(self.weights * turn**2)
                  - self.moment * np.sum(self.sign * (s @ b)))
        grad_s = (self.axial * (length - self.seg) / self.seg / length)[:, None] * s
        moment = self.weights * turn
        dtheta = np.stack([-s[:, 1], s[:, 0]], axis=1) / (length * length)[:, None]
        grad_s += (moment[:-1] - moment[1:])[:, None] * dtheta
        grad_s -= self.moment * self.sign[:, None] * b[None, :]
        grad_p = np.zeros_like(p)
        grad_p[1:] += grad_s
        grad_p[:-1] -= grad_s
        return float(energy), grad_p[1:-1].ravel()

    def hessian(self, q: np.ndarray, B) -> np.ndarray:
        """Hessian by central differences of the gradient; a node's gradient depends on its neighbours within two
        nodes, so columns five nodes apart are perturbed together (20 gradient evaluations)."""
        n = len(q)
        H = np.zeros((n, n))
        h = 1e-7 * self.span
        comp = np.arange(n) % 2
        for color in range(5):
            for c in range(2):
                cols = np.flatnonzero((self._node % 5 == color) & (comp == c))
                d = np.zeros(n)
                d[cols] = h
                dg = (self.energy_gradient(q + d, B)[1] - self.energy_gradient(q - d, B)[1]) / (2.0 * h)
                for j in cols:
                    rows = np.flatnonzero(np.abs(self._node - self._node[j]) <= 2)
                    H[rows, j] = dg[rows]
        return 0.5 * (H + H.T)

    def equilibrium(self, q: np.ndarray, B, tol: float = 1e-11, iterations: int = 60) -> tuple[np.ndarray, bool]:
        """Newton's method from ``q`` (steps capped at 2 % of the span)."""
        q = np.array(q, dtype=np.float64)
        for _ in range(iterations):
            g = self.energy_gradient(q, B)[1]
            dq = np.linalg.solve(self.hessian(q, B), -g)
            big = np.abs(dq).max()
            if big > 0.02 * self.span:
                dq *= 0.02 * self.span / big
            q += dq
            if big < tol * self.span:
                return q, True
        return q, False

    def upper_state(self) -> np.ndarray:
        q, ok = self.equilibrium(self.cosine_arch(+1.0), (0.0, 0.0))
        if not ok or self.crown(q) <= 0:
            raise RobotError("elastica: no upper equilibrium of the pre-buckled arch")
        return q

    def static_threshold(self, direction, q0: np.ndarray | None = None, first: float = 0.004,
                         rtol: float = 1e-3) -> tuple[float, np.ndarray]:
        """Largest field level (T) along the unit ``direction`` up to which the upper equilibrium, continued from
        zero field, stays stable (Hessian positive definite, crown above the mid-plane); continuation steps halve
        past a failure until they are ``rtol`` of the level. Returns (level, the smallest eigenvector there)."""
        d = np.asarray(direction, dtype=np.float64)[:2]
        good_b, good_q = 0.0, self.upper_state() if q0 is None else np.array(q0)
        step, mode = first, None
        while step > rtol * max(good_b, first):
            b = good_b + step
            q, ok = self.equilibrium(good_q, b * d)
            if ok:
                w, V = np.linalg.eigh(self.hessian(q, b * d))
                ok = w[0] > 0.0 and self.crown(q) > 0.0
                mode = V[:, 0]
            if ok:
                good_b, good_q = b, q
            else:
                step *= 0.5
        return good_b, mode

    # dynamics ---------------------------------------------------------------------------------------------
    def step_response(self, q0: np.ndarray, level: float, direction, rise: float, duration: float, damping: float,
                      every: float = READ_EVERY, release: float | None = None):
        """Crown height over time (every ``every`` s) for the field level * direction reached linearly in
        ``rise`` s from t = 0 (switched off again, in ``rise``, at ``release`` when given): velocity Verlet with
        lumped masses and the engine's grid damping (velocities times exp(-c dt) per step)."""
        d = np.asarray(direction, dtype=np.float64)[:2]
        mass = np.repeat(self.mass[1:-1], 2)

        def field(t):
            on = min(max(t / rise, 0.0), 1.0)
            if release is not None:
                on *= 1.0 - min(max((t - release) / rise, 0.0), 1.0)
            return level * on * d

        H = self.hessian(q0, (0.0, 0.0))
        omega_max = math.sqrt(np.linalg.eigvalsh(H / np.sqrt(np.outer(mass, mass)))[-1])
        steps = int(math.ceil(duration / (0.8 / omega_max)))
        dt = duration / steps
        decay = math.exp(-damping * dt)
        q, v = np.array(q0, dtype=np.float64), np.zeros_like(q0)
        g = self.energy_gradient(q, field(0.0))[1]
        times, crown = [0.0], [self.crown(q)]
        stride = max(1, int(round(every / dt)))
        for k in range(1, steps + 1):
            v -= 0.5 * dt * g / mass
            q += dt * v
            g = self.energy_gradient(q, field(k * dt))[1]
            v = (v - 0.5 * dt * g / mass) * decay
            if k % stride == 0 or k == steps:
                times.append(k * dt)
                crown.append(self.crown(q))
        return np.array(times), np.array(crown)


def snap_times(times, crown, height: float, band: float = SETTLE_BAND,
               keep: float = SETTLE_KEEP) -> tuple[bool, float, float]:
    """(snapped, time of the first crossing of the mid-plane, settling time) of a crown history starting at the
    step: snapped when it ends below y = 0; settled from the last time it is farther than ``band`` x ``height``
    from its final value, provided it then stays within the band for ``keep`` s or more (else NaN: not settled
    within the history; NaN times too when it did not snap)."""
    times, crown = np.asarray(times), np.asarray(crown)
    if crown[-1] >= 0.0:
        return False, float("nan"), float("nan")
    below = np.flatnonzero(crown < 0.0)
    k = below[0]
    t_cross = float(times[k - 1] + (times[k] - times[k - 1]) * crown[k - 1] / (crown[k - 1] - crown[k])) if k > 0 else 0.0
    out = np.flatnonzero(np.abs(crown - crown[-1]) > band * height)
    t_settle = float(times[out[-1] + 1]) if len(out) and out[-1] + 1 < len(times) else float(times[0])
    t_settle = max(t_settle, t_cross)
    if t_settle > times[-1] - keep:
        t_settle = float("nan")
    return True, t_cross, t_settle


def bisect_threshold(snaps, lo: float, hi: float, bisections: int, log=None):
    """Bracket [lo, hi] of the smallest snapping level: widened until ``snaps(lo)`` is False and ``snaps(hi)``
    True (lo / 1.25, hi x 1.25, at most 6 times), then halved ``bisections`` times. Returns (lo, hi)."""
    for _ in range(6):
        if not snaps(lo):
            break
        lo, hi = lo / 1.25, lo
    else:
        raise RobotError(f"{NAME}: the arch snaps even at {lo * 1e3:.3g} mT")
    for _ in range(6):
        if snaps(hi):
            break
        lo, hi = hi, hi * 1.25
    else:
        raise RobotError(f"{NAME}: the arch does not snap even at {hi * 1e3:.3g} mT within the hold")
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        if snaps(mid):
            hi = mid
        else:
            lo = mid
        if log is not None:
            log(f"{NAME}: threshold bracket [{lo * 1e3:.3f}, {hi * 1e3:.3f}] mT")
    return lo, hi


# -- the scene --------------------------------------------------------------------------------------------
def _field(data: dict, name: str) -> dict:
    for f in data.get("fields", []):
        if f.get("name") == name:
            return f
    raise RobotError(f"{NAME}: the scene needs a field named {name!r}")


def scene_parameters(data: dict) -> dict:
    """What the reproduction takes from the scene: step rise time (s), unit direction and level (T) of the
    scene's step; eigenstretch and its ramp; span between the clamp faces, thickness, width (m); damping (1/s)."""
    step = _field(data, "step")
    times, values = step["times"], np.asarray(step["values"], dtype=np.float64)
    level = float(np.linalg.norm(values[-1]))
    part = data["robot"]["parts"][0]
    stim = part["material"]["stimulus"]
    faces = sorted(abs(c["region"]["center"][0]) - 0.5 * c["region"]["size"][0] for c in data["clamps"])
    sim = data["simulation"]
    return {"rise": float(times[-1] - times[-2]), "direction": values[-1] / level, "level": level,
            "stretch": float(stim["stretch"][-1][1]), "ramp": float(stim["profile"]["duration"]),
            "span": 2.0 * faces[0], "thickness": float(part["shape"]["size"][1]), "width": float(sim["depth"]),
            "damping": float(sim.get("damping", 0.0))}


def elastica_for(sim, prm: dict, n: int = ELASTICA_NODES) -> ArchElastica:
    """The reference elastica with what the engine simulates: plane-strain modulus from its G and K, density,
    |Br|; geometry and stretch from the scene."""
    h = sim.model.host
    free = h["clamped"] == 0
    G, K = float(np.median(h["shear_modulus"][free])), float(np.median(h["bulk_modulus"][free]))
    youngs_plane = plane_strain_modulus(G, K)
    br = float(np.median(np.linalg.norm(h["remanence"][free], axis=1)))
    rho = float(np.median(h["density"][free]))
    return ArchElastica(prm["span"], prm["stretch"], prm["thickness"], prm["width"], youngs_plane, rho, br, n)


def _crown(sim) -> float:
    return float(sim.probe_values()["crown_y"])


def prebuckle(ctx: Context, data: dict):
    """The arch relaxed to rest in its upper state (a Simulation at time t0 after the eigenstrain ramp and the
    bias), and the relaxation's result."""
    d = dict(data)
    d["fields"] = [f for f in data["fields"] if f.get("name") != "step"]
    bias_end = float(_field(data, "bias")["times"][-1])
    t0 = max(bias_end, scene_parameters(data)["ramp"]) + 0.01
    d["simulation"] = dict(data["simulation"], duration=t0)
    sim = simulation(NAME, d, preview=ctx.preview, device=ctx.device)
    from magsoro.errors import SimulationError

    try:
        sim.advance_to(t0)
        relax = sim.relax(energy_tol=1e-8, max_steps=400_000)
    except SimulationError as exc:
        raise RobotError(f"{NAME}: pre-buckling failed at step {exc.step}, t = {exc.time:.6g} s: {exc}") from None
    if not (relax.converged or relax.stalled):
        raise RobotError(f"{NAME}: the pre-buckled arch did not come to rest: {relax.message}")
    return sim, relax


def step_run(ctx: Context, data: dict, rest, level: float, prm: dict, frames: FrameRecorder | None = None,
             frame_every: float = 0.002, release: bool = False):
    """One field step from the rested arch ``rest`` (a Simulation): the scene's step (rise, direction) at
    ``level`` T from rest's time t0, held HOLD s (then switched off and RELEASE s more when ``release``). Returns
    (times from the step, crown heights, Simulation)."""
    from magsoro.errors import SimulationError

    t0 = rest.state.time
    B = (level * prm["direction"]).tolist()
    zero = [0.0, 0.0, 0.0]
    times, values = [t0, t0 + prm["rise"]], [zero, B]
    end = t0 + HOLD
    if release:
        times += [end, end + prm["rise"]]
        values += [B, zero]
        end += RELEASE
    d = dict(data)
    d["fields"] = [f for f in data["fields"] if f.get("name") != "step"] + [
        {"name": "step", "type": "keyframes", "times": times, "values": values}]
    d["simulation"] = dict(data["simulation"], duration=end)
    d["output"] = dict(data.get("output", {}), particles=False)
    sim = simulation(NAME, d, preview=ctx.preview, device=ctx.device)
    sim.state.assign(rest.state)
    ts, cr = [0.0], [_crown(sim)]
    n = int(round((end - t0) / READ_EVERY))
    stride = max(1, int(round(frame_every / READ_EVERY)))
    if frames is not None:
        frames.record(sim)
    try:
        for k in range(1, n + 1):
            sim.advance_to(t0 + k * READ_EVERY)
            ts.append(k * READ_EVERY)
            cr.append(_crown(sim))
            if frames is not None and k % stride == 0:
                frames.record(sim)
    except SimulationError as exc:
        raise RobotError(f"{NAME}: step {level * 1e3:.3g} mT failed at step {exc.step}, t = {exc.time:.6g} s: {exc}") from None
    return np.array(ts), np.array(cr), sim


# -- the figure -----------------------------------------------------------------------------------------------
def plot_snap_times(path, levels_mT, cross_ms, settle_ms, ref_levels_mT, ref_cross_ms, ref_settle_ms, bracket_mT,
                    ref_dynamic_mT, ref_static_mT, note: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from magsoro.robots.base import _save

    fig, ax = plt.subplots(figsize=(5.6, 4.3), dpi=120)
    ax.axvspan(bracket_mT[0], bracket_mT[1], color="C3", alpha=0.25, label=f"MPM threshold bracket "
               f"{bracket_mT[0]:.2f}-{bracket_mT[1]:.2f} mT")
    ax.axvline(ref_dynamic_mT, color="C3", ls="--", lw=1, label=f"elastica, same step: {ref_dynamic_mT:.2f} mT")
    ax.axvline(ref_static_mT, color="0.4", ls=":", lw=1.2, label=f"elastica, static (quasi-static): {ref_static_mT:.2f} mT")
    ax.plot(levels_mT, cross_ms, "o", color="C0", label="MPM: step to mid-plane crossing")
    ax.plot(levels_mT, settle_ms, "s", color="C1", label=f"MPM: step to settled ({SETTLE_BAND:.0%} band)")
    ax.plot(ref_levels_mT, ref_cross_ms, "-", color="C0", lw=1, label="elastica: crossing")
    ax.plot(ref_levels_mT, ref_settle_ms, "-", color="C1", lw=1, label="elastica: settled")
    ax.set_xlabel("field step level |B| (mT)")
    ax.set_ylabel("time after the step (ms)")
    ax.set_title(f"Bistable arch: snap time vs field step\n{note}", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6.5)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return path


# -- reproduction ---------------------------------------------------------------------------------------------
def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.validation.registry import Row

    wall0 = time.perf_counter()
    data = scene_data(NAME)
    prm = scene_parameters(data)
    rest, relax = prebuckle(ctx, data)
    crown0 = _crown(rest)
    dx = rest.model.dx
    ctx.log(f"{NAME}: {rest.model.n_particles} particles, dx = {dx * 1e3:.3g} mm; pre-buckled crown "
            f"{crown0 * 1e3:.3f} mm ({relax.message})")

    # the reference elastica: rest shape, static threshold, dynamic threshold and snap times of the same step
    wall_ref = time.perf_counter()
    rod = elastica_for(rest, prm)
    q_up = rod.upper_state()
    crown_ref = rod.crown(q_up)
    static_b, mode = rod.static_threshold(prm["direction"], q_up)
    mode_xy = mode.reshape(-1, 2) if mode is not None else np.zeros((1, 2))
    antisym = float(np.abs(mode_xy[:, 1] + mode_xy[::-1, 1]).max() / max(np.abs(mode_xy[:, 1]).max(), 1e-300))

    def rod_run(b):
        return rod.step_response(q_up, b, prm["direction"], prm["rise"], HOLD, prm["damping"])

    def rod_snaps(b):
        return snap_times(*rod_run(b), crown_ref)[0]

    rod_lo, rod_hi = bisect_threshold(rod_snaps, 0.8 * static_b, 1.25 * static_b, 10)
    rod_b = 0.5 * (rod_lo + rod_hi)
    ctx.log(f"{NAME}: elastica: crown {crown_ref * 1e3:.3f} mm, static threshold {static_b * 1e3:.3f} mT "
            f"({'asymmetric' if antisym < 0.5 else 'symmetric'} mode), same step {rod_b * 1e3:.3f} mT "
            f"({time.perf_counter() - wall_ref:.0f} s)")

    # MPM: threshold by bisection, then the sweep
    runs = {}
    frame_every = 0.002  # s between GIF frames

    def mpm(b, frames=None, release=False):
        key = round(b, 9)
        if key not in runs or frames is not None:
            t, c, sim = step_run(ctx, data, rest, b, prm, frames=frames, frame_every=frame_every, release=release)
            hold = t <= HOLD + 1e-12
            snapped, tc, ts = snap_times(t[hold], c[hold], crown0)
            runs[key] = {"level": b, "snapped": snapped, "cross": tc, "settle": ts, "final": float(c[hold][-1]),
                         "t": t, "crown": c, "steps": sim.steps}
            ctx.log(f"{NAME}: {b * 1e3:.3f} mT: " + (f"snaps, mid-plane at {tc * 1e3:.1f} ms, settled at "
                                                       f"{ts * 1e3:.1f} ms" if snapped else
                                                       f"holds (crown {c[-1] * 1e3:.2f} mm)")
                    + f" ({time.perf_counter() - wall0:.0f} s)")
        return runs[key]

    lo, hi = bisect_threshold(lambda b: mpm(b)["snapped"], BRACKET[0] * rod_b, BRACKET[1] * rod_b,
                              BISECTIONS[ctx.preview], log=ctx.log)
    threshold = 0.5 * (lo + hi)
    sweep = [f * hi for f in SWEEP[ctx.preview]]
    # the GIF: one snap, then the field off again (the arch must stay in its lower state); its hold is a sweep level
    gif_b = GIF_LEVEL * hi
    frames = FrameRecorder(axes=(0, 1), max_particles=3000, label=lambda s: (
        f"{gif_b * 1e3:.1f} mT step, t = {(s.time - rest.state.time) * 1e3:.0f} ms"
        + (" (field off)" if s.time - rest.state.time > HOLD + 1e-9 else "")))
    gif_run = mpm(gif_b, frames=frames, release=True)
    released = gif_run["crown"][gif_run["t"] > HOLD + prm["rise"] + 1e-9]
    stays_down = float(released.max()) if len(released) else float("nan")
    for b in sweep:
        mpm(b)

    # elastica at the MPM's levels and on a fine grid for the curves
    snapped = sorted((r for r in runs.values() if r["snapped"]), key=lambda r: r["level"])
    all_runs = sorted(runs.values(), key=lambda r: r["level"])
    ref_at = {round(r["level"], 9): snap_times(*rod_run(r["level"]), crown_ref) for r in all_runs}
    grid = np.linspace(rod_hi, max(r["level"] for r in all_runs) * 1.05, 14)
    grid_ref = [snap_times(*rod_run(b), crown_ref) for b in grid]

    levels_mT = np.array([r["level"] for r in all_runs]) * 1e3
    csv = write_csv(ctx.out / f"{NAME}.csv", {
        "B_mT": levels_mT,
        "snapped": [float(r["snapped"]) for r in all_runs],
        "cross_ms": [r["cross"] * 1e3 for r in all_runs],
        "settle_ms": [r["settle"] * 1e3 for r in all_runs],
        "crown_end_of_hold_mm": [r["final"] * 1e3 for r in all_runs],
        "elastica_snapped": [float(ref_at[round(r["level"], 9)][0]) for r in all_runs],
        "elastica_cross_ms": [ref_at[round(r["level"], 9)][1] * 1e3 for r in all_runs],
        "elastica_settle_ms": [ref_at[round(r["level"], 9)][2] * 1e3 for r in all_runs],
    })
    write_csv(ctx.out / f"{NAME}_snap.csv", {"t_ms": gif_run["t"] * 1e3, "crown_mm": gif_run["crown"] * 1e3})
    note = (f"{'preview, ' if ctx.preview else ''}2D plane strain, dx = {dx * 1e3:.2f} mm, damping "
            f"{prm['damping']:.0f}/s\nstep: rise {prm['rise'] * 1e3:.0f} ms, hold {HOLD * 1e3:.0f} ms, tilted "
            f"{math.degrees(math.atan2(abs(prm['direction'][0]), abs(prm['direction'][1]))):.0f} deg")
    png = plot_snap_times(ctx.out / f"{NAME}.png", levels_mT, [r["cross"] * 1e3 for r in all_runs],
                          [r["settle"] * 1e3 for r in all_runs], grid * 1e3, [g[1] * 1e3 for g in grid_ref],
                          [g[2] * 1e3 for g in grid_ref], (lo * 1e3, hi * 1e3), rod_b * 1e3, static_b * 1e3, note)
    lim = max(abs(crown0), 1e-3) * 1e3
    half = 0.5 * prm["span"] * 1e3

    def draw(ax, k):  # the clamps, and the field while it is on (arrow scaled to the step's direction)
        import matplotlib.patches as mpatches

        for x0 in (-half - 4.0, half):
            ax.add_patch(mpatches.Rectangle((x0, -2.0), 4.0, 4.0, color="0.55", zorder=0))
        if k * frame_every <= HOLD + 1e-9 and k > 0:
            d = prm["direction"] * 0.6 * lim
            ax.annotate("", xy=(-0.6 * half + d[0], 1.3 * lim + d[1]), xytext=(-0.6 * half, 1.3 * lim),
                        arrowprops={"arrowstyle": "-|>", "color": "C3", "lw": 2})
            ax.text(-0.6 * half + 1.0, 1.25 * lim, "B", color="C3", fontsize=9)

    gif = frames.write_gif(ctx.out / f"{NAME}.gif", title="bistable_arch (x-y plane), clamped at both ends", fps=15,
                           lims=((-half - 4.0, half + 4.0), (-2.0 * lim, 2.0 * lim)), patches=draw)

    # checks
    case = f"robot-{NAME}"
    inp = {"dx_mm": round(dx * 1e3, 4), "hold_ms": HOLD * 1e3, "rise_ms": prm["rise"] * 1e3,
           "damping": prm["damping"], "stretch": prm["stretch"]}
    rows = [
        Row(case, "pre-buckled crown height (m) vs planar elastica", dict(inp), crown_ref, crown0,
            abs(crown0 - crown_ref) / abs(crown_ref), CROWN_TOL),
        Row(case, "snap threshold of the field step (T, MPM bisection bracket midpoint) vs planar elastica under "
            "the same step", dict(inp, bracket_mT=[round(lo * 1e3, 4), round(hi * 1e3, 4)]), rod_b, threshold,
            abs(threshold - rod_b) / rod_b, THRESHOLD_TOL),
    ]
    pairs = [(r["cross"], ref_at[round(r["level"], 9)][1]) for r in snapped if r["level"] >= sweep[0] - 1e-12
             and ref_at[round(r["level"], 9)][0]]
    t_err = float(np.mean([abs(a - b) / b for a, b in pairs])) if pairs else float("nan")
    rows.append(Row(case, "time from the step to the mid-plane crossing, sweep levels: mean relative error vs "
                    "planar elastica", dict(inp, levels_mT=[round(b * 1e3, 3) for b in sweep]), 0.0, t_err, t_err,
                    SNAP_TIME_TOL))
    cross_sweep = [r["cross"] for r in snapped if r["level"] >= sweep[0] - 1e-12]
    rise_worst = float(max(np.diff(cross_sweep))) if len(cross_sweep) > 1 else float("nan")
    rows.append(Row(case, "a stronger step snaps sooner: largest increase of the crossing time between "
                    "successive sweep levels (s), must be <= 0", dict(inp), 0.0, rise_worst, max(rise_worst, 0.0)
                    if math.isfinite(rise_worst) else rise_worst, 0.0))
    rows.append(Row(case, f"bistable: highest crown over the {RELEASE * 1e3:.0f} ms after the field is switched off "
                    "again, over the pre-buckled crown (must stay < 0: the arch stays down)",
                    dict(inp, level_mT=round(gif_b * 1e3, 3)), 0.0, stays_down / crown0,
                    max(stays_down / crown0 + 0.0, 0.0) if math.isfinite(stays_down) else stays_down, 0.0))

    wall = time.perf_counter() - wall0
    summary = (f"The arch ({prm['thickness'] * 1e3:.0f} mm thick, {prm['span'] * 1e3:.0f} mm span, pre-buckled by a "
               f"{(prm['stretch'] - 1) * 100:.0f} % axial eigenstretch to a {crown0 * 1e3:.2f} mm crown; elastica {crown_ref * 1e3:.2f} mm) snaps through for field steps "
               f"of {hi * 1e3:.2f} mT and more, holds at {lo * 1e3:.2f} mT: threshold {threshold * 1e3:.2f} mT "
               f"against {rod_b * 1e3:.2f} mT for the planar elastica under the same step "
               f"({(threshold / rod_b - 1) * 100:+.1f} %) and {static_b * 1e3:.2f} mT for its static (slowly "
               f"raised field) stability limit ({(threshold / static_b - 1) * 100:+.1f} %). It crosses the "
               f"mid-plane {snapped[0]['cross'] * 1e3:.1f} ms after a {snapped[0]['level'] * 1e3:.1f} mT step "
               f"(elastica {ref_at[round(snapped[0]['level'], 9)][1] * 1e3:.1f} ms) and "
               f"{snapped[-1]['cross'] * 1e3:.1f} ms after a {snapped[-1]['level'] * 1e3:.1f} mT one (elastica "
               f"{ref_at[round(snapped[-1]['level'], 9)][1] * 1e3:.1f} ms), settling by "
               f"{snapped[-1]['settle'] * 1e3:.0f} ms; with the field switched off again it "
               + ("stays down (bistable)." if stays_down < 0 else "springs back up (not bistable)."))
    info = {"particles": int(rest.model.n_particles), "dx_mm": dx * 1e3, "wall_s": round(wall, 1),
            "prebuckled_crown_mm": round(crown0 * 1e3, 4), "elastica_crown_mm": round(crown_ref * 1e3, 4),
            "threshold_bracket_mT": [round(lo * 1e3, 4), round(hi * 1e3, 4)],
            "elastica_dynamic_threshold_mT": round(rod_b * 1e3, 4),
            "elastica_static_threshold_mT": round(static_b * 1e3, 4),
            "elastica_static_mode_antisymmetry": round(antisym, 4),
            "midpoint_force_per_mT_N": 2 * rod.moment * 1e-3,
            "runs": len(runs), "steps_per_run": [int(r["steps"]) for r in all_runs],
            "relax_steps": int(relax.steps)}
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info)


ROBOT = Robot(
    name=NAME,
    title="Bistable clamped arch (snap-through by a field step)",
    source="seed 002 sec 5.5 + bistable-arch literature",
    quantity="snap threshold and snap time vs field step level",
    sentence=("A strip clamped at both ends and pre-buckled by an axial eigenstrain into an arch, magnetised "
              "along its length in opposite directions in its two halves, snaps through to its mirror state when "
              "a uniform field is switched on above a threshold and stays there when it is switched off; the "
              "threshold and snap times are compared with a planar elastica of the same strip."),
    reproduce=reproduce,
    in_ci=False,
)
