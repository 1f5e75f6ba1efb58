"""``magsoro show SCENE.toml --out robot.png``: draw a scene's particles before any simulation.

Particles are coloured by body, magnetisation (reference-frame Br) is drawn as arrows on a subsample, clamped
particles are marked, and simple colliders (half-spaces, boxes, spheres, cylinders) are outlined. Works for 2D
and 3D scenes; uses matplotlib's Agg backend, so no display is needed.
"""

from pathlib import Path

import numpy as np

from magsoro.errors import SceneError


def register(sub):
    p = sub.add_parser("show", help="render a scene's particles and magnetisation to a PNG", description="Render the particles of a scene, coloured by body, with magnetisation arrows, clamps and colliders; no simulation is run.")
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("--out", required=True, help="output image (.png)")
    p.add_argument("--size", type=float, default=7.0, help="figure width in inches (default 7)")
    p.add_argument("--dpi", type=int, default=120, help="resolution, dots per inch (default 120)")
    p.add_argument("--arrows", type=int, default=200, help="at most this many magnetisation arrows (default 200)")
    p.add_argument("--max-points", type=int, default=60000, help="draw at most this many particles (default 60000)")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.scene import load_scene
    from magsoro.scene.build import fill_bodies

    if not args.size > 0 or args.dpi <= 0 or args.arrows < 0 or args.max_points <= 0:
        raise SceneError("--size, --dpi and --max-points must be > 0, --arrows >= 0")
    if Path(args.out).suffix.lower() != ".png":
        raise SceneError(f"--out: '{args.out}' must end in .png")
    scene = load_scene(args.scene)
    particles = fill_bodies(scene, args.scene)
    render(scene, particles, args.out, width=args.size, dpi=args.dpi, arrows=args.arrows, max_points=args.max_points)
    n = len(particles.positions)
    vols = ", ".join(f"{r['body']} {r['particles']} particles, {r['filled_volume'] * 1e9:.4g} mm^3 (shape {r['shape_volume'] * 1e9:.4g})" for r in particles.report)
    print(f"{args.out}: {n} particles; {vols}")
    return 0


def _subsample(n, k, seed=0):
    if n <= k:
        return np.arange(n)
    # evenly spaced indices: deterministic pictures for the same scene
    return np.unique(np.linspace(0, n - 1, k).astype(int))


