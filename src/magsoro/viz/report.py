"""Self-contained HTML reports of a run or a sweep (``magsoro report DIR``).

One file, no network: the data is embedded as JSON (particle positions as base64 of 16-bit integers quantised
over the bounding box of the run), and the page's small plotting and 3D-viewer code is inlined
(:mod:`magsoro.viz.report_assets`). The page writes ``<div id="status">ok: N curves, viewer ready</div>``
when everything has rendered, or ``error: ...`` otherwise, so a headless browser can check it.
"""

from __future__ import annotations

import base64
import csv
import html
import json
import math
import time
from pathlib import Path

import numpy as np

from magsoro._version import __version__
from magsoro.config_errors import short_repr
from magsoro.errors import MagsoroError
from magsoro.io.files import atomic_write_text


class ReportError(MagsoroError):
    """The directory is not a run or a sweep, or its files cannot be read."""


# Viewer size limits: enough frames for a smooth slider and enough particles to see the shape, while keeping
# a report of a 10^5-particle run around a megabyte or two.
MAX_FRAMES = 60
MAX_PARTICLES = 4000
MAX_SWEEP_CURVES = 200  # runs overlaid per probe column in a sweep report
# metrics.csv rows embedded per run (more are decimated evenly, first and last kept, and the page says so): a
# 3-million-row file made a 187 MB page; a curve of 10,000 points is finer than a screen
MAX_METRIC_ROWS = 10_000
MAX_SWEEP_CURVE_ROWS = 1_000  # per run in a sweep's overlaid curves (up to MAX_SWEEP_CURVES of them)


# ---------------------------------------------------------------------------------------------------- reading
def _finite_or_none(v):
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def read_metrics(run_dir, max_rows: int = MAX_METRIC_ROWS) -> tuple[list[str], list[list[float | None]], int]:
    """metrics.csv as (columns, column-major values with None for non-finite, rows in the file). Above ``max_rows``
    rows every k-th is kept (and the last), read as a stream: the file's size does not set the memory used."""
    path = Path(run_dir) / "metrics.csv"
    if not path.is_file():
        return [], [], 0
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            total = max(sum(1 for _ in fh) - 1, 0)
            fh.seek(0)
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                return [], [], 0
            stride = metrics_stride(total, max_rows)
            rows, last = [], None
            for i, r in enumerate(reader):
                if i % stride == 0:
                    rows.append(r)
                last = (i, r)
            if last is not None and last[0] % stride:
                rows.append(last[1])
    except UnicodeDecodeError as exc:
        raise ReportError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start}); is it a metrics.csv of magsoro?") from None
    except csv.Error as exc:
        raise ReportError(f"{path}: not a readable CSV file ({exc})") from None
    cols = [[_finite_or_none(r[j]) if j < len(r) else None for r in rows] for j in range(len(header))]
    return header, cols, total


