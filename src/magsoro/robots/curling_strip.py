"""Thermo-responsive curling strip in the style of seed 003 (Figs. S2-S4): a bilayer of a hydrogel that shrinks as
the temperature rises, bonded to a passive magnetic elastomer; heated, it curls towards the gel. Curvature against
temperature, MPM against Timoshenko's bimetal formula, and the curled shapes.

The temperature is the gel's stimulus (scenes/curling_strip.toml: stimulus = temperature in degC, stretch(T) the
gel's free linear stretch, modulus_factor(T) its stiffening; docs/engine.md "Mapping to temperature"). The
reproduction replaces the scene's heating history by steps: from 25 degC the temperature ramps to each level of
LEVELS in RAMP s (the strip moves, damped), then dynamic relaxation (Simulation.relax, the stimulus held at the
level) brings it to equilibrium, where the curvature is read.

Curvature: the current positions of the particles of the two rows next to the interface, in the middle MIDDLE of
the strip's reference length (clear of the free ends); a circle through each row (Pratt's algebraic fit, exact
for a straight row); the curvature reported is the mean of the two (the bimetal's curvature at its interface; the
rows across the thickness differ by O(h/R)).

Timoshenko (1925): kappa = 6 eps (1 + m)^2 / (h (3 (1 + m)^2 + (1 + m n)(m^2 + 1/(m n)))), m = t_gel / t_passive,
n = E'_gel / E'_passive (plane strain: E' = E / (1 - nu^2) from each layer's G and K), h = t_gel + t_passive. It is
linear in the mismatch; we evaluate it on the stress-free state at T (the gel lambda t_gel thick, its moduli times
f(T), as the engine's eigenstrain defines them), with eps = 1 - lambda (the gel's free shrinkage; the docs'
convention). At finite mismatch the linear formula does not say from which layer's length the strain is
measured: measured from the gel's, eps = 1/lambda - 1. The two readings bound an O(eps) ambiguity of the closed
form, which the checks allow at large mismatch; at small mismatch (first heated level) they nearly coincide and
the check is strict. The logarithmic strain eps = ln(1/lambda), between the two and symmetric in the layers, is
reported alongside (not checked: we noticed its closeness to the MPM after the first full run).
"""

from __future__ import annotations

import math
import time

import numpy as np

from magsoro.robots.base import (Context, FrameRecorder, ReproduceResult, Robot, RobotError, scene_data,
                                 simulation, write_csv)

NAME = "curling_strip"
LEVELS = {True: (25.0, 30.0, 33.0, 36.0, 40.0, 50.0),                       # degC, preview
          False: (25.0, 28.0, 30.0, 32.0, 33.0, 34.0, 36.0, 40.0, 45.0, 50.0)}  # full
RAMP = 0.01            # s from one level to the next (the motion is damped, then relaxed)
FRAME_EVERY = 0.002    # s between GIF frames during the ramps (plus one frame per relaxed level)
MIDDLE = 0.6           # fraction of the reference length (centred) whose particles give the curvature
# tolerances of the checks
SMALL_TOL = 0.05       # first heated level (small mismatch): MPM / Timoshenko within 5 %
BAND_TOL = 0.05        # every level: within 5 % of the band between Timoshenko's two readings of the mismatch


def timoshenko_curvature(eps: float, t_active: float, t_passive: float, e_active: float, e_passive: float) -> float:
    """Timoshenko's bimetal curvature (1/m) of a bilayer whose active layer (thickness ``t_active`` m, modulus
    ``e_active`` Pa) shrinks by the mismatch strain ``eps`` relative to the passive one (``t_passive``,
    ``e_passive``): positive towards the active layer."""
    m, n = t_active / t_passive, e_active / e_passive
    h = t_active + t_passive
    return 6.0 * eps * (1.0 + m) ** 2 / (h * (3.0 * (1.0 + m) ** 2 + (1.0 + m * n) * (m * m + 1.0 / (m * n))))


def plane_strain_modulus(shear_modulus: float, bulk_modulus: float) -> float:
    """E / (1 - nu^2) of the engine's compressible solid at small strain, Pa."""
    return 4.0 * shear_modulus * (3.0 * bulk_modulus + shear_modulus) / (3.0 * bulk_modulus + 4.0 * shear_modulus)


