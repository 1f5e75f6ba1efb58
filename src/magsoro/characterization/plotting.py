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


def plot_force_torque_fit(fit, path: str | Path, magnet_position=(0.0, 0.0, 0.0), title: str | None = None) -> Path:
    """Measured (markers, error bars = std over repetitions) and fitted (lines) force and torque against the
    distance from the magnet centre, one row per sample orientation, like seed 001 Figs 5-6.

    ``fit`` is a :class:`~magsoro.characterization.magnetization.MagnetizationFit`. Force in mN, torque in mN m,
    distance in cm. Returns the path written.
    """
    plt = _pyplot()
    d = fit.data
    orientations = sorted(set(d.orientation.tolist()))
    show_force = fit.n_force > 0
    ncol = 2 if show_force else 1
    fig, axes = plt.subplots(
        len(orientations), ncol, figsize=(5.2 * ncol, 3.4 * len(orientations)), dpi=150, squeeze=False
    )
    dist = np.linalg.norm(d.position - np.asarray(magnet_position, dtype=np.float64), axis=1)
    colors = ("tab:red", "tab:green", "tab:blue")
    for r, o in enumerate(orientations):
        rows = np.flatnonzero(d.orientation == o)
        rows = rows[np.argsort(dist[rows])]
        panels = [("torque [mN m]", d.torque, d.torque_std, fit.model_torque, d.use_torque, "T")]
        if show_force:
            panels.insert(0, ("force [mN]", d.force, d.force_std, fit.model_force, d.use_force, "F"))
        for c, (label, meas, std, model, use, sym) in enumerate(panels):
            ax = axes[r, c]
            x = 100 * dist[rows]
            for k, axis in enumerate("xyz"):
                ok = use[rows]
                ax.errorbar(
                    x[ok], 1e3 * meas[rows[ok], k], yerr=1e3 * std[rows[ok], k], fmt="o", ms=3, color=colors[k],
                    capsize=2, label=f"{sym}{axis} measured",
                )
                ax.plot(x, 1e3 * model[rows, k], "-", color=colors[k], lw=1.2, label=f"{sym}{axis} model")
            ax.set_xlabel("distance from magnet centre [cm]")
            ax.set_ylabel(label)
            ax.set_title(f"orientation {o}", fontsize=9)
            ax.grid(alpha=0.3)
            if r == 0:
                ax.legend(fontsize=6, ncol=2)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