def metrics_stride(total: int, max_rows: int) -> int:
    """Every how many rows of ``total`` are kept so that they and the last row are at most ``max_rows``."""
    return 1 if total <= max_rows else -(-total // max(max_rows - 1, 1))


def _expect(info: dict, key: str, kind: type, path, what: str) -> None:
    """ReportError naming the file and the key when ``info[key]`` is present (not None) but not a ``kind``."""
    value = info.get(key)
    if value is not None and not isinstance(value, kind):
        raise ReportError(f"{path}: '{key}' should be {what}, got {type(value).__name__} {short_repr(value)}; "
                          f"the file was not written by magsoro, or was edited")


def _check_run_info(info: dict, path) -> None:
    """The types of the run.json entries the report reads (a hand-edited or foreign file: one line, not a
    TypeError)."""
    for key, kind, what in (("scene", dict, "a table"), ("notes", list, "a list of texts"), ("sweep", dict, "a table"),
                            ("bodies", list, "a list of tables"), ("dt", dict, "a table")):
        _expect(info, key, kind, path, what)
    _expect(info.get("scene") or {}, "probes", list, path, "a list of tables (scene.probes)")
    _expect(info.get("sweep") or {}, "params", dict, path, "a table (sweep.params)")


def _check_sweep_plan(plan, path) -> None:
    """The types of the sweep.json entries the report reads: params [{key, values}], runs [{index, name, params}]
    with every swept key."""
    if not isinstance(plan, dict):
        raise ReportError(f"{path}: not a sweep.json of magsoro (a JSON object is expected)")
    for key in ("params", "runs"):
        if not isinstance(plan.get(key), list):
            raise ReportError(f"{path}: '{key}' should be a list, got {short_repr(plan.get(key))}; the file was not "
                              f"written by magsoro, or was edited")
    for i, p in enumerate(plan["params"]):
        if not (isinstance(p, dict) and isinstance(p.get("key"), str) and isinstance(p.get("values"), list)):
            raise ReportError(f"{path}: params[{i}] should be a table with 'key' (text) and 'values' (a list)")
    keys = [p["key"] for p in plan["params"]]
    for i, r in enumerate(plan["runs"]):
        ok = (isinstance(r, dict) and isinstance(r.get("name"), str) and r["name"] not in ("", ".", "..")
              and "/" not in r["name"] and "\\" not in r["name"] and isinstance(r.get("params"), dict))
        if not ok:
            raise ReportError(f"{path}: runs[{i}] should be a table with 'name' (a folder name) and 'params' (a table)")
        missing = [k for k in keys if k not in r["params"]]
        if missing:
            raise ReportError(f"{path}: runs[{i}].params lacks the swept key '{missing[0]}'")


def read_frames(run_dir) -> list[tuple[float, Path]]:
    """(time, file) of every particle frame listed in particles.pvd."""
    import xml.etree.ElementTree as ET

    pvd = Path(run_dir) / "particles.pvd"
    if not pvd.is_file():
        return []
    try:
        root = ET.parse(pvd).getroot()
    except ET.ParseError as exc:
        raise ReportError(f"{pvd}: not a readable .pvd file ({exc})") from None
    out = []
    for ds in root.iter("DataSet"):
        f = Path(run_dir) / ds.get("file", "")
        if f.is_file():
            out.append((float(ds.get("timestep", "nan")), f))
    return out


def _pick(n: int, limit: int) -> np.ndarray:
    """At most ``limit`` indices spread evenly over range(n), first and last included."""
    if n <= limit:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, limit)).astype(int))


def _scene_uniform_field(scene: dict) -> list[float] | None:
    """The sum of the scene echo's constant ``uniform`` fields (T), or None when it has none."""
    total, found = np.zeros(3), False
    fields = scene.get("fields")
    for f in fields if isinstance(fields, list) else []:
        B = f.get("B") if isinstance(f, dict) and f.get("type") == "uniform" else None
        if isinstance(B, list) and 2 <= len(B) <= 3 and all(_is_num(v) for v in B):
            total[: len(B)] += B
            found = True
    return total.tolist() if found and np.any(total) else None


def default_view(positions: np.ndarray, dim: int, magnetisation=None, scene: dict | None = None) -> dict:
    """The viewer's first camera (:func:`magsoro.viz.camera.bend_view`): looking at the plane the bodies bend in,
    found from how they moved over the frames (``positions``: frames x particles x 3), their magnetisation in the
    first frame and the scene's uniform field and gravity (run.json's scene). 2D runs: down z."""
    from magsoro.viz.camera import bend_view, motion_direction

    scene = scene if isinstance(scene, dict) else {}
    sim = scene.get("simulation") if isinstance(scene.get("simulation"), dict) else {}
    gravity = sim.get("gravity")
    if not (isinstance(gravity, list) and len(gravity) == 3 and all(_is_num(v) for v in gravity) and any(gravity)):
        gravity = None
    pts = np.asarray(positions, dtype=np.float64)
    first = pts[0][np.isfinite(pts[0]).all(axis=1)]
    m = None
    if magnetisation is not None:
        m = np.asarray(magnetisation, dtype=np.float64).reshape(-1, 3)
        m = m if np.any(np.isfinite(m) & (m != 0)) else None
    return bend_view(first, dim, m, _scene_uniform_field(scene), gravity, motion=motion_direction(pts))