def circle_fit(P: np.ndarray) -> tuple[float, np.ndarray]:
    """Pratt's algebraic circle fit A (x^2 + y^2) + B x + C y + D = 0 with B^2 + C^2 - 4 A D = 1 (a straight line
    is the case A = 0, so a flat row gives curvature 0, not a wild circle). Returns (curvature 1/m, the unit
    vector from the points' mean towards the centre; for a line, its normal)."""
    from scipy.linalg import eig

    mean = P.mean(axis=0)
    scale = float(np.sqrt(((P - mean) ** 2).sum(axis=1).mean()))
    Q = (P - mean) / scale
    Z = np.c_[(Q * Q).sum(axis=1), Q[:, 0], Q[:, 1], np.ones(len(Q))]
    constraint = np.array([[0.0, 0, 0, -2], [0, 1, 0, 0], [0, 0, 1, 0], [-2, 0, 0, 0]])
    w, V = eig(Z.T @ Z, constraint)
    w = np.real(w)
    ok = np.isfinite(w) & (w > -1e-12)
    k = int(np.flatnonzero(ok)[np.argmin(w[ok])])
    A, B, C, D = np.real(V[:, k])
    norm = math.sqrt(max(B * B + C * C - 4.0 * A * D, 1e-300))
    kappa = 2.0 * abs(A) / norm / scale
    if abs(A) > 1e-12 * norm:
        towards = np.array([-B / (2.0 * A), -C / (2.0 * A)])
    else:
        towards = np.array([B, C])
    return kappa, towards / max(np.linalg.norm(towards), 1e-300)


def _part(data: dict, name: str) -> dict:
    for p in data["robot"]["parts"]:
        if p["name"] == name:
            return p
    raise RobotError(f"{NAME}: scene has no part {name!r}")


class Geometry:
    """The strip as the engine filled it: reference positions, particle rows (by reference height), the rows
    next to the interface, the middle of the length, layer thicknesses from the scene."""

    def __init__(self, sim, data: dict):
        h = sim.model.host
        X = h["positions"]
        spacing = sim.model.dx / sim.scene.simulation.particles_per_cell
        gel, passive = _part(data, "gel")["shape"], _part(data, "magnetic")["shape"]
        self.t_gel, self.t_passive = float(gel["size"][1]), float(passive["size"][1])
        self.interface = float(gel["center"][1]) - 0.5 * self.t_gel
        self.length = float(gel["size"][0])
        self.row = np.round((X[:, 1] - self.interface) / spacing - 0.5).astype(int)  # 0: first row above
        self.mid = np.abs(X[:, 0] - float(gel["center"][0])) <= 0.5 * MIDDLE * self.length
        self.gel_id = list(sim.built.body_names).index("gel")
        self.body = h["body"]
        self.X = X

    def curvature(self, x: np.ndarray) -> float:
        """Curvature (1/m), positive when the centre lies on the gel's side: circles through each of the two
        interface rows (middle of the length), the mean of their curvatures."""
        rows = {r: x[self.mid & (self.row == r)] for r in (-1, 0)}
        fits = {r: circle_fit(P) for r, P in rows.items()}
        kappa = 0.5 * (fits[-1][0] + fits[0][0])
        gel_dir = rows[0].mean(axis=0) - rows[-1].mean(axis=0)  # from the passive interface row to the gel's
        return kappa if np.dot(gel_dir, fits[0][1] + fits[-1][1]) > 0 else -kappa

    def centreline(self, x: np.ndarray, bins: int = 61) -> np.ndarray:
        """The interface line: mean current position of the two interface rows per slice of reference x."""
        sel = (self.row == 0) | (self.row == -1)
        edges = np.linspace(-0.5 * self.length, 0.5 * self.length, bins + 1)
        idx = np.clip(np.digitize(self.X[sel, 0], edges) - 1, 0, bins - 1)
        xs = x[sel]
        return np.array([xs[idx == i].mean(axis=0) for i in range(bins) if np.any(idx == i)])


