"""``magsoro converge``: one scene run at several grid spacings, its probe results tabulated, and their grid-
independent values and order of convergence estimated (:mod:`magsoro.convergence.richardson`).

Each spacing is a complete ``magsoro run`` (with ``--set simulation.dx=...``) in its own folder of the study,
``dx_1`` (the coarsest) to ``dx_N``; the study writes ``converge.csv`` (one row per spacing: its probe values),
``converge.json`` (the estimate of each quantity, the runs and their status) and ``converge.png`` (each quantity
against dx, with the fitted power law and the extrapolated value at dx = 0).
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from magsoro.convergence.richardson import Estimate, estimate
from magsoro.errors import MagsoroError

#: how a quantity is taken from a run's metrics.csv
FEATURES = ("final", "max", "min", "absmax")
#: the study's own files in its folder (beside the runs' folders dx_1 ... dx_N)
STUDY_FILES = ("converge.json", "converge.csv", "converge.png")


class ConvergeError(MagsoroError):
    """A convergence study cannot be set up (bad spacings, an unknown probe, a folder in the way)."""


@dataclass
class RunRow:
    """One spacing of the study: its folder, how the run ended and the quantities it gave."""

    dx: float
    folder: str
    status: str
    wall_time_s: float | None
    message: str = ""
    values: dict = field(default_factory=dict)


def parse_spacings(text: str) -> list[float]:
    """``A,B,C`` (m) as floats, coarse first; each finite, > 0, and different."""
    items = [t.strip() for t in str(text).split(",") if t.strip()]
    try:
        dxs = [float(t) for t in items]
    except ValueError:
        raise ConvergeError(f"--dx {text}: give grid spacings in m separated by commas, e.g. --dx 4e-4,2e-4,1e-4") from None
    if len(dxs) < 2:
        raise ConvergeError(f"--dx {text}: give at least two spacings (three or more to measure the order)")
    bad = [t for t, v in zip(items, dxs) if not (v > 0 and math.isfinite(v))]
    if bad:
        raise ConvergeError(f"--dx {text}: '{bad[0]}' is not a spacing; each must be a finite number > 0 (m)")
    if len({round(v, 15) for v in dxs}) != len(dxs):
        raise ConvergeError(f"--dx {text}: a spacing is given twice")
    return sorted(dxs, reverse=True)


def metric_columns(path: Path) -> tuple[list[str], list[list[float]]]:
    """metrics.csv as (header, rows of floats; NaN for what is not a number)."""
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader, None) or []
        rows = []
        for r in reader:
            row = []
            for v in r:
                try:
                    row.append(float(v))
                except ValueError:
                    row.append(float("nan"))
            rows.append(row)
    return header, rows


def select_columns(header: list[str], probes: list[str], scene: str) -> list[str]:
    """The metrics columns the study follows: every probe column by default; ``probes`` names columns
    (``tip_y``) or probes (``tip``: all its columns). An unknown name is refused, naming those there are."""
    columns = header[1:]
    if not probes:
        return columns
    chosen = []
    for name in probes:
        hit = [c for c in columns if c == name] or [c for c in columns if c.startswith(name + "_")]
        if not hit:
            raise ConvergeError(f"--probe {name}: {scene} has no probe or metrics column of that name; its columns: "
                                f"{', '.join(columns) if columns else 'none (the scene has no [[probes]])'}")
        chosen += [c for c in hit if c not in chosen]
    return chosen


def feature_value(rows: list[list[float]], j: int, feature: str) -> float:
    """One quantity of column ``j``: its last value, or its max, min or largest magnitude over the run."""
    col = [r[j] for r in rows if j < len(r) and math.isfinite(r[j])]
    if not col:
        return float("nan")
    if feature == "final":
        last = rows[-1][j] if j < len(rows[-1]) else float("nan")
        return last
    if feature == "max":
        return max(col)
    if feature == "min":
        return min(col)
    return max(col, key=abs)


def probe_scale(column: str, points: dict) -> float | None:
    """The largest |value| over every run of the columns of ``column``'s probe (``NAME_x``, ``NAME_y``, ``NAME_z``
    share one probe NAME); None for a column of no such group."""
    stem, sep, axis = column.rpartition("_")
    if not sep or axis not in ("x", "y", "z"):
        return None
    values = [abs(v) for c, pts in points.items() if c.rpartition("_")[0] == stem and c.rpartition("_")[2] in ("x", "y", "z")
              for _, v in pts]
    return max(values, default=None)


def run_one(scene: str, dx: float, folder: Path, mode: str, args) -> RunRow:
    """``magsoro run SCENE --set simulation.dx=DX --out FOLDER`` in this process (quiet); its status from run.json."""
    from magsoro.commands.run import run as run_command
    from magsoro.io.outdir import read_run_info

    run_args = argparse.Namespace(
        scene=scene, out=str(folder), overwrite=folder.exists(), device=args.device, duration=args.duration,
        preview=args.preview, equilibrium=False, static=(mode == "static"), from_run=None, quiet=True,
        verbose=False, allow_large=args.allow_large, overrides=[f"simulation.dx={dx!r}"] + list(args.overrides or []),
    )
    t0 = time.perf_counter()
    try:
        run_command(run_args)
    except MagsoroError as exc:  # the scene refused at this spacing: that spacing's result, not the study's end
        return RunRow(dx, folder.name, "failed", time.perf_counter() - t0, str(exc).splitlines()[0])
    info = read_run_info(folder) or {}
    wall = info.get("wall_time_total")
    return RunRow(dx, folder.name, info.get("status", "failed"), wall if isinstance(wall, (int, float)) else None,
                  "" if info.get("status") == "completed" else str(info.get("message", "")))


def prepare_study_dir(out: Path, resume: bool) -> None:
    """A new or empty folder, or (``resume``) one holding an earlier study of this command."""
    if out.exists() and not out.is_dir():
        raise ConvergeError(f"--out: {out} is a file, not a folder; name a new or empty folder")
    if out.is_dir() and any(out.iterdir()):
        if not (out / "converge.json").is_file() and not any((out / f"dx_{i}").is_dir() for i in (1, 2)):
            raise ConvergeError(f"--out: {out} is not empty and holds no convergence study; name a new or empty folder")
        if not resume:
            raise ConvergeError(f"--out: {out} holds a convergence study; add --resume to reuse its completed runs "
                                f"(the spacings and the mode must be the same), or name a new folder")
    out.mkdir(parents=True, exist_ok=True)


def reusable(folder: Path, dx: float, static: bool) -> dict | None:
    """run.json of ``folder`` when it holds a completed run of this spacing and mode (for --resume), else None."""
    from magsoro.io.outdir import read_run_info

    info = read_run_info(folder)
    if not info or info.get("status") != "completed":
        return None
    got = ((info.get("scene") or {}).get("simulation") or {}).get("dx")
    same = (isinstance(got, (int, float)) and math.isclose(float(got), dx, rel_tol=1e-12)
            and bool(info.get("static")) == static)
    return info if same else None


def study(args) -> int:
    """The ``magsoro converge`` command (see :func:`magsoro.commands.converge.register`)."""
    from magsoro.io.files import atomic_write_json
    from magsoro.scene import load_scene

    dxs = parse_spacings(args.dx)
    mode = "static" if args.static else None
    scene = load_scene(args.scene, preview=args.preview, overrides=args.overrides)  # the scene is valid before any run
    if mode is None:
        mode = "implicit" if scene.simulation.integrator == "implicit" else "explicit"
    if args.order is not None and not (args.order > 0 and math.isfinite(args.order)):
        raise ConvergeError(f"--order: must be a finite number > 0, got {args.order}")
    out = Path(args.out)
    prepare_study_dir(out, args.resume)
    say = (lambda text: None) if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    say(f"magsoro converge: {args.scene} at {len(dxs)} spacings ({', '.join(f'{d:g}' for d in dxs)} m), "
        f"{mode}{' (--static)' if mode == 'static' else ''}; results in {out}")
    rows: list[RunRow] = []
    columns: list[str] | None = None
    for i, dx in enumerate(dxs, start=1):
        folder = out / f"dx_{i}"
        info = reusable(folder, dx, mode == "static") if args.resume else None
        if info is not None:
            row = RunRow(dx, folder.name, "completed", info.get("wall_time_total"), "reused (--resume)")
        else:
            say(f"[{i}/{len(dxs)}] dx = {dx:g} m ...")
            row = run_one(args.scene, dx, folder, mode, args)
        if row.status == "completed":
            try:
                header, data = metric_columns(folder / "metrics.csv")
            except (OSError, UnicodeDecodeError, csv.Error) as exc:
                row.status, row.message = "failed", f"its metrics.csv cannot be read ({exc})"
            else:
                if columns is None:
                    columns = select_columns(header, args.probe, args.scene)
                for c in columns:
                    row.values[c] = (feature_value(data, header.index(c), args.feature) if c in header and data
                                     else float("nan"))
        rows.append(row)
        wall = f", {row.wall_time_s:.1f} s" if isinstance(row.wall_time_s, (int, float)) else ""
        shown = ", ".join(f"{c} {v:.6g}" for c, v in row.values.items())
        say(f"[{i}/{len(dxs)}] dx = {dx:g} m: {row.status}{wall}" + (f": {row.message}" if row.message and row.status != "completed" else "")
            + (f"; {shown}" if shown else ""))
    done = [r for r in rows if r.status == "completed"]
    estimates: dict[str, Estimate | None] = {}
    points = {c: [(r.dx, r.values.get(c)) for r in done
                  if isinstance(r.values.get(c), float) and math.isfinite(r.values[c])] for c in columns or []}
    for c, pts in points.items():
        estimates[c] = (estimate([p[0] for p in pts], [p[1] for p in pts], order=args.order,
                                 scale=probe_scale(c, points)) if len(pts) >= 2 else None)
    _write_csv(out / "converge.csv", rows, columns or [])
    figure = None
    if estimates and any(e is not None for e in estimates.values()):
        from magsoro.convergence.plot import plot_study

        figure = plot_study(out / "converge.png", estimates, args.scene, args.feature)
    failed = [r for r in rows if r.status != "completed"]
    summary = {
        "scene": str(args.scene), "mode": mode, "feature": args.feature, "assumed_order": args.order,
        "overrides": list(args.overrides or []), "preview": bool(args.preview),
        "status": "completed" if not failed else "incomplete",
        "runs": [{"dx": r.dx, "folder": r.folder, "status": r.status, "wall_time_s": r.wall_time_s, "message": r.message,
                  "values": r.values} for r in rows],
        "estimates": {c: (e.as_dict() if e is not None else None) for c, e in estimates.items()},
        "figure": figure.name if figure is not None else None,
        "method": "Richardson extrapolation from the finest three spacings (Celik et al. 2008); uncertainty: "
                  "grid convergence index with safety factor 1.25 (Roache 1994), or half the finest three's spread "
                  "when they oscillate",
    }
    atomic_write_json(out / "converge.json", summary)
    _print_table(rows, estimates)
    if failed:
        why = "; ".join(f"dx {r.dx:g}: {r.status}" + (f" ({r.message})" if r.message else "") for r in failed)
        print(f"magsoro converge: {len(failed)} of {len(rows)} runs did not complete: {why}; the estimates use the "
              f"others ({out / 'converge.json'})", file=sys.stderr)
        return 1
    return 0


def _write_csv(path: Path, rows: list[RunRow], columns: list[str]) -> None:
    from magsoro.io.files import atomic_write_text

    lines = [",".join(["dx", "status", "wall_time_s"] + columns)]
    for r in rows:
        vals = [f"{r.values[c]:.17g}" if c in r.values else "" for c in columns]
        wall = f"{r.wall_time_s:.3f}" if isinstance(r.wall_time_s, (int, float)) else ""
        lines.append(",".join([f"{r.dx:.17g}", r.status, wall] + vals))
    atomic_write_text(path, "\n".join(lines) + "\n")


def _print_table(rows: list[RunRow], estimates: dict) -> None:
    """The table of values per spacing and each column's estimate, on stdout (also with --quiet)."""
    cols = list(estimates)
    if not cols:
        print("no probe values to compare (the scene's [[probes]], or --probe)")
        return
    width = max(12, *(len(c) for c in cols))
    print("dx (m)".ljust(12) + "".join(c.rjust(width + 2) for c in cols))
    for r in rows:
        vals = "".join((f"{r.values[c]:.7g}" if c in r.values else r.status).rjust(width + 2) for c in cols)
        print(f"{r.dx:<12.5g}{vals}")
    for c, e in estimates.items():
        print(f"{c}: {e.summary() if e is not None else 'fewer than two completed runs'}")
