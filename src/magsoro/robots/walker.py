"""Hu et al.'s small sheet walker (seed 000 sec 4.5, Fig. 5(b)): displacement per field cycle vs the strength of
a rotating field, on a floor with friction.

One simulation steps the rotating field through the levels: at each level the magnitude ramps up over a quarter
cycle (while the field keeps turning), the gait settles, and the centroid's advance over whole field cycles is
the displacement per cycle. The field is the scene's ``drive`` field (frequency, plane, sense) turned into
keyframes (48 per cycle) so that its magnitude can step.

Predicted direction: the magnetic torque density on the sheet is Br(s) x B(t) ~ sin(w t - 2 pi s / lambda), a
wave that runs along the sheet towards the end where the magnetisation has turned further in the sense the field
turns. A sheet carrying such a bending wave on a floor with friction walks along the wave: its feet (the points
touching the floor) slip backwards relative to the wave, so friction pushes the body forwards. The sign is
computed from the scene (field sense, magnetisation sense, profile axis), not assumed.
"""

from __future__ import annotations

import math
import time

import numpy as np

from magsoro.robots.base import (FrameRecorder, ReproduceResult, Robot, RobotError, plot_curve, scene_data,
                                 simulation, write_csv)

NAME = "walker"
LEVELS_T = (1.0e-3, 1.2e-3, 1.4e-3, 1.6e-3, 1.8e-3)  # field strengths of the full sweep, T
LEVELS_PREVIEW_T = (1.0e-3, 1.4e-3, 1.8e-3)
RAMP_CYCLES = 0.25  # magnitude ramp from one level to the next, in field cycles
SETTLE_CYCLES = (0.5, 0.25)  # (full, preview): cycles from the start of a level to the start of the measurement
MEASURED_CYCLES = (2, 1)  # (full, preview)
KEYS_PER_CYCLE = 48
FRAMES_PER_CYCLE = 12


def _drive(data: dict) -> dict:
    for f in data.get("fields", []):
        if f.get("type") == "rotating":
            return f
    raise RobotError("walker: the scene needs a rotating field (the drive)")


def predicted_direction(data: dict) -> np.ndarray:
    """Unit vector (scene plane) along which the torque wave runs, i.e. the predicted walking direction."""
    drive = _drive(data)
    mag = data["robot"]["parts"][0]["magnetization"]
    u, v = np.asarray(drive.get("u", [1, 0, 0]), float), np.asarray(drive.get("v", [0, 1, 0]), float)
    mu, mv = np.asarray(mag.get("u", [1, 0, 0]), float), np.asarray(mag.get("v", [0, 0, 1]), float)
    axis = np.asarray(mag.get("axis", [1, 0, 0]), float)
    field_sense = np.cross(u, v) * math.copysign(1.0, float(drive["frequency"]))
    profile_sense = np.cross(mu, mv)
    sign = math.copysign(1.0, float(np.dot(field_sense, profile_sense)))
    d = sign * axis / np.linalg.norm(axis)
    return d[:2]


def field_schedule(drive: dict, levels, settle_cycles: float, measured_cycles: int):
    """Keyframes (times, vectors) of the stepped rotating field and, per level, the (start, end) times of the
    measured whole cycles."""
    f = float(drive["frequency"])
    period = 1.0 / abs(f)
    u = np.asarray(drive.get("u", [1, 0, 0]), float)
    v = np.asarray(drive.get("v", [0, 1, 0]), float)
    u = u / np.linalg.norm(u)
    v = v - np.dot(v, u) * u
    v = v / np.linalg.norm(v)
    phase = math.radians(float(drive.get("phase", 0.0)))
    per_level = settle_cycles + measured_cycles
    n_keys = int(round(per_level * KEYS_PER_CYCLE))
    times, values, windows = [0.0], [np.zeros(3)], []
    t0, previous = 0.0, 0.0
    for b in levels:
        for k in range(1, n_keys + 1):
            t = t0 + k * period / KEYS_PER_CYCLE
            ramp = min(1.0, k / (RAMP_CYCLES * KEYS_PER_CYCLE))
            mag = previous + (b - previous) * ramp
            a = 2 * math.pi * f * t + phase
            times.append(t)
            values.append(mag * (math.cos(a) * u + math.sin(a) * v))
        windows.append((t0 + settle_cycles * period, t0 + per_level * period))
        t0, previous = t0 + per_level * period, b
    return np.array(times), np.array(values), windows


