"""Self-contact: a strip folded onto itself by its own magnetisation in a uniform field, then released.

Scene (2D plane strain, no gravity, no clamp): a free strip, L = 30 mm long and t = 1 mm thick, dx = 0.25 mm at 2
particles per cell (8 particle layers through the thickness, 1920 particles), G = 100 kPa, K = 20 G,
1000 kg/m^3, float32. The middle 3 mm (the hinge) is unmagnetised; over the next 1 mm either side |Br| rises
linearly to 0.1 T, and the arms beyond carry Br at 20 degrees past the axis: (cos a, -sin a) on the left,
(-cos a, -sin a) on the right (a = 20 deg). A uniform field B along +y turns the left arm counter-clockwise and
the right arm clockwise, so the strip folds at the hinge into a hairpin with both arms hanging along -y. Aligned
with B, each arm would lean 20 degrees past the vertical towards the other: the arms cross in the field's
preferred shape, so the fold closes until the arms' inner faces (the reference bottom face of the strip) press
onto each other over their last few millimetres. The field rises linearly to Br B/(mu0 G) = 0.2 over 20 ms, is
held 10 ms, falls to zero over 5 ms and stays off for 50 ms; grid damping 100 1/s; frictionless self-contact.
The net force and torque of the uniform field on the strip are zero, so it stays in place.

Acceptance (docs/engine.md, "Contact": ``[contact] self_contact = true``): particles more than 3 dx apart in
the reference configuration never come closer than half a cell, while the fold really closes (such pairs come
within 1.5 cells: the arms touch); with the field off the strip unfolds, i.e. the arms do not stick.

Measures, every ``every`` = 0.1 ms (about 50 steps), from the current positions x and the reference positions X:

* ``far_min``: the smallest |x_i - x_j| over pairs with |X_i - X_j| > ``ref_cells`` = 3 dx, in cells (a k-d tree
  on x within ``search_cells`` = 3 cells; 3 when no such pair is that close). Undeformed it is exactly 3;
* ``far_close``: the number of those pairs closer than half a cell. The contact only removes the layers'
  approach velocity and has no penalty pushing an overlap back out, so an overlap would outlast the 50 steps
  between two measurements;
* ``arm_gap``: the smallest distance between the left arm and the right arm (reference |X_x| beyond the hinge,
  the taper and 4 more cells), in cells;
* ``end_to_end``: the distance between the centroids of the two end regions (the last cell of each end) over L;
* ``stretch``: the largest current distance between reference lattice neighbours (diagonals included), in cells:
  0.71 at rest; above 1.5 the strip has come apart (MPM's numerical fracture), which would make the unfold check
  meaningless.

Controls, same scene: ``self_contact = false`` (one velocity field per node) and ``formulation = "total"`` (the
total-Lagrangian form, which has no contact at all: the arms pass through each other). The second shows that the
measure catches interpenetration.

Measured (float32, two-core CPU, engine of commit 2024bcf):

* self-contact: ``far_min`` 0.91 cells at the first impact (7.9 ms), 1.13 cells at least during the hold, no pair
  under half a cell at any time; end-to-end 0.04 L folded, 0.97 L over the last 12.5 ms; largest neighbour
  distance 1.16 cells; 40.5k steps, 42 s;
* one velocity field: the arms stop 1.6-1.9 cells apart (no interpenetration: the shared field stops them earlier
  than the contact does) and the strip unfolds as well (0.97 L): with the arms touching only near their ends, the
  shared field's adhesion does not hold the fold, so this scene does not show the sticking of one field; 23 s;
* total Lagrangian (no contact): ``far_min`` 0.0002 cells, up to 352 pairs under half a cell; 23 s.

Limits seen while designing it: a step in Br between hinge and arm (``taper = 0``) concentrates the magnetic
traction at the step and stretches the outer surface there to 1.43 cells between neighbours (a permanent 1.0
after release) at the same field; at Br B/(mu0 G) = 0.4 the hinge's outer surface tears (with the taper too; the
self-contact run tears at 23-25 ms, no node near the tear is split into two layers, and the one-field run reaches
1.9 cells without tearing), after which the strip cannot unfold. A strip meant to close into a loop (Br turning
along it) does not get there in a uniform field: where the turning passes 180 degrees the initial torque has
the wrong sign, and the ends fold into tight hooks that tear with or without self-contact.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magsoro.constants import MU0
from magsoro.validation.registry import CaseResult, Context, Row, register

#: Acceptance bounds, in cells: the closest approach allowed of reference-far pairs, and the approach that counts
#: as touching (fields' centroids within the contact range of 1.5 cells, docs/engine.md "Contact").
MIN_CELLS = 0.5
TOUCH_CELLS = 1.5
#: End-to-end distance over L that counts as unfolded, at the end of the field-off phase.
UNFOLDED = 0.9
#: Largest neighbour distance (cells) of a strip in one piece.
TORN_CELLS = 1.5


@dataclass(frozen=True)
class FoldSetup:
    """Geometry (m), material (Pa, kg/m^3, T), loading and numerics of the folding strip.

    ``hinge``: length of the unmagnetised middle section, m; ``taper``: length over which Br rises linearly from
    zero to the arm's value either side of it, m (0: a step); ``overfold``: angle (degrees) by which each arm's
    magnetisation is turned so that, aligned with B, the arms lean towards each other past the vertical.
    ``field_ratio``: the normalised field Br B / (mu0 G) held during the fold. Schedule, in s: the field rises
    linearly over ``ramp_up``, is held for ``hold``, falls linearly to zero over ``ramp_down`` and stays off for
    ``off``. ``damping``: grid damping c, 1/s. ``friction``, ``self_contact``, ``fold_spread``: the [contact]
    keys; ``formulation``, ``precision``: the [simulation] keys. ``every``: interval of the measurements, s.
    """

    length: float = 30e-3
    thickness: float = 1e-3
    hinge: float = 3e-3
    taper: float = 1e-3
    overfold: float = 20.0
    dx: float = 0.25e-3
    ppc: int = 2
    shear_modulus: float = 1e5
    density: float = 1000.0
    remanence: float = 0.1
    field_ratio: float = 0.2
    ramp_up: float = 0.020
    hold: float = 0.010
    ramp_down: float = 0.005
    off: float = 0.050
    damping: float = 100.0
    friction: float = 0.0
    self_contact: bool = True
    fold_spread: float = 1.5
    formulation: str = "updated"
    precision: str = "float32"
    every: float = 0.1e-3

    @property
    def field(self) -> float:
        """Held field magnitude B, T."""
        return self.field_ratio * MU0 * self.shear_modulus / self.remanence

    @property
    def t_field_off(self) -> float:
        """Time at which the field is back to zero, s."""
        return self.ramp_up + self.hold + self.ramp_down

    @property
    def duration(self) -> float:
        return self.t_field_off + self.off

    @property
    def arm_inner(self) -> float:
        """Reference distance from the middle (m) beyond which the strip counts as an arm (``arm_gap``)."""
        return 0.5 * self.hinge + self.taper + 4 * self.dx


def _magnetization(s: FoldSetup) -> dict:
    """Br along the strip: the arms' vectors, zero on the hinge, linear in between over ``taper``."""
    L, Br, h, w = s.length, s.remanence, 0.5 * s.hinge, s.taper
    ca, sa = math.cos(math.radians(s.overfold)), math.sin(math.radians(s.overfold))
    left, zero, right = [Br * ca, -Br * sa, 0.0], [0.0, 0.0, 0.0], [-Br * ca, -Br * sa, 0.0]
    if w <= 0:
        return {"type": "table", "axis": [1.0, 0.0, 0.0], "origin": [0.0, 0.0, 0.0],
                "positions": [-L, -h, h], "vectors": [left, zero, right], "interpolation": "step"}
    return {"type": "table", "axis": [1.0, 0.0, 0.0], "origin": [0.0, 0.0, 0.0],
            "positions": [-L, -h - w, -h, h, h + w, L], "vectors": [left, left, zero, zero, right, right],
            "interpolation": "linear"}