def viewer_data(run_dir, max_frames: int = MAX_FRAMES, max_particles: int = MAX_PARTICLES, dim: int | None = None,
                scene: dict | None = None) -> dict | None:
    """Particle frames for the 3D viewer: a fixed subset of particles, positions quantised to uint16 per axis, and
    the first camera (:func:`default_view`; ``dim`` and ``scene`` from run.json)."""
    from magsoro.io.vtk import read_vtp

    frames = read_frames(run_dir)
    if not frames:
        return None
    chosen = [frames[k] for k in _pick(len(frames), max_frames)]
    pts0, data0 = read_vtp(chosen[0][1])
    n_all = len(pts0)
    # a random but reproducible subset keeps every region of the body represented, unlike a stride
    rng = np.random.default_rng(0)
    keep = np.sort(rng.choice(n_all, size=max_particles, replace=False)) if n_all > max_particles else np.arange(n_all)
    positions, jacobians, times = [], [], []
    for t, f in chosen:
        pts, data = read_vtp(f)
        if len(pts) != n_all:
            raise ReportError(f"{f}: {len(pts)} particles, but the first frame has {n_all}")
        positions.append(np.asarray(pts, dtype=np.float64)[keep])
        jacobians.append(np.asarray(data.get("J", np.ones(n_all)), dtype=np.float64)[keep])
        times.append(t)
    pos = np.stack(positions)  # frames x n x 3
    finite = np.isfinite(pos).all(axis=2)
    lo = np.where(finite[..., None], pos, np.inf).min(axis=(0, 1))
    hi = np.where(finite[..., None], pos, -np.inf).max(axis=(0, 1))
    lo = np.where(np.isfinite(lo), lo, 0.0)
    hi = np.where(np.isfinite(hi), hi, 0.0)
    span = np.maximum(hi - lo, 1e-12)
    q = np.clip(np.round((np.nan_to_num(pos, nan=0.0) - lo) / span * 65535), 0, 65535).astype("<u2")
    J = np.stack(jacobians)
    Jf = J[np.isfinite(J)]
    j_lo, j_hi = (float(Jf.min()), float(Jf.max())) if Jf.size else (1.0, 1.0)
    # a symmetric range about J = 1 keeps white at 'no volume change'
    half = max(abs(j_lo - 1.0), abs(j_hi - 1.0), 1e-6)
    j_lo, j_hi = 1.0 - half, 1.0 + half
    jq = np.clip(np.round((np.nan_to_num(J, nan=1.0) - j_lo) / (j_hi - j_lo) * 255), 0, 255).astype(np.uint8)
    body = np.asarray(data0.get("body", np.zeros(n_all)), dtype=np.int64)[keep]
    flat_z = bool(span[2] <= 1e-11)
    if dim not in (2, 3):
        dim = 2 if flat_z else 3
    m0 = data0.get("magnetization_direction")
    view = default_view(pos, dim, None if m0 is None else np.asarray(m0)[keep], scene)
    return {
        "n": int(len(keep)),
        "n_total": int(n_all),
        "frames": len(chosen),
        "frames_total": len(frames),
        "times": [float(t) for t in times],
        "lo": lo.tolist(),
        "span": span.tolist(),
        "flat_z": flat_z,
        "dim": int(dim),
        "view": view,
        "pos": base64.b64encode(q.tobytes()).decode("ascii"),
        "body": base64.b64encode(np.clip(body, 0, 255).astype(np.uint8).tobytes()).decode("ascii"),
        "J": base64.b64encode(jq.tobytes()).decode("ascii"),
        "J_range": [j_lo, j_hi],
    }


