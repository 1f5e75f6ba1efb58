"""Figures of the characterisation tools (matplotlib, Agg backend: works headless)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_tensile_fits(data, fits, path: str | Path, title: str | None = None, max_markers: int = 600) -> Path:
    """Stress-strain data with every fitted model, like seed 001 Fig 2. Strain in %, stress in kPa.

    ``data`` is a :class:`~magsoro.characterization.hyperelastic.TensileData` (already cut to the fitted range),
    ``fits`` a {name: ModelFit} dict. Returns the path written.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.6), dpi=150)
    # thin out dense curves so the markers do not hide the model lines
    step = max(1, int(np.ceil(data.strain.size / max_markers)))
    ax.plot(
        100 * data.strain[::step], data.stress[::step] / 1e3, "o", ms=2.5, mfc="none", color="0.55", label="data"
    )
    e = np.linspace(0.0, float(np.max(data.strain)), 300)
    for name, fit in fits.items():
        ax.plot(100 * e, fit.stress(e) / 1e3, lw=1.6, label=f"{name} (MAPE {fit.mape:.1f} %)")
    ax.set_xlabel("engineering strain [%]")
    ax.set_ylabel("nominal stress [kPa]")
    if title:
        ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
