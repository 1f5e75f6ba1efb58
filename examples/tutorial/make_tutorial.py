"""Run every step of docs/tutorial.md and regenerate its pictures and numbers.

    .venv/bin/python examples/tutorial/make_tutorial.py [--out DIR] [--docs DIR]

What it does, in order:

1. copies the tutorial's scene files (examples/tutorial/*.toml) into the working folder ``--out`` (default: a
   new temporary folder) - the same as the tutorial's ``cp -r examples/tutorial ...`` - and runs there, one by
   one, exactly the ``magsoro ...`` command lines of :data:`COMMANDS`, which are the command lines the tutorial
   shows (tests/test_tutorial.py checks that the two lists are the same);
2. reads what the commands wrote (metrics.csv, run.json, the rod's centreline.csv, the sweep's summary.csv) and
   computes every number the tutorial quotes, drawing three plots of its own with matplotlib;
3. copies the pictures into ``--docs`` (default: docs/tutorial/ of this repository) and writes
   ``--docs``/numbers.json: each number with its unit, what it is, and the tolerance within which a rerun must
   reproduce it (tests/test_tutorial.py checks the text of docs/tutorial.md against this file, and a fresh run
   of this script against it).

A command that fails stops the script with its output (exit status 1). Every command's output is kept in
``--out``/logs/. The whole script takes about 2 to 3 minutes on a 2-core CPU.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]

#: The tutorial's command lines, in the order it shows them, each run from the working folder. Keep these
#: identical to the ``magsoro ...`` lines in docs/tutorial.md's code blocks (a test compares the two).
COMMANDS: list[str] = [
    # 1. install check
    "magsoro --version",
    # 2. a first scene: a clamped strip in a uniform field
    "magsoro show strip.toml --out strip_show.png --arrows 40",
    "magsoro run strip.toml --out runs/strip",
    "magsoro render runs/strip --out strip_bent.png --color strain --size 800x450",
    # 3. bend it, and check against the rod model and the static solver
    "magsoro rod strip_rod.toml --out runs/strip_rod --json",
    "magsoro run strip.toml --out runs/strip_static --static",
    # 4. a magnetisation profile
    "magsoro show strip_profile.toml --out profile_show.png --arrows 60",
    "magsoro run strip_profile.toml --out runs/strip_profile",
    "magsoro render runs/strip_profile --out profile_bent.png --color magnetisation --size 800x450",
    # 5. a floor and a rotating field: the walker
    "magsoro show walker.toml --out walker_show.png --arrows 60",
    "magsoro run walker.toml --out runs/walker",
    "magsoro run walker.toml --out runs/walker_preview --preview",
    # 6. sweep the field strength
    "magsoro sweep walker.toml --param fields.drive.magnitude=0.0012,0.0015,0.0018 --out sweeps/field --no-particles",
    "magsoro report sweeps/field",
    # 7. render the result
    "magsoro render runs/walker --out walker.png --frames t=0.25 --size 800x400",
    "magsoro render runs/walker --out walker.gif --size 800x400",
]

#: Scene files the tutorial uses (copied into the working folder).
SCENES = ["strip.toml", "strip_rod.toml", "strip_profile.toml", "walker.toml"]

#: Pictures the tutorial shows: written by the commands above or drawn by this script, copied into --docs.
PICTURES = ["strip_show.png", "strip_bent.png", "strip_vs_rod.png", "profile_show.png", "profile_bent.png",
            "walker_show.png", "walker.png", "walker.gif", "walker_x.png", "sweep_speed.png"]

# --- tolerances of a rerun against numbers.json (tests/test_tutorial.py) ---------------------------------------
# The runs are deterministic on one machine: every run here has fewer than 4000 particles, so it steps on one CPU
# thread whatever the core count (docs/engine.md, "CPU threads"), and sweep workers use one thread too. What can
# differ elsewhere is float32 round-off (another CPU, another Warp or LLVM version: fused multiply-adds, summation
# order). Measured on the machine that wrote this file, the size of such differences: the same scenes with 2
# threads (different atomic-add order) moved the strip's tip by 2e-5 relative and the walker's final centroid
# (on the 2-cell grid of --preview) by 8e-4 relative, i.e. 3e-3 of its advance per cycle; with float64 kernels
# instead of float32, by 3e-4 (strip) and 1.6e-3 (walker). The tolerances below
# are about ten times those: tight enough that a change of the physics or of a scene shows, loose enough for
# round-off. The walker gets more room than the clamped strip because its contacts with the floor (stick or
# slip, touch or not) amplify small differences. The Cosserat rod is float64 numpy (bit-for-bit on one platform;
# 1e-6 covers BLAS/CPU differences); the static solver is float64 Newton (1e-4).
TOL_STRIP = {"rel": 5e-3, "abs": 2e-3}      # mm-scale quantities of the clamped strips
TOL_STATIC = {"rel": 1e-4, "abs": 1e-4}
TOL_ROD = {"rel": 1e-6, "abs": 1e-6}
TOL_WALK = {"rel": 3e-2, "abs": 1e-2}      # walker and sweep (mm, mm per cycle, mm/s)
TOL_STEPS = {"rel": 1e-2, "abs": 0}        # the CFL time step depends on the particle speeds
TOL_EXACT = {"rel": 0, "abs": 0}
# percentages formed from two of the quantities above: a relative error e of either moves them by 100 e points
TOL_PCT_STRIP = {"rel": 0, "abs": 100 * TOL_STRIP["rel"]}
TOL_PCT_STATIC = {"rel": 0, "abs": 0.01}
TOL_PCT_WALK = {"rel": 0, "abs": 2 * 100 * TOL_WALK["rel"]}


def magsoro_argv(command: str) -> list[str]:
    """The argument vector of a ``magsoro ...`` command line: the ``magsoro`` next to this Python (the
    virtualenv's), else the one on PATH."""
    argv = shlex.split(command)
    assert argv[0] == "magsoro", command
    exe = Path(sys.executable).with_name("magsoro")
    if not exe.exists():
        found = shutil.which("magsoro")
        if found is None:
            raise SystemExit("make_tutorial: no 'magsoro' executable next to this Python or on PATH; "
                             "install the package first (pip install -e .)")
        exe = Path(found)
    return [str(exe), *argv[1:]]


def run_commands(work: Path, log_dir: Path) -> list[dict]:
    """Run :data:`COMMANDS` in ``work``; return one record per command (command, exit status, seconds, log)."""
    records = []
    for i, command in enumerate(COMMANDS):
        log = log_dir / f"{i:02d}.log"
        print(f"[{i + 1}/{len(COMMANDS)}] {command}", flush=True)
        t0 = time.perf_counter()
        proc = subprocess.run(magsoro_argv(command), cwd=work, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True, check=False)
        seconds = time.perf_counter() - t0
        log.write_text(f"$ {command}\n{proc.stdout}\n[exit status {proc.returncode}, {seconds:.1f} s]\n")
        records.append({"command": command, "returncode": proc.returncode, "seconds": round(seconds, 2),
                        "log": str(log)})
        print(f"    exit status {proc.returncode}, {seconds:.1f} s", flush=True)
        if proc.returncode != 0:
            print(proc.stdout[-4000:], file=sys.stderr)
            raise RuntimeError(f"make_tutorial: '{command}' failed with exit status {proc.returncode} "
                               f"(log: {log})")
    return records


def read_csv(path: Path) -> dict[str, list]:
    """Columns of a CSV file, numbers as floats where they parse."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    cols: dict[str, list] = {k: [] for k in rows[0]} if rows else {}
    for row in rows:
        for k, v in row.items():
            try:
                cols[k].append(float(v))
            except (TypeError, ValueError):
                cols[k].append(v)
    return cols


def value_at(times: list[float], values: list[float], t: float) -> float:
    """The recorded value at time ``t`` (the row nearest it; rows are every output.every)."""
    i = min(range(len(times)), key=lambda j: abs(times[j] - t))
    assert abs(times[i] - t) < 1e-9 + 1e-6 * t, (times[i], t)
    return values[i]


def analyse(work: Path, out_pictures: Path) -> dict[str, dict]:
    """Every number the tutorial quotes, from the files the commands wrote; draws the script's own plots."""
    import matplotlib

    matplotlib.use("Agg")
    import tomllib

    import matplotlib.pyplot as plt
    import numpy as np

    numbers: dict[str, dict] = {}

    def put(key, value, unit, what, tol):
        numbers[key] = {"value": float(value), "unit": unit, "what": what, "tolerance": tol}

    from magsoro.constants import MU0 as mu0

    runs = work / "runs"

    # --- step 2: the strip ----------------------------------------------------------------------------------
    strip_run = json.loads((runs / "strip" / "run.json").read_text())
    m = read_csv(runs / "strip" / "metrics.csv")
    t_end = m["time"][-1]
    tip_x_mm, tip_y_mm = m["tip_x"][-1] * 1e3, m["tip_y"][-1] * 1e3
    tip_x0_mm = m["tip_x"][0] * 1e3
    put("strip_particles", strip_run["n_particles"], "", "particles of the strip", TOL_EXACT)
    put("strip_steps", strip_run["steps"], "", "time steps of the strip run", TOL_STEPS)
    put("strip_dt_us", strip_run["dt"]["max"] * 1e6, "us", "largest (CFL) time step of the strip run", TOL_STEPS)
    put("strip_frames", strip_run["frames"], "", "particle frames the strip run wrote", TOL_EXACT)
    put("strip_t_end_ms", t_end * 1e3, "ms", "end of the strip run", TOL_EXACT)
    put("strip_tip_dy_mm", tip_y_mm, "mm", "tip deflection (y) of the strip at the end of the run", TOL_STRIP)
    put("strip_tip_x_mm", tip_x_mm, "mm", "tip x of the strip at the end of the run", TOL_STRIP)
    peak = max(m["tip_y"]) * 1e3
    put("strip_tip_peak_mm", peak, "mm", "largest tip deflection during the run (overshoot)", TOL_STRIP)
    put("strip_tip_peak_ms", m["time"][int(np.argmax(m["tip_y"]))] * 1e3, "ms",
        "time of the largest deflection (a row of metrics.csv: one row either side allowed)", {"rel": 0, "abs": 5.0})

    # --- step 3: rod, linear estimate, static solver ----------------------------------------------------------
    rod_cfg = tomllib.loads((work / "strip_rod.toml").read_text())
    rod = read_csv(runs / "strip_rod" / "centreline.csv")
    s_tip = tip_x0_mm * 1e-3  # the probe's particles sit at x = 9.95 mm: compare the rod at the same s
    rod_dy_mm = float(np.interp(s_tip, rod["s"], rod["z"])) * 1e3
    tx, tz = rod["tx"][-1], rod["tz"][-1]
    put("probe_s_mm", s_tip * 1e3, "mm", "arc length of the tip probe from the clamp face", TOL_EXACT)
    put("rod_tip_dy_mm", rod_dy_mm, "mm", "rod deflection at the probe's arc length", TOL_ROD)
    put("rod_tip_angle_deg", math.degrees(math.atan2(tz, tx)), "deg", "rod tip angle", TOL_ROD)
    put("mpm_vs_rod_pct", 100 * (tip_y_mm - rod_dy_mm) / rod_dy_mm, "%",
        "MPM tip deflection at the end of the run relative to the rod's", TOL_PCT_STRIP)
    # linear (small-deflection) cantilever under a uniform distributed couple c = A Br B / mu0 per length:
    # bending moment c (L - s), so w(s) = k^2 (L s^2 / 2 - s^3 / 6) with k^2 = c / (E' I) = 12 Br B / (mu0 E' t^2)
    # the rod's modulus: the plane-strain modulus of the engine's material (library G, default K = 20 G)
    from magsoro.materials import get_material

    mat = get_material("ecoflex-00-30-ndfeb100")
    G, K = mat.shear_modulus, 20.0 * mat.shear_modulus
    E_3d = 9 * K * G / (3 * K + G)
    nu = (3 * K - 2 * G) / (2 * (3 * K + G))
    E_plane = E_3d / (1 - nu**2)
    put("material_G_kPa", G / 1e3, "kPa", "library shear modulus", TOL_EXACT)
    put("material_Br_mT", mat.remanence * 1e3, "mT", "library remanence", TOL_EXACT)
    put("material_E_kPa", E_3d / 1e3, "kPa", "Young's modulus of the engine's material (K = 20 G)", TOL_EXACT)
    put("material_nu", nu, "", "Poisson's ratio of the engine's material (K = 20 G)", TOL_EXACT)
    put("material_E_plane_kPa", E_plane / 1e3, "kPa", "plane-strain modulus E / (1 - nu^2)", TOL_EXACT)
    put("stiffness_drop_with_E_pct", 100 * (1 - E_3d / E_plane), "%",
        "how much lower the rod's bending stiffness would be with E instead of E'", TOL_EXACT)
    rod_E = rod_cfg["youngs_modulus"]
    if abs(rod_E - E_plane) > 1e-3 * E_plane:
        raise RuntimeError(f"strip_rod.toml: youngs_modulus {rod_E} Pa is not the plane-strain modulus "
                           f"{E_plane:.0f} Pa of the strip's material")
    L = rod_cfg["length"]
    t = rod_cfg["cross_section"]["thickness"]
    E = rod_cfg["youngs_modulus"]
    Br = abs(rod_cfg["magnetisation"][0]["remanence"][2])
    B = abs(rod_cfg["field"][2])
    k2 = 12 * Br * B / (mu0 * E * t**2)

    def linear_w(s):
        return k2 * (L * s**2 / 2 - s**3 / 6)

    lin_dy_mm = linear_w(s_tip) * 1e3
    put("linear_tip_dy_mm", lin_dy_mm, "mm", "small-deflection estimate w = k^2 (L s^2/2 - s^3/6) at the probe",
        TOL_ROD)
    put("linear_vs_rod_pct", 100 * (lin_dy_mm - rod_dy_mm) / rod_dy_mm, "%", "linear estimate relative to the rod",
        TOL_ROD)
    put("linear_tip_angle_deg", math.degrees(k2 * L**2 / 2), "deg", "tip angle of the linear estimate", TOL_ROD)
    put("load_number", k2 * L**2, "", "k^2 L^2 = 12 Br B L^2 / (mu0 E' t^2)", TOL_ROD)
    static = read_csv(runs / "strip_static" / "metrics.csv")
    static_dy_mm = static["tip_y"][-1] * 1e3
    put("static_tip_dy_mm", static_dy_mm, "mm", "tip deflection of the static (Newton) solve", TOL_STATIC)
    put("static_vs_rod_pct", 100 * (static_dy_mm - rod_dy_mm) / rod_dy_mm, "%",
        "static MPM tip deflection relative to the rod's", TOL_PCT_STATIC)
    put("dynamic_vs_static_pct", 100 * (tip_y_mm - static_dy_mm) / static_dy_mm, "%",
        "end of the dynamic run relative to the static solve", TOL_PCT_STRIP)

    # picture: final shape against the rod's centreline, and the tip over time
    fin = np.load(runs / "strip" / "final.npz")
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(9.5, 3.6), gridspec_kw={"width_ratios": [1.25, 1]})
    ax0.scatter(fin["x"][:, 0] * 1e3, fin["x"][:, 1] * 1e3, s=3, c="tab:blue", label=f"MPM particles, t = {t_end:g} s")
    ax0.plot(np.array(rod["x"]) * 1e3, np.array(rod["z"]) * 1e3, "k-", lw=1.5, label="Kirchhoff rod (magsoro rod)")
    ss = np.linspace(0, L, 50)
    ax0.plot(ss * 1e3, linear_w(ss) * 1e3, "k:", lw=1.2, label="linear estimate")
    ax0.axvspan(-1, 0, color="0.85", zorder=0, label="clamp")
    ax0.set_aspect("equal")
    ax0.set_xlabel("x (mm)")
    ax0.set_ylabel("y (mm)")
    ax0.legend(fontsize=7, loc="upper left")
    ax0.set_title("shape at the end of the run", fontsize=9)
    tm = np.array(m["time"]) * 1e3
    ax1.plot(tm, np.array(m["tip_y"]) * 1e3, "o-", ms=3, label="MPM tip (metrics.csv)")
    ax1.axhline(rod_dy_mm, color="k", lw=1, label="rod")
    ax1.axhline(static_dy_mm, color="tab:red", ls="--", lw=1, label="MPM static (--static)")
    ax1.axhline(lin_dy_mm, color="k", ls=":", lw=1, label="linear estimate")
    ax1.axvspan(0, 20, color="0.92", zorder=0)
    ax1.text(10, 0.3, "field\nramp", ha="center", fontsize=7)
    ax1.set_xlabel("t (ms)")
    ax1.set_ylabel("tip deflection y (mm)")
    ax1.legend(fontsize=7, loc="lower right")
    ax1.set_title("tip over time", fontsize=9)
    fig.tight_layout()
    fig.savefig(out_pictures / "strip_vs_rod.png", dpi=90)
    plt.close(fig)

    # --- step 4: the profile -----------------------------------------------------------------------------------
    mp = read_csv(runs / "strip_profile" / "metrics.csv")
    put("profile_tip_dy_mm", mp["tip_y"][-1] * 1e3, "mm", "tip deflection of the profiled strip", TOL_STRIP)
    put("profile_mid_dy_mm", mp["mid_y"][-1] * 1e3, "mm", "deflection of the profiled strip at mid-length",
        TOL_STRIP)

    # --- step 5: the walker ----------------------------------------------------------------------------------
    walker_cfg = tomllib.loads((work / "walker.toml").read_text())
    drive = walker_cfg["fields"][0]
    f_hz = drive["frequency"]
    length = walker_cfg["bodies"][0]["shape"]["size"][0]
    wr = json.loads((runs / "walker" / "run.json").read_text())
    w = read_csv(runs / "walker" / "metrics.csv")
    t0, t1 = 1.0 / f_hz, w["time"][-1]  # measure over whole field cycles after the first (start-up) one
    cycles = round((t1 - t0) * f_hz)
    x0, xa, xb = w["sheet_x"][0], value_at(w["time"], w["sheet_x"], t0), value_at(w["time"], w["sheet_x"], t1)
    per_cycle_mm = (xb - xa) / cycles * 1e3
    put("walker_particles", wr["n_particles"], "", "particles of the walker", TOL_EXACT)
    put("walker_steps", wr["steps"], "", "time steps of the walker run", TOL_STEPS)
    put("walker_duration_s", t1, "s", "simulated time of the walker run", TOL_EXACT)
    put("walker_cycles", t1 * f_hz, "", "field turns in the walker run", TOL_EXACT)
    put("walker_distance_mm", (xb - x0) * 1e3, "mm", "centroid advance along +x over the whole run", TOL_WALK)
    put("walker_per_cycle_mm", per_cycle_mm, "mm", f"centroid advance per field cycle from t = {t0:g} s to {t1:g} s",
        TOL_WALK)
    put("walker_speed_mm_s", per_cycle_mm * f_hz, "mm/s", "steady walking speed (per cycle x frequency)", TOL_WALK)
    put("walker_body_lengths_per_s", per_cycle_mm * f_hz / (length * 1e3), "1/s", "speed in body lengths per second",
        TOL_WALK)
    put("walker_length_mm", length * 1e3, "mm", "sheet length", TOL_EXACT)
    wp = read_csv(runs / "walker_preview" / "metrics.csv")
    pc_preview = (value_at(wp["time"], wp["sheet_x"], t1) - value_at(wp["time"], wp["sheet_x"], t0)) / cycles * 1e3
    put("walker_preview_per_cycle_mm", pc_preview, "mm", "advance per cycle with --preview (2 cells thick)", TOL_WALK)
    put("preview_vs_full_pct", 100 * (pc_preview - per_cycle_mm) / per_cycle_mm, "%",
        "--preview's advance per cycle relative to the full grid's", TOL_PCT_WALK)
    put("walker_max_height_mm", max(w["sheet_y"]) * 1e3, "mm", "highest centroid height", TOL_WALK)

    fig, ax = plt.subplots(figsize=(6.4, 3.0))
    ax.plot(np.array(w["time"]) * 1e3, (np.array(w["sheet_x"]) - x0) * 1e3, "o-", ms=3, label="centroid x - x(0)")
    ax.plot(np.array(w["time"]) * 1e3, np.array(w["sheet_y"]) * 1e3, "s-", ms=2, color="0.5", label="centroid y")
    for k in range(int(t1 * f_hz) + 1):
        ax.axvline(k / f_hz * 1e3, color="0.85", lw=0.8, zorder=0)
    ax.set_xlabel("t (ms); grey lines: whole field turns")
    ax.set_ylabel("mm")
    ax.legend(fontsize=8)
    ax.set_title(f"walker: {per_cycle_mm:.3f} mm per cycle at {drive['magnitude'] * 1e3:g} mT, {f_hz:g} Hz",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(out_pictures / "walker_x.png", dpi=90)
    plt.close(fig)

    # --- step 6: the sweep -------------------------------------------------------------------------------------
    summary = read_csv(work / "sweeps" / "field" / "summary.csv")
    put("sweep_runs", len(summary["run"]), "", "runs of the sweep", TOL_EXACT)
    put("sweep_completed", sum(s == "completed" for s in summary["status"]), "", "completed runs", TOL_EXACT)
    b_mT, pcs = [], []
    for run, b in zip(summary["run"], summary["fields.drive.magnitude"]):
        ws = read_csv(work / "sweeps" / "field" / "runs" / run / "metrics.csv")
        pc = (value_at(ws["time"], ws["sheet_x"], t1) - value_at(ws["time"], ws["sheet_x"], t0)) / cycles * 1e3
        label = f"{b * 1e3:.1f}".replace(".", "p")
        put(f"sweep_per_cycle_mm_{label}mT", pc, "mm", f"advance per cycle at {b * 1e3:g} mT", TOL_WALK)
        put(f"sweep_final_x_mm_{label}mT", ws["sheet_x"][-1] * 1e3, "mm",
            f"final centroid x at {b * 1e3:g} mT (summary.csv's sheet_x)", TOL_WALK)
        put(f"sweep_speed_mm_s_{label}mT", pc * f_hz, "mm/s", f"walking speed at {b * 1e3:g} mT", TOL_WALK)
        b_mT.append(b * 1e3)
        pcs.append(pc)
    put("sweep_speed_ratio", pcs[-1] / pcs[0], "", "speed at the strongest field over speed at the weakest",
        {"rel": 2 * TOL_WALK["rel"], "abs": 0})
    put("sweep_field_ratio_pct", 100 * (b_mT[-1] / b_mT[0] - 1), "%", "strongest field over weakest, minus 1",
        TOL_EXACT)
    put("sweep_matches_single_run_mm", abs(pcs[-1] - per_cycle_mm), "mm",
        "difference between the sweep's 1.8 mT run and step 5's run", {"rel": 0, "abs": 1e-3})

    fig, ax = plt.subplots(figsize=(4.8, 3.2))
    ax.plot(b_mT, pcs, "o-")
    ax.set_xlabel("field magnitude (mT), 10 Hz")
    ax.set_ylabel("advance per field cycle (mm)")
    ax.set_ylim(bottom=0)
    ax.set_xlim(1.0, 2.0)
    ax2 = ax.secondary_yaxis("right", functions=(lambda y: y * f_hz, lambda v: v / f_hz))
    ax2.set_ylabel("speed (mm/s)")
    ax.set_title("walking speed vs field strength", fontsize=9)
    fig.tight_layout()
    fig.savefig(out_pictures / "sweep_speed.png", dpi=90)
    plt.close(fig)
    return numbers


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None,
                        help="working folder for the runs (new or empty; default: a new temporary folder)")
    parser.add_argument("--docs", type=Path, default=REPO / "docs" / "tutorial",
                        help="where the pictures and numbers.json go (default: docs/tutorial/)")
    args = parser.parse_args(argv)

    work = args.out if args.out is not None else Path(tempfile.mkdtemp(prefix="magsoro-tutorial-"))
    work = work.resolve()
    if work.exists() and any(work.iterdir()):
        parser.error(f"--out {work}: not empty; give a new or empty folder")
    work.mkdir(parents=True, exist_ok=True)
    docs = args.docs.resolve()
    docs.mkdir(parents=True, exist_ok=True)
    log_dir = work / "logs"
    log_dir.mkdir()
    for name in SCENES:  # the tutorial's "cp -r examples/tutorial ..."
        shutil.copy2(HERE / name, work / name)
    print(f"make_tutorial: working in {work}", flush=True)

    t_start = time.perf_counter()
    try:
        records = run_commands(work, log_dir)
    except RuntimeError as exc:
        print(exc, file=sys.stderr)
        return 1
    (work / "commands.json").write_text(json.dumps(records, indent=1) + "\n")

    pictures = work / "plots"
    pictures.mkdir()
    numbers = analyse(work, pictures)
    total = time.perf_counter() - t_start

    for name in PICTURES:
        src = pictures / name if (pictures / name).exists() else work / name
        if not src.exists():
            print(f"make_tutorial: picture {name} was not written", file=sys.stderr)
            return 1
        shutil.copyfile(src, docs / name)  # not copy2: `magsoro render` writes its files readable by the owner only

    timing = {r["command"]: r["seconds"] for r in records}
    informational = {"rel": None, "abs": None}  # wall times: quoted, never compared between runs
    numbers["script_minutes"] = {"value": round(total / 60, 2), "unit": "min", "tolerance": informational,
                                 "what": "wall time of the whole script on the machine that wrote this file"}
    numbers["strip_run_seconds"] = {"value": timing["magsoro run strip.toml --out runs/strip"], "unit": "s",
                                    "tolerance": informational,
                                    "what": "wall time of 'magsoro run strip.toml' (process start included)"}
    numbers["static_run_seconds"] = {"value": timing["magsoro run strip.toml --out runs/strip_static --static"],
                                     "unit": "s", "tolerance": informational,
                                     "what": "wall time of the --static run (process start included)"}
    numbers["walker_run_seconds"] = {"value": timing["magsoro run walker.toml --out runs/walker"], "unit": "s",
                                     "tolerance": informational, "what": "wall time of 'magsoro run walker.toml'"}
    sweep_cmd = next(c for c in COMMANDS if c.startswith("magsoro sweep"))
    numbers["sweep_seconds"] = {"value": timing[sweep_cmd], "unit": "s", "tolerance": informational,
                                "what": "wall time of the sweep (LocalCluster start included)"}
    result = {
        "generated_by": "examples/tutorial/make_tutorial.py",
        "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
                    "cpus": os.cpu_count(), "python": platform.python_version()},
        "numbers": numbers,
        "commands": [{"command": r["command"], "returncode": r["returncode"]} for r in records],
        "pictures": PICTURES,
    }
    (work / "numbers.json").write_text(json.dumps(result, indent=1) + "\n")
    (docs / "numbers.json").write_text(json.dumps(result, indent=1) + "\n")
    print(f"make_tutorial: {len(records)} commands, {len(numbers)} numbers, {len(PICTURES)} pictures in "
          f"{total:.0f} s; numbers in {docs / 'numbers.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
