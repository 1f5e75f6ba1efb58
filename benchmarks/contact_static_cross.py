"""The cross's static field sweep on an elastic plate (contact between two bodies) against the same sweep on the
rigid plate it ships with (a friction collider), timed in one run.

    python benchmarks/contact_static_cross.py [--plate-modulus 6.67e5] [--plate-thickness 0.002] [--max-iterations 40]
                                              [--soft-penalty F]

scenes/cross.toml lies on a friction half-space (mu 0.5), the plate of seed 002 sec 4.1. Here the plate is also
drawn as an elastic body under the robot (its bottom face clamped, its top where the half-space was, the same
friction 0.5 through `[contact]`; the cross's five parts bonded into one piece by `[[contact.pairs]]`), so the
static solver carries its unknowns and the body contact between the two. Both solve the equilibria at the
magnet's holds (-5 to -45 mT at the centre), each from the last. Reported: wall times, their ratio, Newton
iterations, and the centre's rise and the arm tip's height at each hold in both. ``--soft-penalty F`` sets
static.soft_penalty in both (the predictor scales the collider's and the bodies' contact penalty).

Writes benchmarks/results/<date>-cpu-<commit>-contact-static-cross.json with the machine and the commit.
"""

import argparse
import json
import sys
import time
from pathlib import Path

from magsoro.bench.runner import provenance

ROOT = Path(__file__).resolve().parents[1]

HOLDS = [0.05 + 0.06 * k for k in range(1, 10)]  # mid-hold times of the magnet path: -5 ... -45 mT


def scene(plate: bool, modulus: float, thickness: float):
    """scenes/cross.toml, or with ``plate`` its floor drawn as an elastic body in contact with the robot."""
    from magsoro.scene import load_scene

    sc = load_scene(ROOT / "scenes" / "cross.toml")
    sc.simulation.precision = "float64"
    if not plate:
        return sc
    data = sc.model_dump(exclude_none=True, exclude_defaults=False)
    data.pop("base_dir", None)
    names = [b["name"] for b in data["bodies"]]
    data["colliders"] = []
    data["bodies"].append({"name": "plate", "shape": {"type": "box", "center": [0.0, 0.0, -thickness / 2],
                                                      "size": [0.025, 0.025, thickness]},
                           "material": {"density": 1100.0, "shear_modulus": modulus}})
    data["clamps"] = list(data.get("clamps", [])) + [{"region": {"type": "box", "center": [0.0, 0.0, -thickness],
                                                                 "size": [0.028, 0.028, 0.001]}, "body": "plate"}]
    data["contact"] = {"friction": 0.5, "pairs": [{"bodies": ["centre", n], "bonded": True} for n in names if n != "centre"]}
    data["simulation"]["domain_lo"][2] = -thickness - 0.004
    from magsoro.scene import parse_scene

    return parse_scene(data, source="cross with an elastic plate", base_dir=ROOT / "scenes")


def run(plate: bool, args) -> dict:
    from magsoro.simulation import Simulation

    sc = scene(plate, args.plate_modulus, args.plate_thickness)
    sc.static.max_iterations = args.max_iterations
    sc.static.soft_penalty = args.soft_penalty
    sim = Simulation(sc)
    rows = []
    t0 = time.perf_counter()
    def hold(s, r):
        rows.append({"time": r.time, "iterations": r.iterations, "increments": r.increments,
                     "predictor_iterations": r.predictor_iterations,
                     "centre_z_mm": 1e3 * s.probe_values()["centre_z"], "tip_z_mm": 1e3 * s.probe_values()["tip_px_z"],
                     "wall_s": round(r.wall_time, 2)})
        print(rows[-1], flush=True)

    result = sim.solve_static(times=HOLDS, on_level=hold)
    wall = time.perf_counter() - t0
    return {"plate": "elastic body" if plate else "friction collider", "converged": bool(result.converged),
            "message": result.message, "wall_s": round(wall, 2), "particles": int(sim.model.n_particles),
            "newton_iterations": int(sum(r["iterations"] for r in rows)), "holds": rows}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--plate-modulus", type=float, default=6.67e5, help="the elastic plate's shear modulus, Pa (default 10 x the robot's)")
    p.add_argument("--plate-thickness", type=float, default=0.002, help="the elastic plate's thickness, m")
    p.add_argument("--max-iterations", type=int, default=40, help="static.max_iterations for both (a peeling level may need more)")
    p.add_argument("--soft-penalty", type=float, default=None, help="static.soft_penalty for both (default: off)")
    args = p.parse_args(argv)
    collider = run(False, args)
    print(f"collider: {collider['wall_s']} s, {collider['newton_iterations']} Newton iterations", flush=True)
    body = run(True, args)
    print(f"elastic plate: {body['wall_s']} s, {body['newton_iterations']} Newton iterations", flush=True)
    result = {"benchmark": "contact_static_cross", **provenance(), "scene": "scenes/cross.toml",
              "max_iterations": args.max_iterations, "soft_penalty": args.soft_penalty,
              "plate_shear_modulus_pa": args.plate_modulus, "plate_thickness_m": args.plate_thickness,
              "ratio": round(body["wall_s"] / collider["wall_s"], 2), "collider": collider, "elastic_plate": body}
    name = f"{result['date'][:10]}-cpu-{result['commit']}-contact-static-cross{'-soft' if args.soft_penalty else ''}.json"
    out = ROOT / "benchmarks" / "results" / name
    out.write_text(json.dumps(result, indent=1))
    print(f"ratio {result['ratio']}x; {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
