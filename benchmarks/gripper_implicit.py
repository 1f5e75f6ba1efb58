"""Seed 000's six-arm gripper (scenes/gripper.toml) by the implicit integrator, with its lifting magnet moving at a
hand's speed instead of the scene's 500 mm/s.

    python benchmarks/gripper_implicit.py [--speed 20] [--friction 1.0] [--preview] [--until T]

The scene's sequence (scenes/gripper.toml) with two changes: the magnet and its holder come down the same 40 mm
from 0.15 s at ``--speed`` mm/s (20 by default: 2 s), wait 0.05 s, rise the same 6 mm at that speed and stay,
and the run goes on for 1.2 s after that; the integrator is implicit (backward Euler, first step 5 ms, at most
20 ms, no mass damping, as a slow experiment has no grid drag). ``--friction``: Coulomb's coefficient between
gripper and bead (the scene's [contact] friction, 1.0 by default). Berthold et al. 2023 measured the friction
coefficients of the silicone rubbers used in soft robots against several counterfaces and found that they depend
on the contact pressure; no source gives silicone on silicone for these materials, so the scene's value is kept
and stated as an assumption.

Recorded every 10 ms: the arms' mean fold angle, the gap between opposite arm tips, how far the tips reach below the
bead's centre, the bead's lowest point above the floor and the gripper's centroid height
(magsoro.robots.gripper.ArmTracker); checked as `magsoro reproduce gripper` does: the arms closed round the bead
(tips below its centre, opposite tips at most 0.6 of the flat span apart) and the bead's lowest point at least 1 mm
above the floor for 1 s without a break. Writes benchmarks/results/<date>-cpu-<commit>-gripper-implicit[-preview].json
(with the machine and the commit) and a .png beside it: the curves, and side views of the particles at four
moments.
"""

import argparse
import copy
import json
import sys
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]
#: the magnet starts down at this time (s): the arms have closed round the bead by then (the field ramps 0.03-0.13 s)
DOWN_AT = 0.15
#: it waits this long at the bottom (s) before rising, as in the scene
WAIT = 0.05
#: the run goes on this long after the magnet has stopped rising (s): the 1 s hold and a margin
AFTER = 1.2
#: sampling interval (s)
EVERY = 0.01


def slow_scene(data: dict, speed: float, friction: float) -> tuple[dict, list]:
    """The gripper scene ``data`` with its magnet and holder moving at ``speed`` (m/s), the implicit integrator and
    the gripper-bead friction ``friction``. Returns the scene and the path's times."""
    d = copy.deepcopy(data)
    field, holder = d["fields"][1], d["colliders"][1]
    z = [p[2] for p in field["path"]["positions"]]
    down, up = z[0] - z[1], z[3] - z[2]
    t1 = DOWN_AT + down / speed
    t2 = t1 + WAIT
    t3 = t2 + up / speed
    times = [DOWN_AT, t1, t2, t3]
    field["path"]["times"] = list(times)
    holder["path"]["times"] = list(times)
    d["simulation"].update(integrator="implicit", duration=t3 + AFTER, damping=0.0)
    d["implicit"] = {"scheme": "backward_euler", "dt": 0.005, "dt_max": 0.02}
    d["contact"]["friction"] = float(friction)
    return d, times


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=20.0, help="the magnet's speed down and up, mm/s")
    ap.add_argument("--friction", type=float, default=1.0, help="Coulomb coefficient between gripper and bead")
    ap.add_argument("--preview", action="store_true", help="the scene's preview grid (dx 0.75 mm)")
    ap.add_argument("--until", type=float, default=None, help="stop at this simulated time, s (default: the end)")
    args = ap.parse_args(argv)
    from magsoro.errors import SimulationError
    from magsoro.robots.base import scene_data, simulation
    from magsoro.robots.gripper import HOLD_S, LIFT_MARGIN_M, ArmTracker, longest_run

    data, times = slow_scene(scene_data("gripper"), args.speed * 1e-3, args.friction)
    sim = simulation("gripper", data, preview=args.preview)
    arms = ArmTracker(sim)
    floor_z = float(data["colliders"][0]["point"][2])
    t_end = float(data["simulation"]["duration"]) if args.until is None else float(args.until)
    print(f"gripper: {sim.model.n_particles} particles, dx {sim.model.dx * 1e3:g} mm, magnet {args.speed:g} mm/s "
          f"(down {times[0]:.2f}-{times[1]:.2f} s, up {times[2]:.2f}-{times[3]:.2f} s), to {t_end:.2f} s", flush=True)
    rows, shots = [], {}
    shot_times = [0.0, DOWN_AT, t_end]  # and "peak": when the gripper has risen 2 mm off the bead (below)
    wall0 = time.perf_counter()
    message = ""
    z_closed = None  # the gripper's centroid height when the magnet starts down
    x = sim.state.x.numpy()
    k = 0
    try:
        while True:
            m = arms.measure(x)
            rows.append((sim.time, *m))
            for t_shot in shot_times:
                if abs(sim.time - t_shot) < 0.5 * EVERY:
                    shots[t_shot] = x.copy()
            if abs(sim.time - DOWN_AT) < 0.5 * EVERY:
                z_closed = m[3]
            if "peak" not in shots and z_closed is not None and m[3] - z_closed > 2e-3 and m[2] - floor_z < LIFT_MARGIN_M:
                shots["peak"] = (sim.time, x.copy())  # the gripper 2 mm above where it lay, the bead still down
            if sim.time >= t_end - 1e-9:
                break
            k += 1
            sim.advance_to(min(t_end, k * EVERY))
            x = sim.state.x.numpy()
            if k % 10 == 0:
                print(f"t {sim.time:.2f} s, wall {time.perf_counter() - wall0:.0f} s: fold {m[0]:.1f} deg, tips "
                      f"{m[1] * 1e3:.2f} mm apart, bead {1e3 * (m[2] - floor_z):.2f} mm up, gripper at "
                      f"{m[3] * 1e3:.2f} mm", flush=True)
    except SimulationError as exc:
        message = str(exc)
        print("run stopped:", message, flush=True)
    wall = time.perf_counter() - wall0
    t, angle, gap, low, zg, past = (np.array(c) for c in zip(*rows))
    height = low - floor_z
    last = t >= t[-1] - HOLD_S - 1e-9
    held, (h0, h1) = longest_run(t, height >= LIFT_MARGIN_M)
    closed = bool(np.all(past[last] > 0.0) and np.all(gap[last] / gap[0] <= 0.6))
    lifted = bool(height.max() >= LIFT_MARGIN_M)
    rise = zg - zg[min(int(np.searchsorted(t, DOWN_AT)), len(t) - 1)]
    left = np.flatnonzero((t >= DOWN_AT) & (rise > 2e-3) & (height < LIFT_MARGIN_M))
    result = {"benchmark": "gripper_implicit", **provenance(), "preview": args.preview, "particles": int(sim.model.n_particles),
              "dx_m": float(sim.model.dx), "magnet_speed_mm_s": args.speed, "friction": args.friction,
              "magnet_path_times_s": times, "completed": bool(not message and t[-1] >= t_end - 1e-9), "message": message,
              "simulated_s": float(t[-1]), "wall_s": round(wall, 1), "integrator": sim.integrator_info(),
              "checks": {"arms_closed_over_last_1s": closed, "bead_lifted_1mm": lifted,
                         "bead_held_1mm_for_s": float(held), "held_from_to_s": [None if np.isnan(v) else float(v) for v in (h0, h1)],
                         "held_1s": bool(held >= HOLD_S)},
              "gripper_left_bead_at_s": float(t[left[0]]) if len(left) else None,
              "series": {"t_s": t.tolist(), "fold_angle_deg": angle.tolist(), "tip_gap_m": gap.tolist(),
                         "bead_lowest_above_floor_m": height.tolist(), "gripper_centroid_z_m": zg.tolist(),
                         "tips_below_bead_centre_m": past.tolist()}}
    tag = "-preview" if args.preview else ""
    out = ROOT / "benchmarks" / "results" / f"{result['date'][:10]}-cpu-{result['commit']}-gripper-implicit{tag}.json"
    out.write_text(json.dumps(result, indent=1))
    picture(out.with_suffix(".png"), result, sim, shots, floor_z, data["colliders"][1])
    print({k: v for k, v in result.items() if k not in ("series", "integrator")})
    print(out)
    return 0


