"""Hertz contact between two bodies (3D, static solver): an elastic sphere pressed onto a stiff elastic block.

The static solver's contact between bodies (:mod:`magsoro.mpm.newton.body_contact`), checked against Hertz's law
F = 4/3 E* R^(1/2) d^(3/2) with 1/E* = (1 - nu_s^2)/E_s + (1 - nu_b^2)/E_b.

Set-up. A sphere (R = 4 mm, G = 100 kPa, K = 1 MPa: nu = 0.45) has its upper half clamped; the clamp moves down
along a path, pressing the lower half onto a block 100 times stiffer (G = 10 MPa, 2.6 R wide, 3 cells thick, its
bottom clamped), frictionless. R = 10 dx, 2 particles per cell per axis, float64, total form. The static solver
takes the clamp's displacements delta_k = 0.025, 0.05, 0.075 and 0.1 R as its load levels; the force F_k is the
block's force on the sphere (a ``collider_force`` probe between the two bodies).

What the displacement means. Hertz's d is the approach of points far from the contact in two half-spaces; here
the sphere is held a radius away, by its equator. That body is stiffer than Hertz's: the clamp takes the
far-field part of the displacement that a half-space would have. The difference delta_fb(F) = delta(F) - d_H(F)
comes from an independent axisymmetric finite-element model of the same hemisphere held by its flat face
(:meth:`HemisphereFE.pressed <magsoro.validation.hertz.HemisphereFE.pressed>`): delta_fb = -0.36 to -0.34
F / (E* R) for d = 0.025 to 0.1 R, so an exact continuum solution gives F = 1.13 to 1.29 times Hertz's force at
the clamp's displacement.

The discrete sphere's surface is the lattice of its particles, each a ball of half its spacing: its lowest layer
is a flat facet about sqrt(R h) across (h the particle spacing), and first touch is not at delta = 0. As in the
collider case (:mod:`magsoro.validation.hertz`), the contact offset delta_0 is fitted:
delta_k - delta_fb(F_k) = delta_0 + c F_k^(2/3), and each level's local indentation is
d_k = delta_k - delta_fb(F_k) - delta_0. Rows: F_k against Hertz's force at d_k (10 %), and the fitted constant
a = c^(-3/2) against 4/3 E* R^(1/2) (10 %). The comparison without the model's term and without the offset is in
the case's info, for what it would say.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from magsoro.validation.hertz import HemisphereFE, elastic_moduli, hertz_force, hertz_indentation
from magsoro.validation.registry import CaseResult, Context, Row, register

#: the clamp's displacements (units of R) at which the force is read
LEVELS = (0.025, 0.05, 0.075, 0.1)
TOLERANCE = 0.10


@dataclass(frozen=True)
class SphereOnBlock:
    """The sphere and the block (SI). ``cells``: R / dx; moduli (shear, bulk) in Pa."""

    radius: float = 4e-3
    cells: float = 10.0
    sphere: tuple = (1e5, 1e6)
    block: tuple = (1e7, 1e8)
    levels: tuple = LEVELS

    @property
    def dx(self) -> float:
        return self.radius / self.cells

    @property
    def e_star(self) -> float:
        """The pair's contact modulus (Pa)."""
        (nu_s, E_s, _), (nu_b, E_b, _) = elastic_moduli(*self.sphere), elastic_moduli(*self.block)
        return 1.0 / ((1.0 - nu_s**2) / E_s + (1.0 - nu_b**2) / E_b)


def sphere_on_block_scene(setup: SphereOnBlock) -> dict:
    """The scene (dict): the sphere's upper half clamped and moved down to 0.1 R along a path over t in [0, 1],
    the block's bottom clamped, frictionless contact, the static solver's levels at ``setup.levels`` / 0.1."""
    R, dx = setup.radius, setup.dx
    thickness, width, deepest = 3 * dx, 2.6 * R, 0.1 * R

    def material(G, K):
        return {"density": 1000.0, "shear_modulus": G, "bulk_modulus": K}

    return {
        "simulation": {"dim": 3, "dx": dx, "domain_lo": [-2 * R, -2 * R, -1.5 * R], "domain_hi": [2 * R, 2 * R, 3 * R],
                       "duration": 1.0, "precision": "float64", "formulation": "total"},
        "bodies": [{"name": "sphere", "shape": {"type": "sphere", "center": [0, 0, R], "radius": R},
                    "material": material(*setup.sphere)},
                   {"name": "block", "shape": {"type": "box", "center": [0, 0, -thickness / 2], "size": [width, width, thickness]},
                    "material": material(*setup.block)}],
        "clamps": [{"region": {"type": "box", "center": [0, 0, 1.5 * R], "size": [2.2 * R, 2.2 * R, R]}, "body": "sphere",
                    "path": {"times": [0.0, 1.0], "positions": [[0, 0, 0], [0, 0, -deepest]]}},
                   {"region": {"type": "box", "center": [0, 0, -thickness], "size": [1.1 * width, 1.1 * width, 1.5 * dx]},
                    "body": "block"}],
        "contact": {"friction": 0.0},
        "probes": [{"type": "collider_force", "name": "F", "bodies": ["block", "sphere"]}],
        "static": {"times": [round(level / 0.1, 12) for level in setup.levels]},
        "output": {"particles": False},
    }


