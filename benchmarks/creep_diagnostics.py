"""What the engine's slow drift of a loaded slender beam looks like (docs/validation.md, engine finding 4).

Runs the 2D Zhao beam (float64, clamped, grid damping 1.5 omega_1) under a constant load applied over
1.5/omega_1 and held, and prints once per 1/omega_1:

- the tip deflection dy/L and its error against the Kirchhoff rod;
- the largest particle speed;
- the x-F mismatch: for every pair of neighbouring free particles (reference spacing h), the length of
  (x_j - x_i) - F_ij (X_j - X_i) over h, with F_ij the mean of the pair's deformation gradients: how far the
  particles' places and their deformation gradients have drifted apart (rms and largest);
- the energy the engine minimises: elastic (the kernels' Neo-Hookean energy), load potential (magnetic
  -B . F Br / mu0 per reference volume, or the weight's m g y), and their sum.

With ``--relax`` the load is applied at once and the beam first relaxed to rest by kinetic damping
(:meth:`magsoro.simulation.Simulation.relax`) before the damped hold starts.

    python benchmarks/creep_diagnostics.py [--load field|gravity] [--bn 0.001] [--sag 0.25] [--hold 20]
        [--t-over-dx 2] [--ppc 2] [--damping 1.5] [--cfl 0.4] [--velocity-gradient remap|grid] [--relax] [--json]

About 45 s of one core for the default 20/omega_1 at t/dx = 2.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from scipy.spatial import cKDTree

from magsoro import MU0
from magsoro.validation.beam import BeamSetup, Schedule, beam_scene, field_vector, rod_reference


def neo_hookean_energy(F: np.ndarray, G: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Energy density per reference volume of the kernels' model 0 in plane strain (F_zz = 1), J/m^3."""
    J = np.linalg.det(F)
    I1 = np.einsum("nab,nab->n", F, F) + 1.0
    return 0.5 * K * (J - 1.0) ** 2 + 0.5 * G * (J ** (-2.0 / 3.0) * I1 - 3.0)


def mismatch(X0: np.ndarray, x: np.ndarray, F: np.ndarray, pairs: np.ndarray, h: float) -> np.ndarray:
    i, j = pairs[:, 0], pairs[:, 1]
    expected = np.einsum("nab,nb->na", 0.5 * (F[i] + F[j]), X0[j] - X0[i])
    return np.linalg.norm((x[j] - x[i]) - expected, axis=1) / h


