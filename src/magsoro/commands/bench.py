"""``magsoro bench [NAME ...] [--device cpu|cuda] [--steps N] [--threads N] [--json] [--save]``: time the fixed
benchmark scenes."""

import json
import sys
from pathlib import Path


def register(sub):
    p = sub.add_parser("bench", help="time the fixed benchmark scenes", description="Time benchmark scenes (walker, walker_total, walker_dipole, walker_1m, beam2d, block1m, sweep) against a bare reference MPM step; implicit_beam2d (by name): scenes/cantilever_2d.toml over 0.2 s by the implicit integrator and the explicit engine, their wall-time ratio.")
    p.add_argument("names", nargs="*", help="scenes to run (default: all)")
    p.add_argument("--device", default="cpu", help="cpu or cuda[:N]")
    p.add_argument("--steps", type=int, help="timed steps per scene (default depends on the scene)")
    p.add_argument("--threads", type=int, help="CPU threads per step (default: the engine's automatic choice, one per 4000 particles up to the cores)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--save", action="store_true", help="write benchmarks/results/<date>-<device>-<commit>.json")
    p.set_defaults(func=run)


def run(args) -> int:
    import warp as wp

    from magsoro.bench.runner import names_or_all, run as run_bench
    from magsoro.errors import MagsoroError
    from magsoro.warp_setup import quiet_warp

    if args.json:
        # stdout carries one JSON object
        quiet_warp()
    if args.device != "cpu" and wp.get_cuda_device_count() == 0:
        raise MagsoroError(f"--device {args.device}: no CUDA device on this machine")
    if args.steps is not None and args.steps < 1:
        raise MagsoroError("--steps must be >= 1")
    if args.threads is not None and args.threads < 1:
        raise MagsoroError("--threads must be >= 1")
    result = run_bench(names_or_all(args.names), args.device, args.steps, args.threads)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"device {result['device_name']} ({result['device']}), commit {result['commit']}")
        print(f"{'scene':<10} {'particles':>10} {'threads':>7} {'ms/step':>9} {'windowed':>9} {'steps/s':>9} {'Mpart-steps/s':>14} {'ref ratio':>9}  phases ms (p2g/grid/g2p/other)")
        for s in result["scenes"]:
            if "speedup" in s:  # an implicit scene: both integrators over the scene's run
                imp, exp = s["implicit"], s["explicit"]
                print(f"{s['name']:<10} {imp['n_particles']:>10}  {s['duration_s']:g} s simulated: implicit {imp['wall_s']:.2f} s "
                      f"({imp['steps']} steps, {imp['integrator']['newton_iterations']} Newton iterations), explicit "
                      f"{exp['wall_s']:.2f} s ({exp['steps']} steps): {s['speedup']:.1f}x")
                continue
            ph = s["phases_ms"]
            print(f"{s['name']:<10} {s['n_particles']:>10} {s['threads']:>7} {s['ms_per_step']:>9.3f} {s['window_ms_per_step']:>9.3f} {s['steps_per_s']:>9.1f} {s['particle_steps_per_s'] / 1e6:>14.2f} {s['ratio_to_reference']:>9.2f}  "
                  f"{ph['p2g']:.2f}/{ph['grid']:.2f}/{ph['g2p']:.2f}/{ph['other']:.2f}")
        explicit = [s for s in result["scenes"] if "speedup" not in s]
        print(f"ms/step: every step checked (one host read per step); windowed: check windows of "
              f"{explicit[0]['window_steps'] if explicit else '-'} steps (one read per window), "
              f"timed in the same rounds; window loop: "
              f"{', '.join(sorted({s['window_loop'] for s in explicit})) if explicit else '-'}")
    if args.save:
        out_dir = Path("benchmarks") / "results"
        out_dir.mkdir(parents=True, exist_ok=True)
        tag = "" if args.threads is None else f"-threads{args.threads}"
        out = out_dir / f"{result['date'][:10]}-{args.device.replace(':', '')}-{result['commit']}{tag}.json"
        from magsoro.io.files import atomic_write_json

        atomic_write_json(out, result)
        print(f"wrote {out}", file=sys.stderr)
    return 0
