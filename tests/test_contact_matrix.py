"""Every combination of the contact options runs and conserves momentum.

Three blocks collide in 2D without gravity, colliders or walls in reach, so the only forces between them are the
contact's. The two-field law corrects the fields of a node in pairs that conserve its momentum (docs/engine.md,
"Contact"), the transfers conserve it too, and damping is off: the total momentum must stay what the initial
velocities gave. Over formulations, self-contact on or off, two or three contact groups, Coulomb friction or
"sticky" and a per-pair override. (A node no particle reached used to crash the step with self-contact on and two
groups: tests/test_self_contact.py.)
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

COMBOS = [c for c in itertools.product(("updated", "total"), (False, True), (2, 3), (0.3, "sticky"), (False, True))
          if not (c[4] and c[3] == "sticky")]


def _scene(formulation, self_contact, groups, friction, pairs):
    bodies = []
    for i in range(groups):
        bodies.append({"name": f"b{i}", "shape": {"type": "rectangle", "center": [-3e-3 + 3e-3 * i, 0.3e-3 * i],
                                                 "size": [2e-3, 2e-3]},
                       "material": {"density": 1000.0 + 500.0 * i, "shear_modulus": 5e4},
                       "velocity": [(1.0, -0.6, -1.5)[i], (0.1, 0.0, -0.2)[i]]})
    contact = {"friction": friction, "self_contact": self_contact}
    if pairs:
        contact["pairs"] = [{"bodies": ["b0", "b1"], "friction": 0.8}]
    return {"name": "contact_matrix",
            "simulation": {"dim": 2, "dx": 5e-4, "particles_per_cell": 2, "domain_lo": [-8e-3, -8e-3],
                           "domain_hi": [8e-3, 8e-3], "duration": 1.5e-3, "damping": 0.0, "formulation": formulation,
                           "precision": "float64"},
            "bodies": bodies, "contact": contact}


@pytest.mark.parametrize("formulation, self_contact, groups, friction, pairs", COMBOS)
def test_contact_options_run_and_conserve_momentum(formulation, self_contact, groups, friction, pairs):
    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    sim = Simulation(parse_scene(_scene(formulation, self_contact, groups, friction, pairs), "contact matrix"))
    mass = sim.model.host["mass"]
    p0 = (mass[:, None] * sim.particles()["v"]).sum(axis=0)
    res = sim.run(1.5e-3)
    assert res.status == "completed", res.message
    v = sim.particles()["v"]
    p1 = (mass[:, None] * v).sum(axis=0)
    scale = (mass[:, None] * np.abs(v)).sum()
    assert np.all(np.isfinite(v))
    # 1e-9 of the momentum's magnitude: float64 round-off over ~600 steps of scatter and gather
    assert np.abs(p1 - p0).max() <= 1e-9 * scale, (p0, p1)
    # the blocks met: the first one (1 m/s towards the second, 1 mm apart) has been slowed
    first = sim.particles()["body"] == 0
    assert (mass[first] * v[first, 0]).sum() < 0.9 * (mass[first] * 1.0).sum()