def fold_scene(s: FoldSetup) -> dict:
    """Scene dict of the folding strip (2D, centred on the origin, field along +y)."""
    L, t, B, Br = s.length, s.thickness, s.field, s.remanence
    t1, t2, t3 = s.ramp_up, s.ramp_up + s.hold, s.t_field_off
    half = 0.6 * L + 10 * s.dx  # the arms hang about L/2 below the middle; the unfolded strip spans L
    return {
        "name": "self_contact_fold",
        "simulation": {"dim": 2, "dx": s.dx, "particles_per_cell": s.ppc, "domain_lo": [-half, -half],
                       "domain_hi": [half, half], "duration": s.duration, "damping": s.damping,
                       "precision": s.precision, "formulation": s.formulation},
        "bodies": [{
            "name": "strip",
            "shape": {"type": "rectangle", "center": [0.0, 0.0], "size": [L, t]},
            "material": {"density": s.density, "shear_modulus": s.shear_modulus},
            "magnetization": _magnetization(s),
        }],
        "fields": [{"type": "keyframes", "times": [0.0, t1, t2, t3, s.duration],
                    "values": [[0.0, 0.0, 0.0], [0.0, B, 0.0], [0.0, B, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]}],
        "contact": {"friction": s.friction, "self_contact": s.self_contact, "fold_spread": s.fold_spread},
        "output": {"particles": False},
    }


# -- measurements ---------------------------------------------------------------------------------------------
def far_pair_distance(x: np.ndarray, X: np.ndarray, dx: float, ref_cells: float = 3.0,
                      search_cells: float = 3.0, close_cells: float = MIN_CELLS) -> tuple[float, int]:
    """Closest approach of particles that were far apart in the reference configuration.

    x, X: (n, dim) current and reference positions, m; dx: grid spacing, m. Over the pairs with
    |X_i - X_j| > ``ref_cells`` dx: (the smallest |x_i - x_j| in cells, looked for within ``search_cells`` cells,
    ``search_cells`` when none is that close; the number of those pairs closer than ``close_cells`` cells).
    """
    from scipy.spatial import cKDTree

    x = np.asarray(x, dtype=np.float64)
    X = np.asarray(X, dtype=np.float64)
    pairs = cKDTree(x).query_pairs(search_cells * dx, output_type="ndarray")
    if len(pairs) == 0:
        return float(search_cells), 0
    i, j = pairs[:, 0], pairs[:, 1]
    far = np.linalg.norm(X[i] - X[j], axis=1) > ref_cells * dx
    if not np.any(far):
        return float(search_cells), 0
    d = np.linalg.norm(x[i[far]] - x[j[far]], axis=1) / dx
    return float(min(d.min(), search_cells)), int(np.count_nonzero(d < close_cells))


def arm_gap(x: np.ndarray, X: np.ndarray, dx: float, inner: float) -> float:
    """Smallest distance (cells) between the left arm (X_x < -inner) and the right arm (X_x > inner); x, X, m."""
    from scipy.spatial import cKDTree

    left = X[:, 0] < -inner
    right = X[:, 0] > inner
    d, _ = cKDTree(np.asarray(x[right], dtype=np.float64)).query(np.asarray(x[left], dtype=np.float64))
    return float(d.min() / dx)


def end_to_end(x: np.ndarray, X: np.ndarray, dx: float, length: float) -> float:
    """Distance between the centroids of the two end regions (the last cell of each end) over ``length``.
    The strip is the one of :func:`fold_scene`: along x, centred on x = 0 in the reference configuration."""
    a = x[X[:, 0] < -0.5 * length + dx].mean(axis=0)
    b = x[X[:, 0] > 0.5 * length - dx].mean(axis=0)
    return float(np.linalg.norm(b - a) / length)


def neighbour_pairs(X: np.ndarray, spacing: float) -> np.ndarray:
    """(k, 2) index pairs of reference lattice neighbours (particle spacing ``spacing``, diagonals included)."""
    from scipy.spatial import cKDTree

    return cKDTree(np.asarray(X, dtype=np.float64)).query_pairs(1.5 * spacing, output_type="ndarray")


def largest_stretch(x: np.ndarray, pairs: np.ndarray, dx: float) -> float:
    """Largest current distance (cells) between the reference neighbours ``pairs``."""
    x = np.asarray(x, dtype=np.float64)
    return float(np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1).max() / dx)


