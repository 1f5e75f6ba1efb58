"""``magsoro optimize``: gradient-based design of magnetisation, field, magnet pose or material (docs/differentiable.md)."""

import csv
import json
import math
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "optimize",
        help="design magnetisation / field / magnet pose / material by differentiable simulation",
        description=(
            "Minimise a shape target (TARGET.toml: type = 'tip' | 'centreline' | 'fold_angle') at the end of a "
            "fixed-step rollout of SCENE.toml over the design variables --vars, with gradients from Warp's autodiff. "
            "Writes DIR/history.csv, DIR/<scene>_optimized.toml (the design written back, with the rollout's dt "
            "and duration), DIR/before.png, DIR/after.png and DIR/result.json, then re-runs the written scene "
            "with the normal engine and reports its target error. See docs/differentiable.md."
        ),
    )
    p.add_argument("scene", metavar="SCENE.toml")
    p.add_argument("--target", required=True, metavar="TARGET.toml", help="target file (TOML)")
    p.add_argument("--vars", required=True, metavar="KINDS",
                   help="comma-separated variable kinds: magnetisation, magnetisation_particles, field, keyframes, epm, material")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--bodies", metavar="NAMES", help="comma-separated bodies for body variables (default: the magnetised / all bodies)")
    p.add_argument("--method", choices=["adam", "lbfgs"], default="adam")
    p.add_argument("--iterations", type=int, default=50)
    p.add_argument("--lr", type=float, default=0.05, help="Adam step in units of each variable's scale (default 0.05)")
    p.add_argument("--duration", type=float, help="horizon, s (default: the scene's duration)")
    p.add_argument("--dt", type=float, help="fixed time step, s (default: the scene's dt or its CFL bound)")
    p.add_argument("--segment", type=int, help="steps per checkpoint segment (default: the whole rollout)")
    p.add_argument("--margin", type=float, help="grid block margin around the reference bodies, m")
    p.add_argument("--precision", choices=["float32", "float64"], help="override the scene's precision")
    p.add_argument("--no-verify", action="store_true", help="skip the forward re-run of the written scene")
    p.add_argument("--static", action="store_true",
                   help="optimise the static equilibrium instead of a rollout: the scene solved by Newton's method at "
                        "each of its [static] levels (as `magsoro run --static`), the target at the last, gradients by "
                        "the adjoint of the converged system; variables magnetisation and material")
    p.set_defaults(func=run_optimize)


