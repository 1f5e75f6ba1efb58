"""The force on a rigid collider (``[[probes]] type = "collider_force"``, Simulation.collider_forces) against two
closed forms (tests/test_collider_force.py runs the same measurements with tighter checks of their parts).

- ``resting_force``: a 4 x 2 mm block (2D plane strain) resting on a friction floor (mu 0.7) under gravity tilted
  25 degrees carries its weight: at rest the floor's force is minus M g, both components (momentum balance).
- ``squeeze``: a 4 x 4 mm layer between a slip floor and a slip plate lowered in two steps and held: the plate's
  force against :func:`plane_strain_force`, the homogeneous plane-strain solution of the engine's Neo-Hookean law
  at the layer's stretch (read from its top and bottom particle rows), in the dynamics of both formulations and
  by the static solver (``--static`` at the two hold times: the plate moved along its path by the load
  increments).
"""

from __future__ import annotations

import math

import numpy as np

from magsoro.validation.registry import CaseResult, Context, Row, register

DX = 2.5e-4  # m: 8 cells through the block, 16 through the layer
G = 2.0e4  # Pa; K = 20 G (the engine's default), nu = 0.475
DEPTH = 1.0e-3  # m
TILT_DEG = 25.0
LAYER_TOP = 0.00415  # m: the plate starts above the 4 mm layer (it touches after the first lowering)
LOWERS = (0.0003, 0.0004)  # m: the plate's two lowered positions below LAYER_TOP
HOLDS = (0.06, 0.11)  # s: the ends of the two holds
TOLERANCE_WEIGHT = 0.005
TOLERANCE_SQUEEZE = 0.05


def _simulation(scene: dict):
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    return Simulation(parse_scene(scene))


def _base(form: str, gravity, hi_y: float, duration: float) -> dict:
    return {"dim": 2, "dx": DX, "particles_per_cell": 2, "domain_lo": [-0.004, -0.001], "domain_hi": [0.004, hi_y],
            "duration": duration, "damping": 300.0, "gravity": list(gravity), "depth": DEPTH, "formulation": form,
            "precision": "float64"}


def block_scene(form: str, tilt_deg: float = TILT_DEG) -> dict:
    """The block on the friction floor, gravity tilted by ``tilt_deg``, a collider_force probe 'floor'."""
    g = 9.81
    gravity = (g * math.sin(math.radians(tilt_deg)), -g * math.cos(math.radians(tilt_deg)))
    return {
        "name": "resting block",
        "simulation": _base(form, gravity, 0.004, 0.06),
        "bodies": [{"name": "block", "shape": {"type": "rectangle", "center": [0.0, 0.001], "size": [0.004, 0.002]},
                    "material": {"density": 1000.0, "shear_modulus": G}}],
        "colliders": [{"type": "half_space", "point": [0.0, 0.0], "normal": [0.0, 1.0], "mode": "friction",
                       "friction": 0.7}],
        "probes": [{"type": "collider_force", "name": "floor", "collider": 0}],
    }


def squeeze_scene(form: str) -> dict:
    """The layer between a slip floor (collider 0) and a slip plate (collider 1) that is lowered to LAYER_TOP -
    LOWERS[k] and held until HOLDS[k]; collider_force probes 'plate' and 'floor'."""
    top, (d1, d2) = LAYER_TOP, LOWERS
    times = [0.0, 0.01, 0.03, HOLDS[0], HOLDS[0] + 0.02, HOLDS[1]]
    heights = [top, top, top - d1, top - d1, top - d2, top - d2]
    return {
        "name": "squeezed layer",
        "simulation": _base(form, (0.0, 0.0), 0.006, HOLDS[1]),
        "bodies": [{"name": "layer", "shape": {"type": "rectangle", "center": [0.0, 0.002], "size": [0.004, 0.004]},
                    "material": {"density": 1000.0, "shear_modulus": G}}],
        "colliders": [
            {"type": "half_space", "point": [0.0, 0.0], "normal": [0.0, 1.0], "mode": "slip"},
            {"type": "half_space", "point": [0.0, top], "normal": [0.0, -1.0], "mode": "slip",
             "path": {"times": times, "positions": [[0.0, y] for y in heights]}},
        ],
        "probes": [{"type": "collider_force", "name": "plate", "collider": 1},
                   {"type": "collider_force", "name": "floor", "collider": 0}],
    }


