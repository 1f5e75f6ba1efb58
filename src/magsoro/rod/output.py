"""Files written for a rod equilibrium: the centreline table (CSV) and a two-view picture (PNG)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from magsoro.rod.model import RodSolution

CSV_COLUMNS = ("s", "x", "y", "z", "tx", "ty", "tz")


def write_centreline_csv(solution: RodSolution, path) -> Path:
    """Write columns s, x, y, z (m) and the unit tangent tx, ty, tz (dimensionless) at every output node."""
    path = Path(path)
    table = np.column_stack([solution.s, solution.positions, solution.tangents])
    np.savetxt(path, table, delimiter=",", header=",".join(CSV_COLUMNS), comments="", fmt="%.10e")
    return path


def read_centreline_csv(path) -> dict[str, np.ndarray]:
    """Read a file written by :func:`write_centreline_csv` into {column: array}."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.asarray(data[name]) for name in data.dtype.names}


def plot_centreline(solution: RodSolution, path, title: str | None = None) -> Path:
    """Side (x-z) and top (x-y) views of the centreline in mm, with the clamp and the field direction."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    p = solution.positions * 1e3
    fig, axes = plt.subplots(1, 2, figsize=(9, 4.2))
    b = solution.field
    for ax, (i, j), name in zip(axes, ((0, 2), (0, 1)), ("side view (x-z)", "top view (x-y)")):
        ax.plot(p[:, i], p[:, j], "-", color="tab:blue", lw=2, label="centreline")
        ax.plot(p[0, i], p[0, j], "ks", ms=7, label="clamp")
        ax.plot(p[-1, i], p[-1, j], "o", color="tab:red", ms=5, label="tip")
        bij = np.array([b[i], b[j]])
        if np.linalg.norm(bij) > 0:
            # field direction only (its size is in the title), drawn in points from a fixed corner: the axes
            # have equal data aspect, so a direction in points is the direction in the plane
            d = 30.0 * bij / np.linalg.norm(bij)
            ax.annotate("B", xy=(0.12, 0.15), xycoords="axes fraction", xytext=(d[0], d[1]),
                        textcoords="offset points", color="tab:green", ha="center", va="center",
                        arrowprops=dict(arrowstyle="<-", color="tab:green", lw=1.5))
        ax.set_xlabel("xyz"[i] + " (mm)")
        ax.set_ylabel("xyz"[j] + " (mm)")
        ax.set_title(name)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    fig.suptitle(title or f"rod equilibrium, B = [{b[0] * 1e3:.3g}, {b[1] * 1e3:.3g}, {b[2] * 1e3:.3g}] mT")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