def picture(path: Path, result: dict, sim, shots: dict, floor_z: float, holder: dict) -> None:
    """The run's curves, and side views (x, z) of the particles at the start, when the magnet starts down, when
    the gripper has risen 2 mm off the bead (if it did) and at the end, with the floor and the holder's bottom
    (dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = result["series"]
    t = np.array(s["t_s"])
    fig = plt.figure(figsize=(13, 7.5))
    ax = fig.add_subplot(2, 1, 1)
    ax.plot(t, 1e3 * np.array(s["bead_lowest_above_floor_m"]), label="bead's lowest point above the floor (mm)")
    ax.plot(t, 1e3 * (np.array(s["gripper_centroid_z_m"]) - floor_z), label="gripper's centroid above the floor (mm)")
    ax.plot(t, 1e3 * np.array(s["tip_gap_m"]), label="gap between opposite arm tips (mm)")
    ax.plot(t, 1e3 * np.array(s["tips_below_bead_centre_m"]), label="arm tips below the bead's centre (mm)")
    for tt in result["magnet_path_times_s"]:
        ax.axvline(tt, color="0.7", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("mm")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(f"Six-arm gripper, implicit integrator, magnet at {result['magnet_speed_mm_s']:g} mm/s, "
                 f"mu {result['friction']:g}, dx {result['dx_m'] * 1e3:g} mm (grey lines: magnet starts down, "
                 f"stops, starts up, stops)", fontsize=9)
    h = sim.model.host
    body = np.asarray(h["body"])
    views = [(0.0, shots.get(0.0)), (DOWN_AT, shots.get(DOWN_AT))]
    if "peak" in shots:
        views.append(shots["peak"])
    views.append((result["simulated_s"], shots.get(result["simulated_s"], sim.state.x.numpy())))
    for i, (tv, xv) in enumerate(views):
        if xv is None:
            continue
        a = fig.add_subplot(2, len(views), len(views) + i + 1)
        for b, colour in ((0, "tab:red"), (1, "tab:blue")):
            sel = body == b
            a.scatter(1e3 * xv[sel, 0], 1e3 * xv[sel, 2], s=0.5, color=colour)
        a.axhline(1e3 * floor_z, color="0.3", lw=1)
        zh = float(np.interp(tv, holder["path"]["times"], [p[2] for p in holder["path"]["positions"]]))
        a.axhline(1e3 * (zh - 0.5 * holder["length"]), color="0.5", lw=1, ls="--")  # the holder's bottom
        a.set_aspect("equal")
        a.set_xlim(-12, 12)
        a.set_ylim(-1, 30)
        a.set_title(f"t = {tv:.2f} s", fontsize=9)
        a.set_xlabel("x (mm)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