def reproduce(ctx) -> ReproduceResult:
    from magsoro.errors import SimulationError
    from magsoro.validation.registry import Row

    wall0 = time.perf_counter()
    data = scene_data(NAME)
    drive = _drive(data)
    f = abs(float(drive["frequency"]))
    period = 1.0 / f
    mode = 1 if ctx.preview else 0
    levels = LEVELS_PREVIEW_T if ctx.preview else LEVELS_T
    times, values, windows = field_schedule(drive, levels, SETTLE_CYCLES[mode], MEASURED_CYCLES[mode])
    data["fields"] = [{"type": "keyframes", "name": "drive", "times": times.tolist(), "values": values.tolist()}]
    data["simulation"]["duration"] = float(times[-1])
    sim = simulation(NAME, data, preview=ctx.preview, device=ctx.device)
    direction = predicted_direction(scene_data(NAME))
    length = float(data["robot"]["parts"][0]["shape"]["size"][0])
    ctx.log(f"walker: {sim.model.n_particles} particles, dt {sim.dt:.3g} s, {len(levels)} levels, "
            f"{times[-1]:.3f} s simulated")

    def level_at(t):
        for b, (a, e) in zip(levels, windows):
            if t <= e + 1e-12:
                return b
        return levels[-1]

    frames = FrameRecorder(axes=(0, 1), label=lambda s: f"|B| = {level_at(s.time) * 1e3:.1f} mT, "
                                                       f"t = {s.time * 1e3:.0f} ms")
    record_dt = period / FRAMES_PER_CYCLE
    n_rec = int(round(times[-1] / record_dt))
    marks = {}
    for (a, e) in windows:
        marks[int(round(a / record_dt))] = None
        marks[int(round(e / record_dt))] = None
    lowest, highest = math.inf, -math.inf
    frames.record(sim)
    try:
        for k in range(1, n_rec + 1):
            sim.advance_to(k * record_dt)
            frames.record(sim)
            y = sim.state.x.numpy()[:, 1]
            lowest, highest = min(lowest, float(y.min())), max(highest, float(y.max()))
            if k in marks:
                marks[k] = np.array([sim.probe_values()["sheet_x"], sim.probe_values()["sheet_y"]])
    except SimulationError as exc:
        raise RobotError(f"walker: run failed: {exc}") from exc
    per_cycle = []
    for (a, e) in windows:
        dxy = marks[int(round(e / record_dt))] - marks[int(round(a / record_dt))]
        per_cycle.append(float(np.dot(dxy, direction)) / MEASURED_CYCLES[mode])
    per_cycle = np.array(per_cycle)

    out = ctx.out
    b_mT = np.array(levels) * 1e3
    csv = write_csv(out / f"{NAME}.csv", {
        "B_mT": b_mT,
        "displacement_per_cycle_mm": per_cycle * 1e3,
        "displacement_per_cycle_body_lengths": per_cycle / length,
        "frequency_Hz": np.full(len(levels), f),
    })
    png = plot_curve(out / f"{NAME}.png", b_mT, {"displacement per cycle": per_cycle * 1e3},
                     xlabel="rotating field |B| (mT)",
                     ylabel="displacement per field cycle (mm)\n(along the predicted direction)",
                     title=f"Hu et al. sheet walker, {f:g} Hz rotating field",
                     note="seed 000 sec 4.5 / Fig. 5(b) states no values")
    floor_y = float(data["colliders"][0]["point"][1])

    def patches(ax, k):
        # floor, and the field direction (arrow length in proportion to |B|) at the frame's time
        ax.axhline(floor_y * 1e3, color="0.3", lw=1)
        t = k * record_dt
        b = np.array([np.interp(t, times, values[:, j]) for j in range(2)])
        scale = 0.6 / max(levels)  # mm per T
        ax.annotate("", xy=(gif_origin[0] + b[0] * scale, gif_origin[1] + b[1] * scale), xytext=gif_origin,
                    arrowprops=dict(arrowstyle="->", color="tab:red", lw=1.5))
        ax.text(gif_origin[0], gif_origin[1] + 0.75, "B", color="tab:red", ha="center", fontsize=8)

    allx = np.concatenate([fr[0] for fr in frames.frames]) * 1e3
    gif_origin = (float(allx[:, 0].max()) + 0.9, float(allx[:, 1].max()) * 0.5 + 0.3)
    lims = ((float(allx[:, 0].min()) - 0.3, gif_origin[0] + 0.9),
            (floor_y * 1e3 - 0.3, max(float(allx[:, 1].max()), gif_origin[1] + 0.9) + 0.2))
    gif = frames.write_gif(out / f"{NAME}.gif", title="Hu et al. walker (seed 000 sec 4.5)", fps=15,
                           lims=lims, patches=patches)

    inputs = {"frequency_Hz": f, "levels_mT": [round(x, 3) for x in b_mT.tolist()],
              "measured_cycles": MEASURED_CYCLES[mode], "direction": direction.tolist()}
    min_step = float(np.min(np.diff(per_cycle)))
    rows = [
        Row(case=f"robot-{NAME}", quantity="smallest displacement per cycle along the predicted direction over the "
            "field levels (mm); passes when >= 0 (every level walks the predicted way)", inputs=inputs,
            reference=0.0, value=float(per_cycle.min()) * 1e3, error=-float(per_cycle.min()) * 1e3, tolerance=0.0),
        Row(case=f"robot-{NAME}", quantity="displacement per cycle along the predicted direction at the "
            "strongest field (mm); passes when >= 1 % of the body length", inputs=inputs, reference=0.0,
            value=per_cycle[-1] * 1e3, error=0.01 * length * 1e3 - per_cycle[-1] * 1e3, tolerance=0.0),
        Row(case=f"robot-{NAME}", quantity="smallest increase of the displacement per cycle between successive "
            "field levels (mm); passes when every increase is >= 0", inputs=inputs, reference=0.0,
            value=min_step * 1e3, error=-min_step * 1e3, tolerance=0.0),
    ]
    text = ", ".join(f"{d * 1e3:.3f}" for d in per_cycle)
    summary = (f"The sheet walks along the predicted direction (+x, the way the torque wave runs) by {text} mm per "
               f"cycle at {', '.join(f'{b:.1f}' for b in b_mT)} mT and {f:g} Hz; seed 000 (Fig. 5(b)) shows the "
               "walking gait but states no displacement, so there is no paper number to compare with.")
    info = {"particles": sim.model.n_particles, "steps": sim.steps, "dt_s": sim.dt, "dx_m": sim.model.dx,
            "simulated_s": float(sim.time), "wall_s": round(time.perf_counter() - wall0, 1),
            "displacement_per_cycle_mm": (per_cycle * 1e3).tolist(), "levels_mT": b_mT.tolist(),
            "lowest_y_m": lowest, "highest_y_m": highest, "body_length_m": length}
    return ReproduceResult(name=NAME, csv=csv, png=png, animation=gif, summary=summary, rows=rows, info=info)


ROBOT = Robot(
    name=NAME,
    title="Sheet walker (Hu et al.)",
    source="seed 000 sec 4.5",
    quantity="displacement per field cycle vs rotating-field strength",
    sentence="A 3.7 mm magnetic sheet with a one-turn magnetisation profile walks on a frictional floor under a "
             "rotating field; its displacement per cycle grows with the field.",
    reproduce=reproduce,
    in_ci=True,
)