def references(sim, data: dict, geo: Geometry, temperatures) -> dict:
    """Timoshenko's curvature at each temperature, with eps = 1 - lambda, 1/lambda - 1 and ln(1/lambda) (the
    logarithmic strain, between the two and symmetric in the layers; reported, not checked), on the
    stress-free state (gel lambda t thick, moduli times f), from what the engine simulates (G, K per layer) and
    the scene's tables."""
    h = sim.model.host
    gel = h["body"] == geo.gel_id
    Gg, Kg = float(np.median(h["shear_modulus"][gel])), float(np.median(h["bulk_modulus"][gel]))
    Gp, Kp = float(np.median(h["shear_modulus"][~gel])), float(np.median(h["bulk_modulus"][~gel]))
    stim = _part(data, "gel")["material"]["stimulus"]
    st = np.asarray(stim["stretch"], dtype=np.float64)
    mf = np.asarray(stim.get("modulus_factor", [[0.0, 1.0]]), dtype=np.float64)
    out = {"lambda": [], "f": [], "low": [], "high": [], "log": []}
    for T in temperatures:
        lam = float(np.interp(T, st[:, 0], st[:, 1]))
        f = float(np.interp(T, mf[:, 0], mf[:, 1]))
        args = (lam * geo.t_gel, geo.t_passive, f * plane_strain_modulus(Gg, Kg), plane_strain_modulus(Gp, Kp))
        out["lambda"].append(lam)
        out["f"].append(f)
        out["low"].append(timoshenko_curvature(1.0 - lam, *args))
        out["high"].append(timoshenko_curvature(1.0 / lam - 1.0, *args))
        out["log"].append(timoshenko_curvature(math.log(1.0 / lam), *args))
    return {k: np.array(v) for k, v in out.items()}


