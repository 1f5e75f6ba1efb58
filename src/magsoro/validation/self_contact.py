"""Self-contact: a strip folded onto itself by its own magnetisation in a uniform field, then released.

A free strip (2D plane strain) of length L and thickness t is magnetised along its axis, +x on the left half and
-x on the right half. A uniform field B along +y turns both halves towards it, the left one counter-clockwise
and the right one clockwise, so the strip folds at its middle into a hairpin whose two arms hang side by side
along -y and are pressed onto each other by the magnetic torque (the arms' aligned state needs them to overlap).
The field is ramped up, held, ramped to zero, and the strip is left to unfold under its own elasticity with grid
damping. No gravity; the net force and torque of the uniform field on the strip are zero, so it stays in place.

Acceptance (the engine's self-contact, docs/engine.md "Contact"): particles more than 3 dx apart in the reference
configuration never come closer than half a cell, while the fold really closes (such pairs come within about
1.5-2 cells: the arms touch); with the field off the strip unfolds, i.e. the arms do not stick.

Measures, taken every ``every`` seconds from the particles' current positions x and reference positions X:

* ``far_min``: the smallest current distance |x_i - x_j| over pairs with |X_i - X_j| > ``ref_cells`` dx,
  in cells (a k-d tree on x within ``search_cells`` cells; ``search_cells`` when no such pair is that close);
* ``far_close``: the number of such pairs closer than half a cell;
* ``arm_gap``: the smallest distance between a particle of the left arm and one of the right arm, the arms
  being the parts more than ``arm_offset`` x L from the middle in the reference configuration, in cells;
* ``end_to_end``: the distance between the centroids of the two end regions (last cell of each end) over L.

The control run with ``self_contact = false`` (one velocity field per node, the behaviour without self-contact)
shows that the test can fail: the arms merge into one velocity field, interpenetrate and stay glued.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from magsoro.constants import MU0
from magsoro.validation.registry import CaseResult, Context, Row, register


@dataclass(frozen=True)
class FoldSetup:
    """Geometry (m), material (Pa, kg/m^3, T), loading and numerics of the folding strip.

    ``field_ratio``: the normalised field Br B / (mu0 G) held during the fold. The schedule, in s: the field
    rises linearly over ``ramp_up``, is held for ``hold``, falls linearly to zero over ``ramp_down`` and stays
    off for ``off``. ``damping``: grid damping c (1/s). ``every``: interval of the measurements, s.
    """

    length: float = 30e-3
    thickness: float = 1e-3
    hinge: float = 6e-3
    overfold: float = 30.0
    dx: float = 0.25e-3
    ppc: int = 2
    shear_modulus: float = 1e5
    density: float = 1000.0
    remanence: float = 0.1
    field_ratio: float = 0.1
    ramp_up: float = 0.020
    hold: float = 0.010
    ramp_down: float = 0.005
    off: float = 0.050
    damping: float = 100.0
    friction: float = 0.0
    self_contact: bool = True
    fold_spread: float = 1.5
    precision: str = "float32"
    every: float = 0.5e-3

    @property
    def field(self) -> float:
        """Held field magnitude B, T."""
        return self.field_ratio * MU0 * self.shear_modulus / self.remanence

    @property
    def t_field_off(self) -> float:
        """Time at which the field has returned to zero, s."""
        return self.ramp_up + self.hold + self.ramp_down

    @property
    def duration(self) -> float:
        return self.t_field_off + self.off


def fold_scene(s: FoldSetup) -> dict:
    """Scene dict of the folding strip (2D, centred on the origin, field along +y)."""
    L, t, B, Br = s.length, s.thickness, s.field, s.remanence
    ca, sa = math.cos(math.radians(s.overfold)), math.sin(math.radians(s.overfold))
    t1, t2, t3 = s.ramp_up, s.ramp_up + s.hold, s.t_field_off
    half = 0.6 * L + 10 * s.dx  # the folded arms hang about L/2 below the middle
    return {
        "name": "self_contact_fold",
        "simulation": {"dim": 2, "dx": s.dx, "particles_per_cell": s.ppc, "domain_lo": [-half, -half],
                       "domain_hi": [half, half], "duration": s.duration, "damping": s.damping,
                       "precision": s.precision},
        "bodies": [{
            "name": "strip",
            "shape": {"type": "rectangle", "center": [0.0, 0.0], "size": [L, t]},
            "material": {"density": s.density, "shear_modulus": s.shear_modulus},
            # arms magnetised (cos a, -sin a) and (-cos a, -sin a), an unmagnetised hinge between them
            "magnetization": {"type": "table", "axis": [1.0, 0.0, 0.0], "origin": [0.0, 0.0, 0.0],
                              "positions": [-L, -0.5 * s.hinge, 0.5 * s.hinge],
                              "vectors": [[Br * ca, -Br * sa, 0.0], [0.0, 0.0, 0.0], [-Br * ca, -Br * sa, 0.0]],
                              "interpolation": "step"},
        }],
        "fields": [{"type": "keyframes", "times": [0.0, t1, t2, t3, s.duration],
                    "values": [[0.0, 0.0, 0.0], [0.0, B, 0.0], [0.0, B, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]}],
        "contact": {"friction": s.friction, "self_contact": s.self_contact, "fold_spread": s.fold_spread},
        "output": {"particles": False},
    }


# -- measurements ---------------------------------------------------------------------------------------------
def far_pair_distance(x: np.ndarray, X: np.ndarray, dx: float, ref_cells: float = 3.0,
                      search_cells: float = 3.0, close_cells: float = 0.5) -> tuple[float, int]:
    """Closest approach of particles that were far apart in the reference configuration.

    x, X: (n, dim) current and reference positions, m; dx: grid spacing, m. Over the pairs with
    |X_i - X_j| > ``ref_cells`` dx, returns (the smallest |x_i - x_j| in cells, found within ``search_cells``
    cells, else ``search_cells``; the number of those pairs closer than ``close_cells`` cells).
    """
    from scipy.spatial import cKDTree

    pairs = cKDTree(np.asarray(x, dtype=np.float64)).query_pairs(search_cells * dx, output_type="ndarray")
    if len(pairs) == 0:
        return float(search_cells), 0
    X = np.asarray(X, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    i, j = pairs[:, 0], pairs[:, 1]
    far = np.linalg.norm(X[i] - X[j], axis=1) > ref_cells * dx
    if not np.any(far):
        return float(search_cells), 0
    d = np.linalg.norm(x[i[far]] - x[j[far]], axis=1) / dx
    return float(min(d.min(), search_cells)), int(np.count_nonzero(d < close_cells))


def arm_gap(x: np.ndarray, X: np.ndarray, dx: float, inner: float) -> float:
    """Smallest distance (cells) between the left arm (X_x < -inner) and the right arm (X_x > inner); x, X in m."""
    from scipy.spatial import cKDTree

    left = X[:, 0] < -inner
    right = X[:, 0] > inner
    d, _ = cKDTree(np.asarray(x[right], dtype=np.float64)).query(np.asarray(x[left], dtype=np.float64))
    return float(d.min() / dx)


def end_to_end(x: np.ndarray, X: np.ndarray, dx: float, length: float) -> float:
    """Distance between the centroids of the two end regions (the last cell of each end) over L."""
    a = x[X[:, 0] < -0.5 * length + dx].mean(axis=0)
    b = x[X[:, 0] > 0.5 * length - dx].mean(axis=0)
    return float(np.linalg.norm(b - a) / length)


@dataclass
class FoldTrack:
    """Measures over time of one run (see the module docstring); ``wall_s``: wall time of the run, s."""

    setup: FoldSetup
    t: np.ndarray
    far_min: np.ndarray
    far_close: np.ndarray
    arm_gap: np.ndarray
    end_to_end: np.ndarray
    steps: int = 0
    wall_s: float = 0.0
    status: str = "completed"
    info: dict = field(default_factory=dict)

    def window(self, t0: float, t1: float) -> np.ndarray:
        return (self.t >= t0 - 1e-12) & (self.t <= t1 + 1e-12)

    def summary(self) -> dict:
        """The numbers the checks use: the whole run and the phases (folded: the hold; released: the last
        quarter of the field-off time)."""
        s = self.setup
        hold = self.window(s.ramp_up, s.ramp_up + s.hold)
        end = self.window(s.duration - 0.25 * s.off, s.duration)
        if not (hold.any() and end.any()):  # the run stopped early
            hold = end = np.ones(len(self.t), dtype=bool)
        return {
            "self_contact": s.self_contact,
            "far_min_cells": float(self.far_min.min()),
            "far_min_time_s": float(self.t[int(np.argmin(self.far_min))]),
            "far_close_max": int(self.far_close.max()),
            "far_min_hold_cells": float(self.far_min[hold].min()),
            "arm_gap_hold_cells": float(self.arm_gap[hold].min()),
            "end_to_end_hold": float(self.end_to_end[hold].min()),
            "arm_gap_end_cells": float(self.arm_gap[end].min()),
            "end_to_end_end": float(self.end_to_end[end].min()),
            "steps": self.steps,
            "wall_s": self.wall_s,
            "status": self.status,
        }


def run_fold(setup: FoldSetup, log=None) -> FoldTrack:
    """Run the folding strip and measure every ``setup.every`` s. A run the engine stops (NaN, inverted
    element) ends the track there with ``status`` set to the message."""
    from magsoro.errors import SimulationError
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(fold_scene(setup)))
    X = sim.model.host["positions"][:, :2].astype(np.float64)
    dx, L = setup.dx, setup.length
    inner = 0.5 * setup.hinge + 4 * dx  # the arms: beyond the hinge and its first cells
    rows = []
    status = "completed"

    def measure():
        x = sim.state.x.numpy()[:, :2].astype(np.float64)
        fmin, nclose = far_pair_distance(x, X, dx)
        rows.append((sim.time, fmin, nclose, arm_gap(x, X, dx, inner), end_to_end(x, X, dx, L)))

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
        if log is not None and k % 10 == 0:
            r = rows[-1]
            log(f"  self_contact={setup.self_contact} t={r[0] * 1e3:.1f} ms far_min={r[1]:.3f} close={r[2]} "
                f"arm_gap={r[3]:.2f} end_to_end={r[4]:.3f} ({time.perf_counter() - t0:.0f} s)")
    a = np.array(rows, dtype=np.float64)
    return FoldTrack(setup, a[:, 0], a[:, 1], a[:, 2].astype(int), a[:, 3], a[:, 4], steps=sim.steps,
                     wall_s=time.perf_counter() - t0, status=status,
                     info={"particles": int(len(X)), "dt_min_s": sim.dt_min, "dt_max_s": sim.dt_max})