@dataclass
class FoldTrack:
    """Measures over time of one run (see the module docstring); ``wall_s``: wall time of the run, s."""

    setup: FoldSetup
    t: np.ndarray
    far_min: np.ndarray
    far_close: np.ndarray
    arm_gap: np.ndarray
    end_to_end: np.ndarray
    stretch: np.ndarray
    steps: int = 0
    wall_s: float = 0.0
    status: str = "completed"
    info: dict = field(default_factory=dict)

    def window(self, t0: float, t1: float) -> np.ndarray:
        return (self.t >= t0 - 1e-12) & (self.t <= t1 + 1e-12)

    def summary(self) -> dict:
        """The numbers the checks use, over the whole run and its phases: folded (the hold) and released (the
        last quarter of the field-off time). Cells for distances, L for ``end_to_end``."""
        s = self.setup
        hold = self.window(s.ramp_up, s.ramp_up + s.hold)
        end = self.window(s.duration - 0.25 * s.off, s.duration)
        if not (hold.any() and end.any()):  # the run stopped early: judge what there is
            hold = end = np.ones(len(self.t), dtype=bool)
        k = int(np.argmin(self.far_min))
        return {
            "self_contact": s.self_contact,
            "formulation": s.formulation,
            "field_ratio": s.field_ratio,
            "far_min_cells": float(self.far_min[k]),
            "far_min_time_s": float(self.t[k]),
            "far_close_max": int(self.far_close.max()),
            "far_min_hold_cells": float(self.far_min[hold].min()),
            "arm_gap_hold_cells": float(self.arm_gap[hold].min()),
            "end_to_end_hold": float(self.end_to_end[hold].max()),
            "arm_gap_end_cells": float(self.arm_gap[end].min()),
            "end_to_end_end": float(self.end_to_end[end].min()),
            "stretch_max_cells": float(self.stretch.max()),
            "steps": self.steps,
            "wall_s": round(self.wall_s, 1),
            "status": self.status,
        }


