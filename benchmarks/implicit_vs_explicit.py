"""A slow experiment by both integrators, timed in one run: scenes/strip_magnet.toml's hanging strip while its disc
magnet rises along the strip's axis at a constant speed (default 10 mm/s, a hand-moved magnet).

    python benchmarks/implicit_vs_explicit.py [--speed 0.01] [--duration 0.8] [--dx 0.002] [--gap 0.045]
                                              [--implicit-dt 0.04] [--rho-inf 0.8] [--sample 0.04]
                                              [--start equilibrium|rest]

The scene is the file's at the given dx (default its preview's, 2 mm) and damping; the magnet starts with a
``--gap`` (45 mm) to the strip's free end and rises at ``--speed`` for ``--duration`` seconds (0.8 s: to a 37 mm
gap, just clear of the pull-in). Both runs start from the strip hanging at rest below the magnet's first position:
the static solver's equilibrium, settled for 0.5 s by backward-Euler steps of 50 ms with the magnet held (the
static solver slaves the light nodes at the strip's faces and stands 66-74 um stiffer at the tip than both
integrators), its velocities then zeroed (``--start rest``: from the undeformed strip, gravity and the field
switched on at t = 0). Both run in float64, total-Lagrangian form, and record the tip probe every ``--sample``
seconds. Neither wall time includes the start's static solve and settling. The implicit
integrator steps at ``--implicit-dt`` with generalised-alpha's ``--rho-inf`` (0.8 keeps the strip's swing, which
0 damps by a few per cent a period at this step); its wall time includes its setup. Reports both wall times,
their ratio, and the largest difference of the tip's displacement between the runs relative to the tip's largest
displacement. Writes benchmarks/results/<date>-cpu-<commit>-implicit-vs-explicit.json with the machine and the
commit.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "strip_magnet.toml"
#: the magnet's centre sits 6.35 mm below its top face; the strip's free end is at z = -0.1 m
HALF_LENGTH, TIP_Z = 0.00635, -0.1
#: the start's settling by backward Euler (equilibrium_state): its duration and step (s), and the largest particle
#: speed it may leave (m/s), which the start then zeroes
SETTLE_S, SETTLE_DT, SETTLE_SPEED = 0.5, 0.05, 1e-4


def scene(integrator: str, speed: float, duration: float, dx: float, implicit_dt: float, gap: float = 0.045,
          sample: float = 0.01, rho_inf: float = 0.0):
    from magsoro.scene import load_scene

    sc = load_scene(SCENE)
    sc.simulation.dx = dx
    sc.simulation.duration = duration
    sc.simulation.integrator = integrator
    sc.simulation.formulation = "total"
    sc.output.every = sample
    z0 = TIP_Z - gap - HALF_LENGTH
    z1 = z0 + speed * duration
    path = {"times": [0.0, duration], "positions": [[0.0, 0.0, z0], [0.0, 0.0, z1]]}
    sc.fields[0].path = type(sc.fields[0].path).model_validate(path)
    sc.colliders[0].path = type(sc.colliders[0].path).model_validate(path)
    sc.colliders[0].center = [0.0, 0.0, z0]
    sc.implicit.dt = sc.implicit.dt_max = implicit_dt
    sc.implicit.rho_inf = rho_inf
    return sc


def equilibrium_state(args):
    """The strip at rest under gravity and the magnet at its start (the static solver), as a simulation state."""
    from magsoro.simulation import Simulation

    sim = Simulation(scene("explicit", args.speed, args.duration, args.dx, args.implicit_dt, args.gap, args.sample,
                           args.rho_inf), source=str(SCENE))
    res = sim.solve_static(levels=[1.0], t=0.0)
    if not res.converged:
        raise SystemExit(f"the starting equilibrium did not converge: {res.levels[-1].message}")
    sim.state.time = 0.0
    # the static solver slaves the light nodes at the strip's faces, which neither integrator does: from its shape the
    # strip sinks 66-74 um and its light nodes jump, which a second-order implicit scheme carries on as ringing node
    # velocities for many steps. Settle it first by backward Euler (strongly dissipative) with the magnet held
    held = scene("implicit", 0.0, SETTLE_S, args.dx, SETTLE_DT, args.gap, SETTLE_S)
    held.implicit.scheme = "backward_euler"
    settle = Simulation(held, source=str(SCENE))
    settle.state.assign(sim.state)
    settle.state.time = 0.0
    settle.advance_to(SETTLE_S)
    state = settle.state
    speed = float(np.abs(state.v.numpy()).max())
    if speed > SETTLE_SPEED:
        raise SystemExit(f"the strip did not settle: {speed:.3g} m/s after {SETTLE_S} s")
    state.v.zero_()
    state.C.zero_()
    state.time = 0.0
    return state


def run(integrator: str, args, start=None) -> dict:
    from magsoro.simulation import Simulation

    sim = Simulation(scene(integrator, args.speed, args.duration, args.dx, args.implicit_dt, args.gap, args.sample,
                           args.rho_inf), source=str(SCENE))
    wall0 = time.perf_counter()
    if start is not None:  # both integrators from the same state at rest (the implicit one projects it on its nodes)
        sim.state.assign(start)
        sim.state.time = 0.0
    times, tips = [0.0], [sim.probe_values()["tip_z"]]
    n = int(round(args.duration / args.sample))
    for k in range(1, n + 1):
        sim.advance_to(k * args.sample)
        times.append(sim.time)
        tips.append(sim.probe_values()["tip_z"])
    wall = time.perf_counter() - wall0
    out = {"integrator": integrator, "wall_s": round(wall, 2), "steps": sim.steps, "particles": int(sim.model.n_particles),
           "dt_min": sim.dt_min, "dt_max": sim.dt_max, "times": times, "tip_z": tips}
    if integrator == "implicit":
        out["implicit"] = sim.integrator_info()
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--speed", type=float, default=0.01, help="magnet speed, m/s")
    p.add_argument("--duration", type=float, default=0.8, help="simulated time, s")
    p.add_argument("--dx", type=float, default=0.002, help="grid spacing, m")
    p.add_argument("--implicit-dt", type=float, default=0.04, help="the implicit integrator's step, s")
    p.add_argument("--sample", type=float, default=0.04, help="the tip is recorded every this many seconds, s")
    p.add_argument("--rho-inf", type=float, default=0.8, help="generalised-alpha's implicit.rho_inf")
    p.add_argument("--gap", type=float, default=0.045, help="the magnet's starting gap to the strip's free end, m")
    p.add_argument("--start", choices=["equilibrium", "rest"], default="equilibrium",
                   help="equilibrium: both runs start from the strip hanging at rest below the magnet's first position "
                        "(the static solver's); rest: from the undeformed strip, gravity and field switched on at t = 0")
    args = p.parse_args(argv)
    start = equilibrium_state(args) if args.start == "equilibrium" else None
    implicit = run("implicit", args, start)
    print(f"implicit: {implicit['wall_s']} s, {implicit['steps']} steps", flush=True)
    explicit = run("explicit", args, start)
    print(f"explicit: {explicit['wall_s']} s, {explicit['steps']} steps", flush=True)
    a, b = np.asarray(implicit["tip_z"]), np.asarray(explicit["tip_z"])
    span = float(np.max(np.abs(b - b[0])))
    diff = float(np.max(np.abs(a - b))) / span
    result = {"benchmark": "implicit_vs_explicit", **provenance(), "scene": "scenes/strip_magnet.toml",
              "start": args.start, "speed_m_s": args.speed, "duration_s": args.duration, "dx_m": args.dx, "implicit_dt_s": args.implicit_dt,
              "rho_inf": args.rho_inf, "sample_s": args.sample, "gap_m": args.gap,
              "speedup": round(explicit["wall_s"] / implicit["wall_s"], 2),
              "tip_difference_over_tip_travel": diff, "tip_travel_m": span,
              "implicit": implicit, "explicit": explicit}
    prov = result
    name = f"{prov['date'][:10]}-cpu-{prov['commit']}-implicit-vs-explicit.json"
    out = ROOT / "benchmarks" / "results" / name
    out.write_text(json.dumps(result, indent=1))
    print(f"speedup {result['speedup']}x; tip difference {diff:.3%} of its {span * 1e3:.3g} mm travel; {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
