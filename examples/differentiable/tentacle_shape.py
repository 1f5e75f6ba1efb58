"""Shape forming of a 2D multi-segment tentacle (Pittiglio et al.): design the segment magnetisations.

1. Forward run of tentacle_2d.toml with a known "true" magnetisation per segment -> its centreline is the target.
2. `magsoro optimize` from the naive design (every segment magnetised along the axis) with --vars magnetisation.
3. The command writes the optimised scene and re-runs it with the normal engine (Simulation).

    python examples/differentiable/tentacle_shape.py [OUT_DIR]
"""

import json
import sys
from pathlib import Path

import numpy as np

from magsoro.cli import main
from magsoro.diff.optimize import Problem

HERE = Path(__file__).resolve().parent
SCENE = HERE / "tentacle_2d.toml"
SEGMENTS = ["seg1", "seg2", "seg3", "seg4"]
# the "true" design (T): an S-shape maker, unknown to the optimiser
TRUE = {"seg1": [0.1, 0.0, 0.0], "seg2": [0.07, 0.07, 0.0], "seg3": [-0.1, 0.0, 0.0], "seg4": [-0.07, -0.07, 0.0]}
N_POINTS = 10


def make_target(out: Path) -> Path:
    spec = {"type": "centreline", "bodies": SEGMENTS, "points": [[0.0, 0.0]] * N_POINTS}
    prob = Problem(SCENE, spec, ["magnetisation"], bodies=SEGMENTS)
    values = np.concatenate([TRUE[b] for b in SEGMENTS])
    state = prob.final_state(values)
    pts = prob.target.centreline(state["x"])
    lines = ['# centreline of tentacle_2d.toml with the "true" magnetisation of tentacle_shape.py, m', 'type = "centreline"',
             f"bodies = {json.dumps(SEGMENTS)}", "points = ["]
    lines += [f"  [{float(p[0])!r}, {float(p[1])!r}]," for p in pts]
    lines.append("]")
    path = out / "target.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/tentacle_shape")
    out.mkdir(parents=True, exist_ok=True)
    target = make_target(out)
    sys.exit(main(["optimize", str(SCENE), "--target", str(target), "--vars", "magnetisation", "--bodies", ",".join(SEGMENTS),
                   "--method", "lbfgs", "--iterations", "60", "--out", str(out)]))