def run_fold(setup: FoldSetup, log=None) -> FoldTrack:
    """Run the folding strip and measure every ``setup.every`` s. A run the engine stops (NaN, inverted
    element) ends the track there, with the engine's message in ``status``."""
    from magsoro.errors import SimulationError
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(fold_scene(setup)))
    dim = sim.model.dim
    X = sim.model.host["positions"][:, :dim].astype(np.float64)
    dx, L = setup.dx, setup.length
    neighbours = neighbour_pairs(X, dx / setup.ppc)
    rows = []
    status = "completed"

    def measure():
        x = sim.state.x.numpy()[:, :dim].astype(np.float64)
        fmin, nclose = far_pair_distance(x, X, dx)
        rows.append((sim.time, fmin, nclose, arm_gap(x, X, dx, setup.arm_inner), end_to_end(x, X, dx, L),
                     largest_stretch(x, neighbours, dx)))

    t0 = time.perf_counter()
    measure()
    n_out = int(round(setup.duration / setup.every))
    for k in range(1, n_out + 1):
        try:
            sim.advance_to(min(setup.duration, k * setup.every))
        except SimulationError as exc:  # the engine's stop on NaN / det F <= 0: keep what was measured
            status = f"stopped at t = {sim.time:.4g} s: {exc}"
            break
        measure()
        if log is not None and k % max(1, int(round(5e-3 / setup.every))) == 0:  # every 5 ms
            r = rows[-1]
            log(f"  self_contact={setup.self_contact} {setup.formulation} t={r[0] * 1e3:.1f} ms far_min={r[1]:.3f} "
                f"close={r[2]} arm_gap={r[3]:.2f} end_to_end={r[4]:.3f} stretch={r[5]:.2f} "
                f"({time.perf_counter() - t0:.0f} s)")
    a = np.array(rows, dtype=np.float64)
    return FoldTrack(setup, a[:, 0], a[:, 1], a[:, 2].astype(int), a[:, 3], a[:, 4], a[:, 5], steps=sim.steps,
                     wall_s=time.perf_counter() - t0, status=status,
                     info={"particles": int(len(X)), "dt_min_s": sim.dt_min, "dt_max_s": sim.dt_max})