def render(scene, particles, out, width=7.0, dpi=120, arrows=200, max_points=60000):
    """Draw ``particles`` (from :func:`magsoro.scene.build.fill_bodies`) of ``scene`` into the PNG ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dim = scene.simulation.dim
    from magsoro.scene.build import held_particles

    X, Br, body = particles.positions, particles.remanence, particles.body
    clamped = held_particles(scene, particles)  # clamped bodies and [[clamps]] regions, as the engine holds them
    names = particles.body_names
    cmap = plt.get_cmap("tab10")
    scale_mm = 1e3
    shown = _subsample(len(X), max_points)
    br_norm = np.linalg.norm(Br, axis=1)
    magnetic = np.flatnonzero(br_norm > 0)
    arrow_idx = magnetic[_subsample(len(magnetic), arrows)] if arrows else np.zeros(0, dtype=int)
    blo, bhi = X.min(axis=0), X.max(axis=0)
    extent = float(np.max(bhi - blo)) or scene.simulation.dx
    arrow_len = 0.08 * extent  # direction only: |Br| is listed in the legend
    if dim == 2:
        fig, ax = plt.subplots(figsize=(width, width * 0.7))
        for i, name in enumerate(names):
            sel = shown[body[shown] == i]
            label = f"{name} (|Br| max {br_norm[body == i].max() * 1e3:.3g} mT)"
            ax.scatter(X[sel, 0] * scale_mm, X[sel, 1] * scale_mm, s=2, color=cmap(i % 10), label=label, linewidths=0)
        cl = shown[clamped[shown]]
        if len(cl):
            ax.scatter(X[cl, 0] * scale_mm, X[cl, 1] * scale_mm, s=4, color="k", marker="x", label="clamped", linewidths=0.5)
        if len(arrow_idx):
            d = Br[arrow_idx, :2] / br_norm[arrow_idx, None]
            ax.quiver(X[arrow_idx, 0] * scale_mm, X[arrow_idx, 1] * scale_mm, d[:, 0] * arrow_len * scale_mm, d[:, 1] * arrow_len * scale_mm,
                      angles="xy", scale_units="xy", scale=1, color="crimson", width=0.003)
        _colliders_2d(ax, scene, scale_mm)
        pad = 0.15 * extent
        ax.set_xlim((blo[0] - pad) * scale_mm, (bhi[0] + pad) * scale_mm)
        ax.set_ylim((blo[1] - pad) * scale_mm, (bhi[1] + pad) * scale_mm)
        ax.set_aspect("equal")
        if scene.simulation.plane == "axisymmetric":  # the (r, z) section of a body of revolution about y
            ax.axvline(0.0, color="0.5", lw=0.8, ls="-.", label="axis")
            ax.set_xlabel("r (mm)")
            ax.set_ylabel("z (mm), along the axis")
        else:
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("y (mm)")
    else:
        fig = plt.figure(figsize=(width, width * 0.8))
        ax = fig.add_subplot(projection="3d")
        for i, name in enumerate(names):
            sel = shown[body[shown] == i]
            label = f"{name} (|Br| max {br_norm[body == i].max() * 1e3:.3g} mT)"
            ax.scatter(X[sel, 0] * scale_mm, X[sel, 1] * scale_mm, X[sel, 2] * scale_mm, s=1, color=cmap(i % 10), label=label, depthshade=False)
        cl = shown[clamped[shown]]
        if len(cl):
            ax.scatter(X[cl, 0] * scale_mm, X[cl, 1] * scale_mm, X[cl, 2] * scale_mm, s=3, color="k", marker="x", label="clamped")
        if len(arrow_idx):
            d = Br[arrow_idx] / br_norm[arrow_idx, None] * arrow_len * scale_mm
            P = X[arrow_idx] * scale_mm
            ax.quiver(P[:, 0], P[:, 1], P[:, 2], d[:, 0], d[:, 1], d[:, 2], color="crimson", linewidth=0.8, arrow_length_ratio=0.3)
        _colliders_3d(ax, scene, scale_mm, blo, bhi)
        centre, half = 0.5 * (blo + bhi), 0.6 * extent
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
            setter((c - half) * scale_mm, (c + half) * scale_mm)
        try:
            ax.set_box_aspect((1, 1, 1))
        except AttributeError:  # older matplotlib
            pass
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_zlabel("z (mm)")
    title = scene.name or Path(scene.source_path or "scene").stem
    ax.set_title(f"{title}: {len(X)} particles, arrows = Br direction")
    ax.legend(loc="upper left", fontsize=7, markerscale=4, framealpha=0.8)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def _colliders_2d(ax, scene, k):
    import matplotlib.patches as mpatches

    for c in scene.colliders:
        if c.type == "half_space":
            p, n = np.asarray(c.point[:2], dtype=float), np.asarray(c.normal[:2], dtype=float)
            n = n / np.linalg.norm(n)
            t = np.array([-n[1], n[0]])
            L = 1.0  # m: long enough to cross any view
            a, b = p - L * t, p + L * t
            ax.plot([a[0] * k, b[0] * k], [a[1] * k, b[1] * k], color="0.3", lw=1.5)
        elif c.type == "box":
            ctr, size = np.asarray(c.center[:2]), np.asarray(c.size[:2])
            ax.add_patch(mpatches.Rectangle(((ctr - size / 2) * k), size[0] * k, size[1] * k, fill=True, alpha=0.25, color="0.3"))
        elif c.type in ("sphere", "cylinder"):
            ax.add_patch(mpatches.Circle(np.asarray(c.center[:2]) * k, c.radius * k, fill=True, alpha=0.25, color="0.3"))


def _colliders_3d(ax, scene, k, blo, bhi):
    for c in scene.colliders:
        if c.type == "half_space":
            p, n = np.asarray(c.point, dtype=float), np.asarray(c.normal, dtype=float)
            n = n / np.linalg.norm(n)
            helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
            t1 = np.cross(n, helper)
            t1 /= np.linalg.norm(t1)
            t2 = np.cross(n, t1)
            L = 0.6 * float(np.max(bhi - blo))
            centre = p + np.dot(0.5 * (blo + bhi) - p, t1) * t1 + np.dot(0.5 * (blo + bhi) - p, t2) * t2
            s = np.linspace(-L, L, 2)
            S, T = np.meshgrid(s, s)
            P = centre[:, None, None] + t1[:, None, None] * S + t2[:, None, None] * T
            ax.plot_surface(P[0] * k, P[1] * k, P[2] * k, alpha=0.2, color="0.4")
        elif c.type == "sphere":
            u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
            ctr = np.asarray(c.center)
            ax.plot_wireframe((ctr[0] + c.radius * np.cos(u) * np.sin(v)) * k, (ctr[1] + c.radius * np.sin(u) * np.sin(v)) * k,
                              (ctr[2] + c.radius * np.cos(v)) * k, color="0.4", linewidth=0.5)
        elif c.type == "box":
            ctr, h = np.asarray(c.center), 0.5 * np.asarray(c.size)
            for a in range(3):
                for s1 in (-1, 1):
                    for s2 in (-1, 1):
                        e = np.zeros((2, 3))
                        b1, b2 = [i for i in range(3) if i != a]
                        e[:, a] = [-h[a], h[a]]
                        e[:, b1], e[:, b2] = s1 * h[b1], s2 * h[b2]
                        P = (ctr + e) * k
                        ax.plot(P[:, 0], P[:, 1], P[:, 2], color="0.4", lw=0.8)