def _render(path, x, target, title, body):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    dim = x.shape[1]
    axes = (0, 1) if dim == 2 else tuple(np.argsort(-np.ptp(x, axis=0))[:2].tolist())
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.scatter(x[:, axes[0]], x[:, axes[1]], s=4, c=body, cmap="tab10")
    if hasattr(target, "points"):
        ax.plot(target.points[:, axes[0]], target.points[:, axes[1]], "k--o", ms=3, label="target centreline")
        c = target.centreline(x)
        ax.plot(c[:, axes[0]], c[:, axes[1]], "r-", label="centreline")
    elif hasattr(target, "position"):
        ax.plot(*target.position[list(axes)], "k*", ms=12, label="target tip")
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[axes[0]] + " (m)")
    ax.set_ylabel("xyz"[axes[1]] + " (m)")
    ax.set_title(title, fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_optimize(args) -> int:
    import numpy as np

    from magsoro.diff.optimize import Problem, optimise
    from magsoro.errors import MagsoroError
    from magsoro.simulation import Simulation, prepare_static

    kinds = [k.strip() for k in args.vars.split(",") if k.strip()]
    bodies = [b.strip() for b in args.bodies.split(",")] if args.bodies else None
    if args.iterations < 1:
        raise MagsoroError(f"--iterations: must be >= 1, got {args.iterations}")
    for flag, value, low in (("--duration", args.duration, "> 0 s"), ("--dt", args.dt, "> 0 s"), ("--lr", args.lr, "> 0"),
                             ("--margin", args.margin, ">= 0 m")):
        if value is not None and not (math.isfinite(value) and (value >= 0 if low.startswith(">=") else value > 0)):
            raise MagsoroError(f"{flag}: must be a finite number {low}, got {value}")
    if args.segment is not None and args.segment < 1:
        raise MagsoroError(f"--segment: must be >= 1 steps, got {args.segment}")
    static = getattr(args, "static", False)
    if static:
        from magsoro.diff.static_adjoint import StaticProblem

        for flag, value in (("--duration", args.duration), ("--dt", args.dt), ("--segment", args.segment),
                            ("--margin", args.margin), ("--precision", args.precision)):
            if value is not None:
                raise MagsoroError(f"{flag}: not used with --static (the static solve is float64, at the scene's levels)")
        prob = StaticProblem.from_files(args.scene, args.target, kinds, bodies=bodies)
    else:
        prob = Problem.from_files(args.scene, args.target, kinds, bodies=bodies, duration=args.duration, dt=args.dt,
                                  segment=args.segment, margin=args.margin, precision=args.precision)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    what = (f"static equilibrium at levels {prob.levels}" if static else f"{prob.n_steps} steps of {prob.dt:.4g} s")
    print(f"{what}, {prob.built.model.n_particles} particles, "
          f"{len(prob.design.values())} variables ({', '.join(v.name for v in prob.design.vars)})")
    before = prob.final_state()
    err0 = prob.error(before)

    def report(i, L, L0):
        print(f"  evaluation {i:4d}: loss {L:.6e}  ({L / L0:.3e} of initial)", flush=True)

    res = optimise(prob, method=args.method, iterations=args.iterations, lr=args.lr, callback=report)
    after = prob.final_state(res["values"])
    err1 = prob.error(after)
    with open(out / "history.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["evaluation", "loss", "loss_ratio"])
        for i, L in res["history"]:
            w.writerow([i, f"{L:.10e}", f"{L / res['initial_loss']:.6e}"])
    scene_out = prob.write_scene(out / f"{Path(args.scene).stem}_optimized.toml")
    body = prob.built.model.host["body"]
    _render(out / "before.png", before["x"], prob.target, f"initial design: error {err0:.4g}", body)
    _render(out / "after.png", after["x"], prob.target, f"optimised design: error {err1:.4g}", body)
    result = {
        "scene": str(args.scene), "target": str(args.target), "vars": kinds, "method": args.method,
        "static": static, "levels": prob.levels if static else None,
        "steps": None if static else prob.n_steps, "dt": None if static else prob.dt,
        "duration": None if static else prob.duration,
        "initial_loss": res["initial_loss"], "final_loss": res["loss"],
        "loss_ratio": res["initial_loss"] / res["loss"] if res["loss"] > 0 else None,  # None: the loss reached 0
        "initial_error": err0, "final_error": err1, "evaluations": res["evaluations"], "wall_time_s": res["wall_time"],
        "variables": {n: [float(a), float(b)] for n, a, b in zip(prob.design.names(), res["initial_values"], res["values"])},
        "scene_out": str(scene_out),
    }
    if not args.no_verify and static:  # the written scene solved from scratch by the static solver
        from magsoro.scene import load_scene

        scene = load_scene(scene_out)
        prepare_static(scene)
        sim = Simulation(scene, source=str(scene_out))
        run = sim.solve_static(levels=prob.levels)
        if not run.converged:
            raise MagsoroError(f"the static re-solve of {scene_out} failed: {run.message}")
        x = sim.state.x.numpy().astype(np.float64)
        F = sim.state.F.numpy().astype(np.float64)
        result["rerun_error"] = prob.error({"x": x, "F": F})
        result["rerun_max_particle_deviation_m"] = float(np.max(np.linalg.norm(x - after["x"], axis=1)))
    elif not args.no_verify:
        sim = Simulation.from_file(scene_out, device="cpu")
        run = sim.run(duration=prob.duration, record_every=prob.duration)
        if run.status != "completed":
            raise MagsoroError(f"the forward re-run of {scene_out} failed: {run.message}")
        x = sim.state.x.numpy().astype(np.float64)
        F = sim.state.F.numpy().astype(np.float64)
        result["rerun_error"] = prob.error({"x": x, "F": F})
        result["rerun_max_particle_deviation_m"] = float(np.max(np.linalg.norm(x - after["x"], axis=1)))
    (out / "result.json").write_text(json.dumps(result, indent=2))
    print(f"loss {res['initial_loss']:.4e} -> {res['loss']:.4e} (x{result['loss_ratio'] or math.inf:.3g} lower); "
          f"target error {err0:.4g} -> {err1:.4g}" + (f"; re-run of the written scene: {result['rerun_error']:.4g}" if "rerun_error" in result else ""))
    print(f"wrote {out / 'history.csv'}, {scene_out}, {out / 'before.png'}, {out / 'after.png'}, {out / 'result.json'}")
    return 0
