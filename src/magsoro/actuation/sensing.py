"""Shape sensing with Hall sensors and magnetic markers (seed 004 sec II-D, eqs 17-23).

Each sensing station is a Hall sensor on the camera cable in the robot's channel (on the neutral axis) and a
marker on the wall, magnetised along the sensor axis z. The marker is a z-aligned dipole of moment m at gap h
along z and lateral offset rho from the sensor, so the sensor reads (eq 18)

    B_z(rho, h) = mu0 m / (4 pi) (2 h^2 - rho^2) / (rho^2 + h^2)^(5/2),

peaking at B0 = B_z(0, h) = mu0 m / (2 pi h^3) when aligned (eq 19). (The seed writes H; a Hall sensor reads the
flux density, so all fields here are B in tesla, B = mu0 H in air.) With x = rho / h the normalised reading is
(eq 20)

    q = B_z / B0 = (2 - x^2) / (2 (1 + x^2)^(5/2)).

q falls from 1 at x = 0 through 0 at x = sqrt(2) to its minimum -1/(25 sqrt 5) = -0.01789 at x = 2 (dq/dx =
x (3 x^2 - 12) / (2 (1 + x^2)^(7/2)) vanishes there) and rises back towards 0. The inverse used here is the
branch x in [0, 2] that contains the aligned state: q in [0, 1] maps to x in [0, sqrt 2], q in [q_min, 0) to
x in (sqrt 2, 2]; readings above 1 (noise) give x = 0 and readings below q_min give x = 2. Eq 21,
x ~ sqrt((1 - q) / 3), is its first-order expansion about x = 0 (q = 1 - 3 x^2 + O(x^4)), good for q > 0.7.

Bending a segment of arc length L by beta slides the wall fibre carrying the marker, at distance d from the
neutral axis, by rho = d |beta| relative to the sensor. With d = h this is eq 22 (kappa = rho / (L h),
beta = L kappa = rho / h); a separate lever arm d is kept because the marker fibre and the dipole gap need not
coincide, and the seed's +-90 degree operator calibration is what fixes it (:func:`calibrate_lever_arm`).
The dipole reading is even in the offset, so the direction is not in eq 18; as the seed states, it is read from
the sign of H_z: H_z > 0 is a leftward (positive) bend, H_z < 0 a rightward (negative) one. A reading is
therefore sign(beta) B0 q(d |beta| / h), and the inverse is

    beta = sign(B_z) (h / d) x(|B_z| / B0),    kappa = beta / L,    r = 1 / kappa.

The sign is unambiguous only while the reading keeps it, d |beta| / h < sqrt 2: a station measures bends up to
|beta| = sqrt(2) h / d (81 degrees for d = h); beyond, B_z changes sign and reads as a bend the other way. Several
stations along the robot split a large bend (two stations see 45 degrees each of a 90 degree bend).
Near beta = 0 the reading's magnitude is B0 (1 - 3 (d beta / h)^2): a dead zone where noise delta gives
|beta| ~ sqrt(delta / (3 B0)) (h / d), as the seed observes when beta changes sign.

Each segment is an arc of constant curvature (eq 23: xi = [r (1 - cos beta), 0, r sin beta] in the segment's
frame, tangent along z, bending towards x); consecutive segments are chained so that each starts at the end
point and tangent of the one before.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: x = rho / h at the zero crossing of eq 20 and at its minimum, and the minimum value of q.
X_ZERO = float(np.sqrt(2.0))
X_MIN = 2.0
Q_MIN = -1.0 / (25.0 * np.sqrt(5.0))


def marker_field_z(rho, gap, moment) -> np.ndarray:
    """B_z (T) of a z-aligned dipole of ``moment`` (A m^2) at lateral offset ``rho`` and gap ``gap`` (m), eq 18
    (the point dipole of :func:`magsoro.fields.dipole.dipole_B`; inputs broadcast)."""
    from magsoro.fields.dipole import dipole_B  # lazy: keeps `magsoro sense` free of Warp

    rho, h, m = np.broadcast_arrays(np.asarray(rho, dtype=float), np.asarray(gap, dtype=float),
                                    np.asarray(moment, dtype=float))
    r = np.stack([rho.ravel(), np.zeros(rho.size), h.ravel()], axis=1)  # sensor relative to the marker
    return (m.ravel() * dipole_B(r, (0.0, 0.0, 1.0))[:, 2]).reshape(rho.shape)


def peak_field(gap, moment) -> np.ndarray:
    """B0 = mu0 m / (2 pi h^3) (T), the aligned reading of eq 19."""
    return marker_field_z(0.0, gap, moment)


def normalised_ratio(x) -> np.ndarray:
    """q(x) = (2 - x^2) / (2 (1 + x^2)^(5/2)) with x = rho / h (eq 20)."""
    x = np.asarray(x, dtype=float)
    return (2.0 - x * x) / (2.0 * (1.0 + x * x) ** 2.5)


def _dq_dx(x):
    return x * (3.0 * x * x - 12.0) / (2.0 * (1.0 + x * x) ** 3.5)


def offset_closed_form(q) -> np.ndarray:
    """x = rho / h from eq 21, sqrt((1 - q) / 3); valid for q > 0.7 (q > 1 gives 0)."""
    q = np.asarray(q, dtype=float)
    return np.sqrt(np.clip(1.0 - q, 0.0, None) / 3.0)


def offset_exact(q) -> np.ndarray:
    """x = rho / h solving eq 20 exactly on the branch x in [0, 2] (see the module docstring).

    Vectorised bisection on the monotone branch to a bracket of 2^-60, then one Newton step; the result
    satisfies q(x) = q to rounding wherever dq/dx is not tiny.
    """
    q = np.clip(np.asarray(q, dtype=float), Q_MIN, 1.0)
    lo = np.where(q >= 0.0, 0.0, X_ZERO)
    hi = np.where(q >= 0.0, X_ZERO, X_MIN)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        # q decreases on the branch: the root is above mid where q(mid) > q
        above = normalised_ratio(mid) > q
        lo = np.where(above, mid, lo)
        hi = np.where(above, hi, mid)
    x = 0.5 * (lo + hi)
    slope = _dq_dx(x)
    ok = np.abs(slope) > 1e-3
    step = np.where(ok, (normalised_ratio(x) - q) / np.where(ok, slope, 1.0), 0.0)
    x_newton = x - step
    inside = (x_newton >= lo) & (x_newton <= hi)
    x = np.where(ok & inside, x_newton, x)
    # the ends of the branch exactly (the bisection only brackets them to 2^-60)
    return np.where(q >= 1.0, 0.0, np.where(q <= Q_MIN, X_MIN, x))


@dataclass(frozen=True)
class SensingStation:
    """One Hall sensor and its marker.

    segment_length : arc length L of the segment it senses, m.
    peak_field : B0, the aligned reading (eq 19), T.
    gap : h, sensor-marker gap along the sensor axis, m.
    lever_arm : d, distance of the marker fibre from the neutral axis, m (default h, eq 22).
    column : name of its column in a readings CSV.
    """

    segment_length: float
    peak_field: float
    gap: float
    lever_arm: float | None = None
    column: str = "Bz"

    def __post_init__(self):
        for key in ("segment_length", "peak_field", "gap"):
            if not getattr(self, key) > 0:
                raise ValueError(f"{key} must be > 0, got {getattr(self, key)}")
        if self.lever_arm is not None and not self.lever_arm > 0:
            raise ValueError(f"lever_arm must be > 0 m, got {self.lever_arm}")

    @property
    def arm(self) -> float:
        """Lever arm d (m)."""
        return self.gap if self.lever_arm is None else self.lever_arm

    def reading(self, bend_angle) -> np.ndarray:
        """Noise-free sensor reading (T) for segment bend angles ``bend_angle`` (rad): sign(beta) B0 q(d|beta|/h)."""
        beta = np.asarray(bend_angle, dtype=float)
        sign = np.where(beta >= 0.0, 1.0, -1.0)
        return sign * self.peak_field * normalised_ratio(self.arm * np.abs(beta) / self.gap)

    def bend_angle(self, reading, inverse: str = "exact") -> np.ndarray:
        """Bend angle beta (rad) of the segment from readings B_z (T): sign(B_z) (h/d) x(|B_z| / B0)."""
        bz = np.asarray(reading, dtype=float)
        q = np.abs(bz) / self.peak_field
        if inverse == "exact":
            x = offset_exact(q)
        elif inverse == "closed-form":
            x = offset_closed_form(q)
        else:
            raise ValueError(f"inverse must be 'exact' or 'closed-form', got {inverse!r}")
        return np.where(bz >= 0.0, 1.0, -1.0) * x * self.gap / self.arm

    def curvature(self, reading, inverse: str = "exact") -> np.ndarray:
        """kappa = beta / L (1/m), eq 22."""
        return self.bend_angle(reading, inverse) / self.segment_length


def low_pass(times, values, time_constant: float) -> np.ndarray:
    """Causal first-order low-pass of ``values`` (T, ...) sampled at ``times`` (s) with ``time_constant`` (s):
    y_k = y_(k-1) + (1 - exp(-dt / tau)) (v_k - y_(k-1)), exact for a piecewise-constant input. tau = 0 returns
    the input. Applied to bend angles, which are continuous, never to readings, which jump sign at beta = 0."""
    v = np.asarray(values, dtype=float)
    if time_constant <= 0 or len(v) < 2:
        return v.copy()
    t = np.asarray(times, dtype=float)
    out = np.empty_like(v)
    out[0] = v[0]
    gain = 1.0 - np.exp(-np.clip(np.diff(t), 0.0, None) / time_constant)
    for k in range(1, len(v)):
        out[k] = out[k - 1] + gain[k - 1] * (v[k] - out[k - 1])
    return out


def calibrate_lever_arm(station: SensingStation, bend_angles, readings) -> float:
    """Lever arm d (m) that best explains ``readings`` (T) taken at known ``bend_angles`` (rad), e.g. the seed's
    +-90 degree operator calibration: least squares of the bend-angle error with the exact inverse."""
    from scipy.optimize import least_squares

    beta = np.asarray(bend_angles, dtype=float)
    x = offset_exact(np.abs(np.asarray(readings, dtype=float)) / station.peak_field)
    ok = np.abs(beta) > 1e-6
    if not ok.any():
        raise ValueError("calibration needs at least one non-zero bend angle")

    def res(p):
        return station.gap * x[ok] / p[0] - np.abs(beta[ok])

    # start from the ratio of the largest bend, where the inverse is best conditioned
    k = int(np.argmax(np.abs(beta) * ok))
    d0 = station.gap * x[k] / abs(beta[k]) if x[k] > 0 else station.gap
    sol = least_squares(res, [d0], bounds=([1e-9], [np.inf]), x_scale=[station.gap])
    return float(sol.x[0])


def _frame(base_tangent, bend_normal):
    t = np.asarray(base_tangent, dtype=float)
    n = np.asarray(bend_normal, dtype=float)
    t = t / np.linalg.norm(t)
    n = n - (n @ t) * t
    return t, n / np.linalg.norm(n)


def reconstruct_centreline(bend_angles, segment_lengths, points_per_segment: int = 20, base_position=(0, 0, 0),
                           base_tangent=(0, 0, 1), bend_normal=(1, 0, 0)):
    """Centreline of chained constant-curvature segments (eq 23).

    bend_angles : (T, S) or (S,) segment bend angles beta (rad), base to tip, for T samples.
    segment_lengths : (S,) arc lengths (m).
    Returns (s, points): arc lengths (P,) from the base (m) and positions (T, P, 3) in metres, with
    P = S (points_per_segment - 1) + 1; the last point is the tip.
    """
    beta = np.atleast_2d(np.asarray(bend_angles, dtype=float))
    lengths = np.asarray(segment_lengths, dtype=float).ravel()
    if beta.shape[1] != len(lengths):
        raise ValueError(f"{beta.shape[1]} bend angles per sample but {len(lengths)} segment lengths")
    n_t = len(beta)
    t0, n0 = _frame(base_tangent, bend_normal)
    p = np.tile(np.asarray(base_position, dtype=float), (n_t, 1))
    t = np.tile(t0, (n_t, 1))
    n = np.tile(n0, (n_t, 1))
    s_all = [np.zeros(1)]
    pts = [p[:, None, :].copy()]
    s_start = 0.0
    frac = np.linspace(0.0, 1.0, points_per_segment)[1:]
    for k, L in enumerate(lengths):
        theta = beta[:, k][:, None] * frac[None, :]  # angle turned at each sample point (T, P-1)
        # xi = [r (1 - cos th), r sin th] = s [ (th/2) sinc^2(th/2), sinc(th) ], stable as kappa -> 0
        s_loc = L * frac[None, :]
        along = s_loc * np.sinc(theta / np.pi)
        across = s_loc * 0.5 * theta * np.sinc(theta / (2.0 * np.pi)) ** 2
        seg = p[:, None, :] + along[..., None] * t[:, None, :] + across[..., None] * n[:, None, :]
        pts.append(seg)
        s_all.append(s_start + L * frac)
        b = beta[:, k][:, None]
        t, n = np.cos(b) * t + np.sin(b) * n, -np.sin(b) * t + np.cos(b) * n
        p = seg[:, -1, :]
        s_start += L
    return np.concatenate(s_all), np.concatenate(pts, axis=1)


# ------------------------------------------------------------------------------------------- files
def read_readings(path, time_column: str, columns: list[str]):
    """Times (T,) in s and readings (T, S) in T from a CSV with a header naming ``time_column`` and ``columns``."""
    from magsoro.actuation.config import ActuationInputError

    path = Path(path)
    if not path.is_file():
        raise ActuationInputError(f"{path}: no such file")
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        header = reader.fieldnames or []
        missing = [c for c in [time_column, *columns] if c not in header]
        if missing:
            raise ActuationInputError(f"{path}: missing column(s) {missing}; the header has {header}")
        rows = list(reader)
    if not rows:
        raise ActuationInputError(f"{path}: no data rows")
    t = np.empty(len(rows))
    data = np.empty((len(rows), len(columns)))
    for i, row in enumerate(rows):
        try:
            t[i] = float(row[time_column])
            data[i] = [float(row[c]) for c in columns]
        except (TypeError, ValueError):
            raise ActuationInputError(f"{path}: line {i + 2}: not a number in {[time_column, *columns]}") from None
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(data))):
        raise ActuationInputError(f"{path}: non-finite values")
    return t, data


def read_centrelines(path):
    """A centreline CSV (columns t, s, x, y, z in s and m) as {t: (s (P,), points (P, 3))}."""
    from magsoro.actuation.config import ActuationInputError

    path = Path(path)
    if not path.is_file():
        raise ActuationInputError(f"{path}: no such file")
    try:
        data = np.genfromtxt(path, delimiter=",", names=True)
    except ValueError as exc:
        raise ActuationInputError(f"{path}: {exc}") from None
    need = ("t", "s", "x", "y", "z")
    if data.dtype.names is None or any(c not in data.dtype.names for c in need):
        raise ActuationInputError(f"{path}: needs columns {list(need)}, has {data.dtype.names}")
    data = np.atleast_1d(data)
    out = {}
    for t in np.unique(data["t"]):
        rows = data[data["t"] == t]
        order = np.argsort(rows["s"])
        rows = rows[order]
        out[float(t)] = (rows["s"].astype(float), np.stack([rows["x"], rows["y"], rows["z"]], axis=1).astype(float))
    return out


def write_centrelines(path, times, s, points) -> None:
    """Write centrelines (T, P, 3) sampled at arc lengths s (P,) as CSV rows t, s, x, y, z (s, m)."""
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "s", "x", "y", "z"])
        for k, t in enumerate(times):
            for j, sj in enumerate(s):
                x, y, z = points[k, j]
                w.writerow([f"{t:.9g}", f"{sj:.9g}", f"{x:.9e}", f"{y:.9e}", f"{z:.9e}"])


def centreline_rmse(times, s, points, truth: dict) -> dict:
    """RMSE (m) between reconstructed centrelines and ground truth {t: (s, points)} at the reconstructed arc
    lengths (the truth is interpolated linearly in s); also the RMSE and largest error of the tip."""
    errs, tip_errs = [], []
    keys = np.array(sorted(truth))
    for k, t in enumerate(times):
        j = int(np.argmin(np.abs(keys - t)))
        if abs(keys[j] - t) > 1e-9 * max(1.0, abs(t)):
            continue
        ts, tp = truth[float(keys[j])]
        ref = np.stack([np.interp(s, ts, tp[:, c]) for c in range(3)], axis=1)
        d = np.linalg.norm(points[k] - ref, axis=1)
        errs.append(d)
        tip_errs.append(d[-1])
    if not errs:
        return {"matched_samples": 0}
    e = np.concatenate(errs)
    tip = np.asarray(tip_errs)
    return {
        "matched_samples": len(errs),
        "rmse_m": float(np.sqrt(np.mean(e * e))),
        "tip_rmse_m": float(np.sqrt(np.mean(tip * tip))),
        "tip_max_error_m": float(tip.max()),
    }


def stations_from_calibration(calib) -> list[SensingStation]:
    """The :class:`SensingStation` list of a :class:`~magsoro.actuation.config.SensingCalibration`."""
    return [SensingStation(s.segment_length, s.peak_field, s.gap, s.lever_arm, s.column) for s in calib.stations]


def sense(readings_path, calib, out, truth_path=None) -> dict:
    """Reconstruct centrelines from a readings CSV with a calibration; write DIR/centreline.csv (t, s, x, y, z),
    DIR/angles.csv (t, beta and kappa per station, tip position) and DIR/centreline.png; return a summary."""
    import json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stations = stations_from_calibration(calib)
    t, bz = read_readings(readings_path, calib.time_column, [s.column for s in stations])
    beta = np.stack([st.bend_angle(bz[:, k], calib.inverse) for k, st in enumerate(stations)], axis=1)
    beta = low_pass(t, beta, calib.smoothing_time)
    lengths = [st.segment_length for st in stations]
    s, pts = reconstruct_centreline(beta, lengths, calib.points_per_segment, calib.base_position,
                                    calib.base_tangent, calib.bend_normal)
    write_centrelines(out / "centreline.csv", t, s, pts)
    with (out / "angles.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", *[f"beta_{st.column}" for st in stations], *[f"kappa_{st.column}" for st in stations],
                    "tip_x", "tip_y", "tip_z"])
        for k in range(len(t)):
            w.writerow([f"{t[k]:.9g}", *[f"{b:.9e}" for b in beta[k]],
                        *[f"{b / L:.9e}" for b, L in zip(beta[k], lengths)], *[f"{v:.9e}" for v in pts[k, -1]]])
    summary = {
        "samples": int(len(t)),
        "stations": [st.column for st in stations],
        "robot_length_m": float(sum(lengths)),
        "inverse": calib.inverse,
        "bend_angle_range_rad": [float(beta.min()), float(beta.max())],
        "files": ["centreline.csv", "angles.csv", "centreline.png"],
    }
    if truth_path is not None:
        summary["truth"] = str(truth_path)
        summary.update(centreline_rmse(t, s, pts, read_centrelines(truth_path)))
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    summary["files"].append("summary.json")
    _plot(out / "centreline.png", t, pts, calib)
    return summary


def _plot(path, t, pts, calib) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0, n0 = _frame(calib.base_tangent, calib.bend_normal)
    base = np.asarray(calib.base_position, dtype=float)
    along = (pts - base) @ t0
    across = (pts - base) @ n0
    fig, ax = plt.subplots(figsize=(5, 5))
    picks = np.unique(np.linspace(0, len(t) - 1, min(len(t), 12)).round().astype(int))
    cmap = plt.get_cmap("viridis")
    for i, k in enumerate(picks):
        ax.plot(1e3 * across[k], 1e3 * along[k], color=cmap(i / max(1, len(picks) - 1)), label=f"t = {t[k]:.3g} s")
    ax.set_aspect("equal")
    ax.set_xlabel("bend normal [mm]")
    ax.set_ylabel("base tangent [mm]")
    ax.legend(fontsize=7)
    ax.set_title(calib.name or "reconstructed centrelines")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def synthetic_readings(stations: list[SensingStation], bend_angles, noise: float = 0.0, rng=None) -> np.ndarray:
    """Readings (T, S) in tesla for segment bend angles (T, S) in rad, plus Gaussian noise of standard
    deviation ``noise`` (T) -- the forward model of the module docstring, for tests and examples."""
    beta = np.atleast_2d(np.asarray(bend_angles, dtype=float))
    out = np.stack([st.reading(beta[:, k]) for k, st in enumerate(stations)], axis=1)
    if noise > 0:
        rng = np.random.default_rng(rng)
        out = out + rng.normal(0.0, noise, out.shape)
    return out