def _probe_groups(columns: list[str], scene: dict) -> list[tuple[str, list[str]]]:
    """Metrics columns grouped by probe (tip_x, tip_y -> 'tip'), in file order; unknown columns alone."""
    names = [p.get("name") for p in scene.get("probes", []) if isinstance(p, dict) and p.get("name")]
    groups: dict[str, list[str]] = {}
    for c in columns:
        owner = next((n for n in sorted(names, key=len, reverse=True) if c.startswith(n + "_")), c)
        groups.setdefault(owner, []).append(c)
    return list(groups.items())


def _series(name: str, x: list, y: list) -> dict | None:
    pts = [(a, b) for a, b in zip(x, y) if a is not None and b is not None]
    if not pts:
        return None
    return {"name": name, "x": [a for a, _ in pts], "y": [b for _, b in pts]}


def _fmt(v) -> str:
    """Fact text: numbers to 6 significant digits, the rest as JSON or as is."""
    if isinstance(v, float):
        return f"{v:.6g}"
    return v if isinstance(v, str) else json.dumps(v)


def _flatten(obj, prefix: str = "") -> list[tuple[str, str]]:
    """Scene echo as (dotted key, value text) rows; list entries by name when they have one (sweep paths)."""
    rows = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            rows.extend(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(obj, list) and obj and all(isinstance(e, dict) for e in obj):
        for i, e in enumerate(obj):
            label = e.get("name") if isinstance(e.get("name"), str) else str(i)
            rows.extend(_flatten(e, f"{prefix}.{label}"))
    else:
        rows.append((prefix, json.dumps(obj, separators=(", ", ": ")) if not isinstance(obj, str) else obj))
    return rows


# ------------------------------------------------------------------------------------------- page content
def run_content(run_dir, max_frames: int = MAX_FRAMES, max_particles: int = MAX_PARTICLES) -> dict:
    run_dir = Path(run_dir)
    try:
        info = json.loads((run_dir / "run.json").read_text())
    except (OSError, ValueError) as exc:
        raise ReportError(f"{run_dir / 'run.json'}: cannot read ({exc})") from None
    if not isinstance(info, dict):
        raise ReportError(f"{run_dir / 'run.json'}: not a run.json of magsoro (a JSON object is expected)")
    _check_run_info(info, run_dir / "run.json")
    from magsoro.io.outdir import run_state

    state, why = run_state(info)
    scene = info.get("scene") or {}
    columns, values, n_rows = read_metrics(run_dir)
    charts = []
    # a dynamic run's rows are times; a --static run's are field levels ('level') or times along the paths
    static = info.get("static") if isinstance(info.get("static"), dict) else None
    if columns and columns[0] in ("time", "level"):
        t = values[0]
        xlabel = "field level (fraction of the scene's field)" if columns[0] == "level" else "time (s)"
        units = _probe_units(scene)
        for probe, cols in _probe_groups(columns[1:], scene):
            series = [s for c in cols if (s := _series(c, t, values[columns.index(c)])) is not None]
            if series:
                charts.append({"title": f"probe {probe}", "xlabel": xlabel, "ylabel": units.get(probe, "position (m)"),
                               "series": series})
    facts = [
        ("status", state if not why or state != "stale" else f"stale: {why}"),
        ("message", info.get("message", "")),
        ("steps", info.get("steps")),
        ("simulated time (s)", info.get("time")),
        ("wall time (s)", info.get("wall_time_total", info.get("wall_time"))),
        ("steps per second", info.get("steps_per_second")),
        ("time step (s)", info.get("dt")),
        ("particles", info.get("n_particles")),
        ("dimension", info.get("dim")),
        ("device", f"{info.get('device', '?')} ({info.get('device_name', '?')})"),
        ("precision", info.get("precision")),
        ("magsoro / warp", f"{info.get('magsoro_version', '?')} / {info.get('warp_version', '?')}"),
        ("machine", info.get("machine")),
        ("started / finished", f"{info.get('started', '?')} / {info.get('finished', '?')}"),
    ]
    dt = info.get("dt")
    if static is not None:  # no time steps: the equilibria solved, and the time of the loads
        levels = static.get("levels") if isinstance(static.get("levels"), list) else []
        kind = "times" if static.get("times") else "levels"
        facts[2] = (kind, f"{len(levels)} solved by Newton's method"
                          + (f": {', '.join(_fmt(lv.get('time' if kind == 'times' else 'level')) for lv in levels if isinstance(lv, dict))}"
                             if 0 < len(levels) <= 12 else ""))
        facts[3] = ("loads at t (s)", static.get("t_loads", info.get("time")))
        facts[5] = ("steps per second", None)
        facts[6] = ("time step (s)", None)
    elif isinstance(dt, dict):
        facts[6] = ("time step (s)", ("fixed " if dt.get("fixed") else "automatic, ") + ", ".join(
            f"{k} {_fmt(dt[k])}" for k in ("min", "max", "mean") if dt.get(k) is not None))
    # what the run met that the scene may not mean (a body in the domain walls' reach, a body the lattice rounds)
    # and why steps left the check windows: run.json's notes, one row each
    facts += [("note", n) for n in info.get("notes") or []]
    if columns and n_rows > len(values[0]):
        facts.append(("probe curves", f"{len(values[0]):,} of the {n_rows:,} rows of metrics.csv (every "
                                      f"{metrics_stride(n_rows, MAX_METRIC_ROWS)}th, and the last; at most "
                                      f"{MAX_METRIC_ROWS:,} rows are embedded)"))
    sweep = info.get("sweep") or {}
    return {
        "kind": "run",
        "title": f"Run {sweep.get('name') or scene.get('name') or run_dir.name}",
        "subtitle": str(run_dir),
        "status": state,
        "facts": [(k, _fmt(v)) for k, v in facts if v not in (None, "")],
        "sweep_params": [(k, json.dumps(v)) for k, v in (sweep.get("params") or {}).items()],
        "scene_rows": _flatten(scene),
        "charts": charts,
        "viewer": _with_stamp(_with_body_names(viewer_data(run_dir, max_frames, max_particles, info.get("dim"), scene),
                                               info),
                              columns[0] if columns else "time"),
    }


def _with_stamp(viewer: dict | None, stamp: str) -> dict | None:
    """What the viewer's frames are stamped with: 'time' (s), or 'level' (a --static run's field level)."""
    if viewer is not None:
        viewer["stamp"] = "level" if stamp == "level" else "time"
    return viewer


def _probe_units(scene: dict) -> dict[str, str]:
    """The y-axis label of each probe's curve: field probes in T, collider forces in N, the others positions in m."""
    out = {}
    for p in scene.get("probes", []):
        if isinstance(p, dict) and isinstance(p.get("name"), str):
            out[p["name"]] = {"field": "field (T)", "collider_force": "force (N)"}.get(p.get("type"), "position (m)")
    return out


def _with_body_names(viewer: dict | None, info: dict) -> dict | None:
    """Body names for the viewer's legend, in body-id order (run.json's fill report lists the bodies in order)."""
    if viewer is not None:
        viewer["body_names"] = [b.get("body", str(i)) for i, b in enumerate(info.get("bodies") or []) if isinstance(b, dict)]
    return viewer


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def sweep_content(sweep_dir) -> dict:
    from magsoro.sweep.params import format_value
    from magsoro.sweep.summary import read_summary
    from magsoro.sweep.worker import read_record

    sweep_dir = Path(sweep_dir)
    try:
        plan = json.loads((sweep_dir / "sweep.json").read_text())
    except (OSError, ValueError) as exc:
        raise ReportError(f"{sweep_dir / 'sweep.json'}: cannot read ({exc})") from None
    _check_sweep_plan(plan, sweep_dir / "sweep.json")
    keys = [p["key"] for p in plan.get("params", [])]
    # the run directories are the truth (summary.csv may lag a run that just finished); read them directly
    records = [read_record(sweep_dir / "runs" / r["name"], {**r, "scene": None}) for r in plan.get("runs", [])]
    done = [r for r in records if r["status"] == "completed"]
    probe_cols: list[str] = []
    for r in done:
        probe_cols += [c for c in r["probes"] if c not in probe_cols]
    charts = []
    for key in keys:
        values = [r["params"][key] for r in records]
        numeric = all(_is_num(v) for v in values)
        cats = None if numeric else list(dict.fromkeys(format_value(v) for v in values))
        others = [k for k in keys if k != key]
        for col in probe_cols:
            groups: dict[str, list] = {}
            for r in done:
                label = ", ".join(f"{k.split('.')[-1]}={format_value(r['params'][k])}" for k in others) or col
                x = r["params"][key] if numeric else cats.index(format_value(r["params"][key]))
                groups.setdefault(label, []).append((x, r["probes"].get(col)))
            series = []
            for label, pts in groups.items():
                pts.sort(key=lambda p: p[0])
                s = _series(label, [p[0] for p in pts], [_finite_or_none(p[1]) for p in pts])
                if s is not None:
                    series.append(s)
            if series:
                charts.append({"title": f"final {col} vs {key}", "xlabel": key, "ylabel": f"{col} (m)", "series": series,
                               "markers": True, "xcats": cats})
    curves = []
    overlay = done[:MAX_SWEEP_CURVES]
    metrics = {r["run"]: read_metrics(sweep_dir / "runs" / r["run"], MAX_SWEEP_CURVE_ROWS) for r in overlay}
    decimated = sum(1 for _, v, n in metrics.values() if v and n > len(v[0]))
    for col in probe_cols:
        series = []
        for r in overlay:
            columns, values, _ = metrics[r["run"]]
            if col in columns and columns and columns[0] == "time":
                s = _series(r["run"], values[0], values[columns.index(col)])
                if s is not None:
                    series.append(s)
        if series:
            curves.append({"title": f"{col} over time, every completed run", "xlabel": "time (s)", "ylabel": f"{col} (m)", "series": series})
    table_cols = ["index", "run", *keys, "status", "error", "wall_time_s", *probe_cols]
    table = []
    summary_path = sweep_dir / "summary.csv"
    for r in records:
        row = {"index": r["index"], "run": r["run"], **{k: format_value(r["params"][k]) for k in keys}, "status": r["status"],
               "error": r["error"], "wall_time_s": r["wall_time_s"], **r["probes"]}
        table.append([("" if row.get(c) is None else (f"{row[c]:.6g}" if isinstance(row[c], float) else str(row[c]))) for c in table_cols])
    n_failed = sum(r["status"] == "failed" for r in records)
    facts = [
        ("scene file", plan.get("scene_file", "?")),
        ("runs", f"{len(records)} planned, {len(done)} completed, {n_failed} failed, {len(records) - len(done) - n_failed} not finished"),
        ("combination", "paired (--zip)" if plan.get("mode") == "zip" else "cartesian product"),
        ("created", plan.get("created", "?")),
        ("summary table", str(summary_path) + ("" if summary_path.is_file() else " (missing)")),
    ]
    if summary_path.is_file():
        cols, _rows = read_summary(summary_path)
        facts.append(("summary columns", ", ".join(cols)))
    if decimated:
        facts.append(("curves over time", f"{decimated} run(s) have more than {MAX_SWEEP_CURVE_ROWS:,} metrics rows; "
                                          f"their curves show {MAX_SWEEP_CURVE_ROWS:,} of them, evenly spread"))
    return {
        "kind": "sweep",
        "title": f"Sweep {sweep_dir.name}",
        "subtitle": str(sweep_dir),
        "status": "failed" if n_failed else ("completed" if len(done) == len(records) else "incomplete"),
        "facts": facts,
        "sweep_params": [(p["key"], ", ".join(format_value(v) for v in p["values"])) for p in plan.get("params", [])],
        "charts": charts + curves,
        "table": {"columns": table_cols, "rows": table},
        "scene_rows": [],
        "viewer": None,
    }


# ------------------------------------------------------------------------------------------------- output
def _esc(v) -> str:
    return html.escape(str(v), quote=True)


def _kv_table(rows, cls="kv") -> str:
    body = "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in rows)
    return f'<table class="{cls}">{body}</table>'


def render_html(content: dict) -> str:
    """The page: static HTML for the tables, JSON for the plots and the viewer, inline CSS and JS."""
    from magsoro.viz.report_assets import CSS, JS

    expected = sum(len(c["series"]) for c in content["charts"])
    payload = {
        "kind": content["kind"],
        "charts": content["charts"],
        "viewer": content["viewer"],
        "expected_curves": expected,
    }
    # '</script>' or '<!--' inside a <script> would end or confuse it; JSON's \u003c is the same character
    data = json.dumps(payload, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_esc(content['title'])} - magsoro report</title>",
        f"<style>{CSS}</style></head><body>",
        f'<header><h1>{_esc(content["title"])} <span class="badge {_esc(content["status"])}">{_esc(content["status"])}</span></h1>',
        f'<p class="sub">{_esc(content["subtitle"])} &middot; magsoro {_esc(__version__)} report, {_esc(time.strftime("%Y-%m-%d %H:%M"))}</p>',
        '<div id="status" class="pending">rendering...</div></header>',
        "<section><h2>Overview</h2>" + _kv_table(content["facts"]) + "</section>",
    ]
    if content["sweep_params"]:
        parts.append("<section><h2>Swept parameters</h2>" + _kv_table(content["sweep_params"]) + "</section>")
    if content["charts"]:
        heading = "Final probe values and probe curves" if content["kind"] == "sweep" else "Probe curves"
        parts.append(f'<section><h2>{heading}</h2><p class="hint">Hover a plot for values.</p><div id="charts" class="charts"></div></section>')
    else:
        parts.append('<section><h2>Probe curves</h2><p class="hint">No probe data (no completed run with probes).</p><div id="charts"></div></section>')
    if content["viewer"] is not None:
        v = content["viewer"]
        note = f"{v['n']} of {v['n_total']} particles, {v['frames']} of {v['frames_total']} frames"
        start = f" The view starts looking at {_esc(v['view']['why'])}." if v["dim"] == 3 else ""
        parts.append(
            '<section><h2>Particles</h2>'
            f'<p class="hint">{_esc(note)}.{start} Drag to rotate, wheel to zoom, double-click to go back to the view '
            'chosen.</p>'
            '<div id="viewer"></div></section>'
        )
    if content.get("table"):
        t = content["table"]
        head = "".join(f"<th>{_esc(c)}</th>" for c in t["columns"])
        status_col = t["columns"].index("status")
        body = "".join(
            f'<tr class="{_esc(r[status_col])}">' + "".join(f"<td>{_esc(c)}</td>" for c in r) + "</tr>" for r in t["rows"]
        )
        parts.append(f'<section><h2>Runs</h2><div class="scroll"><table class="runs"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div></section>')
    if content["scene_rows"]:
        parts.append('<section><h2>Scene parameters</h2><details><summary>every key of the scene as run</summary>'
                     + _kv_table(content["scene_rows"]) + "</details></section>")
    parts.append(f'<script type="application/json" id="report-data">{data}</script>')
    parts.append(f"<script>{JS}</script></body></html>")
    return "\n".join(parts) + "\n"


def build_report(directory, out=None, max_frames: int = MAX_FRAMES, max_particles: int = MAX_PARTICLES) -> Path:
    """Write the report of a run directory (run.json) or a sweep directory (sweep.json); return its path.

    Default output: DIRECTORY/report.html.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise ReportError(f"{directory}: no such directory")
    if (directory / "sweep.json").is_file():
        content = sweep_content(directory)
    elif (directory / "run.json").is_file():
        content = run_content(directory, max_frames, max_particles)
    else:
        raise ReportError(f"{directory}: neither a run (run.json) nor a sweep (sweep.json) directory")
    out = Path(out) if out is not None else directory / "report.html"
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, render_html(content))
    return out
