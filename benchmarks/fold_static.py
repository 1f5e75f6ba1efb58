"""The folding robots' field sweeps by the static solver at their full-resolution scenes (seed 002 sec 5.3 and 5.4):
the pentahedron (27,000 particles) or the hexahedron (43,200), the magnet under the plate rising through the
positions that give each field level at the robot's centre, one equilibrium per level, each from the last.

    python benchmarks/fold_static.py [--robot pentahedron|hexahedron] [--levels 0 9 18 27 36 45]
                                     [--mode path|scale] [--dx DX] [--linear-solver auto|direct|iterative]
                                     [--preview] [--soft-penalty F]

The scene is the robot's file (float64, the domain's floor lowered as for the triangle's static sweep,
magsoro.robots.triangle.static_magnet_sweep; ``--dx`` replaces its grid spacing). ``--mode path``: the magnet
moves along the path through the levels' positions ([static] times; the first level from the flat robot, which
settles on the plate under gravity there). ``--mode scale``: the magnet stays at the highest level's position and
its field is scaled to each level in turn ([static] levels; gravity settles the robot first). ``--soft-penalty F`` sets static.soft_penalty (the predictor's Newton iterations and linear solves are
recorded too). Records per level: Newton iterations, load increments, linear solves and Krylov
iterations, the level's wall time, the mean fold angle of the side squares (deg) and the particles' largest
displacement; and the sweep's wall time. Writes
benchmarks/results/<date>-cpu-<commit>-fold-static-<robot>-<mode>.json with the machine and the commit, after
every level ("complete": false until the sweep has ended, so a stopped run keeps the levels it finished).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]


def scale_sweep(args, data, magnet, offsets, on_read, on_start):
    """--mode scale: the magnet at the highest level's position, its field scaled to each level (levels / top)."""
    from magsoro.robots.base import RobotError, simulation
    from magsoro.robots.triangle import STATIC_ROOM

    top = max(args.levels)
    magnet.pop("path", None)
    magnet["position"] = offsets([top])[0]
    table = data["simulation"]
    table["precision"] = "float64"
    table["domain_lo"][2] -= STATIC_ROOM
    data.setdefault("output", {})["particles"] = False
    sim = simulation(args.robot, data, preview=args.preview, device="cpu")
    on_start(sim)
    levels = sorted(args.levels)
    done = []

    def on_level(s, res):
        on_read(s, levels[len(done)], res)
        done.append(res)

    out = sim.solve_static(levels=[lv / top for lv in levels], on_level=on_level)
    if not out.converged:
        raise RobotError(f"{args.robot}: static solve failed: {out.message}")
    return sim


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", choices=["pentahedron", "hexahedron"], default="pentahedron")
    ap.add_argument("--levels", type=float, nargs="+", default=[0.0, 9.0, 18.0, 27.0, 36.0, 45.0],
                    help="field levels at the robot's centre, mT")
    ap.add_argument("--mode", choices=["path", "scale"], default="path")
    ap.add_argument("--dx", type=float, default=None, help="grid spacing, m (default the scene's)")
    ap.add_argument("--linear-solver", choices=["auto", "direct", "iterative"], default="auto")
    ap.add_argument("--preview", action="store_true", help="the scene's preview grid instead of its full one")
    ap.add_argument("--soft-penalty", type=float, default=None,
                    help="static.soft_penalty: the predictor chain's penalty fraction (default: off)")
    args = ap.parse_args(argv)

    from magsoro.robots import hexahedron as H
    from magsoro.robots import pentahedron as P
    from magsoro.robots.base import Context, scene_data
    from magsoro.robots.triangle import static_magnet_sweep

    module = P if args.robot == "pentahedron" else H
    sides = P.SIDES if args.robot == "pentahedron" else H.WALLS
    start = P.HALF if args.robot == "pentahedron" else H.START
    point = (0.0, 0.0, module.THICKNESS / 2.0)
    data = scene_data(args.robot)
    data.setdefault("static", {})["linear_solver"] = args.linear_solver
    if args.soft_penalty is not None:
        data["static"]["soft_penalty"] = args.soft_penalty
    if args.dx is not None:
        data["simulation"]["dx"] = args.dx
    magnet = P.magnet_entry(data)

    def offsets(levels_mt):
        return [[0.0, 0.0, P.magnet_center_for(magnet, lv * 1e-3, point)] for lv in levels_mt]

    rows, ref = [], {}
    log = []
    prov = provenance()
    name = (f"{prov['date'][:10]}-cpu-{prov['commit']}-fold-static-{args.robot}-{args.mode}"
            f"{'-preview' if args.preview else ''}{'-soft' if args.soft_penalty else ''}.json")
    path = ROOT / "benchmarks" / "results" / name
    t0 = time.perf_counter()

    def write(sim, complete):
        """The result file, rewritten after every level: ``complete`` False until the sweep has ended, so a run
        stopped by hand or by a limit leaves the levels it finished, marked as such."""
        out = {"benchmark": "fold_static", **prov, "robot": args.robot, "mode": args.mode,
               "dx_m": float(sim.model.dx), "scene": f"scenes/{args.robot}.toml", "preview": args.preview,
               "particles": int(sim.model.n_particles), "linear_solver": args.linear_solver,
               "soft_penalty": args.soft_penalty, "levels_mT": args.levels, "complete": complete,
               "sweep_wall_s": round(time.perf_counter() - t0, 1), "rows": rows}
        tmp = path.with_suffix(".part")
        tmp.write_text(json.dumps(out, indent=1) + "\n")
        tmp.replace(path)

    def say(msg):
        log.append(msg)
        print(msg, flush=True)

    ctx = Context(out=Path("/tmp"), preview=args.preview, device="cpu", log=say)
    clock = {"last": time.perf_counter()}

    def on_start(sim):
        ref["X0"] = sim.model.host["positions"].astype(np.float64)
        ref["masks"] = P.flap_masks(sim, sides, start, P.SIDE)
        say(f"{args.robot}: {sim.model.n_particles} particles, dx = {sim.model.dx * 1e3:.4f} mm")
        clock["last"] = time.perf_counter()

    def on_read(sim, level, res):
        x = sim.state.x.numpy().astype(np.float64)
        angles = P.flap_angles(x, ref["masks"])
        now = time.perf_counter()
        row = {"level_mT": level, "converged": bool(res.converged), "newton_iterations": int(res.iterations),
               "load_increments": int(res.increments), "linear_solver": res.linear_solver,
               "linear_solves": int(res.linear_solves), "linear_iterations": int(res.linear_iterations),
               "linear_setups": int(res.linear_setups), "linear_fallbacks": int(res.linear_fallbacks),
               "predictor_iterations": int(res.predictor_iterations),
               "predictor_linear_solves": int(res.predictor_linear_solves),
               "wall_s": round(now - clock["last"], 1), "mean_fold_deg": float(np.mean(list(angles.values()))),
               "fold_deg": angles, "max_displacement_m": float(np.abs(x - ref["X0"]).max())}
        clock["last"] = now
        rows.append(row)
        say(json.dumps(row))
        write(sim, complete=False)

    if args.mode == "path":
        sim, _ = static_magnet_sweep(ctx, args.robot, data, magnet, offsets, args.levels, [], on_read, on_start)
    else:
        sim = scale_sweep(args, data, magnet, offsets, on_read, on_start)
    write(sim, complete=True)
    print(f"{args.robot}: sweep {time.perf_counter() - t0:.0f} s; wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
