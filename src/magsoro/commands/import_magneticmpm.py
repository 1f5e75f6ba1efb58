"""``magsoro import-magneticmpm ROBOT.yaml --out SCENE.toml``: convert a robot file of the magneticMPM prototype
(YAML: name, n_segments, remenance, segments with mesh, magnetisation_vector, density, shear_modulus, fixed;
meshes under meshes/ beside it) into a magsoro scene with one ``[[robot.parts]]`` per segment (docs/import.md)."""

import argparse
import sys
from pathlib import Path

from magsoro.errors import MagsoroError


def _floor(text: str):
    if text in ("auto", "none", "lowest"):
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected auto, none, lowest or a height in m, got {text!r}") from None


def register(sub):
    p = sub.add_parser(
        "import-magneticmpm",
        help="convert a magneticMPM robot file (YAML + meshes) into a scene",
        description=(
            "Convert a robot file of the magneticMPM prototype (YAML with name, n_segments, remenance, segments: "
            "mesh, magnetisation_vector, density, shear_modulus, fixed; meshes in meshes/ beside it) into a magsoro "
            "scene: one [[robot.parts]] per segment with its mesh, a Neo-Hookean material, the remanence "
            "remenance x magnetisation_vector (T) and clamped = true for fixed segments. Assumed units: mesh "
            "lengths in mm (--scale), remenance in T, density in kg/m^3, shear_modulus in Pa. The grid spacing is "
            "set from the thinnest segment, the domain from the meshes' bounds. The scene is then filled as a run "
            "would and the particle volume of each part compared with its mesh's. Exit status 2 for a file that "
            "cannot be imported (unknown key, missing mesh, bad value), with one line naming the file and key."
        ),
    )
    p.add_argument("robot", help="robot file (YAML)")
    p.add_argument("--out", required=True, help="scene file to write (.toml); mesh paths in it are relative to it")
    p.add_argument("--scale", type=float, default=1e-3,
                   help="metres per mesh-file unit (default 1e-3: the prototype's meshes are in mm)")
    p.add_argument("--cells-across", type=float, default=3.0,
                   help="grid cells across the thinnest segment; dx = its thickness / this (default 3)")
    p.add_argument("--particles-per-cell", type=int, default=2, choices=(1, 2, 3, 4),
                   help="particles per cell along each axis (default 2)")
    p.add_argument("--floor", type=_floor, default="auto",
                   help="auto (a floor at the robot's lowest point unless a segment is fixed), none, lowest, "
                        "or a height z in m (default auto)")
    p.add_argument("--gravity", type=float, default=9.81, help="gravity along -z, m/s^2 (0: none; default 9.81)")
    p.add_argument("--duration", type=float, default=0.1, help="simulated time written to the scene, s (default 0.1)")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.add_argument("--no-check", action="store_true", help="skip filling the scene to compare particle and mesh volumes")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.scene.magneticmpm import convert, fill_report, read_robot

    out = Path(args.out)
    if out.suffix.lower() != ".toml":
        raise MagsoroError(f"--out: '{out}' must end in .toml")
    if out.exists() and not args.overwrite:
        raise MagsoroError(f"--out: '{out}' exists; give --overwrite to replace it")
    if not args.duration > 0 or args.gravity < 0:
        raise MagsoroError("--duration must be > 0 s and --gravity >= 0 m/s^2")
    robot = read_robot(args.robot)
    imported = convert(robot, out, scale=args.scale, cells_across=args.cells_across,
                       particles_per_cell=args.particles_per_cell, floor=args.floor, gravity=args.gravity,
                       duration=args.duration)
    for w in imported.warnings:
        print(f"magsoro import-magneticmpm: warning: {w}", file=sys.stderr)
    made = not out.parent.exists()
    out.parent.mkdir(parents=True, exist_ok=True)  # the scene's relative mesh paths go through it
    try:
        report = None if args.no_check else fill_report(imported.text, out)  # validates before writing
    except BaseException:
        if made:
            out.parent.rmdir()
        raise
    out.write_text(imported.text, encoding="utf-8")
    sim = imported.scene["simulation"]
    floor = "none" if imported.floor is None else f"z = {imported.floor:g} m"
    print(f"{out}: {len(robot.segments)} parts from {args.robot} (scale {args.scale:g} m per mesh unit), "
          f"dx = {sim['dx']:g} m ({args.cells_across:g} cells across the thinnest segment, {imported.thinnest * 1e3:.4g} mm), "
          f"floor {floor}, gravity {args.gravity:g} m/s^2")
    if report is not None:
        print(f"{'part':<12} {'particles':>9} {'mesh mm^3':>11} {'filled mm^3':>11} {'error':>7}  Br (T)")
        worst = 0.0
        for row, part, vol in zip(report, imported.scene["robot"]["parts"], imported.mesh_volumes):
            err = row["filled_volume"] / vol - 1.0
            worst = max(worst, abs(err))
            br = ", ".join(f"{c:.4g}" for c in part["magnetization"])
            print(f"{row['body']:<12} {row['particles']:>9} {vol * 1e9:>11.5g} {row['filled_volume'] * 1e9:>11.5g} "
                  f"{100 * err:>6.2f}%  [{br}]" + ("  clamped" if part.get("clamped") else ""))
        if worst > 0.05:
            print(f"magsoro import-magneticmpm: warning: a part's particle volume differs from its mesh's by "
                  f"{100 * worst:.1f} %; raise --cells-across for a finer grid", file=sys.stderr)
    return 0