def run(args) -> dict:
    from magsoro.rod import CrossSection, Rod
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    s = BeamSetup(dim=2, t_over_dx=args.t_over_dx, ppc=args.ppc, damping=args.damping, cfl=args.cfl,
                  velocity_gradient=args.velocity_gradient)
    tau = 1.0 / s.omega1
    t_end = (args.hold + (0.0 if args.relax else 1.5)) * tau
    zero = [0.0, 0.0, 0.0]
    if args.load == "field":
        B = field_vector(s, args.bn, 90.0)
        sched = Schedule([0.0, t_end], [B, B], [t_end]) if args.relax else \
            Schedule([0.0, 1.5 * tau, t_end], [zero, B, B], [t_end])
        g = 0.0
    else:
        B = zero
        sched = Schedule([0.0, t_end], [zero, zero], [t_end])
        g = args.sag * s.bending_modulus * s.thickness**2 / (1.5 * s.density * s.length**3)
    scene = beam_scene(s, sched)
    if g:
        scene["simulation"]["gravity"] = [0.0, -g]
    sim = Simulation(parse_scene(scene))
    host = sim.model.host
    X0 = host["positions"].copy()
    probe = sim.probes[0]
    tip0 = probe.evaluate(X0)
    L = float(X0[X0[:, 0] > 0, 0].max() + s.dx / s.ppc / 2)
    h = s.dx / s.ppc
    free = ~host["clamped"]
    pairs = cKDTree(X0).query_pairs(1.01 * h, output_type="ndarray")
    pairs = pairs[free[pairs[:, 0]] & free[pairs[:, 1]]]
    vol, G, K, mass = host["volumes"], host["shear_modulus"], host["bulk_modulus"], host["mass"]
    Br = host["remanence"][:, :2]
    B2 = np.asarray(B[:2])

    if args.load == "field":
        ref = float(rod_reference(s, (args.bn,), 90.0, float(tip0[0]), L)[1][0])
    else:
        rod = Rod(L, CrossSection.rectangle(s.width, s.thickness), youngs_modulus=s.bending_modulus,
                  density=s.density, gravity=(0.0, 0.0, -g), magnetisation=(0.0, 0.0, 0.0))
        sol = rod.solve((0.0, 0.0, 0.0))
        ref = float(np.interp(tip0[0], sol.s, sol.positions[:, 2]) / L)

    def sample(label: float) -> dict:
        x = sim.state.x.numpy().astype(np.float64)
        F = sim.state.F.numpy().astype(np.float64)
        v = sim.state.v.numpy().astype(np.float64)
        tip = float((probe.evaluate(x)[1] - tip0[1]) / L)
        mm = mismatch(X0, x, F, pairs, h)
        elastic = float(np.sum(vol * neo_hookean_energy(F, G, K)))
        if args.load == "field":
            potential = float(-np.sum(vol * np.einsum("a,nab,nb->n", B2, F, Br)) / MU0)
        else:
            potential = float(np.sum(mass * g * (x[:, 1] - X0[:, 1])))
        return {"t_over_tau": label, "tip_dy_over_L": tip, "error": tip / ref - 1.0,
                "max_speed_m_s": float(np.linalg.norm(v[free], axis=1).max()),
                "mismatch_rms": float(np.sqrt(np.mean(mm**2))), "mismatch_max": float(mm.max()),
                "elastic_J": elastic, "load_potential_J": potential, "total_J": elastic + potential}

    rows, t0 = [], time.perf_counter()
    relax_msg = None
    start = 0.0
    if args.relax:
        r = sim.relax(energy_tol=1e-8, speed_tol=1e-4, max_steps=3_000_000, patience=200)
        relax_msg = r.message
        rows.append(sample(0.0))
        start = sim.time
    for k in range(1, int(math.floor(t_end / tau + 1e-9)) + 1):
        sim.advance_to(start + k * tau if args.relax else k * tau)
        rows.append(sample(float(k)))
        if not args.json:
            q = rows[-1]
            print(f"t = {k:3d}/omega_1  tip dy/L {q['tip_dy_over_L']:.6f} ({100 * q['error']:+.2f} % vs rod)  "
                  f"max speed {q['max_speed_m_s']:.2e} m/s  x-F mismatch rms {q['mismatch_rms']:.4f} max "
                  f"{q['mismatch_max']:.3f}  energy {1e6 * q['total_J']:.5f} uJ "
                  f"(elastic {1e6 * q['elastic_J']:.5f})", flush=True)
    return {"load": args.load, "bn": args.bn if args.load == "field" else None,
            "sag": args.sag if args.load == "gravity" else None, "t_over_dx": s.t_over_dx, "ppc": s.ppc,
            "damping_over_omega1": s.damping, "cfl": s.cfl, "velocity_gradient": s.velocity_gradient,
            "relax": relax_msg, "rod_tip_dy_over_L": ref, "particles": int(sim.model.n_particles),
            "steps": int(sim.steps), "wall_s": round(time.perf_counter() - t0, 1), "samples": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--load", choices=("field", "gravity"), default="field")
    ap.add_argument("--bn", type=float, default=0.001, help="normalised field Br B/(mu0 G) (perpendicular)")
    ap.add_argument("--sag", type=float, default=0.25, help="linear sag over L of the gravity load")
    ap.add_argument("--hold", type=float, default=20.0, help="hold after the load is on, in 1/omega_1")
    ap.add_argument("--t-over-dx", type=int, default=2)
    ap.add_argument("--ppc", type=int, default=2)
    ap.add_argument("--damping", type=float, default=1.5, help="grid damping in units of omega_1")
    ap.add_argument("--cfl", type=float, default=0.4)
    ap.add_argument("--velocity-gradient", choices=("remap", "grid"), default="remap")
    ap.add_argument("--relax", action="store_true", help="relax by kinetic damping before the hold")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    out = run(args)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"rod tip dy/L {out['rod_tip_dy_over_L']:.6f}; {out['particles']} particles, {out['steps']} steps, "
              f"{out['wall_s']} s" + (f"; relaxation: {out['relax']}" if out["relax"] else ""))


if __name__ == "__main__":
    main()