@dataclass
class Pressed:
    """One level: the clamp's displacement ``approach`` (m), the block's force on the sphere ``force`` (N, up),
    the Newton iterations and the wall time since the start (s)."""

    approach: float
    force: float
    iterations: int
    wall_s: float


def measure(setup: SphereOnBlock, log=None) -> tuple[list[Pressed], int]:
    """Run the static solver through the levels: (the levels, the number of particles). Raises RuntimeError if a
    level does not converge."""
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(sphere_on_block_scene(setup), source="hertz_bodies"))
    out, t0 = [], time.perf_counter()

    def level(s, r):
        out.append(Pressed(0.1 * setup.radius * r.time, float(s.probe_values()["F_Fz"]), int(r.iterations),
                           time.perf_counter() - t0))
        if log is not None:
            log(f"  hertz_bodies delta/R={out[-1].approach / setup.radius:.3f}: F={out[-1].force:.4g} N, "
                f"{r.iterations} Newton iterations, {out[-1].wall_s:.0f} s")

    run = sim.solve_static(on_level=level)
    if not run.converged:
        raise RuntimeError(f"hertz_bodies: the static solver did not converge ({run.message})")
    return out, int(sim.model.n_particles)


def clamped_finite_body_term(force, radius: float, e_star: float, fe: HemisphereFE) -> np.ndarray:
    """delta_fb (m): the clamp displacement of the model hemisphere held by its flat face at which the plane pushes
    back with ``force`` (N, each), less Hertz's d at that force. ``e_star``: the sphere's own E* (the model's plane
    is rigid)."""
    from scipy.optimize import brentq

    out = []
    for F in np.atleast_1d(np.asarray(force, dtype=np.float64)):
        target = F / (e_star * radius**2)
        d_hertz = float(hertz_indentation(target, 1.0, 1.0))
        # the held body is stiffer than a half-space: its displacement lies below Hertz's d
        approach = brentq(lambda a: fe.pressed(a)["reaction"] - target, 0.3 * d_hertz, 1.5 * d_hertz, xtol=1e-9 * d_hertz)
        out.append((approach - d_hertz) * radius)
    return np.array(out)


@dataclass
class BodiesComparison:
    """Levels against Hertz (SI). ``finite_body``: delta_fb(F_k); ``offset``: the fitted delta_0; ``indentation``:
    d_k; ``hertz``: F_H(d_k); ``error``: |F_k - F_H(d_k)| / F_H(d_k); ``constant``, ``hertz_constant``: the fitted
    a and 4/3 E* R^(1/2); ``model_force``: the model hemisphere's force at each clamp displacement (no offset);
    ``bare``: the force over Hertz's at the clamp's displacement (no model term, no offset); ``model``: the FE
    hemisphere used."""

    setup: SphereOnBlock
    levels: list
    finite_body: np.ndarray
    offset: float
    indentation: np.ndarray
    hertz: np.ndarray
    error: np.ndarray
    constant: float
    hertz_constant: float
    model_force: np.ndarray
    bare: np.ndarray
    model: HemisphereFE


def compare(setup: SphereOnBlock, levels: list[Pressed], fe: HemisphereFE | None = None) -> BodiesComparison:
    """Fit the contact offset and Hertz's constant after removing the held hemisphere's far-field term."""
    R, e_star = setup.radius, setup.e_star
    nu_s, _, e_sphere = elastic_moduli(*setup.sphere)
    fe = fe if fe is not None else HemisphereFE(nu_s)
    F = np.array([lv.force for lv in levels])
    delta = np.array([lv.approach for lv in levels])
    fb = clamped_finite_body_term(F, R, e_sphere, fe)
    A = np.stack([np.ones_like(F), F ** (2.0 / 3.0)], axis=1)
    (offset, c), *_ = np.linalg.lstsq(A, delta - fb, rcond=None)
    d = delta - fb - offset
    ref = hertz_force(np.maximum(d, 0.0), R, e_star)
    model = np.array([fe.pressed(a / R)["reaction"] * e_sphere * R**2 for a in delta])
    return BodiesComparison(setup, levels, fb, float(offset), d, ref, np.abs(F - ref) / ref, float(c) ** -1.5,
                            4.0 / 3.0 * e_star * math.sqrt(R), model, F / hertz_force(delta, R, e_star), fe)


