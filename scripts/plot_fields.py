"""Plot each field source along a line (docs/fields_*.png), with Magpylib as the reference where it applies.

    python scripts/plot_fields.py          # writes docs/fields_cylinder.png, _cuboid.png, _coils.png, _magpylib.png
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from magsoro.fields import (  # noqa: E402
    CuboidMagnet,
    CurrentLoop,
    CylinderMagnet,
    Dipole,
    HelmholtzPair,
    MagpylibSource,
    MaxwellPair,
)

try:
    import magpylib as mp
except ImportError:  # the plots still show our sources, without reference markers
    mp = None

MT = 1e3  # tesla -> millitesla


def plot_cylinder(out: Path):
    """Seed 001's N52 magnet (D = L = 101.6 mm, Br = 1.48 T): exact, multipole n = 17 and dipole, on the axis
    and across it, with the error of each model relative to the exact one."""
    D = L = 0.1016
    exact = CylinderMagnet(D, L, 1.48)
    multi = CylinderMagnet(D, L, 1.48, model="multipole", order=17)
    dip = Dipole(exact.moment())
    rb = exact.bounding_radius
    s = np.linspace(1.05 * rb, 5 * rb, 300)
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for col, (direction, label) in enumerate((((0, 0, 1), "on the axis (z)"), ((1, 0, 0), "in the mid-plane (x)"))):
        pts = np.outer(s, direction)
        be = np.linalg.norm(exact.B(pts), axis=1)
        ax = axes[0, col]
        ax.semilogy(s / rb, be * MT, "k-", label="exact (Derby-Olbert)")
        ax.semilogy(s / rb, np.linalg.norm(multi.B(pts), axis=1) * MT, "C0--", label="multipole n = 17")
        ax.semilogy(s / rb, np.linalg.norm(dip.B(pts), axis=1) * MT, "C1:", label="dipole (n = 1)")
        if mp is not None:
            ref = mp.magnet.Cylinder(dimension=(D, L), polarization=(0, 0, 1.48))
            sel = slice(0, None, 25)
            ax.semilogy(s[sel] / rb, np.linalg.norm(mp.getB(ref, pts[sel]), axis=1) * MT, "ko", mfc="none", label="Magpylib")
        ax.set_title(f"|B| {label}")
        ax.set_ylabel("|B| [mT]")
        ax.legend(fontsize=8)
        ax = axes[1, col]
        for model, style, name in ((multi, "C0--", "multipole n = 17"), (dip, "C1:", "dipole")):
            e = np.linalg.norm(model.B(pts) - exact.B(pts), axis=1) / be
            ax.semilogy(s / rb, np.maximum(e, 1e-16), style, label=name)
        ax.axvline(1.5, color="grey", lw=0.8)
        ax.set_xlabel("distance from centre [bounding-sphere radii]")
        ax.set_ylabel("relative error vs exact")
        ax.legend(fontsize=8)
    fig.suptitle("CylinderMagnet: D = L = 101.6 mm, Br = 1.48 T (seed 001)")
    fig.tight_layout()
    fig.savefig(out / "fields_cylinder.png", dpi=110)
    plt.close(fig)


def plot_cuboid(out: Path):
    """A 10 x 10 x 5 mm block, polarisation (0.3, 0, 1.2) T, along a line passing over it at 8 mm height."""
    dims = (0.01, 0.01, 0.005)
    J = (0.3, 0.0, 1.2)
    cub = CuboidMagnet(dims, J)
    x = np.linspace(-0.03, 0.03, 400)
    pts = np.stack([x, np.full_like(x, 0.002), np.full_like(x, 0.008)], axis=1)
    B = cub.B(pts)
    G = cub.grad_B(pts)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for i, c in enumerate("xyz"):
        axes[0].plot(x * 1e3, B[:, i] * MT, f"C{i}-", label=f"B{c}")
    if mp is not None:
        ref = mp.magnet.Cuboid(dimension=dims, polarization=J)
        sel = slice(0, None, 20)
        Bm = mp.getB(ref, pts[sel])
        for i in range(3):
            axes[0].plot(x[sel] * 1e3, Bm[:, i] * MT, f"C{i}o", mfc="none")
        axes[0].plot([], [], "ko", mfc="none", label="Magpylib")
    axes[0].set_xlabel("x [mm]  (y = 2 mm, z = 8 mm)")
    axes[0].set_ylabel("B [mT]")
    axes[0].legend()
    axes[0].set_title("CuboidMagnet field")
    for i, c in enumerate("xyz"):
        axes[1].plot(x * 1e3, G[:, 2, i], f"C{i}-", label=f"dBz/d{c}")
    axes[1].set_xlabel("x [mm]")
    axes[1].set_ylabel("grad B [T/m]")
    axes[1].legend()
    axes[1].set_title("gradient row of Bz")
    fig.tight_layout()
    fig.savefig(out / "fields_cuboid.png", dpi=110)
    plt.close(fig)


def plot_coils(out: Path):
    """Single loop, Helmholtz and Maxwell pairs (radius 0.1 m, 100 turns, 2 A) along their common axis."""
    a, I, N = 0.1, 2.0, 100
    z = np.linspace(-0.2, 0.2, 400)
    pts = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)
    loop = CurrentLoop(a, I, turns=N)
    hh = HelmholtzPair(a, I, turns=N)
    mx = MaxwellPair(a, I, turns=N)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    axes[0].plot(z * 1e3, loop.B(pts)[:, 2] * MT, "C0-", label="CurrentLoop")
    axes[0].plot(z * 1e3, hh.B(pts)[:, 2] * MT, "C1-", label="HelmholtzPair")
    axes[0].plot(z * 1e3, mx.B(pts)[:, 2] * MT, "C2-", label="MaxwellPair")
    axes[0].axhline(hh.center_field() * MT, color="C1", lw=0.6, ls=":")
    axes[0].set_xlabel("z on the axis [mm]")
    axes[0].set_ylabel("Bz [mT]")
    axes[0].legend()
    axes[0].set_title("axial field")
    axes[1].plot(z * 1e3, hh.grad_B(pts)[:, 2, 2], "C1-", label="Helmholtz dBz/dz")
    axes[1].plot(z * 1e3, mx.grad_B(pts)[:, 2, 2], "C2-", label="Maxwell dBz/dz")
    axes[1].axhline(mx.center_gradient(), color="C2", lw=0.6, ls=":")
    axes[1].set_xlabel("z on the axis [mm]")
    axes[1].set_ylabel("dBz/dz [T/m]")
    axes[1].legend()
    axes[1].set_title("axial gradient")
    fig.suptitle("coils: radius 0.1 m, 100 turns, 2 A")
    fig.tight_layout()
    fig.savefig(out / "fields_coils.png", dpi=110)
    plt.close(fig)


def plot_magpylib(out: Path):
    """MagpylibSource interpolating a magnet assembly: interpolant vs direct Magpylib along a line."""
    if mp is None:
        return
    coll = mp.Collection(
        mp.magnet.Cylinder(dimension=(0.02, 0.02), polarization=(0, 0, 1.3), position=(0, 0, -0.04)),
        mp.magnet.Cuboid(dimension=(0.01, 0.01, 0.01), polarization=(1.2, 0, 0), position=(0.04, 0.0, -0.03)),
    )
    bounds = ((-0.02, -0.02, 0.0), (0.03, 0.02, 0.03))
    src = MagpylibSource(coll, bounds, spacing=0.0025)
    x = np.linspace(-0.02, 0.03, 500)
    pts = np.stack([x, np.full_like(x, 0.003), np.full_like(x, 0.004)], axis=1)
    B = src.B(pts)
    Bm = mp.getB(coll, pts)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for i, c in enumerate("xyz"):
        axes[0].plot(x * 1e3, B[:, i] * MT, f"C{i}-", label=f"B{c} interpolated")
        axes[0].plot(x[::25] * 1e3, Bm[::25, i] * MT, f"C{i}o", mfc="none")
    axes[0].plot([], [], "ko", mfc="none", label="Magpylib direct")
    axes[0].set_xlabel("x [mm]  (y = 3 mm, z = 4 mm)")
    axes[0].set_ylabel("B [mT]")
    axes[0].legend(fontsize=8)
    axes[0].set_title("MagpylibSource, 2.5 mm lattice")
    err = np.linalg.norm(B - Bm, axis=1) / np.linalg.norm(Bm, axis=1)
    axes[1].semilogy(x * 1e3, err, "k-")
    axes[1].set_xlabel("x [mm]")
    axes[1].set_ylabel("relative error of B")
    axes[1].set_title("interpolation error (nodes are exact)")
    fig.tight_layout()
    fig.savefig(out / "fields_magpylib.png", dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"), help="output folder (default docs/)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for plot in (plot_cylinder, plot_cuboid, plot_coils, plot_magpylib):
        plot(out)
        print(f"wrote {plot.__name__.replace('plot_', 'fields_')}.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