def plot(path, temps, kappa, ref, shapes, note: str):
    """Curvature vs temperature with Timoshenko's (left); the relaxed interface lines with Timoshenko's arcs of
    the same length (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from magsoro.robots.base import _save

    fig, (a, b) = plt.subplots(1, 2, figsize=(9.0, 3.9), dpi=120)
    a.fill_between(temps, ref["low"], ref["high"], color="0.8", label="Timoshenko, eps from 1-lambda to 1/lambda-1")
    a.plot(temps, ref["low"], "--", color="k", lw=1, label="Timoshenko, eps = 1 - lambda")
    a.plot(temps, ref["log"], "-.", color="0.3", lw=1, label="Timoshenko, eps = ln(1/lambda)")
    a.plot(temps, kappa, "o-", ms=4, color="C0", label="magsoro MPM (relaxed)")
    a.set_xlabel("temperature (degC) = gel stimulus")
    a.set_ylabel("curvature (1/m)")
    a.set_title(f"Curling bilayer: curvature vs temperature\n{note}", fontsize=8)
    a.grid(alpha=0.3)
    a.legend(fontsize=6.5)
    cmap = plt.get_cmap("plasma")
    for k, (T, line) in enumerate(shapes):
        col = cmap(k / max(len(shapes) - 1, 1) * 0.9)
        b.plot(line[:, 0] * 1e3, line[:, 1] * 1e3, "-", color=col, lw=1.5, label=f"{T:.0f} degC")
        kap = ref["low"][k]
        if kap > 0:  # Timoshenko's arc through the middle of the line, tangent there, same length
            mid = line[len(line) // 2]
            tang = line[len(line) // 2 + 1] - line[len(line) // 2 - 1]
            tang = tang / np.linalg.norm(tang)
            normal = np.array([-tang[1], tang[0]])
            s = np.linspace(-0.5, 0.5, 60) * np.sum(np.linalg.norm(np.diff(line, axis=0), axis=1))
            arc = mid + (np.sin(kap * s)[:, None] * tang + ((1 - np.cos(kap * s)) / 1.0)[:, None] * normal) / kap
            b.plot(arc[:, 0] * 1e3, arc[:, 1] * 1e3, ":", color=col, lw=1)
    pts = np.concatenate([line for _, line in shapes]) * 1e3
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.1 * float((hi - lo).max()) + 0.2
    b.set_xlim(lo[0] - pad, hi[0] + pad)
    b.set_ylim(lo[1] - pad, hi[1] + 3 * pad)
    b.set_aspect("equal", adjustable="box")
    b.set_xlabel("x (mm)")
    b.set_ylabel("y (mm)")
    b.set_title("relaxed interface lines (solid);\nTimoshenko arcs, eps = 1 - lambda, same length (dotted)", fontsize=8)
    b.grid(alpha=0.3)
    b.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return path


def reproduce(ctx: Context) -> ReproduceResult:
    from magsoro.errors import SimulationError
    from magsoro.validation.registry import Row

    wall0 = time.perf_counter()
    temps = LEVELS[ctx.preview]
    data = scene_data(NAME)
    stim = _part(data, "gel")["material"]["stimulus"]
    reads = [RAMP * k for k in range(len(temps))]  # temps[k] is reached at reads[k], linearly from the last
    stim["profile"] = {"type": "keyframes", "times": reads, "values": list(temps)}
    data["simulation"]["duration"] = reads[-1]
    data.setdefault("output", {})["particles"] = False
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    geo = Geometry(sim, data)
    ctx.log(f"{NAME}: {sim.model.n_particles} particles, dx = {sim.model.dx * 1e3:.3g} mm, temperatures "
            f"{', '.join(f'{T:g}' for T in temps)} degC")

    def temp_at(t):
        return float(np.interp(t, reads, temps))

    frames = FrameRecorder(axes=(0, 1), max_particles=3000,
                           label=lambda s: f"T = {temp_at(s.time):.1f} degC (gel on top, magnetic layer below)")
    kappa, shapes, relax_msgs, converged, steps = [], [], [], [], []
    t_frame = 0.0
    try:
        for k, t_read in enumerate(reads):
            while t_frame + FRAME_EVERY < t_read - 1e-12:
                t_frame += FRAME_EVERY
                sim.advance_to(t_frame)
                frames.record(sim)
            sim.advance_to(t_read)
            t_frame = t_read
            r = sim.relax(energy_tol=1e-8, max_steps=400_000)
            converged.append(bool(r.converged))
            relax_msgs.append(r.message)
            steps.append(int(r.steps))
            x = sim.state.x.numpy().astype(np.float64)
            kap = geo.curvature(x)
            kappa.append(kap)
            shapes.append((temps[k], geo.centreline(x)))
            frames.record(sim)
            ctx.log(f"{NAME}: {temps[k]:g} degC: curvature {kap:.1f} 1/m ({r.message}; "
                    f"{time.perf_counter() - wall0:.0f} s)")
    except SimulationError as exc:
        raise RobotError(f"{NAME}: run failed at step {exc.step}, t = {exc.time:.6g} s: {exc}") from None

    kappa = np.array(kappa)
    T = np.array(temps)
    arc = np.array([np.sum(np.linalg.norm(np.diff(line, axis=0), axis=1)) for _, line in shapes])  # interface, m
    ref = references(sim, data, geo, temps)
    lam = ref["lambda"]
    csv = write_csv(ctx.out / f"{NAME}.csv", {
        "T_degC": T, "gel_stretch": lam, "gel_modulus_factor": ref["f"], "curvature_per_m": kappa,
        "timoshenko_eps_1_minus_lambda": ref["low"], "timoshenko_eps_1_over_lambda_minus_1": ref["high"],
        "timoshenko_eps_log": ref["log"],
        "ratio_to_timoshenko": np.where(ref["low"] > 0, kappa / np.where(ref["low"] > 0, ref["low"], 1.0), np.nan),
        "curl_angle_deg": np.degrees(kappa * arc), "relax_converged": [float(c) for c in converged]})
    write_csv(ctx.out / f"{NAME}_shapes.csv", {
        "T_degC": np.concatenate([np.full(len(s), Tk) for Tk, s in shapes]),
        "x_mm": np.concatenate([s[:, 0] for _, s in shapes]) * 1e3,
        "y_mm": np.concatenate([s[:, 1] for _, s in shapes]) * 1e3})
    note = (f"{'preview, ' if ctx.preview else ''}2D plane strain, dx = {sim.model.dx * 1e3:.2f} mm, "
            f"gel {geo.t_gel * 1e3:.1f} mm on {geo.t_passive * 1e3:.1f} mm, {geo.length * 1e3:.0f} mm long")
    png = plot(ctx.out / f"{NAME}.png", T, kappa, ref, shapes, note)
    gif = frames.write_gif(ctx.out / f"{NAME}.gif", title="curling_strip: heated from 25 degC (x-y plane)", fps=12)

    case = f"robot-{NAME}"
    inp = {"dx_mm": round(sim.model.dx * 1e3, 4), "temperatures_degC": list(temps)}
    rows = []
    heated = [k for k in range(len(T)) if ref["low"][k] > 0]
    if not heated:
        raise RobotError(f"{NAME}: no level above the gel's reference temperature")
    k0 = heated[0]
    rows.append(Row(case, f"curvature at the first heated level ({T[k0]:g} degC, mismatch "
                    f"{(1 - lam[k0]) * 100:.1f} %) vs Timoshenko (1/m)", dict(inp), ref["low"][k0], kappa[k0],
                    abs(kappa[k0] / ref["low"][k0] - 1.0), SMALL_TOL))
    # every heated level: distance outside the band [low, high] of the closed form, relative to the band's centre
    outside = [max(ref["low"][k] - kappa[k], kappa[k] - ref["high"][k], 0.0) / (0.5 * (ref["low"][k] + ref["high"][k]))
               for k in heated]
    worst = int(np.argmax(outside))
    rows.append(Row(case, "every heated level: curvature outside Timoshenko's band (eps from 1 - lambda to "
                    "1/lambda - 1), largest, relative to the band's centre", dict(inp, worst_degC=float(T[heated[worst]])),
                    0.0, float(outside[worst]), float(outside[worst]), BAND_TOL))
    flat = [k for k in range(len(T)) if lam[k] == 1.0]
    if flat:
        bend0 = float(max(abs(kappa[k]) for k in flat) * geo.length)
        rows.append(Row(case, "no curl at the reference temperature: |curvature| x length (rad)", dict(inp), 0.0,
                        bend0, bend0, 0.01))
    rise = float(np.min(np.diff(kappa[k0 - 1 if k0 > 0 else 0:]))) if len(T) > 1 else float("nan")
    rows.append(Row(case, "the strip curls towards the gel and more as it shrinks: smallest curvature increase "
                    "between successive levels (1/m), must be > 0", dict(inp), 0.0, rise, max(-rise, 0.0), 0.0))
    n_ok = sum(converged)
    rows.append(Row(case, "relaxed to equilibrium at every level (levels not converged)", dict(inp), 0.0,
                    float(len(converged) - n_ok), float(len(converged) - n_ok), 0.0))

    wall = time.perf_counter() - wall0
    ratios = kappa[heated] / ref["low"][heated]
    log_ratios = kappa[heated] / ref["log"][heated]
    summary = (f"Heated from 25 to {T[-1]:g} degC, the gel (free stretch {lam[-1]:.2f}, modulus x{ref['f'][-1]:.1f}: "
               f"placeholder tables, seed 003 gives figures only) curls the {geo.length * 1e3:.0f} mm bilayer to "
               f"{kappa[-1]:.0f} 1/m ({math.degrees(kappa[-1] * arc[-1]):.0f} deg of arc); Timoshenko's bimetal "
               f"formula gives {ref['low'][-1]:.0f} 1/m with eps = 1 - lambda, {ref['high'][-1]:.0f} 1/m with "
               f"eps = 1/lambda - 1 and {ref['log'][-1]:.0f} 1/m with eps = ln(1/lambda) (MPM / Timoshenko {ratios.min():.3f}-{ratios.max():.3f} over the heated levels; "
               f"{ratios[0]:.3f} at {T[k0]:g} degC, mismatch {(1 - lam[k0]) * 100:.1f} %; against the logarithmic "
               f"reading {log_ratios.min():.3f}-{log_ratios.max():.3f}).")
    info = {"particles": int(sim.model.n_particles), "dx_mm": sim.model.dx * 1e3, "wall_s": round(wall, 1),
            "relax_steps": steps, "relax": relax_msgs, "steps": int(sim.steps),
            "curvature_per_m": [round(float(v), 3) for v in kappa],
            "timoshenko_per_m": [round(float(v), 3) for v in ref["low"]],
            "timoshenko_log_strain_per_m": [round(float(v), 3) for v in ref["log"]],
            "interface_arc_mm": [round(float(v) * 1e3, 3) for v in arc]}
    return ReproduceResult(NAME, csv, png, gif, summary, rows, info)


ROBOT = Robot(
    name=NAME,
    title="Thermo-responsive curling bilayer",
    source="seed 003 Figs. S2-S4",
    quantity="curvature vs temperature, against Timoshenko's bimetal formula",
    sentence=("A hydrogel layer that shrinks as it is heated (the stimulus eigenstrain, temperature as the "
              "stimulus) bonded to a passive magnetic elastomer curls the strip towards the gel; its curvature "
              "from 25 to 50 degC is compared with Timoshenko's bimetal formula."),
    reproduce=reproduce,
    in_ci=False,
)