def rows_of(comp: BodiesComparison, tolerance: float = TOLERANCE) -> list[Row]:
    """The force of each level against Hertz's at its local indentation (N), and the fitted constant (N/m^1.5)."""
    s = comp.setup
    base = {"R_over_dx": s.cells, "R_m": s.radius, "nu": round(elastic_moduli(*s.sphere)[0], 4)}
    rows = [Row("hertz_bodies", "contact_force_N", {"d_over_R": round(float(d / s.radius), 4), **base}, float(ref), lv.force,
                float(err), tolerance)
            for lv, d, ref, err in zip(comp.levels, comp.indentation, comp.hertz, comp.error)]
    fitted = {"d_over_R": [round(float(d / s.radius), 4) for d in comp.indentation], **base}
    rows.append(Row("hertz_bodies", "hertz_constant_N_m1.5", fitted, comp.hertz_constant, comp.constant,
                    abs(comp.constant - comp.hertz_constant) / comp.hertz_constant, tolerance))
    return rows


def plot_bodies(comp: BodiesComparison, path) -> Path:
    """Force against local indentation d_k / R with Hertz's law, and the force against the clamp's displacement
    (as run and less the fitted offset) with the model hemisphere's (PNG at ``path``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s, R = comp.setup, comp.setup.radius
    F = [lv.force for lv in comp.levels]
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6))
    d = np.linspace(0.0, 1.15 * max(float(comp.indentation.max()), 0.1 * R), 100)
    a.plot(d / R, hertz_force(d, R, s.e_star), "k-", label="Hertz 4/3 E* R^1/2 d^3/2")
    a.plot(comp.indentation / R, F, "o", label=f"MPM, R = {s.cells:g} dx (offset fitted)")
    a.set_xlabel("local indentation d / R")
    a.set_ylabel("contact force, N")
    a.legend(fontsize=8)
    delta = np.array([lv.approach for lv in comp.levels])
    e_sphere = elastic_moduli(*s.sphere)[2]
    line = np.linspace(0.0, 1.05 * float((delta - comp.offset).max()), 16)[1:]
    b.plot(line / R, [comp.model.pressed(v / R)["reaction"] * e_sphere * R**2 for v in line], "k--",
           label="FE hemisphere held by its face")
    b.plot(delta / R, F, "o", label="MPM")
    b.plot((delta - comp.offset) / R, F, "o", mfc="none", label="MPM, less the fitted offset")
    b.set_xlabel("clamp displacement / R")
    b.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


@register("hertz_bodies", "elastic sphere pressed on a stiff elastic block by the static solver with contact between "
          "bodies (3D, R = 10 dx): contact force vs Hertz at d = 0.025-0.1 R, far-field term from an axisymmetric FE "
          "model", quick=False, cost="~3 min")
def hertz_bodies_case(ctx: Context) -> CaseResult:
    setup = SphereOnBlock()
    levels, particles = measure(setup, log=ctx.log)
    comp = compare(setup, levels)
    R, dx = setup.radius, setup.dx
    info = {
        "setup": {"radius_m": R, "cells": setup.cells, "sphere_G_K_pa": list(setup.sphere), "block_G_K_pa": list(setup.block),
                  "levels_over_R": list(setup.levels)},
        "particles": particles,
        "e_star_pa": setup.e_star,
        "fitted_offset_cells": comp.offset / dx,
        "finite_body_over_R": [float(v / R) for v in comp.finite_body],
        "force_n": [lv.force for lv in levels],
        "model_force_n": [float(v) for v in comp.model_force],
        "force_over_hertz_at_clamp_displacement": [float(v) for v in comp.bare],
        "newton_iterations": [lv.iterations for lv in levels],
        "level_wall_s": [round(lv.wall_s, 1) for lv in levels],
    }
    figures = []
    if ctx.out is not None:
        figures.append(plot_bodies(comp, Path(ctx.out) / "hertz_bodies.png"))
    return CaseResult("hertz_bodies", rows_of(comp), figures, info)


__all__ = ["BodiesComparison", "Pressed", "SphereOnBlock", "clamped_finite_body_term", "compare", "measure", "plot_bodies",
           "rows_of", "sphere_on_block_scene", "LEVELS", "TOLERANCE"]