def acceptance_failures(track: FoldTrack) -> list[str]:
    """What the self-contact run fails of the acceptance (empty when it passes), each with its numbers."""
    s = track.summary()
    fails = []
    if s["status"] != "completed":
        fails.append(f"run {s['status']}")
    if s["far_close_max"] > 0 or s["far_min_cells"] < MIN_CELLS:
        fails.append(f"reference-far pairs came {s['far_min_cells']:.3f} cells close at t = "
                     f"{s['far_min_time_s'] * 1e3:.1f} ms ({s['far_close_max']} pairs under {MIN_CELLS})")
    if s["far_min_hold_cells"] > TOUCH_CELLS or s["end_to_end_hold"] > 0.1:
        fails.append(f"no fold: closest far pair {s['far_min_hold_cells']:.2f} cells, end-to-end "
                     f"{s['end_to_end_hold']:.3f} L during the hold")
    if s["end_to_end_end"] < UNFOLDED:
        fails.append(f"did not unfold: end-to-end {s['end_to_end_end']:.3f} L at the end (>= {UNFOLDED} asked)")
    if s["stretch_max_cells"] > TORN_CELLS:
        fails.append(f"the strip came apart: neighbours {s['stretch_max_cells']:.2f} cells apart")
    return fails


def plot_tracks(tracks: dict, path: Path) -> Path:
    """Closest reference-far pair and end-to-end distance against time for each labelled track."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for label, tr in tracks.items():
        a.plot(tr.t * 1e3, tr.far_min, label=label)
        b.plot(tr.t * 1e3, tr.end_to_end, label=label)
    s = next(iter(tracks.values())).setup
    for ax in (a, b):
        for tt in (s.ramp_up, s.ramp_up + s.hold, s.t_field_off):
            ax.axvline(tt * 1e3, color="0.7", lw=0.8)
    a.axhline(MIN_CELLS, color="r", lw=0.8, ls="--")
    a.set_ylabel("closest pair > 3 dx apart in X (cells)")
    b.set_ylabel("end-to-end / L")
    b.set_xlabel("t (ms)")
    a.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


@register("self_contact", "strip folded onto itself by its field (2D): reference-far particles stay half a cell "
          "apart, and it unfolds when the field is off; controls without self-contact", quick=False, cost="~3 min")
def self_contact(ctx: Context) -> CaseResult:
    setup = FoldSetup()
    on = run_fold(setup, log=ctx.log)
    single = run_fold(FoldSetup(self_contact=False), log=ctx.log)
    total = run_fold(FoldSetup(self_contact=False, formulation="total"), log=ctx.log)
    s, s1, s2 = on.summary(), single.summary(), total.summary()
    inputs = {"field_ratio": setup.field_ratio, "dx_m": setup.dx, "L_over_t": setup.length / setup.thickness,
              "friction": setup.friction}
    rows = [
        # lower bound: error is the shortfall below it (cells), tolerance 0
        Row("self_contact", "closest_far_pair_cells", inputs, MIN_CELLS, s["far_min_cells"],
            max(0.0, MIN_CELLS - s["far_min_cells"]), 0.0),
        # upper bound: the arms touch while the field holds the fold
        Row("self_contact", "closest_far_pair_hold_cells", inputs, TOUCH_CELLS, s["far_min_hold_cells"],
            max(0.0, s["far_min_hold_cells"] - TOUCH_CELLS), 0.0),
        Row("self_contact", "end_to_end_released_over_L", inputs, 1.0, s["end_to_end_end"],
            1.0 - s["end_to_end_end"], 1.0 - UNFOLDED),
        Row("self_contact", "largest_neighbour_distance_cells", inputs, TORN_CELLS, s["stretch_max_cells"],
            max(0.0, s["stretch_max_cells"] - TORN_CELLS), 0.0),
        # control: without any contact (total Lagrangian) the measure must see the arms pass through each other
        Row("self_contact", "control_no_contact_closest_far_pair_cells", {**inputs, "formulation": "total"},
            MIN_CELLS, s2["far_min_cells"], max(0.0, s2["far_min_cells"] - MIN_CELLS), 0.0),
    ]
    figures = []
    if ctx.out is not None:
        figures.append(plot_tracks({"self_contact": on, "one field": single, "no contact (total)": total},
                                   Path(ctx.out) / "self_contact.png"))
    return CaseResult("self_contact", rows, figures,
                      info={"self_contact": s, "one_field": s1, "total_lagrangian": s2, **on.info})
