"""``magsoro plan``: external-magnet pose sequence making a planar magnetic robot follow a shape sequence
(seed 004 sec II-C), optionally replayed by the MPM engine."""

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "plan",
        help="plan the external-magnet poses for a growing planar magnetic robot (PRB model), optionally replay in MPM",
        description=(
            "Time-stepping optimisation of the external permanent magnet's pose sequence for the pseudo-rigid-body "
            "model described by PLAN.toml, following a retroflexion-like shape sequence with follow-the-leader "
            "growth and a small out-of-plane field. Writes DIR/plan.json, DIR/epm_path.csv (keyframes t, x, y, z, "
            "mx, my, mz), DIR/prb_shapes.csv, DIR/plan.png and, for a constant moment, DIR/epm_field.toml (a scene "
            "[[fields]] table). With --replay, also runs the plan in the MPM engine (2D) and writes DIR/replay.csv "
            "and DIR/replay.png. See docs/actuation.md."
        ),
    )
    p.add_argument("plan", metavar="PLAN.toml", help="plan description (TOML)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: out/<PLAN stem>)")
    p.add_argument("--replay", action="store_true", help="replay the plan in the MPM engine ([replay] table)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=run_plan_command)


def run_plan_command(args) -> int:
    import json
    import math

    from magsoro.actuation.config import PlanConfig, load
    from magsoro.actuation.plan_report import run_plan

    if args.json and args.replay:
        # stdout carries one JSON object: keep Warp's banner and module-load lines off it
        from magsoro.warp_setup import quiet_warp

        quiet_warp()
    config = load(PlanConfig, args.plan)
    out = Path(args.out) if args.out else Path("out") / Path(args.plan).stem

    def progress(k, step):
        if not args.json:
            print(f"step {k}: {step.links} links, tip-angle error {math.degrees(step.tip_angle_error):.3g} deg, "
                  f"shape RMS {math.degrees(step.shape_rms_error):.3g} deg, |Bz| <= {1e3 * step.max_out_of_plane_field:.3g} mT",
                  flush=True)

    summary = run_plan(config, out, args.replay, progress)
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"largest tip-angle error {summary['max_tip_angle_error_deg']:.3g} deg over {len(summary['steps'])} steps "
          f"(planned in {summary['planning_wall_time_s']:.3g} s)")
    if "replay" in summary:
        r = summary["replay"]
        print(f"MPM replay: tip at the end of each step within {1e3 * r['max_step_end_tip_error_m']:.3g} mm of the PRB "
              f"({100 * r['max_step_end_tip_error_over_length']:.3g} % of the length); during moves within "
              f"{1e3 * r['max_path_tip_error_m']:.3g} mm ({r['mpm_steps']} MPM steps, {r['wall_time_s']:.3g} s)")
        if r.get("dim") == 3:
            print(f"3D replay{' on a frictionless floor with gravity' if r['floor'] else ' (free, no gravity)'}: in the "
                  f"plane within {1e3 * r['max_step_end_in_plane_tip_error_m']:.3g} mm at the step ends; the tip "
                  f"leaves the plane by up to {1e3 * r['max_abs_tip_z_m']:.3g} mm")
    print(f"wrote {', '.join(str(out / f) for f in summary['files'])}")
    return 0
