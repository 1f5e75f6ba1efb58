"""The figure of a convergence study: each quantity against the grid spacing, with the power law fitted to the
finest values and the extrapolated value at dx = 0."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_study(path: Path, estimates: dict, scene: str, feature: str) -> Path:
    """One panel per quantity (at most 6 shown; those zero by symmetry left out): the values (dots), the fitted ``f0 + C dx^p`` through the finest
    two (line, when an order was measured or assumed), ``f0`` at dx = 0 with its band; returns ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    items = [(c, e) for c, e in estimates.items() if e is not None and e.behaviour != "zero"][:6]
    if not items:
        items = [(c, e) for c, e in estimates.items() if e is not None][:6]
    n = len(items)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows), squeeze=False)
    for ax, (name, e) in zip(axes.ravel(), items):
        h = np.asarray(e.h) * 1e3
        f = np.asarray(e.values)
        ax.plot(h, f, "o", color="C0", label="runs")
        if e.order is not None and e.extrapolated is not None:
            C = (f[-1] - e.extrapolated) / h[-1] ** e.order
            hh = np.linspace(0.0, h.max() * 1.05, 100)
            ax.plot(hh, e.extrapolated + C * hh ** e.order, "-", color="C1", lw=1,
                    label=f"f0 + C dx^{e.order:.2f}" + (" (assumed)" if e.assumed_order is not None else ""))
            ax.errorbar([0.0], [e.extrapolated], yerr=[[e.uncertainty or 0.0]], fmt="s", color="C3", capsize=3,
                        label="extrapolated")
        elif e.uncertainty:
            ax.axhspan(e.value - e.uncertainty, e.value + e.uncertainty, color="C2", alpha=0.15,
                       label=f"finest +- band ({e.behaviour})")
        ax.set_xlim(left=0.0)
        ax.set_xlabel("dx (mm)")
        ax.set_ylabel(f"{name} ({feature})")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    fig.suptitle(f"{Path(scene).name}: convergence with dx", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
