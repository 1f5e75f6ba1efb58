"""The engine stays easy to change: small kernel signatures, a short step (issue "Engine 2.0")."""

import inspect

import pytest
import warp as wp

from magsoro.mpm.kernels import make_kernels
from magsoro.mpm.solver import Solver

MAX_KERNEL_ARGS = 12
MAX_STEP_LINES = 40


@pytest.mark.parametrize("contact", [False, True])
def test_no_kernel_takes_more_than_twelve_arguments(contact):
    k = make_kernels(3, wp.float32, contact)
    kernels = {name: obj for name, obj in k.items() if isinstance(obj, wp.Kernel)}
    assert {"p2g", "p2g_scatter", "grid_update", "g2p", "remap_scatter", "remap_F", "contact_scan"} <= set(kernels)
    counts = {name: len(kern.adj.args) for name, kern in kernels.items()}
    assert max(counts.values()) <= MAX_KERNEL_ARGS, counts


def test_solver_step_is_a_short_list_of_phases():
    lines = [ln for ln in inspect.getsource(Solver.step).splitlines() if ln.strip()]
    assert len(lines) <= MAX_STEP_LINES, len(lines)