def plane_strain_force(stretch: float, shear: float, bulk: float, width: float, depth: float) -> float:
    """Compressive force (N) on a layer of the engine's Neo-Hookean law (W = G/2 (J^-2/3 I1 - 3) + K/2 (J - 1)^2)
    stretched by ``stretch`` through its height between frictionless plates: plane strain (lambda_z = 1), the width
    free (lambda_x from sigma_xx = 0), the nominal stress dW/dlambda_y times the reference width and depth. At
    small strain its slope is E / (1 - nu^2) w depth / h; at 5 % compression the secant is 8 % stiffer."""
    from scipy.optimize import brentq

    Gs, K = shear, bulk

    def dW(lx, ly):
        J, I1 = lx * ly, lx * lx + ly * ly + 1.0
        return (Gs / 2 * (J ** (-2 / 3) * 2 * lx - 2 / 3 * J ** (-5 / 3) * ly * I1) + K * (J - 1) * ly,
                Gs / 2 * (J ** (-2 / 3) * 2 * ly - 2 / 3 * J ** (-5 / 3) * lx * I1) + K * (J - 1) * lx)

    lx = brentq(lambda v: dW(v, stretch)[0], 0.5, 2.0)
    return -dW(lx, stretch)[1] * width * depth


def resting_force(form: str, tilt_deg: float = TILT_DEG):
    """(floor force (2,), weight (2,)) in N: the block settled for 40 ms, the force read over the next 20 ms."""
    sim = _simulation(block_scene(form, tilt_deg))
    sim.advance_to(0.04)
    sim.probe_values()
    sim.advance_to(0.06)
    v = sim.probe_values()
    g = np.asarray(sim.scene.simulation.gravity, dtype=np.float64)
    return np.array([v["floor_Fx"], v["floor_Fy"]]), sim.model.host["mass"].sum() * g


def _layer_reading(sim, h0: float) -> dict:
    v = sim.probe_values()
    x = sim.state.x.numpy()
    stretch = float((x[:, 1].max() - x[:, 1].min()) / h0)
    return {"stretch": stretch, "plate": v["plate_Fy"], "floor": v["floor_Fy"], "top": float(x[:, 1].max()),
            "reference": plane_strain_force(stretch, G, 20.0 * G, 0.004, DEPTH)}


def squeeze_dynamic(form: str) -> list[dict]:
    """At the end of each hold (mean over its last 10 ms): the layer's stretch, the plate's and the floor's force
    (N), the reference force at that stretch."""
    sim = _simulation(squeeze_scene(form))
    X = sim.model.host["positions"]
    h0 = float(X[:, 1].max() - X[:, 1].min())
    out = []
    for t_end in HOLDS:
        sim.advance_to(t_end - 0.01)
        sim.probe_values()
        sim.advance_to(t_end)
        out.append(_layer_reading(sim, h0))
    return out


def squeeze_static() -> list[dict]:
    """The same readings from the static solver at the two hold times (each solved from the unloaded layer)."""
    sim = _simulation(squeeze_scene("total"))
    X = sim.model.host["positions"]
    h0 = float(X[:, 1].max() - X[:, 1].min())
    out = []
    for t in HOLDS:
        res = sim.solve_static(levels=[1.0], t=t)
        if not res.converged:
            raise RuntimeError(f"static squeeze at t = {t} s: {res.message}")
        out.append(_layer_reading(sim, h0))
    return out


@register("collider_force", "force on a rigid collider: a resting block's weight, a layer squeezed between slip "
          "plates vs the plane-strain Neo-Hookean law (runs in both forms, --static)", cost="~20 s")
def collider_force_case(ctx: Context) -> CaseResult:
    rows = []
    for form in ("updated", "total"):
        force, weight = resting_force(form)
        err = float(np.linalg.norm(force - weight) / np.linalg.norm(weight))
        rows.append(Row("collider_force", "floor force of a resting block (N; error: the norm of F - M g over M g)",
                        {"form": form, "tilt_deg": TILT_DEG, "mu": 0.7}, float(np.linalg.norm(weight)),
                        float(np.linalg.norm(force)), err, TOLERANCE_WEIGHT))
    runs = [(f"dynamics, {form}", squeeze_dynamic(form)) for form in ("updated", "total")]
    runs.append(("static solver", squeeze_static()))
    for label, readings in runs:
        for k, r in enumerate(readings):
            err = abs(r["plate"] / r["reference"] - 1.0)
            rows.append(Row("collider_force", "plate force on a squeezed layer (N) vs the plane-strain law at its stretch",
                            {"run": label, "lowered_mm": LOWERS[k] * 1e3, "stretch": round(r["stretch"], 5)},
                            r["reference"], r["plate"], err, TOLERANCE_SQUEEZE))
    return CaseResult("collider_force", rows)
